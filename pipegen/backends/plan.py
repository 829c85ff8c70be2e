"""The compiled plan: what a runtime needs to execute a technique, as frozen dataclasses.

The compiler builds a ``Plan`` once per backend (``technique_plan``); the backend adds its code
to each pass (``PassPlan.code``: ``GLPassCode`` or ``CLPassCode``).  A plan carries IR enums and
``formats.Format`` objects, never backend constants: per-backend enum tables (GL enums, CL
macros) live in the backend or runtime that needs them.

A plan also has a plain-data spelling (``Plan.to_dict`` / ``plan_from_dict``, documented in
docs/internals.md) for generated pipeline modules, which hold it as a literal, and for tests
that write small plans by hand.  ``plan_from_dict`` is the one place where a missing key takes
its default.

The second half of this module holds the IR queries every code generator needs per pass
(which functions, stage inputs and target reads a pass's shader uses).
"""

from __future__ import annotations

from dataclasses import field, replace
from typing import Any, Mapping, Optional, Union

from pipegen.core.records import record
from pipegen.core import formats as F
from pipegen.ir import nodes as ir
# the code queries, here for the emitters (they live in the backend-neutral core)
from pipegen.ir.facts import (
    CodeFacts, code_exprs, code_facts, may_discard, pass_functions, sample_read_targets,
    sampled_targets, shades_per_sample, stage_inputs)


# ``draw scene… within light radius``: the object ids each light reaches, as both runtimes hold
# them (runtime/draws.py's reach_table; the CL raster kernel's pg_reach): bits of 8 uint32
# words per light, object ids being 0..255 (a triangle's flat word, scene/model.py)
REACH_WORDS = 8


# ---- the typed plan ------------------------------------------------------------------------


@record(frozen=True)
class LightTablePlan:
    capacity: int
    fields: tuple[tuple[str, str], ...]      # (name, type) in table-column order
    # `material { … }`: (name, type, default components), stored after the lights
    # (ir/material_layout.py); () without a material block
    materials: tuple[tuple[str, str, tuple[float, ...]], ...] = ()


@record(frozen=True)
class TargetPlan:
    name: str
    format: F.Format
    size: ir.Size
    samples: int = 1
    clear: ir.Clear = ir.Clear()

    def resolve(self, out_w: int, out_h: int) -> tuple[int, int]:
        """The target's size in pixels for an output of ``out_w`` x ``out_h``."""
        return self.size.resolve(out_w, out_h)


@record(frozen=True)
class GLPassCode:
    """GLSL of one pass: ``fragment`` is None for depth/stencil-only passes."""
    vertex: str
    fragment: Optional[str]
    attributes: tuple[str, ...] = ()


@record(frozen=True)
class CLPassCode:
    """OpenCL C of one pass: ``kernel`` the whole program; ``fragment`` the fragment function
    alone (None: no body) with the stage ``inputs`` it reads, whether it may ``discard`` and
    the targets it ``sampled`` (bilinear) — enough to rebuild ``kernel`` with other options.
    ``prelude``: (file name, text) of the prelude ``kernel`` contains, shared by the passes
    of a plan: files and the plain-data spelling hold it once (``included``)."""
    kernel: str
    fragment: Optional[str]
    inputs: tuple[str, ...] = ()
    discard: bool = False
    sampled: tuple[str, ...] = ()
    prelude: tuple[str, str] = ("", "")

    @property
    def included(self) -> str:
        """``kernel`` with its prelude replaced by ``#include "<prelude file>"``."""
        name, text = self.prelude
        at = _find_long(self.kernel, text) if text else -1
        if at < 0:
            return self.kernel
        return self.kernel[:at] + include_line(name) + self.kernel[at + len(text):]


def include_line(prelude_file: str) -> str:
    """The line that stands for a shared prelude in a written CL program."""
    return f'#include "{prelude_file}"\n'


def _find_long(text: str, part: str) -> int:
    """``text.find(part)`` for a long ``part`` near the start of ``text`` (a prelude, tens of
    kB, a few hundred characters into its program): its first 80 characters found, the whole compared
    there.  ``str.find`` preprocesses the whole of a long ``part`` on every call, which cost
    a compile about 6 % of its instructions (callgrind, deferred_calver)."""
    head = part[:80]
    at = text.find(head)
    while at >= 0 and not text.startswith(part, at):
        at = text.find(head, at + 1)
    return at


