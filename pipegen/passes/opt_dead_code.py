"""opt_dead_code: drop the statements after a top-level ``return`` of a function or pass body.

Folding can turn a guard into an unconditional return (``if (shadow_tile < 0.0) return 1.0;``
with ``shadow_tile`` folded to -1 becomes ``return 1.0;``); what follows it never runs, and
dropping it lets ``opt_unused_functions`` drop what only it called and ``opt_unread_reads``
drop the targets only it read.  Only the top level: a ``return`` inside a branch or loop leaves
the statements after that block reachable.
"""

from __future__ import annotations

import dataclasses

from pipegen.ir import nodes as ir


def run(tech: ir.Technique) -> ir.Technique:
    packings = tuple(_packing(k) for k in tech.packings)
    functions = tuple(_function(f) for f in tech.functions)
    passes = tuple(_pass(p) for p in tech.passes)
    if _same(packings, tech.packings) and _same(functions, tech.functions) \
            and _same(passes, tech.passes):
        return tech
    return dataclasses.replace(tech, packings=packings, functions=functions, passes=passes)


def until_return(body: tuple) -> tuple:
    """``body`` without the statements after its first top-level ``return``."""
    for k, s in enumerate(body):
        if isinstance(s, ir.Return):
            return body if k + 1 == len(body) else tuple(body[:k + 1])
    return body


def _same(new: tuple, old: tuple) -> bool:
    return all(a is b for a, b in zip(new, old))


def _function(f: ir.Function) -> ir.Function:
    body = until_return(f.body)
    return f if body is f.body else dataclasses.replace(f, body=body)


def _pass(p: ir.Pass) -> ir.Pass:
    body = until_return(p.body)
    return p if body is p.body else dataclasses.replace(p, body=body)


def _packing(k: ir.Packing) -> ir.Packing:
    functions = tuple(_function(f) for f in k.functions)
    return k if _same(functions, k.functions) else dataclasses.replace(k, functions=functions)
