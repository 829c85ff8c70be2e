"""The shared C-like emitter: typed IR expressions and statements -> C-family source text.

One emitter, dialects as small subclasses of *data* (tinygrad's ``renderer/cstyle.py`` is the
model): ``type_names`` (IR type -> spelling), ``builtin_map`` (builtin -> name, ``{0}``-template
or callable), ``vector_ops`` (functions for component-wise vector comparisons), ``guards``
(builtins emitted through helper functions whose bodies are IR), ``builtin_lowerings`` (IR
rewrites of builtin calls, the backend's passes), literal spellings, qualifiers.  What
genuinely differs between GLSL and OpenCL C goes through the public ``render_*`` hooks at the
end of the class (stage inputs, the light table, target reads and writes, matrix arithmetic,
constructors, calls of user functions, ``return``, vector equality).  Dialects override only
those hooks and ``signature``; the ``_``-methods are the emitter's own.  No dialect knowledge
lives here.

Parenthesisation follows C precedence (GLSL's is the same), plus parentheses for clarity around
bit operations mixed with other operators and ``&&`` inside ``||``; nested ternaries are always
parenthesised.  The IR's evaluation order is kept: ``a - (b - c)``, ``a + (b + c)`` stay so.

Float literals are the shortest decimal that reads back as the same float32 (the value the shader
holds), so every constant round-trips exactly through either compiler.

Guarded forms (DESIGN.md §6-7).  The runtimes disagree where GLSL leaves results undefined, so
these builtins are emitted in forms defined (and equal) on both:

================  ============================================================================
normalize(v)      ``v * inversesqrt(max(dot(v, v), FLT_MIN))``: exact wherever dot(v, v) is a
                  normal float (|v| >= ~1.1e-19; below that the dot underflows anyway, and
                  denormals are flushed on both runtimes); normalize(0) = 0.
pow(x, y)         x > 0: pow(x, y).  x <= 0 (negative bases count as 0): 1 if y == 0, 0 if
                  y > 0, +inf if y < 0, i.e. IEEE pow(+0, y).  With a constant y > 0 the
                  inline ``pow(max(x, 0.0), y)`` is emitted (GLSL defines pow(0, y > 0) = 0).
inversesqrt(x)    x > 0: inversesqrt(x); otherwise +inf.
sqrt(x)           ``sqrt(max(x, 0.0))``: negative -> 0 (rounding noise in 1 - dot(e, e) ...).
log(x), log2(x)   x > 0: log(x); otherwise -inf.
a << b, a >> b    shift amount masked to 0..31 (``b & 31``, OpenCL's rule) unless constant.
uint(float x)     ``uint(max(x, 0.0))``: negative -> 0; >= 2^32 -> 0xffffffff (OpenCL converts
                  saturating, ``opencl/dialect.saturates``, as llvmpipe does).
declarations      locals without an initialiser are zero-initialised.
================  ============================================================================

Guards that need their argument twice are emitted as small helper functions ``pg_NAME_TYPES``
(built here as IR, so each dialect renders them with its own builtins); ``helper_source()``
returns their definitions once the shader's code has been rendered.
"""

from __future__ import annotations

import math
from typing import Callable, Optional, Sequence, Union

from pipegen.ir import nodes as ir
from pipegen.core.float32 import f32, f32_str
from pipegen.ir.light_layout import LightLayout, Place
from pipegen.ir.material_layout import MATERIAL_IDS, MaterialLayout, technique_material_layout
from pipegen.ir.nodes import BOOL, FLOAT, INT, VEC4, Scalar, Type
from pipegen.backends.light_rows import RowLoad, RowPlan, plan_rows

FLT_MIN = 2.0 ** -126   # smallest normal float32: the normalize() guard

# The row plans (light_rows.plan_rows) of the bodies emitted lately, by the identity of the body
# (held, so that its id stays its own) and whether material rows are planned: each pass's
# program emits every function the pass calls, so a function several passes call, in GLSL and
# in OpenCL, was planned once per pass and backend.  The plan is a function of the body, the
# layouts and the parameter names, which a hit must match.  A compile builds new bodies, so
# nothing is reused from one compile to the next; the bound is what a long-lived process keeps.
_ROW_PLANS: dict[tuple[int, bool], tuple] = {}
_ROW_PLANS_MAX = 1024


