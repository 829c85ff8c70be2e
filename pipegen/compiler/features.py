"""What a scene calls for, what a technique renders, and where the two disagree.

- ``scene_features(scene)``: light types and counts, translucent objects and stipple layers,
  specular materials, the ambient term, lights whose volume holds the camera, ids and normal
  groups in use; ``lights_per_pixel_bound(scene)`` (costly: a float64 rasterisation) bounds
  the lights whose volumes a light-index packing must hold at one pixel.
- ``capabilities(tech)``: derived from the IR, not declared: which light types the technique
  draws and evaluates, whether it draws translucent objects, its light-index capacity, the
  faces its light-index passes draw, and the translucent passes reading a back-face index.
- ``mismatches(tech, scene)``: what the technique will not render of this scene, in words
  ("2 spot lights are lit as point lights ..."): ``run``, ``check`` and the API report them,
  ``--strict`` makes them an error.  A silently wrong image is the worst bug.
- ``translucent_missed_lights(scene, lights)`` (costly: a float64 rasterisation): the lights a
  back-face light index misses at the translucent surfaces they reach.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.scene import shadows as S
from pipegen.ir.facts import code_facts, pass_functions

LIGHT_TYPES = ("point", "spot", "directional")
INDEX_SCHEMES = ("bitplanes", "max_pairs")        # packings with a per-pixel light capacity
RENDERED = "rendered"


# ---- the scene ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class SceneFeatures:
    light_counts: tuple[tuple[str, int], ...]    # per light type present, in LIGHT_TYPES order
    translucent_objects: int
    opaque_objects: int
    max_layer: int                               # highest stipple layer used (0: none)
    specular: bool                               # any material with specular > 0
    ambient: bool                                # a non-zero ambient term
    camera_inside: tuple[int, ...]               # lights whose sphere holds the camera
    object_ids: int
    normal_groups: int
    shadow_lights: int = 0                       # lights casting shadows (``shadows = true``)

    @property
    def lights(self) -> int:
        return sum(n for _, n in self.light_counts)

    @property
    def light_types(self) -> tuple[str, ...]:
        return tuple(t for t, _ in self.light_counts)

    def count(self, light_type: str) -> int:
        return dict(self.light_counts).get(light_type, 0)

    def facts(self) -> ir.SceneFacts:
        """The compile-time facts a specialised technique assumes.  The light count is
        rounded up to a power of two so that similar scenes share a variant."""
        return ir.SceneFacts(self.light_types, _pow2(self.lights), self.translucent_objects > 0,
                             self.opaque_objects > 0, self.shadow_lights > 0)

    def describe(self) -> list[str]:
        lights = ", ".join(f"{n} {t}" for t, n in self.light_counts) or "none"
        return [f"lights: {lights}",
                f"objects: {self.opaque_objects} opaque, {self.translucent_objects} translucent"
                + (f" (stipple layers up to {self.max_layer})" if self.max_layer else ""),
                f"specular materials: {'yes' if self.specular else 'no'}; ambient: "
                f"{'yes' if self.ambient else 'no'}",
                f"camera inside the volume of light(s): "
                f"{', '.join(map(str, self.camera_inside)) or 'none'}",
                f"object ids in use: {self.object_ids}; normal groups: {self.normal_groups}"]


def _pow2(n: int) -> int:
    return 1 if n <= 1 else 1 << (int(n) - 1).bit_length()


def scene_features(scene) -> SceneFeatures:
    counts = {t: 0 for t in LIGHT_TYPES}
    for light in scene.lights:
        counts[light.type] = counts.get(light.type, 0) + 1
    eye = np.asarray(scene.camera.position, np.float64)
    inside = tuple(i for i, l in enumerate(scene.lights) if l.radius > 0 and
                   np.linalg.norm(eye - np.asarray(l.position, np.float64)) <= l.radius)
    objects = list(scene.objects)
    groups = {int(g) for o in objects for g in np.unique(o.groups)}
    return SceneFeatures(
        light_counts=tuple((t, n) for t, n in counts.items() if n),
        translucent_objects=sum(o.material.translucent for o in objects),
        opaque_objects=sum(not o.material.translucent for o in objects),
        max_layer=max((o.layer for o in objects), default=0),
        specular=any(o.material.specular > 0 for o in objects),
        ambient=bool(np.any(np.asarray(scene.ambient) > 0)),
        camera_inside=inside,
        object_ids=len({o.id for o in objects}),
        normal_groups=len(groups),
        shadow_lights=len(S.shadow_lights(scene.lights)))


def translucent_missed_lights(scene, lights: list[int]) -> tuple[list[int], int]:
    """Of the scene's lights ``lights`` (point/spot indices), those a light index written by
    light-volume back faces (``cull front``, ``depth gequal`` against the opaque depth) misses
    at a visible translucent surface they reach: the light's sphere holds the translucent
    surface point, but its circumscribing volume (the mesh the light pass draws) has no back
    face at or behind the opaque surface along the pixel's ray (on sky pixels: none at all).
    Returns (the missed lights, sorted; how many translucent objects miss one).  A float64
    rasterisation of the scene's opaque depth and of each translucent object on its own, at
    the scene's resolution."""
    from pipegen.reference.lighting import ray_volume_span, volume_grow
    from pipegen.reference.rounding import as_float32
    from pipegen.reference.raster import rasterize, rasterize_each
    if not lights or not scene.has_translucent:
        return [], 0
    opaque = rasterize(scene, ("opaque",))
    cam = np.asarray(scene.camera.position, dtype=np.float64)
    grow = volume_grow()
    missed: set[int] = set()
    objects = 0
    for _obj, gb in rasterize_each(scene, ("translucent",)):
        visible = gb.coverage & (gb.depth < opaque.depth)
        if not visible.any():
            continue
        T = gb.position[visible]
        ray = T - cam
        u = ray / np.maximum(np.linalg.norm(ray, axis=1), 1e-300)[:, None]
        t_opaque = np.where(opaque.coverage[visible],
                            np.linalg.norm(opaque.position[visible] - cam, axis=1), np.inf)
        hit = False
        for i in lights:
            light = scene.lights[i]
            centre, r = as_float32(light.position), float(as_float32(light.radius))
            d = T - centre
            reaches = np.einsum("ij,ij->i", d, d) < r * r
            if not reaches.any():
                continue
            meets, _, t_far = ray_volume_span(light, cam, u, grow)
            behind = meets & (t_far >= t_opaque)
            if (reaches & ~behind).any():
                missed.add(i)
                hit = True
        objects += hit
    return sorted(missed), objects


