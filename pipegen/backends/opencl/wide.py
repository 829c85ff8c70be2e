"""The OpenCL backend's wide fragment function: the fragment code of a pass evaluated for
``W`` pixels of one triangle at once, explicit SIMD over pixels (ISPC's model), because PoCL's
work-group vectoriser does not vectorise the raster kernel (its work-item loop encloses the
triangle and pixel loops, and LLVM 14 does not widen the ``float3``/``float4`` instructions of
the scalar code: "instruction return type cannot be vectorized").

``wide_fragment(tech, pass_, lang) -> str | None`` renders ``pg_fragment_w`` from the IR, or
None when the code uses what this form does not support (the pass then keeps the scalar
``pg_fragment`` only; nothing changes for it).  The lowering, in the spirit of Mesa's
``nir_lower_alu_to_scalar``:

- every value is a list of scalar *components* (a ``vec3`` is three values, matrices stay
  whole and must be uniform); arithmetic is per component in the scalar code's operation
  order: ``dot`` = ``x + (y + (z + w))`` of unfused products, the guarded forms of
  ``cstyle`` (normalize, pow, inversesqrt, log, sqrt, ``uint(float)``) rendered from the same
  IR, the matrix products of the prelude component by component; ``FP_CONTRACT OFF`` holds, so
  each lane computes exactly what the scalar function computes for its pixel;
- a component is *uniform* (one ``float``/``int``/``uint``/``bool`` for all lanes: frame
  values, technique parameters, the light table at a uniform index, the triangle's flat
  inputs, loop counters) or *varying* (``float8``/``int8``/``uint8``, booleans as ``int8``
  masks -1/0: the interpolated inputs, ``frag_coord``, ``load``/``sample`` of targets and
  everything computed from them).  Locals start uniform and become varying when a varying
  value or a varying branch assigns them (the function is re-rendered until that settles);
  user functions are specialised per call by which arguments are varying;
- control flow on uniform conditions stays control flow (the per-light loops, light-type
  branches); an ``if`` on a varying condition is if-converted: both branches run under masks
  and assignments become ``select``; a varying ``?:`` evaluates both sides (pure code);
  ``discard`` under a varying condition clears lanes of the returned live mask; ``break``
  and ``continue`` under a varying condition make the loop keep masks of the lanes that left
  it (it ends when all have), ``return`` under one a mask of the lanes that returned and
  their values (the function is rendered again in that form).  Light-table reads at a
  varying index (light-indexed shading: each lane its own light, measured 2-3x slower
  wide), varying matrices, varying bit casts and integer division by a varying divisor are
  not supported (None: the scalar path).  Passes whose estimated work per pixel (``cost``)
  is below ``MIN_COST`` keep the scalar path too (the batching does not pay there), and the
  raster kernel shades a triangle's row batch of fewer than ``WMIN`` pixels with the scalar
  function.  A ``load``/``sample`` counts ``GATHER_COST`` against the estimate (0 since the
  gathers are wide: see the constant).

Builtins the generated code calls with varying operands have ``W``-wide overloads in
``wide_helpers()`` (the prelude's definitions applied lane by lane, so the values are the
scalar ones).  ``load``/``sample`` are wide as well (``pgw_load_T`` / ``pgw_sample_T`` in
``cl_pass.cl.j2``): the scalar ``pg_load_T`` / ``pg_sample_T``'s edge clamps, pixel indices,
texel coordinates, weights and lerps as W-wide operations in the same order, only the
memory reads (and decodings other than half's) lane by lane.  The raster kernel batches the
pixels of a triangle's row that pass coverage (and early depth/stencil), fills ``pgw_in``
lane by lane with the scalar interpolation, calls ``pg_fragment_w`` and blends lane by lane,
in pixel order.
"""

from __future__ import annotations

import functools
import os
from typing import Optional

from pipegen.core.records import record
from pipegen.ir import nodes as ir
from pipegen.ir.builtins import BIT_CAST_BUILTINS, FLAT_SCENE_INPUTS, STAGE_INPUTS, Where
from pipegen.ir.nodes import Scalar, Type
from pipegen.ir.walk import child_exprs
from pipegen.backends import plan as planlib
from pipegen.backends.cstyle import guard_call_args, guard_construct_args, guard_shift_count

W = 8                       # lanes: llvmpipe shades 8 pixels at once as well (the helpers
                            # below are written for 8)
