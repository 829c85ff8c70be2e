"""lower_mix_constant: ``mix(x, y, t)`` with a constant float ``t`` -> ``x * (1 - t) + y * t``.

llvmpipe's GLSL compiler (NIR) rewrites a ``mix`` whose weight is a constant into two products
and a sum, with ``1 - t`` folded in float32 (measured on Mesa 22.3: bit-exact), while a
variable weight is evaluated as ``x + (y - x) * t``.  The two round differently, so the OpenCL
reference must see the same split: the CL backend runs this pass on the technique before it
emits (``backends/opencl/emit.py``); the GLSL backend does not (llvmpipe does it itself), and
the IR stays backend-neutral.

``lower_call`` is the rewrite of one call (``None`` when it does not apply); the OpenCL dialect
also applies it to builtin calls that reach its emitter without this pass (single
expressions rendered in tests).
"""

from __future__ import annotations

from typing import Optional

from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.core.float32 import f32
from pipegen.passes.bodies import map_bodies


def run(tech: ir.Technique) -> ir.Technique:
    """The technique with every body that holds such a ``mix`` rewritten; the others are
    kept as they are (``bodies.map_bodies``: what emission learnt of them is reused)."""
    def lower(body: tuple) -> tuple:
        # lowering a call never makes another one lowerable: a body without one is kept
        if not any(type(e) is ir.Call and lower_call(e) is not None
                   for e in irwalk.exprs_of(body)):
            return body
        return irwalk.rewrite_stmts(body, _lower_expr)

    return map_bodies(tech, lower)


def _lower_expr(e: ir.Expr) -> ir.Expr:
    if isinstance(e, ir.Call):
        lowered = lower_call(e)
        if lowered is not None:
            return lowered
    return e


def lower_call(e: ir.Call) -> Optional[ir.Expr]:
    """``x * (1 - t) + y * t`` for ``mix(x, y, t)`` with a float constant ``t`` (a literal,
    or a vector constructor of literals: NIR folds both to constants), else None."""
    if not (e.builtin and e.name == "mix" and len(e.args) == 3):
        return None
    x, y, t = e.args
    values = _float_constant(t)
    if values is None:
        return None
    one_minus = tuple(f32(1.0 - f32(v)) for v in values)      # float32's 1 - t
    om = ir.Const(t.type, one_minus if t.type.is_vector else one_minus[0])
    return ir.Binary("+", ir.Binary("*", x, om, e.type), ir.Binary("*", y, t, e.type), e.type)


def _float_constant(t: ir.Expr) -> Optional[tuple[float, ...]]:
    """The components of a constant float scalar or vector, else None."""
    if t.type.scalar is not ir.Scalar.FLOAT or t.type.is_matrix:
        return None
    if isinstance(t, ir.Const):
        return t.value if isinstance(t.value, tuple) else (t.value,)
    if isinstance(t, ir.Construct) and all(
            isinstance(a, ir.Const) and a.type == ir.FLOAT for a in t.args) \
            and len(t.args) in (1, t.type.size):
        values = tuple(a.value for a in t.args)
        return values * t.type.size if len(values) == 1 else values
    return None
