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

from pipegen.ir import nodes as ir
from pipegen.ir.facts import code_facts, pass_functions


def run(tech: ir.Technique) -> ir.Technique:
    passes = tuple(_pass(tech, p) for p in tech.passes)
    if all(a is b for a, b in zip(passes, tech.passes)):
        return tech
    return dataclasses.replace(tech, passes=passes)


def _pass(tech: ir.Technique, p: ir.Pass) -> ir.Pass:
    if not p.reads:
        return p
    # ``code_facts`` walks each body once and keeps it for the emitters, which ask the same;
    # the functions are looked at only for the reads the body itself does not make
    missing = set(p.reads) - code_facts(p.body).reads
    if missing:
        for f in pass_functions(tech, p.body):
            missing -= code_facts(f.body).reads
            if not missing:
                break
    if not missing:
        return p
    return dataclasses.replace(p, reads=tuple(r for r in p.reads if r not in missing))
