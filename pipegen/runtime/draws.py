"""Host-side draw preparation, decided once for both runtimes: which passes run for which light
(``schedule``), which lights a light draw instances (``LightSelection``), which faces each light
volume draws under ``cull auto`` (``light_runs``), a light's scissor rectangle, and the object
order of a scene draw (``scene_order``, ``scene_geometry``: ``back_to_front`` sorts farthest
first).

GL and CL execute the same decisions, so they draw the same triangles in the same order.  The
float64 reference (``reference/``) decides nothing here and imports none of it.

Light volumes under ``cull auto`` draw their front faces (covering each pixel once, with the
pass's depth test) unless the near plane may cut the mesh; then their back faces, with the
pass's ``inside`` depth test when it has one (Calver's infinite far plane).
"""

from __future__ import annotations

import functools

from dataclasses import dataclass, field
from typing import Iterator, Optional, Sequence

import numpy as np

from pipegen.ir import nodes as ir
from pipegen.backends.plan import REACH_WORDS, PassPlan, Plan

LIGHT_TYPE_CODES = {0: "point", 1: "spot", 2: "directional"}


def light_type(light) -> str:
    """A scene light's type name (``point``, ``spot``, ``directional``; ints as the light
    table codes them)."""
    t = getattr(light, "type", "point")
    if isinstance(t, (int, np.integer)):
        return LIGHT_TYPE_CODES.get(int(t), str(t))
    return str(t)


def light_filter(draw: ir.Draw) -> bool:
    """Whether a light draw instances only some lights (a type filter or a light set)."""
    return bool(draw.light_types or draw.light_set)


@dataclass
class LightSelection:
    """The lights each light draw of a plan instances for one scene, in table order: all of
    them, those of the draw's ``light_types``, and/or those of its CPU-sorted ``light_set``
    ``(pack, k)`` (``light_index.sort_lights_into_slots`` into ``plan.light_sets[pack]`` slots).

    The sorted sets are computed once per scene and pack; ``dropped[pack]`` lists the lights
    no set could take (more overlapping lights than the packing holds)."""

    plan: Plan
    lights: Sequence
    sets: dict[str, list[list[int]]] = field(default_factory=dict)
    dropped: dict[str, list[int]] = field(default_factory=dict)
    _of: dict = field(default_factory=dict, repr=False)
    _schedule: Optional[list] = field(default=None, repr=False)

    def schedule(self) -> list[tuple[int, Optional[int]]]:
        """``schedule(plan, self)`` as a list, found once per scene: it depends on the plan
        and the lights only (a frame of ``deferred`` on many_lights runs 165 passes)."""
        if self._schedule is None:
            self._schedule = list(schedule(self.plan, self))
        return self._schedule

    def of(self, draw: ir.Draw) -> list[int]:
        """The lights ``draw`` takes, in table order."""
        return list(self._cached(draw)[0])

    def members(self, draw: ir.Draw) -> frozenset:
        """``of(draw)`` as a set."""
        return self._cached(draw)[1]

    def _cached(self, draw: ir.Draw) -> tuple[tuple[int, ...], frozenset]:
        # once per draw and scene (the list and its set): a repeat group asks for every
        # light (it was O(lights^2)).  Keyed by the draw's identity, the draw kept beside
        # its entry: hashing the draw record (its fields, enums hashed in Python) at each of
        # deferred's 164 light executions a frame cost more than the lookup saved
        hit = self._of.get(id(draw))
        if hit is not None and hit[0] is draw:
            return hit[1]
        idx = tuple(self._select(draw))
        cached = (idx, frozenset(idx))
        self._of[id(draw)] = (draw, cached)
        return cached

    def _select(self, draw: ir.Draw) -> list[int]:
        idx = list(range(len(self.lights)))
        if draw.light_types:
            idx = [i for i in idx if light_type(self.lights[i]) in draw.light_types]
        if draw.light_set:
            pack, k = draw.light_set
            chosen = self._sets(pack)
            keep = set(chosen[k]) if k < len(chosen) else set()
            idx = [i for i in idx if i in keep]
        return idx

    def _sets(self, pack: str) -> list[list[int]]:
        """The CPU-sorted sets of ``pack``, over the lights its draws take: the light types
        of the draws ``in pack[k]`` (a directional light drawn elsewhere takes no place)."""
        if pack not in self.sets:
            from pipegen.packing.light_index import sort_lights_into_slots
            slots = int(self.plan.light_sets.get(pack, 4))
            types = set()
            for p in self.plan.passes:
                if p.draw.light_set and p.draw.light_set[0] == pack:
                    types |= set(p.draw.light_types) or {"*"}
            members = [i for i, l in enumerate(self.lights)
                       if "*" in types or not types or light_type(l) in types]
            centers = [tuple(getattr(self.lights[i], "position", (0.0, 0.0, 0.0)))
                       for i in members]
            radii = [float(getattr(self.lights[i], "radius", 0.0)) for i in members]
            sets, dropped = sort_lights_into_slots(centers, radii, slots)
            self.sets[pack] = [[members[int(j)] for j in s] for s in sets]
            self.dropped[pack] = [members[int(j)] for j in dropped]
        return self.sets[pack]

    def instance(self, p: PassPlan, light: Optional[int]) -> list[int]:
        """The lights one execution of light pass ``p`` draws: inside a repeat group only
        ``light`` (none when the draw's filter excludes it), else the draw's whole list."""
        if light is None:
            return self.of(p.draw)
        if light_filter(p.draw) and light not in self.members(p.draw):
            return []
        return [light]