def lights_per_pixel_bound(scene, types: Optional[set] = None, gbuffer=None,
                           faces: str = "back", residue: Optional[tuple[int, int]] = None) -> int:
    """The most lights (of ``types``; None: all) whose volumes a light-index pass may write
    at one pixel: lights whose circumscribing volume has a back face at or behind the visible
    surface (or the sky) along the pixel's ray, directional lights everywhere
    (``reference.lighting.lights_per_pixel``, conservative, at the scene's resolution;
    ``gbuffer``: its rasterisation, when the caller has one).  ``faces="front"``: volumes
    meeting the ray in front of the surface (a pass drawing front faces, ``depth lequal``),
    on sky pixels too when the scene has translucent objects.  ``residue (n, k)``: only the
    lights whose index in the scene's table is k modulo n (an index bank)."""
    from pipegen.reference.lighting import lights_per_pixel
    from pipegen.reference.raster import rasterize
    lights = tuple(l for i, l in enumerate(scene.lights) if (types is None or l.type in types)
                   and (residue is None or i % residue[0] == residue[1]))
    if not lights:
        return 0
    counts = lights_per_pixel(gbuffer if gbuffer is not None else rasterize(scene),
                              dataclasses.replace(scene, lights=lights), conservative=True,
                              faces=faces, sky=faces == "front" and scene.has_translucent)
    return int(counts.max()) if counts.size else 0


# ---- the technique -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Capabilities:
    light_types: tuple[tuple[str, str], ...]   # type -> RENDERED or what happens instead
    has_light_table: bool
    translucent: bool                          # draws translucent objects
    index_packings: tuple[tuple[str, str, int, frozenset], ...]   # (pack, scheme, lights
    #                                             per pixel, the light types it holds)
    slot_packings: tuple[tuple[str, int, frozenset], ...]   # channel_slots: (pack, sets, types)
    # per index packing: (pack, the faces its writers draw ("back": cull front, depth gequal;
    # "front": front faces in front of the surface), the index bank (n, k) or None)
    index_rules: tuple[tuple[str, str, Optional[tuple[int, int]]], ...] = ()
    # shadow maps (``draw scene… from lights TYPES tiles N``): the light types drawn into an
    # atlas, and the fewest tiles of any such draw (N^2; 0: the technique draws no shadows)
    shadow_types: frozenset = frozenset()
    shadow_capacity: int = 0
    # passes drawing scene.translucent that read a light-index packing whose writers test
    # depth greater/gequal (light-volume back faces behind the opaque surface): (pass, pack,
    # the point/spot light types those writers draw)
    translucent_back_reads: tuple[tuple[str, str, frozenset], ...] = ()

    def light_type(self, t: str) -> str:
        return dict(self.light_types)[t]