def cl_preludes(plan: Plan) -> dict[str, str]:
    """{file name: text} of the preludes the plan's CL programs include."""
    return {p.code.prelude[0]: p.code.prelude[1] for p in plan.passes
            if isinstance(p.code, CLPassCode) and p.code.prelude[1]
            and _find_long(p.code.kernel, p.code.prelude[1]) >= 0}


PassCode = Union[GLPassCode, CLPassCode, None]


@record(frozen=True)
class PassPlan:
    name: str
    draw: ir.Draw
    state: ir.PassState
    writes: tuple[str, ...] = ()
    reads: tuple[str, ...] = ()
    depth_target: Optional[str] = None
    clears: tuple[tuple[str, ir.Clear], ...] = ()
    repeat_group: Optional[int] = None
    repeat_types: tuple[str, ...] = ()
    sampled: tuple[str, ...] = ()            # reads filtered bilinearly (``sample()``)
    code: PassCode = None
    # reads of a multisampled target's samples (``load_sample``): the runtimes bind the
    # samples themselves, not the resolve
    sample_reads: tuple[str, ...] = ()

    @property
    def attached(self) -> tuple[str, ...]:
        """The targets the pass's framebuffer holds: colour writes, then the depth target."""
        return self.writes + ((self.depth_target,) if self.depth_target else ())

    @property
    def cull_auto(self) -> bool:
        return self.state.cull is ir.CullMode.AUTO


@record(frozen=True)
class Plan:
    technique: str
    title: str
    backend: str
    source: str
    params: Mapping[str, Any]
    lights: LightTablePlan
    output: str
    targets: tuple[TargetPlan, ...]
    passes: tuple[PassPlan, ...]
    light_sets: Mapping[str, int] = field(default_factory=dict)   # channel_slots: slots
    scene: Optional[ir.SceneFacts] = None     # specialised: what every scene must satisfy
    # "f32", or "f64": the float64 evaluation of the technique (CL only; docs/internals.md)
    precision: str = "f32"

    def target(self, name: str) -> TargetPlan:
        for t in self.targets:
            if t.name == name:
                return t
        raise KeyError(name)

    def pass_samples(self, p: PassPlan) -> int:
        """Samples per pixel of a pass's attachments."""
        return max([self.target(n).samples for n in p.attached] or [1])

    def to_dict(self) -> dict:
        return plan_to_dict(self)


# ---- built from the IR ---------------------------------------------------------------------


def technique_plan(tech: ir.Technique, backend: str,
                   codes: Optional[list[PassCode]] = None,
                   sampled: Optional[list[tuple[str, ...]]] = None) -> Plan:
    """The plan of ``tech`` for ``backend``, with each pass's code and sampled reads."""
    codes = codes or [None] * len(tech.passes)
    sampled = sampled or [()] * len(tech.passes)
    return Plan(
        technique=tech.name, title=tech.title, backend=backend, source=tech.source,
        params={p.name: p.default for p in tech.params},
        lights=LightTablePlan(tech.lights.capacity,
                              tuple((f.name, str(f.type)) for f in tech.lights.fields),
                              tuple((f.name, str(f.type), f.default)
                                    for f in (tech.materials.fields if tech.materials else ()))),
        output=tech.output,
        targets=tuple(target_plan(t) for t in tech.targets),
        passes=tuple(pass_plan(p, code, s, _sample_reads(tech, p))
                     for p, code, s in zip(tech.passes, codes, sampled)),
        light_sets={p.name: int(dict(p.options).get("slots", 4))
                    for p in tech.packings if p.scheme == "channel_slots"},
        scene=tech.scene)


def target_plan(t: ir.Target) -> TargetPlan:
    clear = t.clear
    if t.format.is_color and clear.color is None:   # "a target without clear is cleared to 0"
        clear = replace(clear, color=(0, 0, 0, 0))
    return TargetPlan(t.name, t.format, t.size, t.samples, clear)