def schedule(plan: Plan, selection: LightSelection) -> Iterator[tuple[int, Optional[int]]]:
    """The pass executions of a frame, in order: ``(pass index, None)`` for a plain pass;
    consecutive passes with the same ``repeat_group`` run as a group once per light in turn
    (``(pass index, light)``), skipping a pass whose light filter or ``repeat_types``
    excludes the light."""
    passes = plan.passes
    k = 0
    while k < len(passes):
        group = passes[k].repeat_group
        if passes[k].draw.shadow:            # once per atlas tile (a point light has six)
            for tile in shadow_casters(passes[k].draw, selection.lights):
                yield k, tile
            k += 1
            continue
        if group is None:
            yield k, None
            k += 1
            continue
        end = k
        while end < len(passes) and passes[end].repeat_group == group:
            end += 1
        lists = {j: selection.members(passes[j].draw) for j in range(k, end)
                 if passes[j].draw.kind is ir.DrawKind.LIGHTS and light_filter(passes[j].draw)}
        for light in range(len(selection.lights)):
            for j in range(k, end):
                if j in lists and light not in lists[j]:
                    continue
                types = passes[j].repeat_types
                if types and light_type(selection.lights[light]) not in types:
                    continue
                yield j, light
        k = end


# ---- scene draws: object order -----------------------------------------------------------------


def scene_order(objects: Sequence, order: ir.DrawOrder, view) -> list[int]:
    """The order a scene draw submits ``objects`` in (indices into ``objects``): scene order,
    or for ``back_to_front`` farthest first by the view depth of each object's bounding-box
    centre (``-(view @ centre).z`` in float64, the camera looking down -z); equal depths keep
    scene order (a stable sort)."""
    if order is not ir.DrawOrder.BACK_TO_FRONT or len(objects) < 2:
        return list(range(len(objects)))
    view = np.asarray(view, dtype=np.float64)
    depth = []
    for o in objects:
        pos = np.asarray(o.positions, dtype=np.float64)
        centre = 0.5 * (pos.min(axis=0) + pos.max(axis=0)) if len(pos) else np.zeros(3)
        depth.append(-(view[2, :3] @ centre + view[2, 3]))
    return sorted(range(len(objects)), key=lambda i: -depth[i])


def scene_geometry(scene, draw: ir.Draw, light: Optional[int] = None):
    """The triangles a scene draw submits, in its object order (``scene_order``): what both
    runtimes upload for the draw, so that GL and CL blend the objects in the same order.  A
    ``shadow_volumes`` draw submits light ``light``'s volumes (``volume_geometry``)."""
    if draw.shadow_volumes:
        return volume_geometry(scene, draw, light)
    if draw.order is not ir.DrawOrder.BACK_TO_FRONT:
        return scene.geometry(draw.material)
    import dataclasses
    objects = list(scene.select(draw.material))
    order = scene_order(objects, draw.order, scene.camera.view_matrix())
    return dataclasses.replace(scene, objects=tuple(objects[i] for i in order)).geometry(
        draw.material)


def scene_key(draw: ir.Draw, light: Optional[int] = None) -> tuple:
    """What a scene draw's uploaded geometry depends on (for the runtimes' caches): a
    ``shadow_volumes`` draw's, on the light too."""
    if draw.shadow_volumes:
        return (draw.material, draw.order, "shadow_volumes", light)
    return (draw.material, draw.order)