def _volume_fills(volume: Optional[ir.Volume], light_type: str) -> bool:
    """Whether a light volume covers every pixel a light of this type reaches: spheres hold
    points and spots (a spot's cone lies in its sphere), cones spots; quads cover a light's
    screen bounds, the whole screen for a directional light (radius 0)."""
    v = volume or ir.Volume.SPHERE
    if v is ir.Volume.QUAD:
        return True
    if v is ir.Volume.CONE:
        return light_type == "spot"
    return light_type in ("point", "spot")


def _types_match(types: tuple[str, ...], light_type: str) -> bool:
    return not types or light_type in types


def _light_fields_read(tech: ir.Technique, passes) -> set[str]:
    fields: set[str] = set()
    for p in passes:
        functions = pass_functions(tech, p.body)
        for stmts in [p.body] + [f.body for f in functions]:
            fields |= {e.field for e in irwalk.walk_exprs(stmts) if isinstance(e, ir.LightField)}
    return fields


def capabilities(tech: ir.Technique) -> Capabilities:
    has_table = bool(tech.lights.fields)
    volumes = [p for p in tech.passes if p.draw.kind is ir.DrawKind.LIGHTS]
    repeats = [p for p in tech.passes if p.repeat_per_light and p.draw.kind is not
               ir.DrawKind.LIGHTS]
    fields = _light_fields_read(tech, tech.passes)
    out = []
    for t in LIGHT_TYPES:
        if volumes:       # light volumes decide which pixels a light reaches
            covered = any(_types_match(p.draw.light_types, t) and _types_match(p.repeat_types, t)
                          and _volume_fills(p.draw.volume, t) for p in volumes) or any(
                _types_match(p.repeat_types, t) for p in repeats)
        else:             # light-table loops and per-light full passes reach every pixel
            covered = has_table
        if not has_table:
            how = "ignored (the technique has no light table)"
        elif not covered:
            how = ("not drawn (its light volumes do not cover a directional light)"
                   if t == "directional" else f"not drawn (no light draw takes {t} lights)")
        elif t == "spot" and not fields & {"cos_outer", "cos_inner"}:
            how = "lit as point lights (the technique reads no cone angle)"
        elif t == "directional" and not fields & {"direction", "type"}:
            how = "not lit (the technique reads no light direction; radius 0 attenuates them)"
        else:
            how = RENDERED
        out.append((t, how))
    translucent = any(p.draw.kind is ir.DrawKind.SCENE and
                      (not p.draw.material or "translucent" in p.draw.material)
                      for p in tech.passes)
    index = tuple((k.name, k.scheme, int(k.capacity), _packing_types(tech, k))
                  for k in tech.packings if k.scheme in INDEX_SCHEMES and k.capacity)
    slots = tuple((k.name, int(dict(k.options).get("slots", 4)), _packing_types(tech, k))
                  for k in tech.packings if k.scheme == "channel_slots")
    rules = tuple((k.name,) + _packing_rule(tech, k) for k in tech.packings
                  if k.scheme in INDEX_SCHEMES and k.capacity)
    shadow_draws = [p.draw for p in tech.passes if p.draw.shadow]
    shadow_types = frozenset(t for d in shadow_draws for t in d.light_types)
    shadow_capacity = min((d.shadow_tiles ** 2 for d in shadow_draws), default=0)
    return Capabilities(tuple(out), has_table, translucent, index, slots, rules,
                        shadow_types, shadow_capacity, _translucent_back_reads(tech, rules))


_BEHIND_TESTS = (ir.CompareFunc.GREATER, ir.CompareFunc.GEQUAL)


def _translucent_back_reads(tech: ir.Technique, rules) -> tuple:
    """(pass, pack, types) for each pass drawing ``scene.translucent`` that reads a light-index
    packing (its target in ``reads``, or its unpack functions called from the body or the
    functions it reaches) written with back faces: the writers that keep only fragments at or
    behind the opaque surface (``depth … greater|gequal``) and the point/spot types they draw.
    Such an index holds the lights reaching the opaque surface, not those reaching only a
    translucent surface in front of it."""
    faces = {r[0]: r[1] for r in rules}
    out = []
    for p in tech.passes:
        if not (p.draw.kind is ir.DrawKind.SCENE and
                (not p.draw.material or "translucent" in p.draw.material)):
            continue
        calls = _calls(tech, p)
        for k in tech.packings:
            if faces.get(k.name) != "back":
                continue
            if not (dict(k.options).get("target") in p.reads or
                    calls & {f.name for f in k.functions}):
                continue
            behind = [w for w in _writers(tech, k)
                      if w.depth_target and w.state.depth.func in _BEHIND_TESTS]
            types = frozenset(t for w in behind for t in (w.draw.light_types or LIGHT_TYPES)
                              if t != "directional" and _types_match(w.repeat_types, t))
            if types:
                out.append((p.name, k.name, types))
    return tuple(out)


