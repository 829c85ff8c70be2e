"""The IR verifier: ``verify(tech)`` asserts the invariants every phase must preserve.

It checks what the front end guarantees and what later phases and backends rely on: names are
unique and resolvable, every expression's type follows from its operands (by the same rules the
front end uses, ``builtins.binary_type`` & co.), constructors are in normal form, passes attach
targets of the right kind, blend entries exist only for written targets, repeat groups are
contiguous, and functions come after the functions they call.

Violations are compiler bugs, not user errors: they raise ``AssertionError`` naming the pass or
function and the offending node.  (Explicit raises rather than ``assert`` statements, so that
``python -O`` does not silence them.)
"""

from __future__ import annotations

from dataclasses import field
from typing import Callable, Optional, Union

from pipegen.core.records import record
from pipegen.ir import facts, nodes as ir
from pipegen.ir.builtins import (
    BUILTINS, LIGHT_FIELDS, LIGHT_INDEX, LIGHT_TYPES, STAGE_INPUTS, Where, binary_type,
    construct_error, resolve_builtin, target_read_type, target_write_type, unary_type)
from pipegen.core.formats import FORMATS

_PARAM_TYPES = (ir.FLOAT, ir.INT, ir.UINT, ir.BOOL, ir.VOID)
_ASSIGN_OPS = ("=", "+=", "-=", "*=", "/=")


def verify(tech: ir.Technique) -> None:
    _Verifier(tech).run()


def _check(cond: bool, where: str, message: Union[str, Callable[[], str]]) -> None:
    """Raise unless ``cond``.  A message that names values is given as a ``lambda``, formatted
    only on failure: formatting the types of every operator's check took half the verifier's
    time, and the verifier runs on every compile ("validate")."""
    if not cond:
        text = message() if callable(message) else message
        raise AssertionError(f"IR invariant violated in {where}: {text}")


def _unique(names: list[str], where: str, what: str) -> None:
    seen = set()
    for n in names:
        _check(n not in seen, where, lambda: f"duplicate {what} '{n}'")
        seen.add(n)


@record
class _Needs:
    """What a function needs from the pass that calls it (transitively)."""

    scene: set[str] = field(default_factory=set)
    light: bool = False
    reads: set[str] = field(default_factory=set)