# how much farther than its radius a light is taken to reach: the fragment's float32 world
# position and distance, and the interpolation, err by ~1e-6 of the coordinates; an object
# left out must lie beyond where ``clamp(1 - d*d / (r*r), 0, 1)`` can round to above 0
REACH_SLACK = 1e-3


def reach_table(scene, draw: ir.Draw) -> np.ndarray:
    """``draw scene… within light radius``: per scene light, the object ids its draw submits,
    (lights, ``REACH_WORDS``) uint32 words of bits (bit i of word w: id 32 w + i).

    An id is reached where the axis-aligned box around the world positions of the draw's
    objects with that id comes within the light's radius of its position, with a margin
    (``REACH_SLACK`` of the radius and of the coordinates' size); directional lights reach
    every id.  Both runtimes read the same table: GL submits the reached objects' runs
    (``reached_runs``), CL's raster kernel skips a light for a triangle whose id it does not
    reach (cl_pass.cl.j2's ``pg_reaches``), so they draw the same fragments."""
    lo = np.full((256, 3), np.inf)
    hi = np.full((256, 3), -np.inf)
    for o in scene.select(draw.material):
        if len(o.positions):
            lo[o.id] = np.minimum(lo[o.id], o.positions.min(axis=0))
            hi[o.id] = np.maximum(hi[o.id], o.positions.max(axis=0))
    used = np.flatnonzero(np.isfinite(lo[:, 0]))
    table = np.zeros((len(scene.lights), REACH_WORDS), np.uint32)
    if not len(used):
        return table
    lo, hi = lo[used], hi[used]
    size = np.maximum(np.abs(lo), np.abs(hi)).max(axis=1)
    bits = np.zeros((len(scene.lights), 256), bool)
    for i, light in enumerate(scene.lights):
        if light_type(light) == "directional":
            bits[i, used] = True
            continue
        p = np.asarray(light.position, np.float64)
        gap = np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)
        r = float(light.radius)
        bits[i, used] = gap <= r + REACH_SLACK * (r + size + float(np.abs(p).max()))
    for w in range(REACH_WORDS):
        table[:, w] = np.packbits(bits[:, 32 * w:32 * w + 32], axis=1,
                                  bitorder="little").view("<u4")[:, 0]
    return table


def triangle_ids(geometry) -> np.ndarray:
    """Per triangle of a scene draw's geometry (``scene_geometry``), (object id, normal group)
    as both runtimes' shaders read them: the provoking (last) vertex's ``uvec2(a_ids + 0.5)``."""
    return np.floor(np.asarray(geometry.ids, np.float32)[2::3].astype(np.float64)
                    + 0.5).astype(np.uint32)


def reaches(table: np.ndarray, light: int, ids: np.ndarray) -> np.ndarray:
    """Whether light ``light`` of a ``reach_table`` reaches each object id of ``ids``."""
    ids = np.asarray(ids, np.int64)
    return ((table[int(light), ids >> 5] >> (ids & 31).astype(np.uint32)) & 1).astype(bool)


def reached_runs(table: np.ndarray, light: int, tri_ids: np.ndarray) -> list[tuple[int, int]]:
    """(first vertex, vertex count) of each run of consecutive triangles of a scene draw (object
    id ``tri_ids`` per triangle, submission order) that light ``light`` reaches: the draw calls
    that submit only them, in order."""
    keep = reaches(table, light, tri_ids)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.view(np.int8), [0]])))
    return [(3 * int(a), 3 * int(b - a)) for a, b in zip(edges[0::2], edges[1::2])]


def volume_geometry(scene, draw: ir.Draw, light: int):
    """A ``shadow_volumes`` draw for scene light ``light``: the float32 triangles of
    ``shadow_volumes.shadow_volume`` as a scene ``Geometry`` (positions only; the other
    attributes zero: the pass has no fragment code to read them), the same for both runtimes."""
    from pipegen.scene.model import Geometry
    from pipegen.scene.shadow_volumes import shadow_volume
    pos = shadow_volume(scene, scene.lights[int(light)], draw.material).positions
    zero = np.zeros_like(pos)
    return Geometry(pos, zero, zero, zero, np.zeros((len(pos), 2), np.float32),
                    np.zeros(len(pos), np.float32))


# ---- shadow maps -------------------------------------------------------------------------------


