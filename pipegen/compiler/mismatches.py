"""Where a technique and a scene disagree: ``mismatches(tech, scene)`` says what the
technique will not render of the scene, in words ("2 spot lights are lit as point lights
..."); ``run``, ``check`` and the API report them, ``--strict`` makes them an error.  A
silently wrong image is the worst bug.

Two of its questions look at the scene's visible surface in float64 (``reference/``), so
they are asked only when a technique's capabilities make them matter:

- whether a light-index packing holds the lights at every pixel (``reference.light_bound``:
  a tile bound first, which needs no rasterisation; "lights will be dropped" only when more
  lights than it holds reach a shaded surface point, "may be dropped" when only the
  conservative count of light volumes exceeds it); ``lights_per_pixel_bound(scene)`` is that
  conservative count's maximum;
- ``translucent_missed_lights(scene, lights)``: the lights a back-face light index misses at
  the translucent surfaces they reach;
- ``nearest_texel_misses(scene)``: where a search for the nearest pixel centre of a polygon
  (Trebilco's MSAA technique 3) finds none within one pixel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from pipegen.ir import nodes as ir
from pipegen.scene import shadows as S
from pipegen.scene.features import LIGHT_TYPES, SceneFeatures, scene_features
from pipegen.compiler.capabilities import RENDERED, capabilities


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


def nearest_texel_misses(scene, n: int = 2) -> tuple[int, int]:
    """(pixels, objects): the pixels where an opaque object covers one of n x n sub-pixel
    samples but none of the 3x3 pixel centres around (the nearest-fragment search of
    Trebilco's MSAA technique 3 fails there: "if a polygon is made up of mostly sub-pixel
    fragments, (long thin polygon case) searching for a nearest fragment edge may fail"), and
    how many objects do so.  Object ids rasterised in float64 at the pixel centres and at n x
    n the resolution (a regular grid standing in for the MSAA pattern)."""
    from pipegen.reference.raster import rasterize
    centre = rasterize(scene, ("opaque",)).object_id
    fine = rasterize(scene.with_size(scene.width * n, scene.height * n), ("opaque",)).object_id
    h, w = centre.shape
    pad = np.pad(centre, 1, constant_values=-2)
    around = np.stack([pad[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
                       for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=-1)
    missed = np.zeros((h, w), bool)
    objects: set[int] = set()
    for a in range(n):
        for b in range(n):
            ids = fine[a::n, b::n]
            miss = (ids >= 0) & ~(around == ids[..., None]).any(axis=-1)
            missed |= miss
            objects |= set(np.unique(ids[miss]).tolist())
    return int(missed.sum()), len(objects)


def _packed_lights(scene, types: Optional[set], residue: Optional[tuple[int, int]]) -> list:
    """The scene's lights of ``types`` (None: all) whose index in its table is k modulo n for
    ``residue`` (n, k) (an index bank; None: every index)."""
    return [l for i, l in enumerate(scene.lights) if (types is None or l.type in types)
            and (residue is None or i % residue[0] == residue[1])]


def lights_per_pixel_bound(scene, types: Optional[set] = None, gbuffer=None,
                           faces: str = "back", residue: Optional[tuple[int, int]] = None) -> int:
    """The most lights (of ``types``; None: all) whose volumes a light-index pass may write
    at one pixel: lights whose circumscribing volume has a back face at or behind the visible
    surface (or the sky) along the pixel's ray, directional lights everywhere
    (``reference.lighting.lights_per_pixel``'s conservative count, at the scene's resolution,
    evaluated per pixel only where a tile bound allows more than found so far;
    ``gbuffer``: the scene's rasterisation, when the caller has one).  ``faces="front"``:
    volumes meeting the ray in front of the surface (a pass drawing front faces, ``depth
    lequal``), on sky pixels too when the scene has translucent objects.  ``residue (n, k)``:
    only the lights whose index in the scene's table is k modulo n (an index bank)."""
    from pipegen.reference.light_bound import Surfaces, volume_bound
    lights = _packed_lights(scene, types, residue)
    if not lights:
        return 0
    return volume_bound(scene, lights, Surfaces(scene, gbuffer).full(), faces,
                        faces == "front" and scene.has_translucent)


@dataclass(frozen=True)
class Mismatch:
    kind: str          # "light_type", "translucent", "capacity", "table", "order", "search"
    message: str


def _n(count: int, noun: str) -> str:
    return f"{count} {noun}" + ("" if count == 1 else "s")


def _capacity_message(load, pack: str, scheme: str, capacity: int, types, faces: str,
                      bank: Optional[tuple[int, int]]) -> Optional[str]:
    """What a light-index packing does not hold, worded as surely as the count allows:
    "will be dropped" from lights that reach a shaded surface point, "may be dropped" from
    the conservative count of light volumes (None: it holds them all)."""
    verdict = load.verdict(capacity)
    if verdict == "fits":
        return None
    kinds = "/".join(t for t in LIGHT_TYPES if t in types)
    which = f" with index % {bank[0]} == {bank[1]}" if bank else ""
    holds = f"the packing `{pack}` ({scheme}) holds {capacity}"
    if verdict == "will":
        return (f"{load.reaching} {kinds} lights{which} reach the surface seen at one pixel, "
                f"{holds}: lights will be dropped")
    volumes = (f"up to {load.volumes} {kinds} light volumes{which} lie along a pixel's view "
               f"ray in front of its surface (light-volume front faces)" if faces == "front"
               else f"up to {load.volumes} {kinds} light volumes{which} cover a pixel")
    reach = (f"; at most {load.reaching} of them reach the surface it shows" if load.exact
             else "")
    return f"{holds}: lights may be dropped (a conservative bound: {volumes}{reach})"


def _late_casters_message(scene, late: list[int], cap) -> str:
    """Shadow-casting lights past the light indices a technique's shadow maps take (``first
    K``, Trebilco: "only a limited light index range has shadows"): named, with the remedy."""
    k = cap.shadow_first
    names = ", ".join(f"{i} ({scene.lights[i].type})" for i in late)
    taken = "index 0" if k == 1 else f"indices 0..{k - 1}"
    one = len(late) == 1
    return (f"{_n(len(late), 'light')} {'casts' if one else 'cast'} shadows but "
            f"{'its index lies' if one else 'their indices lie'} past the range this technique "
            f"draws shadows for ({taken}: `first {k}` in {cap.shadow_first_at}): "
            f"light{'' if one else 's'} {names} {'is' if one else 'are'} lit unshadowed; list "
            f"the shadow-casting lights first in the scene, or declare more in `first`")


def mismatches(tech: ir.Technique, scene, features: Optional[SceneFeatures] = None,
               per_pixel: Optional[int] = None) -> list[Mismatch]:
    """What ``tech`` will not render of ``scene`` (empty: it renders everything).
    ``per_pixel``: the most lights that reach the surface at one pixel, given instead of
    counted (they are counted only when the technique has a per-pixel light-index
    capacity, and from the scene's visible surface only when a tile bound exceeds it)."""
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
    rules = {r[0]: r[1:] for r in cap.index_rules}
    surfaces = None
    for pack, scheme, capacity, types in cap.index_packings:
        if not any(f.count(t) for t in types):
            continue
        faces, bank = rules.get(pack, ("back", None))
        from pipegen.reference.light_bound import Load, Surfaces, load as packing_load
        if per_pixel is not None:
            load = Load(None, per_pixel, True)
        else:
            surfaces = surfaces or Surfaces(scene)
            load = packing_load(scene, _packed_lights(scene, types, bank), capacity, surfaces,
                                faces, faces == "front" and scene.has_translucent)
        message = _capacity_message(load, pack, scheme, capacity, types, faces, bank)
        if message:
            out.append(Mismatch("capacity", message))
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
    if cap.index_searches:
        pixels, objects = nearest_texel_misses(scene)
        if pixels:
            readers: dict[str, list] = {}
            for p, t in cap.index_searches:
                readers.setdefault(p, []).append(f"`{t}`")
            where = "; ".join(f"pass {p} reads {', '.join(ts)}" for p, ts in readers.items())
            out.append(Mismatch(
                "search", f"the nearest-fragment search ({where} at a neighbouring texel) "
                f"finds no pixel centre of the polygon within one pixel at about "
                f"{_n(pixels, 'pixel')}, where {_n(objects, 'object')} "
                f"{'covers' if objects == 1 else 'cover'} samples but no pixel centre near "
                f"them (polygons narrower than a pixel): those pixels are lit with the "
                f"lights of the surface behind"))
    if f.translucent_objects >= 2:
        from pipegen.compiler.blend_order import describe, order_dependent_blends
        for p, target, what in order_dependent_blends(tech):
            out.append(Mismatch("order", f"{describe(p, target, what)} "
                                         f"({f.translucent_objects} translucent objects)"))
    for pack, slots, types in cap.slot_packings:
        from pipegen.packing.light_index import sort_lights_into_slots
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
    late = S.casters_from(scene.lights, cap.shadow_first)
    if late:
        out.append(Mismatch("shadows", _late_casters_message(scene, late, cap)))
    drawn = S.casting_below(scene, cap.shadow_first)      # what the runtimes draw
    casting: dict[str, int] = {}
    for light in drawn.lights:
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
    total, tiles = sum(casting.values()), S.tiles_needed(drawn.lights)
    if cap.shadow_capacity and tiles > cap.shadow_capacity:
        out.append(Mismatch("capacity", f"the scene's {_n(total, 'shadow-casting light')} "
                                        f"{'needs' if total == 1 else 'need'} "
                                        f"{tiles} atlas tiles (six per point light), the "
                                        f"shadow atlas holds {cap.shadow_capacity}: the "
                                        f"technique refuses the scene"))
    if tech.lights.fields and f.lights > tech.lights.capacity:
        out.append(Mismatch("table", f"the scene has {f.lights} lights, the light table holds "
                                     f"{tech.lights.capacity}"))
    return out