def _sample_reads(tech: ir.Technique, p: ir.Pass) -> tuple[str, ...]:
    per_sample = sample_read_targets(p.body, pass_functions(tech, p.body))
    return tuple(r for r in p.reads if r in per_sample)


def pass_plan(p: ir.Pass, code: PassCode = None, sampled: tuple[str, ...] = (),
              sample_reads: tuple[str, ...] = ()) -> PassPlan:
    # the plan keeps blend state for the written targets only, in write order
    state = replace(p.state, blend=tuple((t, p.state.blend_for(t)) for t in p.writes))
    return PassPlan(p.name, p.draw, state, tuple(p.writes), tuple(p.reads), p.depth_target,
                    tuple(p.clears), p.repeat_group, tuple(p.repeat_types), tuple(sampled), code,
                    tuple(sample_reads))


# ---- the plain-data spelling ---------------------------------------------------------------


def plan_to_dict(plan: Plan) -> dict:
    """The plan as plain data (docs/internals.md, "Compiled plan"): IR enums as their
    ``.value`` strings, formats by name, containers as lists."""
    out = {
        "technique": plan.technique, "title": plan.title, "backend": plan.backend,
        "source": plan.source, "params": dict(plan.params),
        "lights": {"capacity": plan.lights.capacity,
                   "fields": [list(f) for f in plan.lights.fields],
                   **({"materials": [[n, t, list(d)] for n, t, d in plan.lights.materials]}
                      if plan.lights.materials else {})},
        "output": plan.output,
        "targets": [_target_to_dict(t) for t in plan.targets],
        "passes": [_pass_to_dict(p) for p in plan.passes],
        "light_sets": dict(plan.light_sets),
    }
    preludes = cl_preludes(plan)
    if preludes:         # the CL programs' shared preludes, once (``CLPassCode.included``)
        out["cl_preludes"] = preludes
    if plan.scene is not None:
        f = plan.scene
        out["scene"] = {"light_types": list(f.light_types), "lights": f.lights,
                        "translucent": f.translucent, "opaque": f.opaque,
                        **({} if f.shadows else {"shadows": False})}
    if plan.precision != "f32":
        out["precision"] = plan.precision
    return out


def _clear_to_dict(c: ir.Clear) -> dict:
    return {"clear_color": None if c.color is None else list(c.color),
            "clear_depth": c.depth, "clear_stencil": c.stencil}


def _target_to_dict(t: TargetPlan) -> dict:
    return {"name": t.name, "format": t.format.name, "scale": t.size.scale,
            "width": t.size.width, "height": t.size.height, "samples": t.samples,
            **_clear_to_dict(t.clear)}


def _pass_to_dict(p: PassPlan) -> dict:
    d = p.draw
    out = {
        "name": p.name,
        "draw": {"kind": d.kind.value, "material": list(d.material),
                 "volume": None if d.volume is None else d.volume.value,
                 "light_types": list(d.light_types),
                 "light_set": None if d.light_set is None else list(d.light_set),
                 "scissor": d.scissor,
                 # only when not the default, so plans of scene-order draws keep their text
                 **({"order": d.order.value} if d.order is not ir.DrawOrder.SCENE else {}),
                 **({"shadow_tiles": d.shadow_tiles} if d.shadow else {}),
                 **({"shadow_first": d.shadow_first} if d.shadow_first else {}),
                 **({"shadow_volumes": True} if d.shadow_volumes else {}),
                 **({"within": True} if d.within else {})},
        "repeat_group": p.repeat_group,
        "repeat_types": list(p.repeat_types),
        "clears": [{"target": name, **_clear_to_dict(c)} for name, c in p.clears],
        "writes": list(p.writes),
        "reads": list(p.reads),
        "depth_target": p.depth_target,
        "state": state_to_dict(p.state, p.writes),
    }
    if p.sample_reads:      # only when there are any (the other plans keep their text)
        out["sample_reads"] = list(p.sample_reads)
    if isinstance(p.code, GLPassCode):
        out.update(vertex=p.code.vertex, fragment=p.code.fragment, sampled=list(p.sampled),
                   attributes=list(p.code.attributes))
    elif isinstance(p.code, CLPassCode):
        out["cl"] = {"fragment": p.code.fragment, "inputs": list(p.code.inputs),
                     "discard": p.code.discard, "sampled": list(p.code.sampled)}
        out["sampled"] = list(p.sampled)
        out["kernel"] = p.code.included
    return out


