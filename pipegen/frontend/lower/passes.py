"""Lowering of ``pass`` declarations (not to be confused with ``pipegen.passes``, the
compiler's IR passes): draw, attachments, depth, stencil, blending and other fixed-function
state, clears, repeat groups and the fragment body."""

from __future__ import annotations

from typing import Optional

from pipegen.frontend import ast
from pipegen.ir import nodes as ir
from pipegen.ir.builtins import LIGHT_TYPES, VOLUME_LIGHT_FIELDS
from pipegen.frontend.lower.collect import PassItem
from pipegen.frontend.lower.names import MATERIALS, Lowering, Context, did_you_mean, error
from pipegen.frontend.lower.statements import BodyChecker

_SINGLE = (ast.Draw, ast.Writes, ast.Reads, ast.Depth, ast.BlendConstant, ast.Cull, ast.Offset,
           ast.Fragment, ast.RepeatPerLight)
_STMT_WORD = {ast.Draw: "draw", ast.Writes: "writes", ast.Reads: "reads", ast.Depth: "depth",
              ast.BlendConstant: "blend constant", ast.Cull: "cull", ast.Offset: "offset",
              ast.Fragment: "fragment", ast.RepeatPerLight: "repeat per light"}


class PassLowerer:
    def __init__(self, low: Lowering, item: PassItem):
        self.low = low
        self.decl = item.decl
        self.name = item.decl.name.name
        self.item = item
        self.group = item.group
        self.single: dict[type, ast.Node] = {}
        for s in self.decl.stmts:
            if isinstance(s, _SINGLE):
                if type(s) in self.single:
                    raise error(s.span, f"pass '{self.name}' has two `{_STMT_WORD[type(s)]}` "
                                f"statements", "merge them into one")
                self.single[type(s)] = s

    def _all(self, kind: type) -> list:
        return [s for s in self.decl.stmts if isinstance(s, kind)]

    def lower(self) -> ir.Pass:
        draw = self._draw()
        writes = self._writes()
        reads = self._reads(writes)
        depth_target, depth = self._depth(reads)
        stencil = self._stencil(depth_target)
        blend = self._blend(writes)
        attached = list(writes) + ([depth_target] if depth_target else [])
        samples = max([self.low.targets[n].samples for n in attached] or [1])
        if draw.within and samples > 1:
            raise error(self.single.get(ast.Draw).within.span,
                        f"pass '{self.name}' draws the objects within a light's radius at "
                        f"{samples} samples: a fragment is shaded at its pixel's centre, which "
                        f"may lie outside its triangle and its object's bounds, so an object "
                        f"left out could have lit a pixel", "drop `within light radius`, or "
                        "draw this pass's targets at one sample")
        ctx = Context(self.name, draw.kind, self.group is not None, writes, reads,
                      samples=samples)
        body = self._fragment(ctx, writes)
        state = ir.PassState(depth, stencil, blend, self._blend_constant(), self._cull(),
                             self._offset())
        return ir.Pass(self.name, draw, state, writes, reads, depth_target, body, self.group,
                       self._clears(), self.decl.span, self._repeat_types())

    # -- draw --------------------------------------------------------------------------------
    def _draw(self) -> ir.Draw:
        d = self.single.get(ast.Draw)
        if d is None:
            raise error(self.decl.name.span, f"pass '{self.name}' draws nothing",
                        "add `draw scene`, `draw lights as sphere` or `draw fullscreen`")
        if d.kind == "scene":
            material = ()
            if d.material is not None:
                if d.material.name not in MATERIALS:
                    raise error(d.material.span, f"unknown material '{d.material.name}'",
                                f"scene draws filter by {' or '.join(MATERIALS)}")
                material = (d.material.name,)
            order = ir.DrawOrder.BACK_TO_FRONT if d.back_to_front else ir.DrawOrder.SCENE
            if d.from_lights is not None:
                return self._shadow_draw(d, material, order)
            if d.shadow_volumes is not None:
                return self._volume_draw(d, material, order)
            if d.within is not None:
                return self._within_draw(d, material, order)
            return ir.Draw(ir.DrawKind.SCENE, material=material, order=order)
        if d.kind == "fullscreen":
            return ir.Draw(ir.DrawKind.FULLSCREEN)
        types: list[str] = []
        for w in d.light_types:
            if w.value in types:
                raise error(w.span, f"light type '{w.value}' is listed twice", "list it once")
            types.append(w.value)
        missing = [f for f in VOLUME_LIGHT_FIELDS[d.volume.value]
                   if self.low.lights.field_type(f) is None]
        if missing:
            raise error(d.volume.span, f"{d.volume.value} light volumes need the light "
                        f"field(s) {', '.join(missing)}, which the lights schema lacks",
                        "add them to `lights[N] { … }`")
        return ir.Draw(ir.DrawKind.LIGHTS, volume=ir.Volume(d.volume.value),
                       light_types=tuple(t for t in LIGHT_TYPES if t in types),
                       light_set=self._light_set(d), scissor=d.scissor)

    def _shadow_draw(self, d: ast.Draw, material: tuple[str, ...],
                     order: ir.DrawOrder) -> ir.Draw:
        """``draw scene… from lights [point] [spot] [directional] [first K] [tiles N]``: the
        scene from each shadow-casting light into its tiles of the depth target (six for a point
        light; pipegen/scene/shadows.py); no types listed: all three; ``first K``: only light
        indices below K cast (at most the light table's capacity)."""
        f = d.from_lights
        types: list[str] = []
        for w in f.light_types:
            if w.value in types:
                raise error(w.span, f"light type '{w.value}' is listed twice", "list it once")
            types.append(w.value)
        tiles = 1 if f.tiles is None else self.low.integer(f.tiles, "the shadow atlas's tiles "
                                                            "per side", 1, 64)
        first = 0 if f.first is None else self.low.integer(
            f.first, "`first` (the light indices that may cast shadows)", 1,
            self.low.lights.capacity or None)
        if order is not ir.DrawOrder.SCENE:
            raise error(f.span, "a shadow-map draw keeps the scene order",
                        "drop `back_to_front`")
        if self.group is not None or self.single.get(ast.RepeatPerLight) is not None:
            raise error(f.span, f"pass '{self.name}' draws from the lights already (once per "
                        f"shadow-casting light) and cannot also repeat per light",
                        "move it out of the `repeat per light` group")
        for s in (self.single.get(ast.Writes), self.single.get(ast.Fragment),
                  *self._all(ast.PassClear)):
            if s is not None:
                raise error(s.span, f"pass '{self.name}' draws shadow maps: it writes only "
                            f"depth (no `writes`, `fragment` or `clear`; the atlas is cleared "
                            f"by its target's `clear` at the start of the frame)",
                            "remove this statement")
        if self.single.get(ast.Depth) is None:
            raise error(d.span, f"pass '{self.name}' draws shadow maps but attaches no depth "
                        f"target", "add e.g. `depth shadow_atlas less write`")
        return ir.Draw(ir.DrawKind.SCENE, material=material, order=order,
                       light_types=tuple(t for t in LIGHT_TYPES if t in types) or
                       tuple(LIGHT_TYPES), shadow_tiles=tiles, shadow_first=first)

    def _volume_draw(self, d: ast.Draw, material: tuple[str, ...],
                     order: ir.DrawOrder) -> ir.Draw:
        """``draw scene… shadow_volumes``: the stencil shadow volumes of the scene's objects
        (material filter as for scene draws) from the light of a ``repeat per light`` pass,
        extruded on the host (pipegen/scene/shadow_volumes.py); it writes only stencil."""
        at = d.shadow_volumes.span
        if order is not ir.DrawOrder.SCENE:
            raise error(at, "shadow volumes are counted in the stencil: their order does not "
                        "matter", "drop `back_to_front`")
        if self.group is None and self.single.get(ast.RepeatPerLight) is None:
            raise error(at, f"pass '{self.name}' draws the shadow volumes of a light but does "
                        f"not repeat per light", "put it in a `repeat per light` group, before "
                        "the passes that test its stencil")
        for s in (self.single.get(ast.Writes), self.single.get(ast.Fragment)):
            if s is not None:
                raise error(s.span, f"pass '{self.name}' draws shadow volumes: it writes only "
                            f"stencil (no `writes` or `fragment`)", "remove this statement")
        if not self._all(ast.Stencil):
            raise error(at, f"pass '{self.name}' draws shadow volumes but sets no stencil "
                        f"operations", "count them, e.g. `stencil back { func always zfail "
                        "incr_wrap }` and `stencil front { func always zfail decr_wrap }`")
        return ir.Draw(ir.DrawKind.SCENE, material=material, order=order, shadow_volumes=True)

    def _within_draw(self, d: ast.Draw, material: tuple[str, ...],
                     order: ir.DrawOrder) -> ir.Draw:
        """``draw scene… within light radius``: in a ``repeat per light`` pass, each light's
        draw submits only the objects whose bounds come within the light's radius (every object
        for a directional light), as a multi-pass forward renderer selects them on the CPU."""
        at = d.within.span
        if self.group is None and self.single.get(ast.RepeatPerLight) is None:
            raise error(at, f"pass '{self.name}' draws the objects within a light's radius but "
                        f"does not repeat per light", "put it in a `repeat per light` group, "
                        "or drop `within light radius`")
        missing = [f for f in ("position", "radius") if self.low.lights.field_type(f) is None]
        if missing:
            raise error(at, f"`within light radius` needs the light field(s) "
                        f"{', '.join(missing)}, which the lights schema lacks",
                        "add them to `lights[N] { … }`")
        return ir.Draw(ir.DrawKind.SCENE, material=material, order=order, within=True)

    def _light_set(self, d: ast.Draw) -> Optional[tuple[str, int]]:
        if d.light_set is None:
            return None
        pack, index = d.light_set
        decl = self.low.packs.get(pack.name)
        if decl is None:
            raise error(pack.span, f"unknown packing '{pack.name}'",
                        did_you_mean(pack.name, self.low.packs,
                                     "declare it with `pack NAME = channel_slots(…)`"))
        scheme = self.low.pack_schemes[pack.name]
        if scheme != "channel_slots":
            raise error(pack.span, f"packing '{pack.name}' is a {scheme} packing; "
                        f"light sets come from channel_slots", "use a channel_slots packing")
        slots = self.low.pack_options[pack.name].get("slots", 4)
        k = self.low.integer(index, "a light set index", 0, int(slots) - 1)
        return pack.name, k

    # -- attachments ---------------------------------------------------------------------------
    def _target(self, name: ast.Name) -> ir.Target:
        t = self.low.targets.get(name.name)
        if t is None:
            raise error(name.span, f"unknown target '{name.name}'",
                        did_you_mean(name.name, self.low.targets, "declare it with `target`"))
        return t

    def _writes(self) -> tuple[str, ...]:
        stmt = self.single.get(ast.Writes)
        names = self._unique_targets(stmt, "writes")
        for n in (stmt.targets if stmt else ()):
            t = self._target(n)
            if not t.format.is_color:
                raise error(n.span, f"'{n.name}' is a depth target and cannot be written as a "
                            f"colour", f"attach it with `depth {n.name} …`")
        return names

    def _reads(self, writes: tuple[str, ...]) -> tuple[str, ...]:
        stmt = self.single.get(ast.Reads)
        names = self._unique_targets(stmt, "reads")
        for n in (stmt.targets if stmt else ()):
            self._target(n)
            if n.name in writes:
                raise error(n.span, f"pass '{self.name}' both writes and reads target "
                            f"'{n.name}'", "a pass cannot read a target it renders to; "
                            "write a copy in an earlier pass and read that")
        return names

    def _unique_targets(self, stmt, word: str) -> tuple[str, ...]:
        if stmt is None:
            return ()
        seen: list[str] = []
        for n in stmt.targets:
            if n.name in seen:
                raise error(n.span, f"'{n.name}' is listed twice in `{word}`", "list it once")
            seen.append(n.name)
        return tuple(seen)

    def _depth(self, reads: tuple[str, ...]) -> tuple[Optional[str], ir.DepthState]:
        d = self.single.get(ast.Depth)
        if d is None:
            return None, ir.DepthState()
        t = self._target(d.target)
        if not t.format.has_depth:
            raise error(d.target.span, f"'{t.name}' ({t.format.name}) is not a depth target",
                        "attach a d24s8 or d32f target")
        if d.func is None:
            return t.name, ir.DepthState()
        flags = [f.value for f in d.flags]
        for f in set(flags):
            if flags.count(f) > 1:
                raise error(d.span, f"`{f}` is given twice", "give it once")
        if "write" in flags and "nowrite" in flags:
            raise error(d.span, "depth is both `write` and `nowrite`", "choose one")
        write = "nowrite" not in flags
        if write and t.name in reads:
            raise error(d.span, f"pass '{self.name}' writes depth to '{t.name}' while reading "
                        f"it", f"test without writing: `depth {t.name} {d.func.value} nowrite`")
        inside = None
        if d.inside is not None:
            cull = self.single.get(ast.Cull)
            if cull is None or cull.mode.value != "auto":
                raise error(d.inside.span, "`inside FUNC` is the depth test of the lights that "
                            "`cull auto` draws with their back faces, but pass "
                            f"'{self.name}' does not `cull auto`",
                            "add `cull auto` or drop `inside`")
            inside = ir.CompareFunc(d.inside.value)
        return t.name, ir.DepthState(ir.CompareFunc(d.func.value), write, "clamp" in flags,
                                     inside)

    # -- stencil -------------------------------------------------------------------------------
    def _stencil(self, depth_target: Optional[str]) -> ir.StencilState:
        stmts = self._all(ast.Stencil)
        if not stmts:
            return ir.StencilState()
        self._require_stencil(stmts[0], depth_target)
        faces: dict[str, ir.StencilFace] = {}
        for s in stmts:
            face = self._stencil_face(s)
            names = (s.face.value,) if s.face is not None else ("front", "back")
            for n in names:
                if n in faces:
                    raise error(s.span, f"the {n} stencil face is set twice",
                                "give each face one `stencil` statement")
                faces[n] = face
        return ir.StencilState(faces.get("front", ir.StencilFace()),
                               faces.get("back", ir.StencilFace()))

    def _require_stencil(self, s: ast.Stencil, depth_target: Optional[str]) -> None:
        hint = ("attach a d24s8 target with `depth T …` (or `depth T off` to use only its "
                "stencil)")
        if depth_target is None:
            raise error(s.span, f"stencil state without a stencil target: pass '{self.name}' "
                        f"attaches no depth/stencil target", hint)
        fmt = self.low.targets[depth_target].format
        if not fmt.has_stencil:
            raise error(s.span, f"stencil state without a stencil target: '{depth_target}' "
                        f"({fmt.name}) has no stencil bits", hint)

    def _stencil_face(self, s: ast.Stencil) -> ir.StencilFace:
        values: dict[str, object] = {}
        for item in s.items:
            if item.key in values:
                raise error(item.span, f"`{item.key}` is given twice in this stencil block",
                            "give it once")
            if item.key == "func":
                values["func"] = ir.CompareFunc(item.value.value)
            elif item.key in ("fail", "zfail", "pass"):
                values[item.key] = ir.StencilOp(item.value.value)
            else:
                values[item.key] = self.low.integer(item.value, f"the stencil {item.key} "
                                                     f"value", 0, 255)
        return ir.StencilFace(
            func=values.get("func", ir.CompareFunc.ALWAYS), ref=values.get("ref", 0),
            read_mask=values.get("read", 0xFF), write_mask=values.get("write", 0xFF),
            fail=values.get("fail", ir.StencilOp.KEEP),
            zfail=values.get("zfail", ir.StencilOp.KEEP),
            zpass=values.get("pass", ir.StencilOp.KEEP))

    # -- blending ------------------------------------------------------------------------------
    def _blend(self, writes: tuple[str, ...]) -> tuple[tuple[str, ir.TargetBlend], ...]:
        """One entry per written target, in attachment order."""
        blends: dict[str, ir.TargetBlend] = {}
        masks: dict[str, tuple[bool, bool, bool, bool]] = {}
        for b in self._all(ast.Blend):
            t = self._written(b.target, writes, "blend")
            if t.name in blends:
                raise error(b.target.span, f"target '{t.name}' is blended twice",
                            "give each target one `blend` statement")
            if b.rgb is not None and not t.format.blendable:
                raise error(b.span, f"blend on an integer target: '{t.name}' ({t.format.name}) "
                            f"cannot be blended", "blend unorm or float targets; integer "
                            "targets are only overwritten")
            blends[t.name] = self._target_blend(b)
        for m in self._all(ast.Mask):
            t = self._written(m.target, writes, "mask")
            if t.name in masks:
                raise error(m.target.span, f"target '{t.name}' is masked twice",
                            "give each target one `mask` statement")
            masks[t.name] = _write_mask(m, t)
        out = []
        for name in writes:
            b = blends.get(name, ir.TargetBlend())
            out.append((name, ir.TargetBlend(b.enabled, b.rgb, b.alpha,
                                             masks.get(name, b.write_mask))))
        return tuple(out)

    def _written(self, name: ast.Name, writes: tuple[str, ...], word: str) -> ir.Target:
        t = self._target(name)
        if name.name not in writes:
            raise error(name.span, f"`{word}` for target '{name.name}', which pass '{self.name}' "
                        f"does not write", f"add `writes {name.name}` or remove the `{word}`")
        return t

    def _target_blend(self, b: ast.Blend) -> ir.TargetBlend:
        if b.rgb is None:
            return ir.TargetBlend(enabled=False)
        return ir.TargetBlend(True, _equation(b.rgb), _equation(b.alpha))

    def _blend_constant(self) -> tuple[float, float, float, float]:
        s = self.single.get(ast.BlendConstant)
        if s is None:
            return (0.0, 0.0, 0.0, 0.0)
        items = s.value.items if isinstance(s.value, ast.TupleLit) else [s.value] * 4
        if len(items) != 4:
            raise error(s.value.span, f"the blend constant has 4 components, not {len(items)}",
                        "write `blend constant (r, g, b, a)` or one value for all four")
        return tuple(float(self.low.number(e, "a blend constant component")) for e in items)

    def _repeat_types(self) -> tuple[str, ...]:
        """``repeat per light TYPE …`` (on the pass or on its block): the light types the
        repeat group runs this pass for; () for every light."""
        stmt = self.single.get(ast.RepeatPerLight)
        own = list(stmt.light_types) if stmt is not None else []
        block = list(self.item.block_types)
        if own and block:
            raise error(own[0].span, f"pass '{self.name}' is in a `repeat per light "
                        f"{' '.join(w.value for w in block)} {{ … }}` block and names light "
                        f"types again", "give the light types once, on the block or the pass")
        words = own or block
        types: list[str] = []
        for w in words:
            if w.value in types:
                raise error(w.span, f"light type '{w.value}' is listed twice", "list it once")
            types.append(w.value)
        return tuple(t for t in LIGHT_TYPES if t in types)

    # -- other state ---------------------------------------------------------------------------
    def _cull(self) -> ir.CullMode:
        s = self.single.get(ast.Cull)
        if s is None:
            return ir.CullMode.NONE
        mode = ir.CullMode(s.mode.value)
        if mode is ir.CullMode.AUTO:
            d = self.single.get(ast.Draw)
            volume = d.volume.value if d is not None and d.volume is not None else None
            if d is None or d.kind != "lights" or volume not in ("sphere", "cone"):
                what = ("nothing" if d is None else "a screen quad" if volume == "quad" else
                        "scene geometry" if d.kind == "scene" else "a full-screen triangle")
                raise error(s.span, f"`cull auto` chooses the faces of light volumes, but pass "
                            f"'{self.name}' draws {what}",
                            "use it with `draw lights as sphere` or `draw lights as cone`; "
                            "otherwise write `cull back`, `cull front` or `cull none`")
        return mode

    def _offset(self) -> Optional[ir.PolygonOffset]:
        s = self.single.get(ast.Offset)
        if s is None:
            return None
        return ir.PolygonOffset(float(self.low.number(s.factor, "the offset factor")),
                                float(self.low.number(s.units, "the offset units")))

    def _clears(self) -> tuple[tuple[str, ir.Clear], ...]:
        out: dict[str, ir.Clear] = {}
        for c in self._all(ast.PassClear):
            t = self._target(c.target)
            if t.name in out:
                raise error(c.target.span, f"target '{t.name}' is cleared twice in pass "
                            f"'{self.name}'", "merge the clears")
            out[t.name] = self.low.clear(c.clear, t.name, t.format)
        return tuple(out.items())

    # -- fragment ------------------------------------------------------------------------------
    def _fragment(self, ctx: Context, writes: tuple[str, ...]) -> tuple[ir.Stmt, ...]:
        frag = self.single.get(ast.Fragment)
        if frag is None:
            if writes:
                raise error(self.single[ast.Writes].span, f"pass '{self.name}' writes "
                            f"{', '.join(writes)} but has no fragment body",
                            "add `fragment { … }` that assigns the targets, or drop `writes`")
            return ()
        checker = BodyChecker(self.low, ctx)
        body = checker.block(frag.body)
        missing = [w for w in writes if w not in checker.outputs]
        if missing:
            raise error(self.single[ast.Writes].span, f"pass '{self.name}' declares `writes "
                        f"{missing[0]}` but its fragment body never writes it",
                        f"assign it: `{missing[0]} = …;`, or drop it from `writes`")
        return body


