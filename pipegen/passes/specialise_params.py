"""specialise_params: replace every technique parameter read in shader code by its value.

Parameters are compile-time constants: a sweep compiles one variant per parameter set, so each
variant's shaders see literals the later folding pass can simplify (loop bounds, branches on
feature switches).
"""

from __future__ import annotations

from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.passes.bodies import map_bodies


def run(tech: ir.Technique) -> ir.Technique:
    values = {p.name: p for p in tech.params}

    def replace(e: ir.Expr) -> ir.Expr:
        if isinstance(e, ir.Var) and e.kind == "param":
            p = values[e.name]
            return ir.Const(e.type, _typed(p.default, e.type))
        return e

    def specialise(body: tuple) -> tuple:
        # a body that reads no parameter is kept as it is (bodies.map_bodies)
        if not any(type(e) is ir.Var and e.kind == "param" for e in irwalk.exprs_of(body)):
            return body
        return irwalk.rewrite_stmts(body, replace)

    return map_bodies(tech, specialise)


def _typed(value, t: ir.Type):
    if t.scalar is ir.Scalar.FLOAT:
        return float(value)
    if t.scalar is ir.Scalar.BOOL:
        return bool(value)
    return int(value)
