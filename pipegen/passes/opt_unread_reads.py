"""opt_unread_reads: a pass stops reading the targets its code no longer reads.

A pass's ``reads`` lists the targets its body and the functions it calls read (``load``,
``sample``, ``size``).  When earlier passes fold that code away (a scene without
shadow-casting lights: ``shadow_factor`` becomes ``return 1.0``, no ``load(shadow_atlas)``
is left), the target stays bound and keeps the pass that writes it alive; dropping it from
``reads`` lets ``cull_unread`` remove the writer and the target.  Reads by the depth test are
not in ``reads`` (``depth_target``) and are left alone.
"""

from __future__ import annotations

import dataclasses

from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.ir.facts import pass_functions


def run(tech: ir.Technique) -> ir.Technique:
    passes = tuple(_pass(tech, p) for p in tech.passes)
    if all(a is b for a, b in zip(passes, tech.passes)):
        return tech
    return dataclasses.replace(tech, passes=passes)


def _pass(tech: ir.Technique, p: ir.Pass) -> ir.Pass:
    if not p.reads:
        return p
    used = targets_read(tech, p)
    reads = tuple(r for r in p.reads if r in used)
    return p if len(reads) == len(p.reads) else dataclasses.replace(p, reads=reads)


def targets_read(tech: ir.Technique, p: ir.Pass) -> set[str]:
    """The targets the code of pass ``p`` (its body and the functions it reaches) reads."""
    out: set[str] = set()
    for stmts in [p.body] + [f.body for f in pass_functions(tech, p.body)]:
        for e in irwalk.walk_exprs(stmts):
            if isinstance(e, (ir.Load, ir.Sample, ir.TargetSize)):
                out.add(e.target)
    return out
