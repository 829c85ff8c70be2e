"""The wide path's expressions: per component, in the scalar code's operation order, uniform
components kept uniform and varying ones ``W`` wide; ``cstyle``'s guarded forms rendered from
the same IR, ``load``/``sample`` through the wide gathers of ``cl_pass.cl.j2``, builtins
through the prelude's functions (their ``W``-wide overloads: ``helpers``), the library
functions whose wide forms may differ lane by lane.  A mixin of ``emitter.WideEmitter``."""

from __future__ import annotations

from pipegen.ir import expand, nodes as ir
from pipegen.ir.builtins import BIT_CAST_BUILTINS
from pipegen.ir.nodes import Scalar, Type
from pipegen.backends.cstyle import guard_call_args, guard_construct_args, guard_shift_count
from pipegen.backends.opencl.dialect import saturates
from pipegen.backends.opencl.expansions import c_text
from pipegen.backends.opencl.wide.values import (
    C_TYPES_W, W, Unsupported, Val, varying_inputs, widen)

# library functions whose float8 forms may differ from their scalar forms: lane by lane
_LANEWISE = {"sin", "cos", "tan", "atan", "atan2", "ceil", "rint", "step"}


class WideExpressions:
    """Expressions and builtin calls of ``WideEmitter``."""

    # ---- expressions ---------------------------------------------------------------------------
    def expr(self, e) -> Val:
        return getattr(self, "_" + type(e).__name__.lower())(e)

    def _const(self, e: ir.Const) -> Val:
        el = Type(e.type.scalar)
        vals = e.value if isinstance(e.value, tuple) else (e.value,) * max(1, e.type.size)
        if e.type.is_matrix:
            raise Unsupported("matrix constant")
        return Val([self.lang.literal(v, el) for v in vals], e.type, False)

    def _var(self, e: ir.Var) -> Val:
        if e.kind == "input":
            if e.name in varying_inputs():
                return Val([f"win->{e.name}[{k}]" for k in range(e.type.size)], e.type, True)
            s = self.lang.render_input(e.name, e.type)
            if e.type.is_matrix or e.type.size == 1:
                return Val([s], e.type, False)
            for suffix in (".xyzw", ".xyz", ".xy"):
                if s.endswith(suffix):
                    s = s[:-len(suffix)]
                    break
            return Val([f"{s}.{'xyzw'[k]}" for k in range(e.type.size)], e.type, False)
        if e.kind == "param":
            return Val([self.lang.render_param(e.name, e.type)], e.type, False) \
                if e.type.size == 1 else self._const(ir.Const(e.type, tuple(
                    next(p.default for p in self.tech.params if p.name == e.name))))
        if e.name not in self.env:
            raise Unsupported(f"unknown local {e.name}")
        return self.env[e.name]

    def _unary(self, e: ir.Unary) -> Val:
        v = self.expr(e.operand)
        if e.op == "!":
            return Val([f"(~{c})" if v.varying else f"(!{c})" for c in v.comps], e.type, v.varying)
        return Val([f"({e.op}{c})" for c in v.comps], e.type, v.varying)

    def _binary(self, e: ir.Binary) -> Val:
        op = e.op
        lt, rt = e.left.type, e.right.type
        if lt.is_matrix or rt.is_matrix:
            return self._matrix_op(e)
        right = e.right
        if op in ("<<", ">>") and not getattr(self, "_raw", 0):
            right = guard_shift_count(right)      # cstyle's rule: the count masked to 0..31
        a, b = self.expr(e.left), self.expr(right)
        vary = a.varying or b.varying
        if op in ("&&", "||", "^^"):
            if not vary:
                sym = {"&&": "&&", "||": "||", "^^": "!="}[op]
                return Val([f"({a.comps[0]} {sym} {b.comps[0]})"], e.type, False)
            ac = a.comps[0] if a.varying else widen(a.comps[0], Scalar.BOOL)
            bc = b.comps[0] if b.varying else widen(b.comps[0], Scalar.BOOL)
            sym = {"&&": "&", "||": "|", "^^": "^"}[op]
            return Val([f"({ac} {sym} {bc})"], e.type, True)
        if op in ("/", "%") and e.type.scalar in (Scalar.INT, Scalar.UINT) and vary:
            if not (isinstance(e.right, ir.Const) and not isinstance(e.right.value, tuple)
                    and e.right.value != 0):
                raise Unsupported("varying integer division")
        n = max(len(a.comps), len(b.comps))
        ac = a.comps if len(a.comps) == n else a.comps * n
        bc = b.comps if len(b.comps) == n else b.comps * n
        if op in ("<<", ">>") and b.varying and not a.varying:
            # OpenCL C: a scalar left operand takes a scalar count only
            ac = [widen(c, e.type.scalar) for c in ac]
        if op in ("==", "!=") and lt.is_vector and not e.type.is_vector:
            parts = [f"({x} {op} {y})" for x, y in zip(ac, bc)]
            if vary:
                j = " & " if op == "==" else " | "
            else:
                j = " && " if op == "==" else " || "
            return Val([f"({j.join(parts)})"], e.type, vary)
        return Val([f"({x} {op} {y})" for x, y in zip(ac, bc)], e.type, vary)

    def _matrix_op(self, e: ir.Binary) -> Val:
        a, b = self.expr(e.left), self.expr(e.right)
        lt, rt = e.left.type, e.right.type
        if a.varying and lt.is_matrix or b.varying and rt.is_matrix:
            raise Unsupported("varying matrix")
        if not a.varying and not b.varying:
            l = self._cvec(a)
            r = self._cvec(b)
            text = self.lang.render_matrix_op(e.op, l, r, lt, rt, e.type)
            if e.type.is_matrix or e.type.size == 1:
                return Val([text], e.type, False)
            self.ntmp += 1
            name = f"pg_wt{self.ntmp}"
            self.pre.append(f"const {self.lang.type_name(e.type)} {name} = {text};")
            return Val([f"{name}.{'xyzw'[k]}" for k in range(e.type.size)], e.type, False)
        if e.op != "*":
            raise Unsupported("varying matrix arithmetic")
        # the prelude's products component by component, in expand's order
        if lt.is_matrix and rt.is_vector:
            m, v = a.comps[0], self.tmp(b)
            n = lt.mat
            return Val([c_text(expand.matrix_vector([f"{m}.c[{j}].{'xyzw'[k]}" for j in range(n)],
                                                    v.comps)) for k in range(n)], e.type, True)
        if lt.is_vector and rt.is_matrix:
            v, m = self.tmp(a), b.comps[0]
            n = rt.mat
            columns = [[f"{m}.c[{k}].{'xyzw'[j]}" for j in range(n)] for k in range(n)]
            return Val([c_text(d) for d in expand.vector_matrix(v.comps, columns)], e.type, True)
        raise Unsupported("varying matrix arithmetic")

    def _cvec(self, v: Val) -> str:
        if v.type.is_matrix or v.type.size == 1:
            return v.comps[0]
        return f"(({self.lang.type_name(v.type)})({', '.join(v.comps)}))"

    def _ternary(self, e: ir.Ternary) -> Val:
        c, a, b = self.expr(e.cond), self.expr(e.then), self.expr(e.other)
        if e.type.is_matrix:
            if c.varying or a.varying or b.varying:
                raise Unsupported("varying matrix")
            return Val([f"({c.comps[0]} ? {a.comps[0]} : {b.comps[0]})"], e.type, False)
        vary = a.varying or b.varying or c.varying
        s = e.type.scalar
        ac = [x if a.varying or not vary else widen(x, s) for x in a.comps]
        bc = [x if b.varying or not vary else widen(x, s) for x in b.comps]
        if not c.varying:
            return Val([f"({c.comps[0]} ? {x} : {y})" for x, y in zip(ac, bc)], e.type, vary)
        m = self.tmp(c).comps[0] if len(ac) > 1 else c.comps[0]
        if s is Scalar.UINT or s is Scalar.FLOAT or s is Scalar.INT or s is Scalar.BOOL:
            return Val([f"pg_sel({y}, {x}, {m})" for x, y in zip(ac, bc)], e.type, True)
        raise Unsupported("ternary type")

    def _construct(self, e: ir.Construct) -> Val:
        t = e.type
        if t.is_matrix:
            vals = [self.expr(a) for a in e.args]
            if any(v.varying for v in vals):
                raise Unsupported("varying matrix")
            return Val([self.lang.render_construct(t, [self._cvec(v) for v in vals],
                                                   [a.type for a in e.args])], t, False)
        vals = [self.expr(a) for a in guard_construct_args(t, e.args)]
        if any(v.type.is_matrix for v in vals):
            raise Unsupported("vector from a matrix")
        vary = any(v.varying for v in vals)
        comps = []
        for v in vals:
            for c in v.comps:
                c = self._convert(c, v.type.scalar, t.scalar, v.varying)
                if vary and not v.varying:
                    c = widen(c, t.scalar)
                comps.append(c)
        if len(comps) == 1 and t.size > 1:
            comps = comps * t.size
        return Val(comps[:t.size], t, vary)

    def _convert(self, c: str, src: Scalar, dst: Scalar, varying: bool) -> str:
        if src is dst:
            return c
        if not varying:
            return self.lang.render_construct(Type(dst), [c], [Type(src)])
        if dst is Scalar.BOOL:
            return f"({c} != 0)" if src is not Scalar.FLOAT else f"({c} != 0.0f)"
        if src is Scalar.BOOL:
            c = f"(-{c})"
            src = Scalar.INT
        sat = "_sat" if saturates(src, dst) else ""
        return f"convert_{C_TYPES_W[dst]}{sat}({c})"

    def _swizzle(self, e: ir.Swizzle) -> Val:
        v = self.expr(e.base)
        if e.base.type.is_scalar:
            return Val(v.comps * e.type.size, e.type, v.varying)
        return Val([v.comps["xyzw".index(c)] for c in e.components], e.type, v.varying)

    def _index(self, e: ir.Index) -> Val:
        base, idx = self.expr(e.base), self.expr(e.index)
        if e.base.type.is_matrix:
            if base.varying or idx.varying:
                raise Unsupported("varying matrix index")
            col = f"{base.comps[0]}.c[{idx.comps[0]}]"
            return Val([f"{col}.{'xyzw'[k]}" for k in range(e.type.size)], e.type, False)
        if isinstance(e.index, ir.Const):
            return Val([base.comps[int(e.index.value)]], e.type, base.varying)
        if idx.varying:
            raise Unsupported("varying vector index")
        b = self.tmp(base)
        i = idx.comps[0]
        acc = b.comps[-1]
        for k in range(len(b.comps) - 2, -1, -1):
            acc = f"({i} == {k} ? {b.comps[k]} : {acc})"
        return Val([acc], e.type, base.varying)

    def table_row(self, index: "ir.Expr | None", row_of,
                  name: "str | None" = None) -> tuple[str, bool]:
        """A row of the light table (a ``float4`` texel) at ``index`` (None: the light being
        drawn), as (text, lanes).  Uniform: ``row_of(index text, index type, False)``.  At a
        varying index the row is gathered lane by lane into a local array of ``W`` rows
        (lanes True; ``name``: the array's, else a temporary), lane ``j``'s row
        ``row_of(lane j's index, type, True)``: the scalar code's read at that lane's index."""
        if index is None:
            return row_of(self.lang.render_current_light(), ir.UINT, False), False
        iv = self.expr(index)
        if not iv.varying:
            return row_of(iv.comps[0], index.type, False), False
        i = self.tmp(iv).comps[0]
        if name is None:
            self.ntmp += 1
            name = f"pg_wt{self.ntmp}"
        rows = ", ".join(row_of(f"{i}.s{j}", index.type, True) for j in range(W))
        self.count_gathers(self.loop_weight)
        self.pre.append(f"const {self.lang.type_name(ir.VEC4)} {name}[{W}] = {{{rows}}};")
        return name, True

    def light_row_of(self, row: int):
        """``row_of`` for ``table_row``: row ``row`` of a light's record.  A lane's record is
        clamped to the table: a lane that does not use the light still loads its row (LIDR's
        ``i - 1u`` of an empty slot, under a lane mask); one that uses it reads the record
        the scalar code reads."""
        def row_of(index: str, itype: Type, lane: bool) -> str:
            if itype != ir.INT:
                index = self.lang.render_construct(ir.INT, [index], [itype])
            if lane:
                index = f"clamp({index}, 0, {self._table_records() - 1})"
            return self.lang.render_light_row(index, row)
        return row_of

    def _table_records(self) -> int:
        """Records in the light table: its lights, then the material records (runtime's
        ``light_table.table_records``)."""
        n = max(1, self.tech.lights.capacity)
        if self.tech.materials is not None:
            n += self.lang.material_layout().records
        return n

    def _lightfield(self, e: ir.LightField) -> Val:
        if e.field == "index":
            if e.index is None:
                index, itype = Val([self.lang.render_current_light()], ir.UINT, False), ir.UINT
            else:
                index, itype = self.expr(e.index), e.index.type
            c = self._convert(index.comps[0], itype.scalar, e.type.scalar, index.varying)
            return Val([c], e.type, index.varying)
        place = self.lang.light_layout.place(e.field)
        local = None if self.rows is None else self.rows.local_for(self.path, e)
        if local is not None:       # its row, loaded once (light_rows.py)
            return self._row_field(local[0], place, e.type, local[0] in self.lane_rows)
        row, lanes = self.table_row(e.index, self.light_row_of(place.row))
        return self._row_field(row, place, e.type, lanes)

    def _materialfield(self, e: ir.MaterialField) -> Val:
        local = None if self.rows is None else self.rows.local_for(self.path, e)
        if local is not None:       # its row, loaded once (light_rows.py)
            return self._row_field(local[0], local[1], e.type, local[0] in self.lane_rows)
        place = self.lang.material_layout().place(e.field)[1]
        row, lanes = self.table_row(e.index, self.material_row_of(e.field))
        return self._row_field(row, place, e.type, lanes)

    def material_row_of(self, field: str):
        """``row_of`` for ``table_row``: the row holding material ``field`` (the scalar
        code's read: the id clamped to the table's ids, so every lane's is in the table)."""
        return lambda index, itype, lane: self.lang.material_row(field, index, itype)[0]

    def _row_field(self, row: str, place, t: Type, lanes: bool = False) -> Val:
        """The components of a table field at ``place`` of ``row``: a uniform row's, or (lanes)
        those of ``row``'s ``W`` lane rows, each lane converted as the scalar code does."""
        def conv(c: str) -> str:
            if t.scalar is Scalar.FLOAT:
                return c
            return self.lang.render_construct(Type(t.scalar), [c], [ir.FLOAT])
        if not lanes:
            return Val([conv(f"{row}.{k}") for k in place.components], t, False)
        if t.scalar is Scalar.BOOL:
            raise Unsupported("boolean table field at a varying index")
        wide = C_TYPES_W[t.scalar]
        return Val([f"(({wide})({', '.join(conv(f'{row}[{j}].{k}') for j in range(W))}))"
                    for k in place.components], t, True)

    def _gather(self, fn: str, args: list, t: Type) -> Val:
        self.ntmp += 1
        name = f"pg_wt{self.ntmp}"
        s = "uint" if t.scalar is Scalar.UINT else "float"
        self.pre.append(f"const pgw_{s}{W}x4 {name} = {fn}(in, {', '.join(args)});")
        return Val([f"{name}.c[{k}]" for k in range(t.size)], t, True)

    def _load(self, e: ir.Load) -> Val:
        if e.sample is not None:
            raise Unsupported("load_sample")
        if e.coord is None:
            args = ["win->pix[0]", "win->pix[1]"]
        else:
            v = self.expr(e.coord)
            args = [c if v.varying else widen(c, Scalar.INT) for c in v.comps]
        return self._gather(f"pgw_load_{e.target}", args, e.type)

    def _sample(self, e: ir.Sample) -> Val:
        v = self.expr(e.uv)
        args = [c if v.varying else widen(c, Scalar.FLOAT) for c in v.comps]
        return self._gather(f"pgw_sample_{e.target}", args, e.type)

    def _targetsize(self, e: ir.TargetSize) -> Val:
        s = self.lang.render_target_size(e.target)
        return Val([f"{s}.x", f"{s}.y"], e.type, False)

    # ---- calls ---------------------------------------------------------------------------------
    def _call(self, e: ir.Call) -> Val:
        if not e.builtin:
            return self.user_call(e)
        lower = self.lang.builtin_lowerings.get(e.name)
        lowered = lower(e) if lower is not None else None
        if lowered is not None:
            return self.expr(lowered)
        args = e.args
        name = e.name
        if getattr(self, "_raw", 0):            # guard bodies: builtins as they are
            pass
        elif (guarded := guard_call_args(name, args)) is not None:   # cstyle's inline guards
            args = guarded
        elif name in self.lang.guards:
            return self._guard(name, args, e.type)
        return self._builtin(name, [self.expr(a) for a in args], e.type)

    def _guard(self, name: str, args, ret: Type) -> Val:
        """A guarded builtin: the guard's IR body over temporaries of the arguments, per
        component for the componentwise guards (as ``cstyle.helper`` builds the helpers)."""
        vals = [self.tmp(self.expr(a)) for a in args]
        if ret.is_vector and name in self.lang.componentwise:
            out, vary = [], False
            for k in range(ret.size):
                parts = [Val([v.comps[k] if len(v.comps) > 1 else v.comps[0]],
                             Type(v.type.scalar), v.varying) for v in vals]
                r = self._guard_body(name, parts, Type(ret.scalar))
                out += r.comps
                vary = vary or r.varying
            return Val(out, ret, vary)
        return self._guard_body(name, vals, ret)

    def _guard_body(self, name: str, vals: list, ret: Type) -> Val:
        saved = dict(self.env)
        names = []
        for k, v in enumerate(vals):
            n = f"pgw_guard_arg{k}"
            self.env[n] = v
            names.append(ir.Var(n, v.type))
        body = self.lang.guards[name](*names)
        self._raw = getattr(self, "_raw", 0) + 1
        try:
            return self.expr(body)
        finally:
            self._raw -= 1
            self.env = saved

    def _builtin(self, name: str, vals: list, ret: Type) -> Val:
        vary = any(v.varying for v in vals)
        # expand's trees, the prelude's order, over the components; an operand used twice
        # is in temporaries first
        if name == "dot":
            a, b = vals
            return Val([c_text(expand.dot(a.comps, b.comps))], ret, vary)
        if name in ("length", "distance"):
            def length(comps: list):
                v = self.tmp(Val([c_text(c) for c in comps], vals[0].type, vary))
                return expand.length(v.comps)
            tree = length(vals[0].comps) if name == "length" else expand.distance(
                vals[0].comps, vals[1].comps, length_of=length)
            return Val([c_text(tree, call=lambda f, args: self._render1(f, args, ir.FLOAT))],
                       ret, vary)
        if name == "cross":
            a, b = self.tmp(vals[0]), self.tmp(vals[1])
            return Val([c_text(c) for c in expand.cross(a.comps, b.comps)], ret, vary)
        if name == "mix":
            a, b, t = self.tmp(vals[0]), vals[1], vals[2]
            n = ret.size
            tc = t.comps if len(t.comps) == n else t.comps * n
            return Val([c_text(expand.mix(x, y, z)) for x, y, z in zip(a.comps, b.comps, tc)],
                       ret, vary)
        if name in BIT_CAST_BUILTINS:
            if vary:
                raise Unsupported("varying bit cast")
            text = self.lang.render_builtin(name, [self._cvec(v) for v in vals],
                                            [v.type for v in vals], ret)
            return self._from_vec(text, ret)
        if name not in ("abs", "sign", "floor", "ceil", "round", "fract", "mod", "min", "max",
                        "clamp", "step", "smoothstep", "sqrt", "exp", "exp2", "log", "log2",
                        "pow", "inversesqrt", "sin", "cos", "tan", "atan"):
            raise Unsupported(f"builtin {name}")
        # componentwise
        n = ret.size
        out = []
        macro = name in ("mod", "fract", "pow", "exp", "log")   # macros use an argument twice
        if macro:
            vals = [self.tmp(v) for v in vals]
        for k in range(n):
            cs, ts = [], []
            for v in vals:
                c = v.comps[k] if len(v.comps) > 1 else v.comps[0]
                if vary and not v.varying:
                    c = widen(c, v.type.scalar)
                cs.append(c)
                ts.append(Type(v.type.scalar))
            out.append(self._render1(name, cs, Type(ret.scalar), ts, vary))
        return Val(out, ret, vary)

    def _render1(self, name: str, args: list, ret: Type, types=None, vary: bool = False) -> str:
        types = types or [ret] * len(args)
        text = self.lang.render_builtin(name, args, types, ret)
        if vary:
            head = text.split("(", 1)[0]
            if head in _LANEWISE:
                text = f"PGW_LANES{len(args)}({head}, {ret.scalar.value}, {', '.join(args)})"
        return text

    def _from_vec(self, text: str, t: Type) -> Val:
        if t.size == 1:
            return Val([text], t, False)
        self.ntmp += 1
        name = f"pg_wt{self.ntmp}"
        self.pre.append(f"const {self.lang.type_name(t)} {name} = {text};")
        return Val([f"{name}.{'xyzw'[k]}" for k in range(t.size)], t, False)