_FRONT_TESTS = (ir.CompareFunc.LESS, ir.CompareFunc.LEQUAL)


def _calls(tech: ir.Technique, p: ir.Pass) -> set[str]:
    """The user and packing functions pass ``p`` calls, directly or through the functions it
    reaches."""
    return set(code_facts(p.body).calls) | {f.name for f in pass_functions(tech, p.body)}


def _writers(tech: ir.Technique, k: ir.Packing) -> list:
    names = {f.name for f in k.functions}
    return [p for p in tech.passes
            if p.draw.kind is ir.DrawKind.LIGHTS and _calls(tech, p) & names]


def _packing_rule(tech: ir.Technique, k: ir.Packing) -> tuple[str, Optional[tuple[int, int]]]:
    """How the light passes writing a light-index packing choose their lights: the faces
    (``"front"`` when every writer draws front faces with a depth-less test: ``cull back`` or
    ``cull auto``, ``depth … less|lequal``; else ``"back"``) and the index bank, when every
    writer begins with ``if (light.index % N != K) discard;`` for one (N, K)."""
    writers = _writers(tech, k)
    front = bool(writers) and all(
        p.state.cull in (ir.CullMode.BACK, ir.CullMode.AUTO) and p.depth_target and
        p.state.depth.func in _FRONT_TESTS for p in writers)
    banks = {_bank(p.body) for p in writers}
    bank = banks.pop() if len(banks) == 1 else None
    return ("front" if front else "back"), bank


def _bank(body) -> Optional[tuple[int, int]]:
    """(N, K) for a body that begins ``if (light.index % N != K) discard;`` (uint constants)."""
    if not body or not isinstance(body[0], ir.If):
        return None
    s = body[0]
    if s.other or len(s.then) != 1 or not isinstance(s.then[0], ir.Discard):
        return None
    c = s.cond
    if not (isinstance(c, ir.Binary) and c.op == "!=" and isinstance(c.right, ir.Const)):
        return None
    m = c.left
    if not (isinstance(m, ir.Binary) and m.op == "%" and isinstance(m.right, ir.Const) and
            isinstance(m.left, ir.LightField) and m.left.field == "index" and
            m.left.index is None):
        return None
    n, r = int(m.right.value), int(c.right.value)
    return (n, r) if 0 <= r < n else None


def _packing_types(tech: ir.Technique, k: ir.Packing) -> frozenset:
    """The light types whose indices a light-index packing holds: those instanced by the
    passes that write through it (call its functions, or draw ``in PACK[k]``)."""
    names = {f.name for f in k.functions}
    types: set[str] = set()
    for p in tech.passes:
        if not (_calls(tech, p) & names or (p.draw.light_set and p.draw.light_set[0] == k.name)):
            continue
        if p.draw.kind is not ir.DrawKind.LIGHTS and not p.repeat_per_light:
            continue        # a reader (the shading pass), not a writer
        chosen = set(p.draw.light_types or LIGHT_TYPES) & set(p.repeat_types or LIGHT_TYPES)
        types |= chosen
    return frozenset(types or LIGHT_TYPES)


# ---- where they disagree -----------------------------------------------------------------------


@dataclass(frozen=True)
class Mismatch:
    kind: str          # "light_type", "translucent", "capacity", "table"
    message: str


def _n(count: int, noun: str) -> str:
    return f"{count} {noun}" + ("" if count == 1 else "s")