# Measured (one pass's raster kernel alone, its scalar and wide programs interleaved in one
# process, 640x360, 2 PoCL threads, medians of 15-21 runs on a shared 2-core machine; scalar
# -> wide ms, two rounds on scene many_lights / two on mixed_lights), pass (cost, gathers):
#   deferred_calver point_lights (226, 9)    60.3 -> 47.6, 45.7 -> 38.0 / 23.1 -> 15.3, 22.2 -> 15.5
#   deferred directional_lights (178, 3)     - / 10.4 -> 8.8, 11.9 -> 10.1
#   deferred shade_cone (173, 3)             - / 0.80 -> 0.58, 1.15 -> 0.80
#   inferred lighting (184, 3)               6.1 -> 5.8, 7.5 -> 7.0 / 2.37 -> 2.30, 4.3 -> 5.0
#   light_prepass light_accumulation (129, 2)  19.7 -> 19.1, 22.1 -> 20.8 / 8.7 -> 6.9, 7.0 -> 5.7
#   lidr_bitplanes spot_indices (122, 1)     - / 4.0 -> 3.4, 3.0 -> 2.4
#   lidr_bitplanes light_indices (86, 1)     16.9 -> 18.0, 19.6 -> 20.0 / 7.2 -> 6.5, 7.7 -> 7.0
#   deferred shade_light_volume (84, 3)      0.29 -> 0.26, 0.30 -> 0.27 / 0.85 -> 0.79, 0.95 -> 0.85
#   deferred_calver global_lights (46, 3)    5.5 -> 7.4, 5.5 -> 8.2 / 8.1 -> 9.5, 5.9 -> 8.5
# ("-": no such light in the scene).  The wide form pays from a cost of about 100 on, gathers
# or not (no shipped pass without gathers has a cost between 84 and 150: that range's bound
# is not measured for gather-free code)
MIN_COST = 100              # below this estimated work per pixel, the scalar function only
# what a load()/sample() costs the wide form more: nothing measurable since the gathers are
# wide (lane by lane through the scalar functions, 25 kept point_lights scalar, and forcing it
# wide measured 35 vs 30 ms; with the wide gathers its kernel is 17-34 % faster wide, above)
GATHER_COST = 0
WMIN = 4                    # a row's batch of fewer pixels is shaded pixel by pixel
# False (or PIPEGEN_CL_WIDE=0 in the environment): every pass keeps the scalar path (tests,
# before/after benchmarks); the emitted text then is the scalar path's alone
ENABLED = os.environ.get("PIPEGEN_CL_WIDE", "1") != "0"
# False (or PIPEGEN_CL_XBATCH=0): a wide pass batches the pixels of one triangle's row only,
# never across triangles (cl_pass.cl.j2's cross-triangle batches; comparisons)
CROSS_TRIANGLE = os.environ.get("PIPEGEN_CL_XBATCH", "1") != "0"
MARK = "/* pg_fragment_w */"     # the first line of the wide function's text (has_wide)

# library functions whose float8 forms may differ from their scalar forms: lane by lane
_LANEWISE = {"sin", "cos", "tan", "atan", "atan2", "ceil", "rint", "step"}


_STATE = ("varying_locals", "env", "fixed", "mask", "dyn", "loop_masks", "loops",
          "masked_loops", "retmode", "main", "ret_type", "ret_varying", "returned_varying",
          "ntmp", "pre", "final_ret_varying", "dirty")


@functools.cache
def varying_inputs() -> frozenset[str]:
    """The stage inputs that differ per pixel, the fields of ``pgw_in`` (cl_pass.cl.j2):
    ``frag_coord`` and the scene inputs both backends interpolate.  The others are uniform
    over a triangle: frame values, facing, the light, and the flat scene inputs (the
    provoking vertex's material and ids: ``builtins.FLAT_SCENE_INPUTS``)."""
    return frozenset({"frag_coord", *(name for name, inp in STAGE_INPUTS.items()
                                      if inp.where is Where.SCENE
                                      and name not in FLAT_SCENE_INPUTS)})


class Unsupported(Exception):
    """The code uses something the wide form does not support."""


class _Restart(Exception):
    """A local became varying (or a loop needs lane masks): render the function again."""


class _RetMode(Exception):
    """A return under a varying condition: render the function with a return mask."""


@record
class Val:
    comps: list            # C expressions, one per component (a matrix: one, the matrix)
    type: Type
    varying: bool


_CT = {Scalar.FLOAT: "float", Scalar.INT: "int", Scalar.UINT: "uint", Scalar.BOOL: "bool"}
_CT8 = {Scalar.FLOAT: f"float{W}", Scalar.INT: f"int{W}", Scalar.UINT: f"uint{W}",
        Scalar.BOOL: f"int{W}"}


def ctype(s: Scalar, varying: bool) -> str:
    return (_CT8 if varying else _CT)[s]


def widen(c: str, s: Scalar) -> str:
    """A uniform component as a varying one."""
    if s is Scalar.BOOL:
        return f"((int{W})(-(int)({c})))"
    return f"(({_CT8[s]})({c}))"


