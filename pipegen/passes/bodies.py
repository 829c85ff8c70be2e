"""Rewriting a technique's code body by body, for the passes whose rewrite changes few bodies:
a body the rewrite leaves as it is stays the same object, and so do its function, its pass and,
when no body changes, the technique.  What later phases learnt of such a body, keyed by its
identity (``ir.facts.code_facts``, the backends' light-row plans), is then found again instead
of being worked out once more for an equal copy (``ir.walk.map_technique_code`` rebuilds every
statement that holds an expression)."""

from __future__ import annotations

import dataclasses
from typing import Callable

from pipegen.ir import nodes as ir


def map_bodies(tech: ir.Technique, rewrite: Callable[[tuple], tuple]) -> ir.Technique:
    """``tech`` with ``rewrite`` applied to every function body (packing functions included)
    and pass body; ``rewrite`` returns its argument itself to keep a body."""
    def function(f: ir.Function) -> ir.Function:
        body = rewrite(f.body)
        return f if body is f.body else dataclasses.replace(f, body=body)

    def pass_(p: ir.Pass) -> ir.Pass:
        body = rewrite(p.body)
        return p if body is p.body else dataclasses.replace(p, body=body)

    packings = tuple(_kept(k, "functions", tuple(function(f) for f in k.functions))
                     for k in tech.packings)
    functions = tuple(function(f) for f in tech.functions)
    passes = tuple(pass_(p) for p in tech.passes)
    if _same(packings, tech.packings) and _same(functions, tech.functions) \
            and _same(passes, tech.passes):
        return tech
    return dataclasses.replace(tech, packings=packings, functions=functions, passes=passes)


def _kept(record, field: str, items: tuple):
    """``record`` itself when ``items`` are its ``field``'s own objects, else a copy with them."""
    return record if _same(items, getattr(record, field)) else \
        dataclasses.replace(record, **{field: items})


def _same(a: tuple, b: tuple) -> bool:
    return len(a) == len(b) and all(x is y for x, y in zip(a, b))
