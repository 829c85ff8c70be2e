"""The wide path's functions and statements: the local-uniformity fixpoint (a function is
rendered again until the set of varying locals settles), if-conversion of branches on varying
conditions, loops left per lane (break and continue masks), returns under a varying condition
(a return mask and the returned values), discard as a live mask, and the user functions,
specialised per call by which arguments are varying.  A mixin of ``emitter.WideEmitter``; the
expressions are ``expressions.WideExpressions``'s."""

from __future__ import annotations

from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.ir.nodes import VEC4, Scalar, Type
from pipegen.backends.cstyle import row_plan
from pipegen.backends.opencl.wide.cost import iterations
from pipegen.backends.opencl.wide.values import (
    C_TYPES, W, TooManyGathers, Unsupported, Val, ctype, widen)

# what a function's rendering sets on the emitter: saved and restored around the rendering of
# a function it calls
_STATE = ("varying_locals", "env", "fixed", "mask", "dyn", "loop_masks", "loops",
          "masked_loops", "retmode", "main", "ret_type", "ret_varying", "returned_varying",
          "ntmp", "pre", "final_ret_varying", "dirty", "rows", "path", "lane_rows",
          "lane_gathers", "loop_weight")


class _Restart(Exception):
    """A local became varying (or a loop needs lane masks): render the function again."""


class _RetMode(Exception):
    """A return under a varying condition: render the function with a return mask."""