class WideEmitter:
    def __init__(self, tech: ir.Technique, pass_: ir.Pass, lang):
        self.tech, self.pass_, self.lang = tech, pass_, lang
        self.functions: dict = {}
        # what the emitted text holds: the structs and specialised functions the current
        # render uses (a discarded render's additions are taken back, see _function_body)
        self.out_funcs: dict[str, str] = {}      # specialised name -> source
        self.structs: dict[str, str] = {}
        self.func_ret: dict[str, Val] = {}       # specialised name -> return shape (all renders)
        # specialised name -> the (dict, key, text) entries its emission added, itself last:
        # a function a discarded render emitted is put back without rendering it again
        self.emitted: dict[str, list] = {}

    # ---- entry -------------------------------------------------------------------------------
    def fragment(self, functions) -> str:
        self.functions = {f.name: f for f in functions}
        body = self._function_body(self.pass_.body, {}, main=True)
        lines = [f"static inline int{W} pg_fragment_w(const pg_in *in, const pgw_in *win, "
                 "pgw_out *out) {", f"    int{W} pg_live = (int{W})(-1);", *body,
                 "    return pg_live;", "}"]
        parts = [MARK] + list(self.structs.values()) + list(self.out_funcs.values())
        return "\n\n".join(parts + ["\n".join(lines)]) + "\n"

    # ---- function bodies with the local-uniformity fixpoint --------------------------------
    def _function_body(self, body, params: dict, main: bool = False,
                       ret: Optional[Type] = None) -> list[str]:
        varying: set = set()
        ret_varying = [False]
        masked_loops: set = set()
        retmode = False
        kept = (len(self.structs), len(self.out_funcs))
        for _ in range(200):
            _truncate(self.structs, kept[0])
            _truncate(self.out_funcs, kept[1])
            self.varying_locals = set(varying)
            self.env = dict(params)
            self.fixed = set(params)
            self.mask: Optional[str] = None
            self.dyn: list = []            # masks of lanes that left (returned, broke, continued)
            self.loop_masks: list = []
            self.loops: list = []
            self.masked_loops = masked_loops
            self.retmode = retmode
            self.main, self.ret_type = main, ret
            self.ret_varying = ret_varying[0] or (retmode and not main)
            self.returned_varying = False
            self.ntmp = 0
            self.pre: list[str] = []
            self.dirty = False
            head: list[str] = []
            if retmode:
                head.append(f"    int{W} pg_wdone = (int{W})(0);")
                self.dyn = ["pg_wdone"]
                if not main and not ret.is_void:
                    for k in range(ret.size):
                        head.append(f"    {ctype(ret.scalar, True)} pg_wrv{k} = "
                                    f"{widen(self.lang.literal(0 if ret.scalar is not Scalar.BOOL else False, Type(ret.scalar)), ret.scalar)};")
            try:
                lines = self._block(body, 1)
            except _Restart:
                varying = set(self.varying_locals)
                continue
            except (_RetMode, Unsupported) as e:
                # a render that found new varying locals ran on in a state it had already
                # proven wrong: only a render without new ones may give up or change mode
                if self.dirty:
                    varying = set(self.varying_locals)
                    continue
                if isinstance(e, Unsupported):
                    raise
                if retmode:
                    raise Unsupported("return mode")
                retmode = True
                continue
            if self.dirty:
                varying = set(self.varying_locals)
                continue
            if not main and self.returned_varying and not ret_varying[0]:
                ret_varying[0] = True
                continue
            self.final_ret_varying = self.ret_varying
            if retmode and not main and not ret.is_void:
                lines += self._return_rv(ret, "    ")
            return head + lines
        raise Unsupported("uniformity did not settle")

    def active(self) -> Optional[str]:
        """The lanes the current statement runs for (None: all of them)."""
        parts = ([self.mask] if self.mask is not None else []) + [f"~{d}" for d in self.dyn]
        return " & ".join(parts) if parts else None

    def _return_rv(self, t: Type, pad: str) -> list[str]:
        if t.size == 1:
            return [f"{pad}return pg_wrv0;"]
        sname = self._struct(t, True)
        return ([f"{pad}{{ {sname} pg_wr;"] + [f"{pad}  pg_wr.c[{k}] = pg_wrv{k};" for k in range(t.size)]
                + [f"{pad}  return pg_wr; }}"])

    def _mark_varying(self, name: str) -> None:
        """``name`` is varying: the function is rendered again with it declared varying.  The
        render goes on meanwhile (its text is discarded) to find every other local that
        becomes varying in the same render: one render per round of discoveries instead of
        one per local (a local marked here is varying in the final render too, since
        varyingness only grows with the set of varying locals)."""
        if name not in self.varying_locals:
            self.varying_locals.add(name)
            self.dirty = True

    # ---- temporaries ---------------------------------------------------------------------------
    def tmp(self, v: Val, force: bool = False) -> Val:
        """``v`` in temporaries (each component evaluated once)."""
        if v.type.is_matrix:
            return v
        out = []
        for c in v.comps:
            if not force and _simple(c):
                out.append(c)
                continue
            self.ntmp += 1
            name = f"pg_wt{self.ntmp}"
            self.pre.append(f"const {ctype(v.type.scalar, v.varying)} {name} = {c};")
            out.append(name)
        return Val(out, v.type, v.varying)

    # ---- statements ----------------------------------------------------------------------------
    def _block(self, body, depth: int) -> list[str]:
        out = []
        for s in body:
            out += self._stmt(s, depth)
        return out

    def _flush(self, depth: int, lines: list[str]) -> list[str]:
        pad = "    " * depth
        pre, self.pre = self.pre, []
        return [pad + p for p in pre] + lines

    def _stmt(self, s, depth: int) -> list[str]:
        pad = "    " * depth
        if isinstance(s, ir.Declare):
            t = s.type
            if t.is_matrix:
                if s.init is None:
                    raise Unsupported("matrix local without initialiser")
                v = self.expr(s.init)
                if v.varying:
                    raise Unsupported("varying matrix")
                name = self.lang.ident(s.name)
                self.env[s.name] = Val([name], t, False)
                return self._flush(depth, [f"{pad}{self.lang.type_name(t)} {name} = {v.comps[0]};"])
            if s.init is not None:
                v = self.expr(s.init)
            else:
                v = Val([self.lang.literal(0 if t.scalar is not Scalar.BOOL else False,
                                           Type(t.scalar))] * t.size, t, False)
            if v.varying or self.active() is not None:
                if s.name not in self.varying_locals:
                    self._mark_varying(s.name)
            var = s.name in self.varying_locals
            names = self._local_names(s.name, t)
            lines = []
            for n, c in zip(names, v.comps):
                if var and not v.varying:
                    c = widen(c, t.scalar)
                lines.append(f"{pad}{ctype(t.scalar, var)} {n} = {c};")
            self.env[s.name] = Val(names, t, var)
            return self._flush(depth, lines)
        if isinstance(s, ir.Assign):
            return self._flush(depth, self._assign(s, pad))
        if isinstance(s, ir.Output):
            v = self.expr(s.value)
            lines = []
            for k, c in enumerate(v.comps):
                if not v.varying:
                    c = widen(c, v.type.scalar)
                dst = f"out->o_{s.target}[{k}]"
                if self.active() is not None:
                    c = f"pg_sel({dst}, {c}, {self.active()})"
                lines.append(f"{pad}{dst} = {c};")
            return self._flush(depth, lines)
        if isinstance(s, ir.ExprStmt):
            v = self.expr(s.expr)
            return self._flush(depth, [f"{pad}(void)({c});" for c in v.comps])
        if isinstance(s, ir.If):
            c = self.expr(s.cond)
            if not c.varying:
                head = self._flush(depth, [f"{pad}if ({c.comps[0]}) {{"])
                then = self._block(s.then, depth + 1)
                out = head + then
                if s.other:
                    out += [f"{pad}}} else {{"] + self._block(s.other, depth + 1)
                return out + [f"{pad}}}"]
            # if-conversion: both branches under masks
            self.ntmp += 1
            m = f"pg_wm{self.ntmp}"
            outer = self.mask
            cond = c.comps[0]
            lines = self._flush(depth, [f"{pad}const int{W} {m} = {cond if outer is None else f'({cond}) & {outer}'};"])
            lines.append(f"{pad}{{")
            self.mask = m
            lines += self._block(s.then, depth + 1)
            lines.append(f"{pad}}}")
            if s.other:
                self.ntmp += 1
                m2 = f"pg_wm{self.ntmp}"
                neg = f"~({cond})" if outer is None else f"~({cond}) & {outer}"
                lines.append(f"{pad}const int{W} {m2} = {neg};")
                lines.append(f"{pad}{{")
                self.mask = m2
                lines += self._block(s.other, depth + 1)
                lines.append(f"{pad}}}")
            self.mask = outer
            return lines
        if isinstance(s, ir.For):
            start, bound = self.expr(s.start), self.expr(s.bound)
            if start.varying or bound.varying:
                raise Unsupported("varying loop bounds")
            v = self.lang.ident(s.var)
            self.env[s.var] = Val([v], Type(s.type.scalar), False)
            self.fixed.add(s.var)
            head = self._flush(depth, [
                f"{pad}for ({_CT[s.type.scalar]} {v} = {start.comps[0]}; {v} < {bound.comps[0]}; {v}++) {{"])
            key = id(s)
            self.loop_masks.append(self.mask)
            self.loops.append(key)
            if key not in self.masked_loops:
                body = self._block(s.body, depth + 1)
                self.loop_masks.pop()
                self.loops.pop()
                return head + body + [f"{pad}}}"]
            # lanes leave the loop (break) or the iteration (continue) under masks; the loop
            # ends when every lane has left
            self.ntmp += 1
            brk, cont = f"pg_wbrk{self.ntmp}", f"pg_wcont{self.ntmp}"
            entry = self.active()
            init = f"(int{W})(0)" if entry is None else f"~({entry})"
            head = [f"{pad}int{W} {brk} = {init};"] + head
            self.dyn = self.dyn + [brk, cont]
            body = self._block(s.body, depth + 1)
            self.dyn = self.dyn[:-2]
            self.loop_masks.pop()
            self.loops.pop()
            left = " | ".join([brk] + [d for d in self.dyn if d == "pg_wdone"])
            return (head + [f"{pad}    int{W} {cont} = (int{W})(0);"] + body
                    + [f"{pad}    if (pgw_all({left})) break;", f"{pad}}}"])
        if isinstance(s, (ir.Break, ir.Continue)):
            if not self.loops:
                raise Unsupported("break outside a loop")
            key = self.loops[-1]
            if key in self.masked_loops:
                brk, cont = self.dyn[-2], self.dyn[-1]
                which = brk if isinstance(s, ir.Break) else cont
                return [f"{pad}{which} |= {self.active()};"]
            if self.loop_masks[-1] != self.mask:
                self.masked_loops.add(key)
                raise _Restart()
            return [f"{pad}{'break' if isinstance(s, ir.Break) else 'continue'};"]
        if isinstance(s, ir.Return):
            uniform_here = self.mask is None and self.dyn == (["pg_wdone"] if self.retmode else [])
            if not self.retmode and not uniform_here:
                raise _RetMode()
            if not self.retmode:
                if self.main:
                    return [f"{pad}return pg_live;"]
                if s.value is None:
                    return [f"{pad}return;"]
                v = self.expr(s.value)
                if v.varying:
                    self.returned_varying = True
                return self._flush(depth, self._return(v, pad))
            # return mode: the returning lanes keep their value and leave
            act = self.active()
            lines = []
            if not self.main and s.value is not None:
                v = self.expr(s.value)
                for k, c in enumerate(v.comps):
                    if not v.varying:
                        c = widen(c, v.type.scalar)
                    lines.append(f"{pad}pg_wrv{k} = pg_sel(pg_wrv{k}, {c}, {act});")
            lines.append(f"{pad}pg_wdone |= {act};")
            if uniform_here:
                if self.main:
                    lines.append(f"{pad}return pg_live;")
                elif s.value is None:
                    lines.append(f"{pad}return;")
                else:
                    lines += self._return_rv(self.ret_type, pad)
            return self._flush(depth, lines)
        if isinstance(s, ir.Discard):
            if not self.main:
                raise Unsupported("discard in a function")
            if self.active() is None:
                return [f"{pad}return (int{W})(0);"]
            return [f"{pad}pg_live &= ~({self.active()});"]
        raise Unsupported(f"statement {type(s).__name__}")

    def _local_names(self, name: str, t: Type) -> list[str]:
        base = self.lang.ident(name)
        if t.size == 1:
            return [base]
        # user names never start with pg_ (reserved): no clash with a scalar named base_x
        return [f"pg_v_{base}_{'xyzw'[k]}" for k in range(t.size)]

    def _assign(self, s: ir.Assign, pad: str) -> list[str]:
        tgt = s.target
        comps_sel = None
        if isinstance(tgt, ir.Swizzle) and isinstance(tgt.base, ir.Var):
            var, comps_sel = tgt.base, ["xyzw".index(c) for c in tgt.components]
        elif isinstance(tgt, ir.Index) and isinstance(tgt.base, ir.Var):
            if not isinstance(tgt.index, ir.Const) or tgt.base.type.is_matrix:
                raise Unsupported("assignment through a dynamic index")
            var, comps_sel = tgt.base, [int(tgt.index.value)]
        elif isinstance(tgt, ir.Var):
            var = tgt
        else:
            raise Unsupported("assignment target")
        if var.kind != "local" or var.name not in self.env:
            raise Unsupported("assignment to a non-local")
        cur = self.env[var.name]
        if cur.type.is_matrix:
            v = self.expr(s.value)
            if v.varying or self.active() is not None or s.op != "=":
                raise Unsupported("varying matrix")
            return [f"{pad}{cur.comps[0]} = {v.comps[0]};"]
        v = self.expr(s.value)
        if (v.varying or self.active() is not None) and not cur.varying:
            if var.name in self.fixed:    # a function parameter or loop counter
                raise Unsupported("varying assignment to a uniform parameter")
            self._mark_varying(var.name)
        idx = comps_sel if comps_sel is not None else list(range(cur.type.size))
        vals = v.comps if len(v.comps) == len(idx) else v.comps * len(idx)
        news = []
        for k, c in zip(idx, vals):
            dst = cur.comps[k]
            if s.op != "=":
                op = s.op[0]
                if op in "/%" and cur.type.scalar in (Scalar.INT, Scalar.UINT) and (
                        cur.varying or v.varying):
                    raise Unsupported("varying integer division")
                c = f"({dst} {op} {c})"
            if cur.varying and not v.varying:
                c = widen(c, cur.type.scalar)
            if self.active() is not None:
                c = f"pg_sel({dst}, {c}, {self.active()})"
            news.append(c)
        if len(news) > 1:     # c = c.zyx: every component's value before any is written
            news = self.tmp(Val(news, Type(cur.type.scalar, len(news)), cur.varying),
                            force=True).comps
        return [f"{pad}{cur.comps[k]} = {c};" for k, c in zip(idx, news)]

    def _return(self, v: Val, pad: str) -> list[str]:
        t = self.ret_type
        var = self.ret_varying
        comps = [widen(c, t.scalar) if var and not v.varying else c for c in v.comps]
        if t.size == 1:
            return [f"{pad}return {comps[0]};"]
        sname = self._struct(t, var)
        self.ntmp += 1
        r = f"pg_wr{self.ntmp}"
        return ([f"{pad}{{ {sname} {r};"] + [f"{pad}  {r}.c[{k}] = {c};" for k, c in enumerate(comps)]
                + [f"{pad}  return {r}; }}"])

    def _struct(self, t: Type, varying: bool) -> str:
        name = f"pgw_ret_{ctype(t.scalar, varying)}x{t.size}"
        self.structs.setdefault(name, f"typedef struct {{ {ctype(t.scalar, varying)} c[{t.size}]; }} {name};")
        return name

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
        if lt.is_matrix and rt.is_vector:        # m * v = ((c0 v.x + c1 v.y) + c2 v.z) + c3 v.w
            m, v = a.comps[0], self.tmp(b)
            n = lt.mat
            out = []
            for k in range(n):
                terms = [f"({m}.c[{j}].{'xyzw'[k]} * {v.comps[j]})" for j in range(n)]
                acc = terms[0]
                for t in terms[1:]:
                    acc = f"({acc} + {t})"
                out.append(acc)
            return Val(out, e.type, True)
        if lt.is_vector and rt.is_matrix:        # v * m = (dot(v, c0), dot(v, c1), ...)
            v, m = self.tmp(a), b.comps[0]
            n = rt.mat
            return Val([_dot([f"({v.comps[j]} * {m}.c[{k}].{'xyzw'[j]})" for j in range(n)])
                        for k in range(n)], e.type, True)
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
        return f"convert_{_CT8[dst]}({c})"

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

    def _lightfield(self, e: ir.LightField) -> Val:
        if e.index is None:
            index, itype = self.lang.render_current_light(), ir.UINT
        else:
            iv = self.expr(e.index)
            if iv.varying:
                # each lane its own light (light-indexed shading): measured 2-3x slower than
                # the scalar function (gathers, and every light type's branch for all lanes)
                raise Unsupported("varying light index")
            index, itype = iv.comps[0], e.index.type
        if e.field == "index":
            c = index if itype == e.type else self.lang.render_construct(e.type, [index], [itype])
            return Val([c], e.type, False)
        if itype != ir.INT:
            index = self.lang.render_construct(ir.INT, [index], [itype])
        slot = self.lang.light_fields.index(e.field)
        base = f"in->lights[({index}) * PG_LIGHT_FIELDS + {slot}]"
        comps = []
        for k in range(e.type.size):
            c = f"{base}.{'xyzw'[k]}"
            if e.type.scalar is not Scalar.FLOAT:
                c = self.lang.render_construct(Type(e.type.scalar), [c], [ir.FLOAT])
            comps.append(c)
        return Val(comps, e.type, False)

    def _gather(self, fn: str, args: list, t: Type) -> Val:
        self.ntmp += 1
        name = f"pg_wt{self.ntmp}"
        s = "uint" if t.scalar is Scalar.UINT else "float"
        self.pre.append(f"const pgw_{s}{W}x4 {name} = {fn}(in, {', '.join(args)});")
        return Val([f"{name}.c[{k}]" for k in range(t.size)], t, True)

    def _load(self, e: ir.Load) -> Val:
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
            return self._user_call(e)
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
        if name in ("dot", "length", "distance"):
            if name == "distance":
                a, b = vals
                vals = [Val([f"({x} - {y})" for x, y in zip(a.comps, b.comps)], a.type, vary)]
                name = "length"
            if name == "length":
                v = self.tmp(vals[0])
                d = _dot([f"({c} * {c})" for c in v.comps])
                return Val([self._render1("sqrt", [d], ir.FLOAT)], ret, vary)
            a, b = vals
            return Val([_dot([f"({x} * {y})" for x, y in zip(a.comps, b.comps)])], ret, vary)
        if name == "cross":
            a, b = self.tmp(vals[0]), self.tmp(vals[1])
            x, y = a.comps, b.comps
            return Val([f"(({x[1]} * {y[2]}) - ({x[2]} * {y[1]}))",
                        f"(({x[2]} * {y[0]}) - ({x[0]} * {y[2]}))",
                        f"(({x[0]} * {y[1]}) - ({x[1]} * {y[0]}))"], ret, vary)
        if name == "mix":
            a, b, t = self.tmp(vals[0]), vals[1], vals[2]
            n = ret.size
            tc = t.comps if len(t.comps) == n else t.comps * n
            return Val([f"({x} + (({y} - {x}) * {z}))" for x, y, z in zip(a.comps, b.comps, tc)],
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

    def _user_call(self, e: ir.Call) -> Val:
        f = self.functions.get(e.name)
        if f is None:
            raise Unsupported(f"function {e.name}")
        vals = [self.expr(a) for a in e.args]
        flags = tuple(v.varying for v in vals)
        spec = f"{self.lang.ident(f.name)}_w{''.join('v' if x else 'u' for x in flags) or '0'}"
        if spec in self.emitted:
            for table, key, text in self.emitted[spec]:
                table.setdefault(key, text)
        else:
            before = (dict(self.structs), dict(self.out_funcs))
            self._emit_function(f, flags, spec)
            self.emitted[spec] = [(table, k, t) for table, old in zip(
                (self.structs, self.out_funcs), before) for k, t in table.items() if k not in old]
        ret = self.func_ret[spec]
        args = ["in", "win"] + [c for v in vals for c in v.comps]
        call = f"{spec}({', '.join(args)})"
        if f.ret.is_void:
            return Val([call], f.ret, False)
        if f.ret.size == 1:
            return Val([call], f.ret, ret.varying)
        self.ntmp += 1
        name = f"pg_wt{self.ntmp}"
        self.pre.append(f"const {self._struct(f.ret, ret.varying)} {name} = {call};")
        return Val([f"{name}.c[{k}]" for k in range(f.ret.size)], f.ret, ret.varying)

    def _emit_function(self, f: ir.Function, flags, spec: str) -> None:
        if f.ret.is_matrix or any(t.is_matrix and v for (n, t), v in zip(f.params, flags)):
            raise Unsupported("varying matrix")
        # the caller's state
        saved = {k: getattr(self, k) for k in _STATE if hasattr(self, k)}
        params, decl = {}, ["const pg_in *in", "const pgw_in *win"]
        for (n, t), v in zip(f.params, flags):
            if t.is_matrix:
                name = self.lang.ident(n)
                params[n] = Val([name], t, False)
                decl.append(f"const {self.lang.type_name(t)} {name}")
                continue
            names = self._local_names(n, t)
            params[n] = Val(names, t, v)
            decl += [f"{ctype(t.scalar, v)} {x}" for x in names]
        try:
            body = self._function_body(f.body, params, main=False, ret=f.ret)
            rv = self.final_ret_varying
        finally:
            for k, v in saved.items():
                setattr(self, k, v)
        if f.ret.is_void:
            rtype = "void"
        elif f.ret.size == 1:
            rtype = ctype(f.ret.scalar, rv)
        else:
            rtype = self._struct(f.ret, rv)
        self.func_ret[spec] = Val([], f.ret, rv)
        self.out_funcs[spec] = "\n".join(
            [f"static inline {rtype} {spec}({', '.join(decl)}) {{", *body, "}"])


def _dot(products: list) -> str:
    """x + (y + (z + w)) of the products (the prelude's pg_dot)."""
    acc = products[-1]
    for p in reversed(products[:-1]):
        acc = f"({p} + {acc})"
    return acc


def _simple(c: str) -> bool:
    return c.replace("_", "").replace(".", "").replace("->", "").replace("[", "").replace(
        "]", "").isalnum() or c.startswith("win->")


def wide_fragment(tech: ir.Technique, p: ir.Pass, lang) -> Optional[str]:
    """``pg_fragment_w`` of pass ``p`` (OpenCL C), or None when the wide form does not
    support its code (see the module docstring)."""
    if not p.body or not ENABLED:
        return None
    functions = planlib.pass_functions(tech, p.body)
    fmap = {f.name: f for f in functions}
    if cost(p.body, fmap) - GATHER_COST * gathers(p.body, fmap) < MIN_COST:
        return None
    try:
        return WideEmitter(tech, p, lang).fragment(functions)
    except Unsupported:
        return None


def has_wide(fragment: Optional[str]) -> bool:
    """Whether a pass's fragment text (``CLPassCode.fragment``) holds ``pg_fragment_w``, so
    its program needs the wide helpers and batching.  Read from the text, which is what
    the program compiles: a plan's plain-data spelling, old ones included, carries it."""
    return bool(fragment) and MARK in fragment


def _lanes(n: int) -> str:
    args = ", ".join("abc"[:n])
    per = ", ".join("f(" + ", ".join(f"({x}).s{k}" for x in "abc"[:n]) + ")" for k in range(W))
    return f"#define PGW_LANES{n}(f, T, {args}) ((T##{W})({per}))"


# W-wide forms of the prelude builtins the wide code calls: the scalar definitions per lane
# (selects with the same comparisons; sqrt, floor, fma lane by lane through the same
# intrinsics), so every lane gets the scalar value
def wide_helpers() -> str:
    """The W-wide builtins and helpers a program with ``pg_fragment_w`` starts with."""
    return "\n".join(_helpers())


def _helpers() -> list:
    return ([
    f"/* ---- wide forms ({W} pixels per call) of the builtins: the scalar definitions per lane ---- */",
    f"#define PG_W {W}",
    f"#define PG_WMIN {WMIN}   /* fewer pixels of a triangle's row than this: the scalar function */",
    _lanes(1), _lanes(2), _lanes(3),
    "/* select() as the ternary operator, which OpenCL C defines as select(exp3, exp2, exp1)",
    " * (the sign bit of each mask lane): PoCL's library select() is not inlined into the raster",
    " * kernel (90 out-of-line calls in inferred's material kernel, every live ymm register",
    " * spilled around each); the ternary is expanded in place. 10-18 % of a wide kernel */",
    "PG_INL float8 pg_sel(const float8 a, const float8 b, const int8 m) { return m ? b : a; }",
    "PG_INL int8 pg_sel(const int8 a, const int8 b, const int8 m) { return m ? b : a; }",
    "PG_INL uint8 pg_sel(const uint8 a, const uint8 b, const int8 m) { return m ? b : a; }",
    "PG_INL float8 pg_b_fmax(const float8 a, const float8 b) { return pg_sel(b, a, (b != b) | (a > b)); }",
    "PG_INL float8 pg_b_fmin(const float8 a, const float8 b) { return pg_sel(b, a, (b != b) | (a < b)); }",
    "PG_INL float8 pg_b_fmax(const float8 a, const float b) { return pg_b_fmax(a, (float8)(b)); }",
    "PG_INL float8 pg_b_fmin(const float8 a, const float b) { return pg_b_fmin(a, (float8)(b)); }",
    "PG_INL float8 pg_b_max(const float8 a, const float8 b) { return pg_sel(b, a, a > b); }",
    "PG_INL float8 pg_b_min(const float8 a, const float8 b) { return pg_sel(b, a, a < b); }",
    "PG_INL float8 pg_b_clamp(const float8 x, const float8 lo, const float8 hi) { return pg_b_fmin(pg_b_fmax(x, lo), hi); }",
    "PG_INL float8 pg_b_fma(const float8 a, const float8 b, const float8 c) { return PGW_LANES3(__builtin_fmaf, float, a, b, c); }",
    "PG_INL float8 pg_b_fma(const float8 a, const float8 b, const float c) { return pg_b_fma(a, b, (float8)(c)); }",
    "PG_INL float8 pg_b_sqrt(const float8 a) { return PGW_LANES1(__builtin_sqrtf, float, a); }",
    "PG_INL float8 pg_b_floor(const float8 a) { return PGW_LANES1(__builtin_floorf, float, a); }",
    "PG_INL float8 pg_b_fabs(const float8 x) { return as_float8(as_uint8(x) & 0x7fffffffu); }",
    "PG_INL float8 pg_b_copysign(const float8 x, const float8 y) { return as_float8((as_uint8(x) & 0x7fffffffu) | (as_uint8(y) & 0x80000000u)); }",
    *[line for T in ("int8", "uint8") for line in (
        f"PG_INL {T} pg_b_max(const {T} a, const {T} b) {{ return pg_sel(a, b, a < b); }}",
        f"PG_INL {T} pg_b_min(const {T} a, const {T} b) {{ return pg_sel(a, b, a > b); }}",
        f"PG_INL {T} pg_b_clamp(const {T} x, const {T} lo, const {T} hi) {{ return pg_b_min(pg_b_max(x, lo), hi); }}")],
    "PG_INL uint8 pg_b_sub_sat(const uint8 a, const uint8 b) { return pg_sel((uint8)(0u), a - b, a > b); }",
    "static inline int8 __attribute__((overloadable)) pg_abs(int8 x) { return pg_sel(x, -x, x < 0); }",
    "static inline float8 __attribute__((overloadable)) pg_abs(float8 x) { return pg_b_fabs(x); }",
    "static inline int8 __attribute__((overloadable)) pg_sign(int8 x) { return pg_sel((int8)(0), (int8)(1), x > 0) - pg_sel((int8)(0), (int8)(1), x < 0); }",
    "static inline float8 __attribute__((overloadable)) pg_sign(float8 x) { return PGW_LANES1(sign, float, x); }",
    "static inline float8 __attribute__((overloadable)) pg_smoothstep(const float8 e0, const float8 e1, const float8 x) {",
    "    const float8 t = pg_b_fmin(pg_b_fmax((x - e0) / (e1 - e0), 0.0f), 1.0f);",
    "    return t * (t * (3.0f - 2.0f * t));",
    "}",
    "static inline float8 __attribute__((overloadable)) pg_exp2(float8 x) {",
    "    x = pg_b_fmax(pg_b_fmin(x, 129.0f), -126.99999f);",
    "    const float8 ip = pg_b_floor(x);",
    "    const float8 f = x - ip;",
    "    const float8 ei = as_float8((convert_int8(ip) + 127) << 23);",
    "    const float8 f2 = f * f;",
    "    const float8 odd = pg_b_fma(f2, pg_b_fma(f2, ((float8)(0.0018775767f)), ((float8)(0.055826318f))), ((float8)(0.6931531f)));",
    "    const float8 even = pg_b_fma(f2, pg_b_fma(f2, ((float8)(0.00898934f)), ((float8)(0.24015361f))), ((float8)(1.0f)));",
    "    return ei * pg_b_fma(odd, f, even);",
    "}",
    "static inline float8 __attribute__((overloadable)) pg_log2(const float8 x) {",
    "    const int8 i = as_int8(x);",
    "    const float8 le = convert_float8(((i & 0x7f800000) >> 23) - 127);",
    "    const float8 m = as_float8((i & 0x007fffff) | 0x3f800000);",
    "    const float8 y = (m - 1.0f) / (m + 1.0f);",
    "    const float8 z = y * y;",
    "    const float8 z2 = z * z;",
    "    const float8 odd = pg_b_fma(z2, ((float8)(0.40334386f)), ((float8)(0.9617916f)));",
    "    const float8 even = pg_b_fma(z2, pg_b_fma(z2, ((float8)(0.40671805f)), ((float8)(0.5774403f))), ((float8)(2.88539f)));",
    "    return pg_b_fma(y, pg_b_fma(odd, z, even), le);",
    "}",
    "/* 8 half codes to floats: the prelude's pg_half_bits_to_float (vload_half) per lane; with",
    " * F16C vcvtph2ps, as the prelude's half4 form (exact, a NaN's payload kept and quieted: the",
    " * same bits for all 65536 codes, measured), else its branches as selects */",
    "#ifdef __F16C__",
    "PG_INL float8 pgw_half8_to_float8(const ushort8 h) {",
    "    typedef short pgw_v8hi __attribute__((__vector_size__(16)));",
    "    typedef float pgw_v8sf __attribute__((__vector_size__(32)));",
    "    union { ushort8 u; pgw_v8hi v; } a;",
    "    union { pgw_v8sf v; float8 f; } r;",
    "    a.u = h;",
    "    r.v = __builtin_ia32_vcvtph2ps256(a.v);",
    "    return r.f;",
    "}",
    "#else",
    "PG_INL float8 pgw_half8_to_float8(const ushort8 c) {",
    "    const uint8 h = __builtin_convertvector(c, uint8);",
    "    const uint8 s = (h & 0x8000u) << 16, e = (h >> 10) & 31u, m = h & 1023u;",
    "    const uint8 special = s | 0x7f800000u | (m << 13) | pg_sel((uint8)(0u), (uint8)(0x00400000u), m != 0u);",
    "    const uint8 small = s | as_uint8(convert_float8(m) * 5.9604644775390625e-8f);",
    "    const uint8 normal = s | ((e + 112u) << 23) | (m << 13);",
    "    return as_float8(pg_sel(pg_sel(normal, small, e == 0u), special, e == 31u));",
    "}",
    "#endif",
    f"typedef struct {{ float{W} c[4]; }} pgw_float{W}x4;",
    f"typedef struct {{ uint{W} c[4]; }} pgw_uint{W}x4;",
    f"PG_INL int pgw_all(const int{W} m) {{ return (" + " & ".join(f"m.s{k}" for k in range(W)) + ") != 0; }",
    ])


def cost(body, functions: dict) -> int:
    """A rough count of the operations a pixel runs (expression nodes, calls of user functions
    counted with their bodies, bounded loops times their bound): the wide form pays its
    batching only when the shading does enough work per pixel (``MIN_COST``)."""
    memo: dict = {}

    def fcost(name: str) -> int:
        if name not in memo:
            memo[name] = 0
            f = functions.get(name)
            memo[name] = stmts(f.body) if f is not None else 0
        return memo[name]

    def expr(e) -> int:
        n = 1
        if isinstance(e, ir.Call) and not e.builtin:
            n += fcost(e.name)
        for sub in child_exprs(e):
            n += expr(sub)
        return n

    def stmts(body) -> int:
        n = 0
        for s in body:
            if isinstance(s, ir.For):
                b = s.bound.value if isinstance(s.bound, ir.Const) else 8
                a = s.start.value if isinstance(s.start, ir.Const) else 0
                n += max(1, int(b) - int(a)) * stmts(s.body)
            elif isinstance(s, ir.If):
                n += expr(s.cond) + stmts(s.then) + stmts(s.other)
            else:
                for e in child_exprs(s):
                    n += expr(e)
        return n

    return stmts(body)


def gathers(body, functions: dict) -> int:
    """How many ``load``/``sample`` calls the code holds (functions counted with theirs), for
    ``GATHER_COST`` (0 since the gathers are wide: lane by lane they measured slower than the
    scalar code where they were a large share of the work, deferred_calver's point lights)."""
    return _gathers(body, functions, {})


def _gathers(body, functions: dict, memo: dict) -> int:
    facts = planlib.code_facts(body)      # one walk per body (memoised in codefacts.py)
    n = facts.loads
    for name in facts.call_list:
        if name in functions:
            if name not in memo:
                memo[name] = _gathers(functions[name].body, functions, memo)
            n += memo[name]
    return n


def _truncate(table: dict, n: int) -> None:
    """Drop the entries added after the first ``n`` (dicts keep insertion order)."""
    for key in list(table)[n:]:
        del table[key]
