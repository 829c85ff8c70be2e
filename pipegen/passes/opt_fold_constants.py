"""opt_fold_constants: evaluate constant scalar expressions and branches at compile time.

Folding follows the runtime's arithmetic, not Python's: floats in float32 (``float32.f32``:
numpy's float32 results without importing numpy), ints as
32-bit two's complement, uints modulo 2^32.  Anything whose result could differ between
backends (division by zero, shifts out of range, NaN-producing operations) is left alone so
that both backends evaluate it the same way at run time.
"""

from __future__ import annotations

import math
import operator

from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.core.float32 import f32
from pipegen.passes.bodies import map_bodies

_ARITH = {"+": operator.add, "-": operator.sub, "*": operator.mul}
_COMPARE = {"==": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le,
            ">": operator.gt, ">=": operator.ge}
_BITS = {"&": operator.and_, "|": operator.or_, "^": operator.xor}


def run(tech: ir.Technique) -> ir.Technique:
    return map_bodies(tech, _fold_body)


def _fold_body(body: tuple) -> tuple:
    """``body`` folded; itself (bodies.map_bodies) when none of its expressions and statements
    folds: folding rewrites bottom-up, so a body where nothing folds as it is stays as it is."""
    if not (any(fold_expr(e) is not e for e in irwalk.exprs_of(body))
            or any(_fold_stmt(s) is not None for s in irwalk.walk_stmts(body))):
        return body
    return irwalk.rewrite_stmts(body, fold_expr, _fold_stmt)


def _scalar_const(e: ir.Expr) -> bool:
    return isinstance(e, ir.Const) and e.type.is_scalar


def _wrap(value: int, t: ir.Type) -> int:
    if t.scalar is ir.Scalar.UINT:
        return value & 0xFFFFFFFF
    return (value + 2 ** 31) % 2 ** 32 - 2 ** 31     # two's complement wrap


def fold_expr(e: ir.Expr) -> ir.Expr:
    if isinstance(e, ir.Binary) and _scalar_const(e.left) and _scalar_const(e.right):
        value = _fold_binary(e.op, e.left, e.right)
        if value is not None:
            return ir.Const(e.type, value)
    if isinstance(e, ir.Unary) and _scalar_const(e.operand):
        v = e.operand.value
        if e.op == "!" and e.type == ir.BOOL:
            return ir.Const(ir.BOOL, not v)
        if e.op == "-" and e.type == ir.FLOAT:
            return ir.Const(ir.FLOAT, -f32(v))
        if e.op == "-" and e.type.scalar in (ir.Scalar.INT, ir.Scalar.UINT):
            return ir.Const(e.type, _wrap(-v, e.type))
    if isinstance(e, ir.Ternary) and isinstance(e.cond, ir.Const):
        return e.then if e.cond.value else e.other
    if isinstance(e, ir.Construct) and e.type.is_scalar and len(e.args) == 1 \
            and _scalar_const(e.args[0]):
        return _fold_conversion(e.type, e.args[0]) or e
    return e


def _fold_binary(op: str, a: ir.Const, b: ir.Const):
    t = a.type
    x, y = a.value, b.value
    if op in _COMPARE:
        if t == ir.FLOAT:
            x, y = f32(x), f32(y)
        return bool(_COMPARE[op](x, y))
    if op in ("&&", "||") and t == ir.BOOL:
        return (x and y) if op == "&&" else (x or y)
    if t == ir.FLOAT:
        if op in _ARITH:
            r = f32(_ARITH[op](f32(x), f32(y)))   # double, then float32: float32's result
            return r if math.isfinite(r) else None
        if op == "/" and y != 0:
            return _divide(f32(x), f32(y))
        return None
    if t.scalar in (ir.Scalar.INT, ir.Scalar.UINT):
        if op in _ARITH:
            return _wrap(_ARITH[op](x, y), t)
        if op in _BITS:
            return _wrap(_BITS[op](x, y), t)
        if op in ("<<", ">>") and 0 <= y < 32:
            if op == "<<":
                return _wrap(x << y, t)
            return _wrap((x & 0xFFFFFFFF if t.scalar is ir.Scalar.UINT else x) >> y, t)
        if op in ("/", "%") and y != 0 and (x >= 0 and y > 0):   # C truncation == floor here
            return x // y if op == "/" else x % y
    return None


def _divide(x: float, y: float) -> float:
    """float32 ``x / y`` (IEEE: a zero divisor gives ±inf, or NaN for 0/0 and NaN; the divisor
    is a float32 that may have rounded to zero although the constant was not zero)."""
    if y == 0:
        if x == 0 or math.isnan(x):
            return math.nan
        return math.copysign(math.inf, x) * math.copysign(1.0, y)
    return f32(x / y)


def _fold_conversion(t: ir.Type, c: ir.Const):
    v = c.value
    if t == ir.FLOAT:
        return ir.Const(t, f32(v))
    if t == ir.BOOL:
        return ir.Const(t, bool(v))
    if t.scalar in (ir.Scalar.INT, ir.Scalar.UINT):
        if c.type == ir.FLOAT and not (0 <= v < 2 ** 31):
            return None       # negative/huge float -> int conversions are backend-defined
        return ir.Const(t, _wrap(int(v), t))
    return None


def _fold_stmt(s: ir.Stmt):
    """``if (true) A else B`` -> A;  ``if (false) A`` -> nothing.  A branch that declares
    locals keeps its own scope (``if (true) { A }``): spliced into the enclosing block, its
    names could clash with the block's own (``{ float r; return r; } float r;``)."""
    if isinstance(s, ir.If) and isinstance(s.cond, ir.Const):
        branch = s.then if s.cond.value else s.other
        if any(isinstance(x, ir.Declare) for x in branch):
            kept = ir.If(ir.Const(ir.BOOL, True), tuple(branch))
            return None if kept == s else [kept]
        return list(branch)
    return None