def shadow_casters(draw: ir.Draw, lights: Sequence) -> list[int]:
    """The atlas tiles a shadow-map draw (``draw scene… from lights TYPES tiles N``) draws, in
    order: those of the shadow-casting lights of its types (``shadows.first_tiles``: one per
    spot or directional light, six per point light) that fit the ``N x N`` atlas
    (``common.check_shadow_capacity`` refuses a scene needing more).  The schedule runs the
    pass once per tile, with the tile in place of a light."""
    from pipegen.scene.shadows import first_tiles, tile_count
    cap = draw.shadow_tiles * draw.shadow_tiles
    return [k + f for i, k in first_tiles(lights).items()
            if light_type(lights[i]) in draw.light_types
            for f in range(tile_count(lights[i])) if k + f < cap]


def shadow_view(scene, tile: int, draw: ir.Draw, width: int, height: int):
    """A shadow-map draw of atlas tile ``tile``: (its rectangle (x, y, w, h) in the depth
    target of ``width x height``, view, projection) -- the float64 matrices of
    ``shadows.light_view_proj`` for the tile's light (a point light's face), which the
    runtimes upload as float32 like a camera's."""
    from pipegen.scene import shadows as S
    light, face = S.tile_owner(scene.lights, tile)
    view, proj = S.light_view_proj(scene, scene.lights[light], face=face)
    return S.tile_rect(tile, draw.shadow_tiles, width, height), view, proj


# ---- cull auto ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class LightRun:
    """Consecutive lights of a light draw that share a face choice, in submission order."""
    cull: ir.CullMode             # the faces culled for these lights (never AUTO)
    lights: tuple[int, ...]

    @property
    def inside(self) -> bool:
        """Drawn with their back faces under ``cull auto``: the ``inside`` depth test."""
        return self.cull is ir.CullMode.FRONT


def light_runs(cull: ir.CullMode, volume: Optional[ir.Volume], lights: Sequence,
               indices: Sequence[int], eye, proj) -> list[LightRun]:
    """Split a light draw of ``indices`` (scene ``lights``) into runs of one cull mode each:
    one run for a fixed mode; under ``cull auto`` each light asks ``volume_cull``."""
    indices = tuple(int(i) for i in indices)
    if not indices:
        return []
    if cull is not ir.CullMode.AUTO:
        return [LightRun(cull, indices)]
    shape = (volume or ir.Volume.SPHERE).value
    reach = near_plane_reach(proj)
    if shape == "sphere":       # every light's choice at once
        inside = _spheres_inside([lights[i] for i in indices], eye, reach)
        modes = [ir.CullMode.FRONT if k else ir.CullMode.BACK for k in inside.tolist()]
    else:
        modes = [volume_cull(shape, lights[i], eye, reach) for i in indices]
    runs: list[LightRun] = []
    for i, mode in zip(indices, modes):
        if runs and runs[-1].cull is mode:
            runs[-1] = LightRun(mode, runs[-1].lights + (i,))
        else:
            runs.append(LightRun(mode, (i,)))
    return runs


def auto_inside(volume: Optional[ir.Volume], lights: Sequence, indices: Sequence[int], eye,
                proj) -> dict[int, bool]:
    """``cull auto``'s choice for each light of ``indices``: whether it is drawn with its back
    faces (``LightRun.inside``).  Each light's choice is its own (``light_runs`` only groups
    equal neighbours), so a runtime may decide a draw's lights at once and look one up."""
    return {i: run.inside for run in light_runs(ir.CullMode.AUTO, volume, lights, indices,
                                                 eye, proj) for i in run.lights}


def near_plane_reach(proj) -> float:
    """Distance from the eye to the farthest point of the near-plane rectangle of a GL
    perspective projection (``Camera.projection``; an infinite far plane works too):
    ``near * sqrt(1 + tan_x^2 + tan_y^2)`` with ``near = P[2,3] / (P[2,2] - 1)``,
    ``tan_x = 1 / P[0,0]``, ``tan_y = 1 / P[1,1]``.  Every point that the near plane clips
    away in front of a visible pixel lies within this distance of the eye."""
    p = np.asarray(proj, np.float64)
    near = abs(p[2, 3] / (p[2, 2] - 1.0))
    return float(near * np.sqrt(1.0 + (1.0 / p[0, 0]) ** 2 + (1.0 / p[1, 1]) ** 2))