def row_plan(body: Sequence[ir.Stmt], layout: LightLayout, params: Sequence[str] = (),
             materials: Optional[MaterialLayout] = None) -> RowPlan:
    """``plan_rows(body, layout, params, materials)``, planned once per body."""
    params = tuple(params)
    key = (id(body), materials is not None)
    hit = _ROW_PLANS.get(key)
    if hit is not None and hit[0] is body and hit[1] == (layout, params, materials):
        return hit[2]
    plan = plan_rows(body, layout, params, materials)
    if isinstance(body, tuple):      # a list may change: planned each time
        if len(_ROW_PLANS) >= _ROW_PLANS_MAX:
            _ROW_PLANS.clear()
        _ROW_PLANS[key] = (body, (layout, params, materials), plan)
    return plan

# C precedence, higher binds tighter.
PREC = {"||": 3, "^^": 4, "&&": 5, "|": 6, "^": 7, "&": 8, "==": 9, "!=": 9, "<": 10,
        "<=": 10, ">": 10, ">=": 10, "<<": 11, ">>": 11, "+": 12, "-": 12, "*": 13, "/": 13,
        "%": 13}
TERNARY, UNARY, ATOM = 2, 14, 15
_CLARIFY = {"&", "|", "^", "<<", ">>"}


def _f(x: float) -> ir.Const:
    return ir.Const(FLOAT, x)


def _gt0(x: ir.Expr) -> ir.Expr:
    return ir.Binary(">", x, _f(0.0), BOOL)


def _call(name: str, args: Sequence[ir.Expr], t: Type) -> ir.Call:
    return ir.Call(name, tuple(args), t)


# Bodies of the guard helpers (scalar forms; "componentwise" ones are lifted per component).
_GUARDS: dict[str, Callable[..., ir.Expr]] = {
    "normalize": lambda v: ir.Binary("*", v, _call("inversesqrt", [_call("max", [
        _call("dot", [v, v], FLOAT), _f(FLT_MIN)], FLOAT)], FLOAT), v.type),
    "pow": lambda x, y: ir.Ternary(_gt0(x), _call("pow", [x, y], FLOAT), ir.Ternary(
        ir.Binary("==", y, _f(0.0), BOOL), _f(1.0),
        ir.Ternary(_gt0(y), _f(0.0), _f(math.inf), FLOAT), FLOAT), FLOAT),
    "inversesqrt": lambda x: ir.Ternary(_gt0(x), _call("inversesqrt", [x], FLOAT),
                                        _f(math.inf), FLOAT),
    "log": lambda x: ir.Ternary(_gt0(x), _call("log", [x], FLOAT), _f(-math.inf), FLOAT),
    "log2": lambda x: ir.Ternary(_gt0(x), _call("log2", [x], FLOAT), _f(-math.inf), FLOAT),
}
_COMPONENTWISE = frozenset({"pow", "inversesqrt", "log", "log2"})


def _positive_const(e: ir.Expr) -> bool:
    v = e.value if isinstance(e, ir.Const) else None
    vals = v if isinstance(v, tuple) else (v,)
    return v is not None and all(isinstance(x, (int, float)) and x > 0 for x in vals)


def _max0(x: ir.Expr) -> ir.Call:
    return _call("max", [x, _f(0.0)], x.type)


# The inline guards (no helper function), as IR rewrites: the scalar emitter below and the
# OpenCL wide emitter (backends/opencl/wide/) both apply these, so the rules live here only.
def guard_shift_count(right: ir.Expr) -> ir.Expr:
    """The count of ``a << b`` / ``a >> b``: masked to 0..31 (``b & 31``) unless a constant
    already in range."""
    if (isinstance(right, ir.Const) and not isinstance(right.value, tuple)
            and 0 <= right.value < 32):
        return right
    return ir.Binary("&", right, ir.Const(Type(right.type.scalar), 31), right.type)


def guard_call_args(name: str, args: Sequence[ir.Expr]) -> Optional[tuple]:
    """The arguments of builtin ``name`` with its inline guard applied (``sqrt(max(x, 0))``,
    ``pow(max(x, 0), y)`` for a constant y > 0), or None when it has none."""
    if name == "sqrt" or (name == "pow" and _positive_const(args[1])):
        return (_max0(args[0]),) + tuple(args[1:])
    return None