def _face_to_dict(f: ir.StencilFace) -> dict:
    return {"func": f.func.value, "ref": f.ref, "read_mask": f.read_mask,
            "write_mask": f.write_mask, "fail": f.fail.value, "zfail": f.zfail.value,
            "zpass": f.zpass.value}


def _eq_to_list(e: ir.BlendEquation) -> list:
    return [e.op.value, e.src.value, e.dst.value]


def state_to_dict(s: ir.PassState, writes: tuple[str, ...]) -> dict:
    blend = {}
    for t in writes:
        b = s.blend_for(t)
        blend[t] = {"enabled": b.enabled, "rgb": _eq_to_list(b.rgb),
                    "alpha": _eq_to_list(b.alpha), "write_mask": list(b.write_mask)}
    depth = {"func": s.depth.func.value, "write": s.depth.write, "clamp": s.depth.clamp}
    if s.depth.inside is not None:      # `cull auto` passes: the back-face lights' test
        depth["inside"] = s.depth.inside.value
    return {
        "depth": depth,
        "stencil": {"front": _face_to_dict(s.stencil.front),
                    "back": _face_to_dict(s.stencil.back)},
        "blend": blend,
        "blend_constant": list(s.blend_constant),
        "cull": s.cull.value,
        "polygon_offset": None if s.polygon_offset is None else
        [s.polygon_offset.factor, s.polygon_offset.units],
    }


def plan_from_dict(d: Union[Mapping, Plan]) -> Plan:
    """A ``Plan`` from its plain-data spelling; missing keys take their defaults (a plan
    written by hand may leave out whatever it does not use).  A ``Plan`` is returned as is."""
    if isinstance(d, Plan):
        return d
    lights = d.get("lights") or {}
    return Plan(
        technique=d.get("technique", ""), title=d.get("title", ""),
        backend=d.get("backend") or "", source=d.get("source") or "",
        params=dict(d.get("params") or {}),
        lights=LightTablePlan(int(lights.get("capacity") or 0),
                              tuple((str(n), str(t)) for n, t in lights.get("fields") or []),
                              tuple((str(n), str(t), tuple(float(x) for x in v))
                                    for n, t, v in lights.get("materials") or [])),
        output=d.get("output", ""),
        targets=tuple(_target_from_dict(t) for t in d.get("targets") or []),
        passes=tuple(_pass_from_dict(p, d.get("cl_preludes") or {})
                     for p in d.get("passes") or []),
        light_sets={k: int(v) for k, v in (d.get("light_sets") or {}).items()},
        scene=_facts_from_dict(d.get("scene")),
        precision=str(d.get("precision") or "f32"))


def _facts_from_dict(f: Optional[Mapping]) -> Optional[ir.SceneFacts]:
    if f is None:
        return None
    return ir.SceneFacts(tuple(f.get("light_types") or ()), int(f.get("lights") or 0),
                         bool(f.get("translucent")), bool(f.get("opaque", True)),
                         bool(f.get("shadows", True)))


def _clear_from_dict(c: Mapping) -> ir.Clear:
    color = c.get("clear_color")
    return ir.Clear(None if color is None else tuple(color), c.get("clear_depth"),
                    c.get("clear_stencil"))


def _target_from_dict(t: Mapping) -> TargetPlan:
    size = ir.Size(float(t.get("scale") or 1.0), int(t.get("width") or 0),
                   int(t.get("height") or 0))
    return TargetPlan(t["name"], F.get(t["format"]), size,
                      max(1, int(t.get("samples") or 1)), _clear_from_dict(t))


def draw_from_dict(d: Optional[Mapping]) -> ir.Draw:
    d = d or {"kind": "fullscreen"}
    light_set = d.get("light_set")
    return ir.Draw(ir.DrawKind(d.get("kind", "fullscreen")), tuple(d.get("material") or ()),
                   None if d.get("volume") is None else ir.Volume(d["volume"]),
                   tuple(d.get("light_types") or ()),
                   None if not light_set else (str(light_set[0]), int(light_set[1])),
                   bool(d.get("scissor")), ir.DrawOrder(d.get("order") or "scene"),
                   int(d.get("shadow_tiles") or 0), int(d.get("shadow_first") or 0),
                   bool(d.get("shadow_volumes")), bool(d.get("within")))