_UNIT_MESHES: dict = {}


def _unit_mesh(volume: str) -> np.ndarray:
    if volume not in _UNIT_MESHES:
        from pipegen.scene.meshes import light_volume
        _UNIT_MESHES[volume] = np.asarray(light_volume(volume), np.float64)
    return _UNIT_MESHES[volume]


@functools.lru_cache(maxsize=None)
def _unit_circumradius() -> float:
    """The unit sphere mesh's farthest vertex from its centre (``volume_bound``; computed once:
    ``cull auto`` asks for it per light and frame)."""
    m = _unit_mesh("sphere")
    return float(np.sqrt((m * m).sum(axis=1)).max())


@functools.lru_cache(maxsize=None)
def _unit_cone_rim() -> float:
    """The unit cone mesh's rim radius (``volume_clearance``), computed once."""
    m = _unit_mesh("cone")
    return float(np.sqrt(m[:, 0] ** 2 + m[:, 1] ** 2).max())


def _cos_clamped(cos_outer: float) -> float:
    """cos(outer) as the vertex stages clamp it before taking tan(outer)."""
    return min(max(float(cos_outer), 0.001), 1.0)


def volume_bound(volume: str, radius: float, cos_outer: float = -2.0) -> float:
    """Radius of a sphere around the light's position that contains its light-volume mesh as
    the vertex stages place it (``meshes.light_volume`` scaled like gl_vertex_lights.glsl.j2):

    - sphere: ``radius * R`` with ``R`` the unit mesh's circumradius (its farthest vertex,
      about 1.02: the mesh circumscribes the unit sphere);
    - cone: the farthest vertex from the apex of the unit cone scaled by ``spread`` in x/y
      (``radius * tan(outer)``) and ``radius`` in z.
    """
    r = max(float(radius), 0.0)
    if volume == "sphere":
        return r * _unit_circumradius()
    m = _unit_mesh(volume)
    if volume == "cone":
        c = _cos_clamped(cos_outer)
        spread = r * np.sqrt(1.0 - c * c) / c
        scaled = m * np.array([spread, spread, r])
        return float(np.sqrt((scaled * scaled).sum(axis=1)).max())
    raise ValueError(f"`cull auto` has no rule for {volume!r} light volumes (sphere, cone)")


# Relative slack on the distances: the GPU places the mesh from float32 light fields.
CULL_SLACK = 1e-3


def volume_clearance(volume: str, position, radius: float, eye, cos_outer: float = -2.0,
                     direction=(0.0, 0.0, -1.0)) -> float:
    """A lower bound on the distance from ``eye`` to a light's volume mesh (<= 0: the eye may
    be inside it), from a shape that contains the mesh:

    - sphere: the ball of radius ``volume_bound`` around the light's position;
    - cone: the circular cone around the light direction (apex at the light, half-angle
      ``atan(rim * tan(outer))`` with ``rim`` the unit mesh's rim radius, since its polygon
      circumscribes the unit circle) cut by its base plane at ``radius`` along the axis: the
      larger of the separating-plane distances to the base, ``h - radius``, and to the
      tangent plane nearest the eye, ``q cos(a) - h sin(a)`` (h, q: the eye's axial and radial
      offsets from the apex), whatever the mesh's rotation about its axis.
    """
    v = np.asarray(eye, np.float64) - np.asarray(position, np.float64)
    r = max(float(radius), 0.0)
    if volume == "sphere":
        return float(_sphere_clearances(np.asarray(position, np.float64)[None], np.array([r]),
                                        eye)[0])
    if volume == "cone":
        d = np.asarray(direction, np.float64)
        n = float(np.linalg.norm(d))
        axis = d / n if n > 0 else np.array([0.0, 0.0, -1.0])
        h = float(v @ axis)
        q = float(np.linalg.norm(v - h * axis))
        rim = _unit_cone_rim()
        c = _cos_clamped(cos_outer)
        half = float(np.arctan(rim * np.sqrt(1.0 - c * c) / c))
        return float(max(q * np.cos(half) - h * np.sin(half), h - r))
    raise ValueError(f"`cull auto` has no rule for {volume!r} light volumes (sphere, cone)")