def _equation(eq: ast.BlendEq) -> ir.BlendEquation:
    op = ir.BlendOp(eq.op.value)
    if op in (ir.BlendOp.MIN, ir.BlendOp.MAX):
        if eq.src is not None:
            raise error(eq.src.span, f"`{op.value}` blending ignores factors",
                        f"write just `{op.value}`")
        return ir.BlendEquation(op)
    if eq.src is None:
        raise error(eq.span, f"`{op.value}` blending needs factors",
                    f"e.g. `{op.value}(one, one)` or `{op.value}(src_alpha, one_minus_src_alpha)`")
    return ir.BlendEquation(op, ir.BlendFactor(eq.src.value), ir.BlendFactor(eq.dst.value))


def _write_mask(m: ast.Mask, t: ir.Target) -> tuple[bool, bool, bool, bool]:
    text = m.channels.name
    if text == "none":
        return (False, False, False, False)
    channels = "rgba"[:t.format.channels]
    if not all(c in "rgba" for c in text) or len(set(text)) != len(text):
        raise error(m.channels.span, f"'{text}' is not a channel mask",
                    "list channels from r, g, b, a once each (e.g. `rg`), or write `none`")
    for c in text:
        if c not in channels:
            raise error(m.channels.span, f"target '{t.name}' ({t.format.name}) has no "
                        f"{c} channel", f"its channels are {channels}")
    return tuple(c in text for c in "rgba")