def guard_construct_args(t: Type, args: Sequence[ir.Expr]) -> tuple:
    """The arguments of constructor ``t(args)`` with the ``uint(float)`` guard applied
    (``uint(max(x, 0))`` unless x is a positive constant)."""
    if (t.scalar is Scalar.UINT and len(args) == 1 and args[0].type.scalar is Scalar.FLOAT
            and not _positive_const(args[0])):
        return (_max0(args[0]),)
    return tuple(args)


class CStyleLanguage:
    # ---- data a dialect overrides ------------------------------------------------------------
    type_names: dict[Type, str] = {}          # missing types are spelled str(Type) (GLSL style)
    builtin_map: dict[str, Union[str, Callable]] = {}  # "name" | "tmpl({0}, {1})" | fn
    vector_ops: dict[str, str] = {}           # op -> function, for vector-valued comparisons / !
    float_suffix = ""
    uint_suffix = "u"
    inf_literal = "INFINITY"
    nan_literal = "NAN"
    function_qualifier = ""                   # before every function definition
    reserved: frozenset = frozenset()         # identifiers renamed with a trailing "_"
    reserved_prefixes: tuple[str, ...] = ("gl_", "u_", "v_", "t_", "o_", "a_", "pg_")
    light_layout: Optional[LightLayout] = None   # the light table's rows (ir/light_layout.py)
    guards: dict[str, Callable[..., ir.Expr]] = _GUARDS   # builtin -> helper body (IR)
    componentwise: frozenset = _COMPONENTWISE  # guards lifted per component for vectors
    # builtin -> IR rewrite of a call (None: emit the call); the rewrites are compiler passes
    # (pipegen/passes) a backend runs on the technique first: this catches IR that reaches
    # the emitter without them (single expressions)
    builtin_lowerings: dict[str, Callable[[ir.Call], Optional[ir.Expr]]] = {}
    indent = "    "

    def __init__(self) -> None:
        self.helpers: dict[str, ir.Function] = {}
        self._raw = False   # rendering guard helpers: builtins are emitted as they are
        # the body being rendered: its light-row loads (light_rows.py) and the path of the
        # statement being rendered (None: outside a body)
        self._rows: Optional[RowPlan] = None
        self._path: Optional[tuple] = None
        self._materials: Optional[tuple] = None   # (technique, its MaterialLayout)

    # ---- names, types, literals ---------------------------------------------------------------
    def type_name(self, t: Type) -> str:
        name = self.type_names.get(t)
        return str(t) if name is None else name     # str(t) only when needed: it is not cheap

    def ident(self, name: str) -> str:
        if name in self.helpers:
            return name
        if name in self.reserved or name.startswith(self.reserved_prefixes):
            return name + "_"
        return name

    def render_float(self, x: float) -> str:
        f = f32(x)   # the value the shader holds (may overflow to inf)
        if math.isnan(f):
            return self.nan_literal
        if math.isinf(f):
            return self.inf_literal if f > 0 else "-" + self.inf_literal
        s = f32_str(f)  # the shortest digits that identify this float32 (as numpy prints it)
        if "." not in s and "e" not in s:
            s += ".0"
        return s + self.float_suffix

    def literal(self, value, t: Type) -> str:
        if t.scalar is Scalar.BOOL:
            return "true" if value else "false"
        if t.scalar is Scalar.FLOAT:
            return self.render_float(float(value))
        v = int(value)
        if t.scalar is Scalar.UINT:
            return f"{v & 0xFFFFFFFF}{self.uint_suffix}"
        return "(-2147483647 - 1)" if v == -2 ** 31 else str(v)

    def zero(self, t: Type) -> ir.Const:
        n = t.mat * t.mat if t.mat else t.size
        v = False if t.scalar is Scalar.BOOL else 0.0 if t.scalar is Scalar.FLOAT else 0
        return ir.Const(t, v if n == 1 else (v,) * n)

    # ---- expressions ----------------------------------------------------------------------------
    def expr(self, e: ir.Expr) -> str:
        return self._expr(e)[0]

    def _expr(self, e: ir.Expr) -> tuple[str, int]:
        return getattr(self, "_" + type(e).__name__.lower())(e)

    def _sub(self, e: ir.Expr, below: int) -> str:
        """``e`` as an operand that needs a precedence above ``below``."""
        s, p = self._expr(e)
        return f"({s})" if p <= below else s

    def _const(self, e: ir.Const) -> tuple[str, int]:
        if isinstance(e.value, tuple):
            el = Type(e.type.scalar)
            parts = [self.literal(v, el) for v in e.value]
            parts = parts[:1] if len(set(parts)) == 1 else parts
            return self.render_construct(e.type, parts, [el] * len(parts)), ATOM
        s = self.literal(e.value, e.type)
        return s, UNARY if s.startswith("-") else ATOM

    def _var(self, e: ir.Var) -> tuple[str, int]:
        if e.kind == "input":
            return self.render_input(e.name, e.type), ATOM
        if e.kind == "param":
            return self.render_param(e.name, e.type), ATOM
        return self.ident(e.name), ATOM

    def _unary(self, e: ir.Unary) -> tuple[str, int]:
        if e.type.is_vector and e.op in self.vector_ops:
            return f"{self.vector_ops[e.op]}({self.expr(e.operand)})", ATOM
        s, p = self._expr(e.operand)
        if p < UNARY or s[0] in "-+":      # never "--x" / "- -1.0"
            s = f"({s})"
        return e.op + s, UNARY

    def _binary(self, e: ir.Binary) -> tuple[str, int]:
        op, left, right = e.op, e.left, e.right
        assert not (op in ("&&", "||", "^^") and e.type.is_vector), \
            "vector logical operators are not in the language"
        if op in ("==", "!=") and left.type.is_vector and not e.type.is_vector:
            text = self.render_vector_equality(op, self.expr(left), self.expr(right))
            if text is not None:
                return text, ATOM
        if op in ("<<", ">>") and not self._raw:
            right = guard_shift_count(right)
        if left.type.is_matrix or right.type.is_matrix:
            text = self.render_matrix_op(op, self.expr(left), self.expr(right), left.type,
                                         right.type, e.type)
            if text is not None:
                return text, ATOM
        if e.type.is_vector and op in self.vector_ops:
            return f"{self.vector_ops[op]}({self.expr(left)}, {self.expr(right)})", ATOM
        return f"{self._operand(left, op, False)} {op} {self._operand(right, op, True)}", PREC[op]

    def _operand(self, e: ir.Expr, op: str, right: bool) -> str:
        s, p = self._expr(e)
        prec = PREC[op]
        sub = e.op if isinstance(e, ir.Binary) and p == PREC.get(e.op) else None
        clarify = sub is not None and sub != op and (
            op in _CLARIFY or sub in _CLARIFY or (op == "||" and sub == "&&"))
        return f"({s})" if p < prec or (right and p == prec) or clarify else s

    def _ternary(self, e: ir.Ternary) -> tuple[str, int]:
        return (f"{self._sub(e.cond, TERNARY)} ? {self._sub(e.then, TERNARY)} : "
                f"{self._sub(e.other, TERNARY)}", TERNARY)

    def _call(self, e: ir.Call) -> tuple[str, int]:
        if not e.builtin:
            return self.render_call(e.name, [self.expr(a) for a in e.args], e.type), ATOM
        lower = self.builtin_lowerings.get(e.name)
        lowered = lower(e) if lower is not None else None
        if lowered is not None:
            return f"({self.expr(lowered)})", ATOM
        args = e.args
        if not self._raw:
            guarded = guard_call_args(e.name, args)
            if guarded is not None:
                args = guarded
            elif e.name in self.guards:
                name = self.helper(e.name, [a.type for a in args], e.type)
                return f"{name}({', '.join(self.expr(a) for a in args)})", ATOM
        return self.render_builtin(e.name, [self.expr(a) for a in args],
                                   [a.type for a in args], e.type), ATOM

    def _construct(self, e: ir.Construct) -> tuple[str, int]:
        args = e.args if self._raw else guard_construct_args(e.type, e.args)
        return self.render_construct(e.type, [self.expr(a) for a in args],
                                     [a.type for a in args]), ATOM

    def _swizzle(self, e: ir.Swizzle) -> tuple[str, int]:
        if e.base.type.is_scalar:   # x.xxx: a splat
            return self.render_construct(e.type, [self.expr(e.base)], [e.base.type]), ATOM
        return f"{self._sub(e.base, UNARY)}.{e.components}", ATOM

    def _index(self, e: ir.Index) -> tuple[str, int]:
        return self.render_index(self._sub(e.base, UNARY), self.expr(e.index), e.base.type), ATOM

    def _lightfield(self, e: ir.LightField) -> tuple[str, int]:
        if e.field == "index":
            if e.index is None:
                index, itype = self.render_current_light(), ir.UINT
            else:
                index, itype = self.expr(e.index), e.index.type
            return (index if itype == e.type else self.render_construct(e.type, [index], [itype])), ATOM
        assert self.light_layout is not None and e.field in self.light_layout.places, \
            f"light field {e.field} not in the schema"
        place = self.light_layout.place(e.field)
        local = None if self._rows is None else self._rows.local_for(self._path, e)
        row = local[0] if local else self.render_light_row(self._light_index(e.index), place.row)
        return self.field_of_row(row, place, e.type), ATOM

    def _materialfield(self, e: ir.MaterialField) -> tuple[str, int]:
        row, place = self.material_row(e.field, self.expr(e.index), e.index.type)
        return self.field_of_row(row, place, e.type), ATOM

    def material_row(self, field: str, index: str, itype: Type) -> tuple[str, Place]:
        """The row (a vec4 expression) holding material ``field`` of object ``index`` and the
        field's place in it.  The records follow the lights in the light table
        (ir/material_layout.py); the id is clamped to the table's ids, so a stray id reads a
        record, never past the table."""
        ml = self.material_layout()
        offset, place = ml.place(field)
        if itype != INT:
            index = self.render_construct(INT, [index], [itype])
        record = f"clamp({index}, 0, {MATERIAL_IDS - 1})"
        if ml.stride > 1:
            record = f"{ml.stride} * {record}"
        record = f"{ml.base} + {record}" + (f" + {offset}" if offset else "")
        return self.render_light_row(record, place.row), place

    def material_layout(self) -> MaterialLayout:
        """The material layout of ``self.tech`` (ir/material_layout.py), laid out once per
        technique: every material read of a pass asks for it."""
        if self._materials is None or self._materials[0] is not self.tech:
            self._materials = (self.tech, technique_material_layout(self.tech))
        return self._materials[1]

    def _light_index(self, index: Optional[ir.Expr]) -> str:
        """A light-table index as an int expression (None: the light being drawn)."""
        if index is None:
            text, itype = self.render_current_light(), ir.UINT
        else:
            text, itype = self.expr(index), index.type
        return text if itype == INT else self.render_construct(INT, [text], [itype])

    def field_of_row(self, row: str, place: Place, t: Type) -> str:
        """A field of type ``t`` at ``place`` taken out of ``row`` (a vec4 expression)."""
        text = row if place.size == 4 else f"{row}.{place.components}"
        if t.scalar is Scalar.FLOAT:
            return text
        return self.render_construct(t, [text], [Type(Scalar.FLOAT, t.size)])

    def _load(self, e: ir.Load) -> tuple[str, int]:
        coord = None if e.coord is None else self.expr(e.coord)
        if e.sample is not None:
            return self.render_load_sample(e.target, coord, self.expr(e.sample), e.type), ATOM
        return self.render_load(e.target, coord, e.type), ATOM

    def _sample(self, e: ir.Sample) -> tuple[str, int]:
        return self.render_sample(e.target, self.expr(e.uv), e.type), ATOM

    def _targetsize(self, e: ir.TargetSize) -> tuple[str, int]:
        return self.render_target_size(e.target), ATOM

    # ---- guard helpers ------------------------------------------------------------------------
    def helper(self, name: str, types: Sequence[Type], ret: Type) -> str:
        """Register (once) and name the guard helper for builtin ``name`` at these types."""
        hname = "pg_" + "_".join([name] + [str(t) for t in types])
        if hname not in self.helpers:
            params = tuple(zip("xyzw", types))
            vs = [ir.Var(n, t) for n, t in params]
            if ret.is_vector and name in self.componentwise:
                scalar = self.helper(name, [Type(t.scalar) for t in types], Type(ret.scalar))
                body = ir.Construct(ret, tuple(ir.Call(scalar, tuple(
                    ir.Swizzle(v, "xyzw"[i], Type(v.type.scalar)) if v.type.is_vector else v
                    for v in vs), Type(ret.scalar), builtin=False) for i in range(ret.size)))
            else:
                body = self.guards[name](*vs)
            self.helpers[hname] = ir.Function(hname, params, ret, (ir.Return(body),))
        return hname

    def helper_source(self) -> str:
        """Definitions of the guard helpers used so far (dependencies first)."""
        self._raw = True
        try:
            return "\n\n".join(self.function(f) for f in self.helpers.values())
        finally:
            self._raw = False

    # ---- statements and functions ---------------------------------------------------------------
    def stmts(self, body: Sequence[ir.Stmt], depth: int = 1,
              params: Sequence[str] = ()) -> list[str]:
        """A block's lines; a whole body (``params``: its function's parameter names) has
        each light-table row it reads loaded once (``light_rows.py``)."""
        if self._path is None:
            if self.light_layout is None:
                return [line for s in body for line in self.stmt(s, depth)]
            self._rows, self._path = row_plan(body, self.light_layout, params), ()
            try:
                return self.stmts(body, depth)
            finally:
                self._rows, self._path = None, None
        out: list[str] = []
        block = self._path
        for k, s in enumerate(body):
            self._path = block + (k,)
            for load in self._rows.loads_before(self._path):
                out.append(self.indent * depth + self.row_declaration(load))
            out += self.stmt(s, depth)
        self._path = block
        return out

    def row_declaration(self, load: RowLoad) -> str:
        """The declaration loading one light-table row into its local."""
        row = self.render_light_row(self._light_index(load.index), load.row)
        return f"{self.type_name(VEC4)} {load.name} = {row};"

    def _block(self, name: str, body: Sequence[ir.Stmt], depth: int) -> list[str]:
        """The lines of nested block ``name`` (then, other, body) of the current statement."""
        if self._path is None:
            return self.stmts(body, depth)
        outer = self._path
        self._path = outer + (name,)
        try:
            return self.stmts(body, depth)
        finally:
            self._path = outer

    def stmt(self, s: ir.Stmt, depth: int) -> list[str]:
        pad = self.indent * depth
        if isinstance(s, ir.Declare):
            init = self.expr(s.init if s.init is not None else self.zero(s.type))
            return [f"{pad}{self.type_name(s.type)} {self.ident(s.name)} = {init};"]
        if isinstance(s, ir.Assign):
            return [f"{pad}{self.expr(s.target)} {s.op} {self.expr(s.value)};"]
        if isinstance(s, ir.Output):
            return [pad + line for line in
                    self.render_output(s.target, self.expr(s.value)).splitlines()]
        if isinstance(s, ir.If):
            out = [f"{pad}if ({self.expr(s.cond)}) {{", *self._block("then", s.then, depth + 1)]
            if len(s.other) == 1 and isinstance(s.other[0], ir.If):
                chained = self._block("other", s.other, depth)
                if not chained[0].lstrip().startswith("if ("):   # a row load before the if
                    return out + [f"{pad}}} else {{", *self._block("other", s.other, depth + 1),
                                  f"{pad}}}"]
                return out + [f"{pad}}} else {chained[0].lstrip()}"] + chained[1:]
            if s.other:
                out += [f"{pad}}} else {{", *self._block("other", s.other, depth + 1)]
            return out + [f"{pad}}}"]
        if isinstance(s, ir.For):
            v = self.ident(s.var)
            return [f"{pad}for ({self.type_name(s.type)} {v} = {self.expr(s.start)}; "
                    f"{v} < {self.expr(s.bound)}; {v}++) {{",
                    *self._block("body", s.body, depth + 1), f"{pad}}}"]
        if isinstance(s, ir.Break):
            return [f"{pad}break;"]
        if isinstance(s, ir.Continue):
            return [f"{pad}continue;"]
        if isinstance(s, ir.Return):
            return [pad + self.render_return(None if s.value is None else self.expr(s.value))]
        if isinstance(s, ir.Discard):
            return [pad + self.render_discard()]
        if isinstance(s, ir.ExprStmt):
            return [f"{pad}{self.expr(s.expr)};"]
        raise AssertionError(f"unknown statement {s!r}")

    def signature(self, f: ir.Function) -> str:
        params = ", ".join(f"{self.type_name(t)} {self.ident(n)}" for n, t in f.params)
        return f"{self.function_qualifier}{self.type_name(f.ret)} {self.ident(f.name)}({params})"

    def function(self, f: ir.Function) -> str:
        body = self.stmts(f.body, 1, [n for n, _ in f.params])
        return "\n".join([self.signature(f) + " {", *body, "}"])

    def functions_once(self, functions: Sequence[ir.Function], rendered: dict) -> list[str]:
        """The user functions a pass calls, as text, each rendered once per technique and
        ``function_key``: a function's text depends on the pass only through what that key
        holds.  Each is rendered by a language of its own (``fresh``), which then holds exactly
        the helpers (and the dialect's other needs) it uses, in the order it first uses them;
        taken in (``absorb``) in function order, they are what this one language would have
        collected rendering them itself.  ``rendered``: one dict for all the passes of a
        technique, (dialect, id of the function, key) -> (the function, kept so that its
        ``id`` stays its own; its text; the language that rendered it)."""
        code = []
        for f in functions:
            key = (type(self), id(f), self.function_key())
            if key not in rendered:
                own = self.fresh()
                rendered[key] = (f, own.function(f), own)
            _, text, own = rendered[key]
            self.absorb(own)
            code.append(text)
        return code

    def function_key(self) -> tuple:
        """What of the pass a user function's text depends on (``functions_once``)."""
        return ()

    def fresh(self) -> "CStyleLanguage":
        """A language for the same pass with nothing collected yet."""
        return type(self)()

    def absorb(self, other: "CStyleLanguage") -> None:
        """Take in what ``other`` collected rendering a function (its guard helpers)."""
        for name, helper in other.helpers.items():
            self.helpers.setdefault(name, helper)

    # ---- hooks: what differs between dialects ----------------------------------------------------
    def render_builtin(self, name: str, args: list[str], types: list[Type], ret: Type) -> str:
        t = self.builtin_map.get(name, name)
        if callable(t):
            return t(self, args, types, ret)
        if "{" in t:   # a template; it must yield a primary expression
            return t.format(*args, args=", ".join(args))
        return f"{t}({', '.join(args)})"

    def render_construct(self, t: Type, args: list[str], types: list[Type]) -> str:
        return f"{self.type_name(t)}({', '.join(args)})"

    def render_call(self, name: str, args: list[str], ret: Type) -> str:
        """A call of user (or guard helper) function ``name`` (the IR name)."""
        return f"{self.ident(name)}({', '.join(args)})"

    def render_return(self, value: Optional[str]) -> str:
        """A ``return`` statement (``value``: the rendered expression, None for none)."""
        return "return;" if value is None else f"return {value};"

    def render_vector_equality(self, op: str, left: str, right: str) -> Optional[str]:
        """``==`` / ``!=`` of two vectors, giving one bool (all / any component): a primary
        expression, or None for the infix operator (GLSL's meaning)."""
        return None

    def render_index(self, base: str, index: str, base_type: Type) -> str:
        return f"{base}[{index}]"

    def render_matrix_op(self, op: str, left: str, right: str, lt: Type, rt: Type,
                         result: Type) -> Optional[str]:
        """Arithmetic with a matrix operand (``*`` with a matrix and a vector or matrix is the
        linear-algebra product): a primary expression, or None for the infix operator."""
        return None

    def render_discard(self) -> str:
        return "discard;"

    def render_param(self, name: str, t: Type) -> str:
        raise NotImplementedError("technique parameters are folded before emission")

    def render_input(self, name: str, t: Type) -> str:
        raise NotImplementedError

    def render_current_light(self) -> str:
        """The (uint) index of the light this pass is drawing."""
        raise NotImplementedError

    def render_light_row(self, index: str, row: int) -> str:
        """Row ``row`` (a vec4) of the record of light ``index`` (an int expression)."""
        raise NotImplementedError

    def render_load(self, target: str, coord: Optional[str], t: Type) -> str:
        raise NotImplementedError

    def render_load_sample(self, target: str, coord: Optional[str], sample: str,
                           t: Type) -> str:
        """Sample ``sample`` of multisampled ``target`` at this pixel (``coord`` None) or at
        ``coord``, clamped to the target as ``load`` is."""
        raise NotImplementedError

    def render_sample(self, target: str, uv: str, t: Type) -> str:
        raise NotImplementedError

    def render_target_size(self, target: str) -> str:
        raise NotImplementedError

    def render_output(self, target: str, value: str) -> str:
        """One or more complete statements writing ``value`` to colour target ``target``."""
        raise NotImplementedError


def texel_select(t) -> str:
    """The swizzle that takes a value of type ``t`` out of a texel (always 4 components):
    ``""`` for vec4, ``".xyz"`` for vec3, ``".x"`` for scalars."""
    return "" if t.size == 4 else "." + "xyzw"[:t.size]