def volume_cull(volume: str, light, eye, reach: float) -> ir.CullMode:
    """The faces to cull for one light under ``cull auto``: FRONT (draw the back faces) when
    the near plane may touch the mesh, conservatively
    ``clearance <= reach * (1 + CULL_SLACK) + bound * CULL_SLACK``; else BACK."""
    if volume == "sphere":
        inside = bool(_spheres_inside([light], eye, reach)[0])
        return ir.CullMode.FRONT if inside else ir.CullMode.BACK
    cos_outer = float(getattr(light, "cos_outer", -2.0))
    bound = volume_bound(volume, light.radius, cos_outer)
    clearance = volume_clearance(volume, light.position, light.radius, eye, cos_outer,
                                 getattr(light, "direction", (0.0, 0.0, -1.0)))
    inside = clearance <= reach * (1.0 + CULL_SLACK) + bound * CULL_SLACK
    return ir.CullMode.FRONT if inside else ir.CullMode.BACK


def _spheres_inside(lights: Sequence, eye, reach: float) -> np.ndarray:
    """``volume_cull``'s test for sphere volumes, of many lights at once: the distance from
    ``eye`` to each light minus its ``volume_bound`` against the near plane's reach."""
    pos = np.array([np.asarray(l.position, np.float64) for l in lights]).reshape(-1, 3)
    radius = np.array([float(l.radius) for l in lights], np.float64)
    bound = np.maximum(radius, 0.0) * _unit_circumradius()
    clearance = _sphere_clearances(pos, radius, eye)
    return clearance <= reach * (1.0 + CULL_SLACK) + bound * CULL_SLACK


def _sphere_clearances(pos: np.ndarray, radius: np.ndarray, eye) -> np.ndarray:
    """``volume_clearance`` of sphere volumes, (N, 3) positions at once: the distance from
    ``eye`` to each light less its ``volume_bound``."""
    v = np.asarray(eye, np.float64) - pos
    bound = np.maximum(radius, 0.0) * _unit_circumradius()
    return np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2]) - bound


# ---- scissor -----------------------------------------------------------------------------------


def scissor_rect(light, view, proj, width: int, height: int) -> tuple[int, int, int, int]:
    """Window rectangle ``(x, y, w, h)`` (GL convention, y up) covering a light's sphere.

    Projects the 8 corners of the sphere's world-space bounding box; when any corner is at or
    behind the camera plane (w <= 1e-6) the rectangle is the whole viewport.  The rectangle is
    conservative (floor/ceil, clamped to the viewport) and may be empty (w or h 0).  A light
    without a radius (``radius <= 0``: a directional light) covers the whole viewport.
    (``scissor_rects`` of the one light: both runtimes get the same rectangles.)
    """
    return tuple(int(v) for v in scissor_rects([light], view, proj, width, height)[0])


_BOX_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                      np.float64)


def scissor_rects(lights: Sequence, view, proj, width: int, height: int) -> np.ndarray:
    """``scissor_rect`` of every light at once: (N, 4) int64 rows ``x, y, w, h``.  The corners
    go through ``proj @ view`` as four products summed left to right (elementwise float64,
    the same for one light as for many)."""
    W, H = int(width), int(height)
    out = np.tile(np.array([0, 0, W, H], np.int64), (len(lights), 1))
    if not len(lights):
        return out
    c = np.array([np.asarray(l.position, np.float64) for l in lights]).reshape(-1, 3)
    r = np.array([float(l.radius) for l in lights], np.float64)
    m = np.asarray(proj, np.float64) @ np.asarray(view, np.float64)
    corner = c[:, None, :] + _BOX_SIGNS[None] * r[:, None, None]          # (N, 8, 3)
    x, y, z = corner[..., 0], corner[..., 1], corner[..., 2]
    clip = [x * m[j, 0] + y * m[j, 1] + z * m[j, 2] + m[j, 3] for j in (0, 1, 3)]
    w = clip[2]
    whole = (r <= 0.0) | np.any(w <= 1e-6, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        nx, ny = clip[0] / w, clip[1] / w
    size = np.array([W, H], np.float64)
    lo = (np.stack([nx.min(axis=1), ny.min(axis=1)], axis=1) * 0.5 + 0.5) * size
    hi = (np.stack([nx.max(axis=1), ny.max(axis=1)], axis=1) * 0.5 + 0.5) * size
    a = np.minimum(np.maximum(np.floor(lo), 0), size)
    b = np.minimum(np.maximum(np.ceil(hi), 0), size)
    keep = ~whole
    rect = np.concatenate([a, np.maximum(b - a, 0)], axis=1)
    out[keep] = rect[keep].astype(np.int64)
    return out


