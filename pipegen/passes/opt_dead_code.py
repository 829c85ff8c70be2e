"""opt_dead_code: drop the statements after a top-level ``return`` of a function or pass body.

Folding can turn a guard into an unconditional return (``if (shadow_tile < 0.0) return 1.0;``
with ``shadow_tile`` folded to -1 becomes ``return 1.0;``); what follows it never runs, and
dropping it lets ``opt_unused_functions`` drop what only it called and ``opt_unread_reads``
drop the targets only it read.  Only the top level: a ``return`` inside a branch or loop leaves
the statements after that block reachable.
"""

from __future__ import annotations

from pipegen.ir import nodes as ir
from pipegen.passes.bodies import map_bodies


def run(tech: ir.Technique) -> ir.Technique:
    return map_bodies(tech, until_return)      # the technique itself when nothing follows


def until_return(body: tuple) -> tuple:
    """``body`` without the statements after its first top-level ``return``."""
    for k, s in enumerate(body):
        if isinstance(s, ir.Return):
            return body if k + 1 == len(body) else tuple(body[:k + 1])
    return body