class _Verifier:
    def __init__(self, tech: ir.Technique):
        self.tech = tech
        self.targets = {t.name: t for t in tech.targets}
        self.params = {p.name: p for p in tech.params}
        self.functions: dict[str, ir.Function] = {}
        self.needs: dict[str, _Needs] = {}

    def run(self) -> None:
        t = self.tech
        _unique([p.name for p in t.params] + [x.name for x in t.targets]
                + [p.name for p in t.packings] + [f.name for f in t.all_functions()],
                "technique", "top-level name")
        _unique([p.name for p in t.passes], "technique", "pass name")
        self._output()
        for target in t.targets:
            self._target(target)
        self._lights()
        for p in t.params:
            self._param(p)
        for pk in t.packings:
            self._packing(pk)
        for f in t.all_functions():   # in order: a function may only call earlier ones
            self._function(f)
        for p in t.passes:
            self._pass(p)
        self._repeat_groups()

    # -- declarations ----------------------------------------------------------------------------
    def _output(self) -> None:
        out = self.targets.get(self.tech.output)
        _check(out is not None, "technique",
               lambda: f"output '{self.tech.output}' is not a target")
        _check(out.format.is_color, "technique",
               lambda: f"output '{out.name}' is not a colour target")

    def _target(self, t: ir.Target) -> None:
        where = f"target '{t.name}'"
        _check(FORMATS.get(t.format.name) == t.format, where, lambda: f"unknown format {t.format}")
        s = t.size
        _check(s.scale > 0 if s.relative else s.width > 0 and s.height > 0, where,
               lambda: f"bad size {s}")
        _check(t.samples in (1, 2, 4, 8), where, lambda: f"bad sample count {t.samples}")
        self._clear(t, t.clear, where)

    def _clear(self, t: ir.Target, c: ir.Clear, where: str) -> None:
        if t.format.is_color:
            _check(c.depth is None and c.stencil is None, where, "depth/stencil clear of a "
                   "colour target")
            _check(c.color is None or len(c.color) == 4, where, lambda: f"clear colour {c.color}")
        else:
            _check(c.color is None, where, "colour clear of a depth target")
            _check(c.stencil is None or t.format.has_stencil, where, "stencil clear without "
                   "stencil bits")
            _check(c.depth is None or 0.0 <= c.depth <= 1.0, where,
                   lambda: f"depth clear {c.depth}")

    def _lights(self) -> None:
        lt = self.tech.lights
        _check(lt.capacity >= 0, "light table", lambda: f"capacity {lt.capacity}")
        _unique([f.name for f in lt.fields], "light table", "field")
        for f in lt.fields:
            _check(LIGHT_FIELDS.get(f.name) == f.type, "light table",
                   lambda: f"field {f.name}: {f.type}")

    def _param(self, p: ir.Param) -> None:
        where = f"parameter '{p.name}'"
        _check(p.type in _PARAM_TYPES, where, lambda: f"type {p.type}")
        expected = {ir.FLOAT: float, ir.INT: int, ir.UINT: int, ir.BOOL: bool, ir.VOID: str}
        _check(isinstance(p.default, expected[p.type]), where,
               lambda: f"value {p.default!r} is not a {p.type}")
        _check(not p.allowed or p.default in p.allowed, where,
               lambda: f"value {p.default!r} not in {p.allowed}")

    def _packing(self, pk: ir.Packing) -> None:
        where = f"packing '{pk.name}'"
        for f in pk.functions:
            _check(f.name.startswith(pk.name + "_"), where, lambda: f"function '{f.name}'")
        for name, const in pk.constants:
            self._const(const, f"{where} constant '{name}'")

    # -- functions and passes --------------------------------------------------------------------
    def _function(self, f: ir.Function) -> None:
        where = f"function '{f.name}'"
        _check(not any(t.is_void for _, t in f.params), where, "void parameter")
        _unique([n for n, _ in f.params], where, "parameter")
        body = _Body(self, where, ret=f.ret, in_pass=None)
        for name, t in f.params:
            body.scopes[-1][name] = t
        body.stmts(f.body)
        self.functions[f.name] = f      # only now: no recursion, callees come first
        self.needs[f.name] = body.needs

    def _pass(self, p: ir.Pass) -> None:
        where = f"pass '{p.name}'"
        self._draw(p, where)
        _unique(list(p.writes), where, "written target")
        _unique(list(p.reads), where, "read target")
        for n in p.writes:
            _check(n in self.targets and self.targets[n].format.is_color, where,
                   lambda: f"writes '{n}', which is not a colour target")
        for n in p.reads:
            _check(n in self.targets, where, lambda: f"reads unknown target '{n}'")
            _check(n not in p.writes, where, lambda: f"reads and writes '{n}'")
        self._attachments(p, where)
        self._blend(p, where)
        for name, c in p.clears:
            _check(name in self.targets, where, lambda: f"clears unknown target '{name}'")
            self._clear(self.targets[name], c, where)
        body = _Body(self, where, ret=ir.VOID, in_pass=p)
        body.stmts(p.body)
        self._per_sample(p, where)

    def _per_sample(self, p: ir.Pass, where: str) -> None:
        """``sample_id`` only where the attachments have samples; a target read either per
        sample or through its resolve, not both (the runtimes bind one of the two)."""
        functions = facts.pass_functions(self.tech, p.body)
        if facts.shades_per_sample(p.body, functions):
            attached = list(p.writes) + ([p.depth_target] if p.depth_target else [])
            samples = max([self.targets[n].samples for n in attached if n in self.targets]
                          or [1])
            _check(samples > 1, where, "reads sample_id without multisampled attachments")
        both = facts.sample_read_targets(p.body, functions) & \
            facts.resolved_read_targets(p.body, functions)
        _check(not both, where, lambda: f"reads {sorted(both)} both per sample and resolved")

    def _draw(self, p: ir.Pass, where: str) -> None:
        d = p.draw
        if d.kind is ir.DrawKind.LIGHTS:
            _check(d.volume is not None, where, "light draw without a volume")
            _check(set(d.light_types) <= set(LIGHT_TYPES), where, lambda: f"types {d.light_types}")
            if d.light_set is not None:
                pack = next((pk for pk in self.tech.packings if pk.name == d.light_set[0]),
                            None)
                _check(pack is not None and pack.scheme == "channel_slots", where,
                       lambda: f"light set {d.light_set}")
        else:
            _check(d.volume is None and (not d.light_types or d.shadow) and d.light_set is None
                   and not d.scissor, where, lambda: f"light-draw options on a {d.kind.value} draw")
            _check(not d.shadow or (d.kind is ir.DrawKind.SCENE and not p.writes and not p.body
                                    and p.depth_target and p.repeat_group is None
                                    and set(d.light_types) <= {"point", "spot", "directional"}),
                   where, "a shadow-map draw writes depth only, once per atlas tile")
            _check(not d.shadow_volumes or (
                d.kind is ir.DrawKind.SCENE and not d.shadow and not p.writes and not p.body
                and p.depth_target and p.repeat_group is not None
                and d.order is ir.DrawOrder.SCENE),
                where, "a shadow-volume draw writes stencil only, once per light")
            _check(not d.within or (d.kind is ir.DrawKind.SCENE and not d.shadow
                                    and not d.shadow_volumes and p.repeat_group is not None),
                   where, "a `within light radius` draw is a scene draw repeated per light")
        _check(d.kind is ir.DrawKind.SCENE or not d.material, where, "material filter")
        _check(p.state.cull is not ir.CullMode.AUTO or (
            d.kind is ir.DrawKind.LIGHTS and d.volume in (ir.Volume.SPHERE, ir.Volume.CONE)),
            where, "cull auto on a draw that is not a sphere or cone light draw")
        _check(p.state.depth.inside is None or p.state.cull is ir.CullMode.AUTO, where,
               "a depth `inside` test without cull auto")
        _check(set(p.repeat_types) <= set(LIGHT_TYPES), where, lambda: f"types {p.repeat_types}")
        _check(not p.repeat_types or p.repeat_group is not None, where,
               "repeat light types on a pass that does not repeat per light")

    def _attachments(self, p: ir.Pass, where: str) -> None:
        st = p.state
        if p.depth_target is None:
            _check(not st.depth.enabled, where, "depth test without a depth target")
            _check(not st.stencil.enabled, where, "stencil test without a depth target")
            return
        t = self.targets.get(p.depth_target)
        _check(t is not None and t.format.has_depth, where,
               lambda: f"depth target '{p.depth_target}' is not a depth target")
        _check(not st.stencil.enabled or t.format.has_stencil, where,
               "stencil state without stencil bits")
        _check(not (st.depth.write and p.depth_target in p.reads), where,
               "writes depth to a target it reads")

    def _blend(self, p: ir.Pass, where: str) -> None:
        names = [n for n, _ in p.state.blend]
        _unique(names, where, "blend entry")
        for name, b in p.state.blend:
            _check(name in p.writes, where, lambda: f"blend for '{name}', which it does not write")
            _check(not b.enabled or self.targets[name].format.blendable, where,
                   lambda: f"blending into integer target '{name}'")

    def _repeat_groups(self) -> None:
        last: dict[int, int] = {}
        for i, p in enumerate(self.tech.passes):
            g = p.repeat_group
            if g is None:
                continue
            _check(g not in last or last[g] == i - 1, f"pass '{p.name}'",
                   lambda: f"repeat group {g} is not contiguous")
            last[g] = i

    def _const(self, c: ir.Const, where: str) -> None:
        t = c.type
        _check(not t.is_void, where, "void constant")
        if t.is_scalar:
            _check(_scalar_value_ok(c.value, t.scalar), where, lambda: f"{c.value!r} is not a {t}")
        else:
            n = t.mat * t.mat if t.is_matrix else t.size
            _check(isinstance(c.value, tuple) and len(c.value) == n
                   and all(_scalar_value_ok(v, t.scalar) for v in c.value), where,
                   lambda: f"{c.value!r} is not a {t}")