def _pass_from_dict(p: Mapping, preludes: Mapping[str, str]) -> PassPlan:
    writes = tuple(p.get("writes") or ())
    code: PassCode = None
    if "kernel" in p or "cl" in p:
        cl = p.get("cl") or {}
        kernel, prelude = p.get("kernel") or "", ("", "")
        for name, text in preludes.items():      # the include line ``included`` wrote
            line = include_line(name)
            if line in kernel:
                kernel, prelude = kernel.replace(line, text, 1), (name, text)
                break
        code = CLPassCode(kernel, cl.get("fragment"), tuple(cl.get("inputs") or ()),
                          bool(cl.get("discard")), tuple(cl.get("sampled") or ()), prelude)
    elif "vertex" in p:
        code = GLPassCode(p["vertex"], p.get("fragment") or None,
                          tuple(p.get("attributes") or ()))
    return PassPlan(
        name=p["name"], draw=draw_from_dict(p.get("draw")),
        state=state_from_dict(p.get("state") or {}, writes), writes=writes,
        reads=tuple(p.get("reads") or ()), depth_target=p.get("depth_target"),
        clears=tuple((c["target"], _clear_from_dict(c)) for c in p.get("clears") or []),
        repeat_group=p.get("repeat_group"), repeat_types=tuple(p.get("repeat_types") or ()),
        sampled=tuple(p.get("sampled") or ()), code=code,
        sample_reads=tuple(p.get("sample_reads") or ()))


def _face_from_dict(f: Mapping) -> ir.StencilFace:
    base = ir.StencilFace()
    return ir.StencilFace(
        ir.CompareFunc(f.get("func", base.func.value)), int(f.get("ref", base.ref)),
        int(f.get("read_mask", base.read_mask)), int(f.get("write_mask", base.write_mask)),
        ir.StencilOp(f.get("fail", "keep")), ir.StencilOp(f.get("zfail", "keep")),
        ir.StencilOp(f.get("zpass", "keep")))


def _eq_from_list(e) -> ir.BlendEquation:
    if not e:
        return ir.BlendEquation()
    if len(e) == 1:                   # min / max take no factors
        return ir.BlendEquation(ir.BlendOp(e[0]), ir.BlendFactor.ONE, ir.BlendFactor.ONE)
    return ir.BlendEquation(ir.BlendOp(e[0]), ir.BlendFactor(e[1]), ir.BlendFactor(e[2]))


def state_from_dict(s: Mapping, writes: tuple[str, ...] = ()) -> ir.PassState:
    """An ``ir.PassState`` from the plain-data state (missing keys: the IR defaults, which are
    GL's: depth and stencil tests off, blending off, no culling)."""
    depth = s.get("depth") or {}
    inside = depth.get("inside")
    stencil = s.get("stencil") or {}
    blend = s.get("blend") or {}
    names = list(writes) + [n for n in blend if n not in writes]
    targets = []
    for name in names:
        b = blend.get(name)
        if b is None:
            continue
        targets.append((name, ir.TargetBlend(
            bool(b.get("enabled")), _eq_from_list(b.get("rgb")), _eq_from_list(b.get("alpha")),
            tuple(bool(m) for m in b.get("write_mask", (True,) * 4)))))
    offset = s.get("polygon_offset")
    return ir.PassState(
        depth=ir.DepthState(ir.CompareFunc(depth.get("func", "always")),
                            bool(depth.get("write", False)), bool(depth.get("clamp", False)),
                            None if inside is None else ir.CompareFunc(inside)),
        stencil=ir.StencilState(_face_from_dict(stencil.get("front") or {}),
                                _face_from_dict(stencil.get("back") or {})),
        blend=tuple(targets),
        blend_constant=tuple(float(c) for c in s.get("blend_constant") or (0.0,) * 4),
        cull=ir.CullMode(s.get("cull") or "none"),
        polygon_offset=None if offset is None else ir.PolygonOffset(float(offset[0]),
                                                                    float(offset[1])))