class WideStatements:
    """Function bodies and statements of ``WideEmitter``."""

    # ---- function bodies with the local-uniformity fixpoint --------------------------------
    def _function_body(self, body, params: dict, main: bool = False,
                       ret: Optional[Type] = None) -> list[str]:
        varying: set = set()
        ret_varying = [False]
        masked_loops: set = set()
        retmode = False
        kept = (len(self.structs), len(self.out_funcs))
        layout = self.lang.light_layout
        materials = None if self.tech.materials is None else self.lang.material_layout()
        # each light-table row read once (light_rows.py), as the scalar emitter does, and
        # each material row: read at a varying index, a row is a gather of W rows
        self.rows = None if layout is None else row_plan(body, layout, params, materials)
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
            self.path = ()
            self.lane_rows: set = set()      # the rows' locals gathered lane by lane
            # table rows a pixel gathers lane by lane, loops counted with their bounds (as
            # cost.py counts them) and calls with their functions' (the wide path's choice)
            self.lane_gathers, self.loop_weight = 0, 1
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
                # a value it returned varying is varying in the last render too (varying
                # locals only grow): the next render returns varying values already, instead
                # of a render more to learn it
                ret_varying[0] = ret_varying[0] or (not main and self.returned_varying)
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

    def count_gathers(self, rows: int) -> None:
        """``rows`` more table rows gathered lane by lane per pixel.  A count that rules the
        wide form out ends the rendering (``TooManyGathers``).  The count that decides is the
        pass body's in its last render; what is counted so far, in the body and in the
        functions being rendered for its calls (``callers``: each caller's count before the
        call and the call's loop weight), is at most that: no render counts more than the
        last one does (each render reads every table read site once, and its varying locals
        and arguments only grow from one render to the next)."""
        self.lane_gathers += rows
        counted = self.lane_gathers
        for before, weight in reversed(self.callers):
            counted = before + weight * counted
        if self.too_many_gathers(counted):
            raise TooManyGathers()

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
    def _block(self, body, depth: int, name: Optional[str] = None) -> list[str]:
        """The lines of a body, or of nested block ``name`` (then, other, body) of the current
        statement; ``self.path`` is the path of the statement being rendered."""
        outer = self.path
        block = outer if name is None else outer + (name,)
        out = []
        try:
            for k, s in enumerate(body):
                self.path = block + (k,)
                out += self._row_loads(depth)
                out += self._stmt(s, depth)
        finally:
            self.path = outer
        return out

    def _row_loads(self, depth: int) -> list[str]:
        """The table rows loaded before the current statement: a uniform index's row, or a
        varying index's ``W`` rows, one per lane (``table_row``)."""
        lines = []
        for load in [] if self.rows is None else self.rows.loads_before(self.path):
            row_of = (self.light_row_of(load.row) if load.material is None
                      else self.material_row_of(load.material))
            row, lanes = self.table_row(load.index, row_of, load.name)
            if lanes:
                self.lane_rows.add(load.name)
                lines += self._flush(depth, [])
            else:
                lines += self._flush(depth, [f"{'    ' * depth}const "
                                             f"{self.lang.type_name(VEC4)} {load.name} = {row};"])
        return lines

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
                head = self._flush(depth, [f"{pad}if ({_condition(c.comps[0])}) {{"])
                then = self._block(s.then, depth + 1, "then")
                out = head + then
                if s.other:
                    out += [f"{pad}}} else {{"] + self._block(s.other, depth + 1, "other")
                return out + [f"{pad}}}"]
            # if-conversion: both branches under masks
            self.ntmp += 1
            m = f"pg_wm{self.ntmp}"
            outer = self.mask
            cond = c.comps[0]
            lines = self._flush(depth, [f"{pad}const int{W} {m} = {cond if outer is None else f'({cond}) & {outer}'};"])
            lines.append(f"{pad}{{")
            self.mask = m
            lines += self._block(s.then, depth + 1, "then")
            lines.append(f"{pad}}}")
            if s.other:
                self.ntmp += 1
                m2 = f"pg_wm{self.ntmp}"
                neg = f"~({cond})" if outer is None else f"~({cond}) & {outer}"
                lines.append(f"{pad}const int{W} {m2} = {neg};")
                lines.append(f"{pad}{{")
                self.mask = m2
                lines += self._block(s.other, depth + 1, "other")
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
                f"{pad}for ({C_TYPES[s.type.scalar]} {v} = {start.comps[0]}; {v} < {bound.comps[0]}; {v}++) {{"])
            key = id(s)
            self.loop_masks.append(self.mask)
            self.loops.append(key)
            weight = self.loop_weight
            self.loop_weight *= iterations(s)
            if key not in self.masked_loops:
                body = self._block(s.body, depth + 1, "body")
                self.loop_masks.pop()
                self.loops.pop()
                self.loop_weight = weight
                return head + body + [f"{pad}}}"]
            # lanes leave the loop (break) or the iteration (continue) under masks; the loop
            # ends when every lane has left
            self.ntmp += 1
            brk, cont = f"pg_wbrk{self.ntmp}", f"pg_wcont{self.ntmp}"
            entry = self.active()
            init = f"(int{W})(0)" if entry is None else f"~({entry})"
            head = [f"{pad}int{W} {brk} = {init};"] + head
            self.dyn = self.dyn + [brk, cont]
            body = self._block(s.body, depth + 1, "body")
            self.dyn = self.dyn[:-2]
            self.loop_masks.pop()
            self.loops.pop()
            self.loop_weight = weight
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

    # ---- user functions, specialised per call ---------------------------------------------
    def user_call(self, e: ir.Call) -> Val:
        f = self.functions.get(e.name)
        if f is None:
            raise Unsupported(f"function {e.name}")
        vals = [self.expr(a) for a in e.args]
        flags = tuple(v.varying for v in vals)
        spec = f"{self.lang.ident(f.name)}_w{''.join('v' if x else 'u' for x in flags) or '0'}"
        shared_key = (type(self.lang), id(f), flags)
        if spec not in self.emitted and shared_key in self.shared:
            # rendered for another pass of the technique: the same text (a specialised
            # function's rendering reads only the function, its flags and technique-wide facts)
            _, self.emitted[spec], self.func_ret[spec], self.func_gathers[spec] = \
                self.shared[shared_key]
        if spec in self.emitted:
            for table, key, text in self.emitted[spec]:
                getattr(self, table).setdefault(key, text)
        else:
            before = (dict(self.structs), dict(self.out_funcs))
            self._emit_function(f, flags, spec)
            self.emitted[spec] = [(name, k, t) for name, old in zip(("structs", "out_funcs"), before)
                                  for k, t in getattr(self, name).items() if k not in old]
            self.shared[shared_key] = (f, self.emitted[spec], self.func_ret[spec],
                                       self.func_gathers[spec])
        self.count_gathers(self.func_gathers[spec] * self.loop_weight)
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
        self.callers.append((self.lane_gathers, self.loop_weight))
        try:
            body = self._function_body(f.body, params, main=False, ret=f.ret)
            rv = self.final_ret_varying
            self.func_gathers[spec] = self.lane_gathers
        finally:
            self.callers.pop()
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


def _simple(c: str) -> bool:
    """Whether a component is a name or a field read: no temporary needed to evaluate it once."""
    return c.replace("_", "").replace(".", "").replace("->", "").replace("[", "").replace(
        "]", "").isalnum() or c.startswith("win->")


def _truncate(table: dict, n: int) -> None:
    """Drop the entries added after the first ``n`` (dicts keep insertion order)."""
    for key in list(table)[n:]:
        del table[key]


def _condition(text: str) -> str:
    """``text`` without parentheses that wrap it whole: the values here are parenthesised
    operations, and ``if ((a == b))`` is clang's -Wparentheses-equality warning (the double
    parentheses that would silence an assignment meant as a comparison)."""
    if not text.startswith("("):
        return text
    depth = 0
    for k, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if depth == 0:
            return text[1:-1] if k == len(text) - 1 else text
    return text