def _scalar_value_ok(v, scalar: ir.Scalar) -> bool:
    if scalar is ir.Scalar.BOOL:
        return isinstance(v, bool)
    if scalar is ir.Scalar.FLOAT:
        return isinstance(v, (int, float)) and not isinstance(v, bool)
    return isinstance(v, int) and not isinstance(v, bool)


class _Body:
    """Checks one function or pass body: scopes of locals, loop nesting, types."""

    def __init__(self, v: _Verifier, where: str, ret: ir.Type, in_pass: Optional[ir.Pass]):
        self.v = v
        self.where = where
        self.ret = ret
        self.pass_ = in_pass
        self.scopes: list[dict[str, ir.Type]] = [{}]
        self.loops = 0
        self.needs = _Needs()

    def check(self, cond: bool, message: Union[str, Callable[[], str]]) -> None:
        _check(cond, self.where, message)

    # -- statements ----------------------------------------------------------------------------
    def stmts(self, stmts: tuple[ir.Stmt, ...]) -> None:
        for s in stmts:
            self.stmt(s)

    def block(self, stmts: tuple[ir.Stmt, ...]) -> None:
        self.scopes.append({})
        self.stmts(stmts)
        self.scopes.pop()

    def stmt(self, s: ir.Stmt) -> None:
        if isinstance(s, ir.Declare):
            self.check(not s.type.is_void, lambda: f"void local '{s.name}'")
            self.check(self.local(s.name) is None, lambda: f"'{s.name}' declared twice")
            if s.init is not None:
                self.check(self.expr(s.init) == s.type, lambda: f"'{s.name}' initialised with a "
                           f"{s.init.type}")
            self.scopes[-1][s.name] = s.type
        elif isinstance(s, ir.Assign):
            self.assign(s)
        elif isinstance(s, ir.Output):
            self.output(s)
        elif isinstance(s, ir.If):
            self.check(self.expr(s.cond) == ir.BOOL, "if condition is not a bool")
            self.block(s.then)
            self.block(s.other)
        elif isinstance(s, ir.For):
            self.loop(s)
        elif isinstance(s, (ir.Break, ir.Continue)):
            self.check(self.loops > 0, lambda: f"{type(s).__name__.lower()} outside a loop")
        elif isinstance(s, ir.Return):
            self.ret_stmt(s)
        elif isinstance(s, ir.ExprStmt):
            self.check(isinstance(s.expr, ir.Call), lambda: f"expression statement {s.expr}")
            self.expr(s.expr, allow_void=True)
        else:
            self.check(isinstance(s, ir.Discard), lambda: f"unknown statement {s!r}")

    def assign(self, s: ir.Assign) -> None:
        self.check(s.op in _ASSIGN_OPS, lambda: f"assignment operator {s.op}")
        root = s.target
        while isinstance(root, (ir.Swizzle, ir.Index)):
            if isinstance(root, ir.Swizzle):
                self.check(len(set(root.components)) == len(root.components),
                           "assignment to a swizzle with repeated components")
            root = root.base
        self.check(isinstance(root, ir.Var) and root.kind == "local",
                   lambda: f"assignment to {root!r}")
        tt, vt = self.expr(s.target), self.expr(s.value)
        if s.op == "=":
            self.check(tt == vt, lambda: f"assigns a {vt} to a {tt}")
        else:
            self.check(binary_type(s.op[0], tt, vt) == tt, lambda: f"{tt} {s.op} {vt}")

    def output(self, s: ir.Output) -> None:
        p = self.pass_
        self.check(p is not None, lambda: f"output to '{s.target}' outside a pass")
        self.check(s.target in p.writes, lambda: f"writes '{s.target}' without declaring it")
        want = target_write_type(self.v.targets[s.target].format)
        self.check(self.expr(s.value) == want, lambda: f"output to '{s.target}' is a "
                   f"{s.value.type}, not a {want}")

    def loop(self, s: ir.For) -> None:
        self.check(s.type in (ir.INT, ir.UINT), lambda: f"loop counter of type {s.type}")
        self.check(self.expr(s.start) == s.type and self.expr(s.bound) == s.type,
                   lambda: f"loop '{s.var}' bounds are not {s.type}")
        self.check(self.local(s.var) is None, lambda: f"loop counter '{s.var}' shadows a local")
        self.scopes.append({s.var: s.type})
        self.loops += 1
        self.block(s.body)
        self.loops -= 1
        self.scopes.pop()

    def ret_stmt(self, s: ir.Return) -> None:
        if s.value is None:
            self.check(self.ret.is_void, "return without a value")
        else:
            self.check(self.pass_ is None, "fragment body returns a value")
            self.check(self.expr(s.value) == self.ret, lambda: f"returns a {s.value.type}, not a "
                       f"{self.ret}")

    def local(self, name: str) -> Optional[ir.Type]:
        for scope in reversed(self.scopes):
            if name in scope:
                return scope[name]
        return None

    # -- expressions ---------------------------------------------------------------------------
    def expr(self, e: ir.Expr, allow_void: bool = False) -> ir.Type:
        """Check ``e`` and return its (declared) type."""
        method = getattr(self, "_" + type(e).__name__, None)
        if method is None:        # the messages repr the whole expression: only on failure
            self.check(False, f"unknown expression {e!r}")
        method(e)
        if not allow_void and e.type.is_void:
            self.check(False, f"void value {e!r}")
        return e.type

    def _Const(self, e: ir.Const) -> None:
        self.v._const(e, self.where)

    def _Var(self, e: ir.Var) -> None:
        if e.kind == "local":
            self.check(self.local(e.name) == e.type,
                       lambda: f"local '{e.name}': {e.type} is not in scope")
        elif e.kind == "param":
            p = self.v.params.get(e.name)
            self.check(p is not None and p.type == e.type and not p.type.is_void,
                       lambda: f"parameter '{e.name}': {e.type}")
        else:
            self.check(e.kind == "input", lambda: f"variable kind {e.kind}")
            inp = STAGE_INPUTS.get(e.name)
            self.check(inp is not None and inp.type == e.type,
                       lambda: f"input '{e.name}': {e.type}")
            if inp.where is Where.SCENE:
                self.needs.scene.add(e.name)
                self.check(self.pass_ is None or self.pass_.draw.kind is ir.DrawKind.SCENE,
                           lambda: f"scene input '{e.name}' outside a scene draw")

    def _Unary(self, e: ir.Unary) -> None:
        self.check(unary_type(e.op, self.expr(e.operand)) == e.type,
                   lambda: f"{e.op}{e.operand.type} is not a {e.type}")

    def _Binary(self, e: ir.Binary) -> None:
        lt, rt = self.expr(e.left), self.expr(e.right)
        self.check(binary_type(e.op, lt, rt) == e.type,
                   lambda: f"{lt} {e.op} {rt} is not a {e.type}")

    def _Ternary(self, e: ir.Ternary) -> None:
        self.check(self.expr(e.cond) == ir.BOOL, "?: condition is not a bool")
        self.check(self.expr(e.then) == self.expr(e.other) == e.type, "?: branch types")

    def _Call(self, e: ir.Call) -> None:
        types = [self.expr(a) for a in e.args]
        if e.builtin:
            self.check(e.name in BUILTINS and resolve_builtin(e.name, types) == e.type,
                       lambda: f"builtin {e.name}{tuple(map(str, types))} is not a {e.type}")
            return
        f = self.v.functions.get(e.name)
        self.check(f is not None, lambda: f"calls '{e.name}', which is not defined before it")
        self.check([t for _, t in f.params] == types and f.ret == e.type,
                   lambda: f"call of '{e.name}' does not match its signature")
        needs = self.v.needs[e.name]
        self.needs.scene |= needs.scene
        self.needs.light |= needs.light
        self.needs.reads |= needs.reads
        p = self.pass_
        if p is not None:
            self.check(not needs.scene or p.draw.kind is ir.DrawKind.SCENE,
                       lambda: f"'{e.name}' needs scene inputs")
            self.check(not needs.light or self._has_light(p), lambda: f"'{e.name}' needs `light`")
            self.check(needs.reads <= set(p.reads), lambda: f"'{e.name}' reads {needs.reads}")

    def _Construct(self, e: ir.Construct) -> None:
        types = [self.expr(a) for a in e.args]
        problem = construct_error(e.type, types)
        self.check(problem is None, lambda: f"{e.type}{tuple(map(str, types))}: {problem}")

    def _Swizzle(self, e: ir.Swizzle) -> None:
        bt = self.expr(e.base)
        n = len(e.components)
        self.check(bt.is_vector and 1 <= n <= 4
                   and all(c in "xyzw"[:bt.size] for c in e.components),
                   lambda: f"swizzle .{e.components} of a {bt}")
        self.check(e.type == (bt.element if n == 1 else bt.with_size(n)),
                   lambda: f"swizzle .{e.components} typed {e.type}")

    def _Index(self, e: ir.Index) -> None:
        bt = self.expr(e.base)
        self.check(bt.is_vector or bt.is_matrix, lambda: f"indexing a {bt}")
        self.check(self.expr(e.index) in (ir.INT, ir.UINT), "index is not an int or uint")
        self.check(e.type == bt.element, lambda: f"element of a {bt} typed {e.type}")

    def _MaterialField(self, e: ir.MaterialField) -> None:
        table = self.v.tech.materials
        self.check(table is not None and table.field_type(e.field) == e.type,
                   lambda: f"material field {e.field}: {e.type}")
        self.check(self.expr(e.index) in (ir.INT, ir.UINT), "material index type")

    def _LightField(self, e: ir.LightField) -> None:
        if e.field == LIGHT_INDEX:
            self.check(e.index is None and e.type == ir.UINT, "light.index")
        else:
            self.check(self.v.tech.lights.field_type(e.field) == e.type,
                       lambda: f"light field {e.field}: {e.type}")
        if e.index is not None:
            self.check(self.expr(e.index) in (ir.INT, ir.UINT), "light index type")
            return
        self.needs.light = True
        self.check(self.pass_ is None or self._has_light(self.pass_),
                   "`light` read outside a light draw or repeat-per-light pass")

    @staticmethod
    def _has_light(p: ir.Pass) -> bool:
        return p.draw.kind is ir.DrawKind.LIGHTS or p.repeat_group is not None

    def _read(self, target: str) -> ir.Target:
        t = self.v.targets.get(target)
        self.check(t is not None, lambda: f"reads unknown target '{target}'")
        self.needs.reads.add(target)
        self.check(self.pass_ is None or target in self.pass_.reads,
                   lambda: f"reads '{target}' without declaring it")
        return t

    def _Load(self, e: ir.Load) -> None:
        t = self._read(e.target)
        self.check(e.type == target_read_type(t.format), lambda: f"load({e.target}) typed {e.type}")
        self.check(e.coord is None or self.expr(e.coord) == ir.IVEC2, "load coordinate")
        if e.sample is not None:
            self.check(self.expr(e.sample) == ir.INT, "load_sample's sample index is an int")
            self.check(t.samples > 1 and t.format.is_color,
                       lambda: f"load_sample of '{e.target}', not a multisampled colour target")

    def _Sample(self, e: ir.Sample) -> None:
        t = self._read(e.target)
        self.check(not t.format.is_integer, lambda: f"samples integer target '{e.target}'")
        self.check(e.type == target_read_type(t.format),
                   lambda: f"sample({e.target}) typed {e.type}")
        self.check(self.expr(e.uv) == ir.VEC2, "sample coordinate")

    def _TargetSize(self, e: ir.TargetSize) -> None:
        self._read(e.target)
        self.check(e.type == ir.IVEC2, "size() is an ivec2")