def mismatches(tech: ir.Technique, scene, features: Optional[SceneFeatures] = None,
               per_pixel: Optional[int] = None) -> list[Mismatch]:
    """What ``tech`` will not render of ``scene`` (empty: it renders everything).
    ``per_pixel`` overrides the lights-per-pixel bound (computed only when the technique
    has a per-pixel light-index capacity)."""
    f = features or scene_features(scene)
    cap = capabilities(tech)
    out: list[Mismatch] = []
    for t, how in cap.light_types:
        n = f.count(t)
        if n and how != RENDERED:
            verb = "is" if n == 1 else "are"
            out.append(Mismatch("light_type", f"{_n(n, t + ' light')} {verb} {how}"))
    if f.translucent_objects and not cap.translucent:
        n = f.translucent_objects
        out.append(Mismatch("translucent", f"{_n(n, 'translucent object')} "
                                           f"{'is' if n == 1 else 'are'} not drawn "
                                           f"(no pass draws scene.translucent)"))
    gbuffer = None
    rules = {r[0]: r[1:] for r in cap.index_rules}
    for pack, scheme, capacity, types in cap.index_packings:
        if not any(f.count(t) for t in types):
            continue
        if per_pixel is None and gbuffer is None:
            from pipegen.reference.raster import rasterize
            gbuffer = rasterize(scene)
        faces, bank = rules.get(pack, ("back", None))
        bound = (lights_per_pixel_bound(scene, types, gbuffer, faces, bank) if per_pixel is None
                 else per_pixel)
        if bound > capacity:
            kinds = "/".join(t for t in LIGHT_TYPES if t in types)
            which = f" with index % {bank[0]} == {bank[1]}" if bank else ""
            what = (f"up to {bound} {kinds} light volumes{which} lie along a pixel's view ray "
                    f"in front of its surface (light-volume front faces)" if faces == "front"
                    else f"up to {bound} {kinds} lights{which} reach a pixel")
            out.append(Mismatch("capacity", f"{what}, the packing `{pack}` ({scheme}) holds "
                                            f"{capacity}: lights will be dropped"))
    if f.translucent_objects and cap.translucent_back_reads:
        readers: dict[str, list] = {}
        for pass_name, pack, types in cap.translucent_back_reads:
            readers.setdefault(pass_name, []).append((pack, types))
        for pass_name, packs in readers.items():
            lights = sorted({i for pack, types in packs
                             for i, l in enumerate(scene.lights) if l.type in types and
                             (rules.get(pack, ("back", None))[1] is None or
                              i % rules[pack][1][0] == rules[pack][1][1])})
            missed, objects = translucent_missed_lights(scene, lights)
            if missed:
                names = ", ".join(f"`{pack}`" for pack, _ in packs)
                out.append(Mismatch(
                    "translucent", f"{_n(objects, 'translucent object')} "
                    f"{'is' if objects == 1 else 'are'} lit from a light index written by "
                    f"light-volume back faces ({names}, read by pass {pass_name}): "
                    f"{_n(len(missed), 'light')} that reach{'es' if len(missed) == 1 else ''} "
                    f"{'it' if objects == 1 else 'them'} but not the opaque surface behind "
                    f"{'is' if len(missed) == 1 else 'are'} missed (lights "
                    f"{', '.join(map(str, missed))})"))
    for pack, slots, types in cap.slot_packings:
        from pipegen.packing.schemes import sort_lights_into_slots
        members = [i for i, l in enumerate(scene.lights) if l.type in types]
        _, dropped = sort_lights_into_slots([tuple(scene.lights[i].position) for i in members],
                                            [float(scene.lights[i].radius) for i in members],
                                            slots)
        dropped = [members[j] for j in dropped]
        if dropped:
            out.append(Mismatch("capacity", f"{_n(len(dropped), 'light')} overlap more than "
                                            f"the {slots} light sets of `{pack}` hold: "
                                            f"{'it is' if len(dropped) == 1 else 'they are'} "
                                            f"dropped (lights {', '.join(map(str, dropped))})"))
    casting: dict[str, int] = {}
    for light in scene.lights:
        if S.casts_shadows(light):
            casting[light.type] = casting.get(light.type, 0) + 1
    for t in LIGHT_TYPES:
        n = casting.get(t, 0)
        if n and t not in cap.shadow_types:
            why = ("this technique does not render shadows" if not cap.shadow_capacity else
                   f"no shadow-map pass draws from {t} lights")
            out.append(Mismatch("shadows", f"{_n(n, t + ' light')} "
                                           f"{'casts' if n == 1 else 'cast'} shadows that are "
                                           f"not drawn ({why}): lit unshadowed"))
    total = sum(casting.values())
    if cap.shadow_capacity and total > cap.shadow_capacity:
        out.append(Mismatch("capacity", f"the scene has {total} shadow-casting lights, the "
                                        f"shadow atlas holds {cap.shadow_capacity}: the "
                                        f"technique refuses the scene"))
    if tech.lights.fields and f.lights > tech.lights.capacity:
        out.append(Mismatch("table", f"the scene has {f.lights} lights, the light table holds "
                                     f"{tech.lights.capacity}"))
    return out
