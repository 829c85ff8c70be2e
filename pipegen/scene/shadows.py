"""Shadow maps: which lights cast shadows, their projections and their tiles in the atlas.

The one place both runtimes and the float64 reference take these from (so a shadow map drawn by
GL, by OpenCL and by ``reference/shadows.py`` is the same picture of the same frustum):

- ``shadow_lights(lights)``: the indices of the shadow-casting lights (``shadows = true`` in the
  scene), in light-table order; each owns consecutive tiles of the atlas in that order
  (``first_tiles``): one for a spot or directional light, six for a point light (its cube's
  faces +x, -x, +y, -y, +z, -z, Trebilco's "6 consecutive shadow map indexes");
  ``casting_below(scene, K)``: the scene as a technique whose shadow maps take only light
  indices below K sees it (``draw … from lights first K``, Trebilco's "limited light index
  range"): later lights cast none;
- ``light_view_proj(scene, light)``: the light's (view, projection) as float64 4x4 matrices,
  GL conventions (column vectors, clip z in [-w, w], window depth 0 near, 1 far):

  - spot: a look-at from the light's position along its direction and a square perspective
    frustum of full angle ``2 * (outer_deg + SPOT_MARGIN_DEG)``, near ``radius *
    SPOT_NEAR_FRACTION``, far ``radius`` (nothing beyond the radius is lit);
  - point, face f: a 90-degree perspective from the light's position looking along the face's
    axis (``POINT_FACES``: the GL cube-map orientation, axis permutations), widened so that
    ``tan(half-angle) = 1 + POINT_FACE_MARGIN`` (PCF taps near a face's edge read that face's own
    depths: see ``POINT_FACE_MARGIN``), near ``radius * SPOT_NEAR_FRACTION``, far ``radius``;
  - directional: an orthographic box along the light's direction fitted to the bounding box of
    every object of the scene (the box's eight corners in light view space, widened by
    ``ORTHO_MARGIN`` of its extent on each side), so every object both casts and receives;

- ``tile_rect(k, tiles, width, height)``: tile k of an atlas of ``tiles x tiles`` tiles of a
  ``width x height`` depth target: ``(x, y, w, h)`` in texels, column ``k % tiles``, row
  ``k // tiles`` (window coordinates, y up), ``w = width // tiles``, ``h = height // tiles``.

The light table carries what a shader needs to look a shadow up (``Scene.light_table``):
``shadow_tile`` (its first tile, or -1 for a light that casts none) and ``shadow_m0`` ..
``shadow_m3``, the rows of ``projection @ view`` rounded to float32; for a point light (whose six
faces are axis permutations the shader rebuilds) ``shadow_m0 = (t, p22, p23, 0)``, the entries
of its faces' projection, ``shadow_m1 = (position, 1)`` and ``shadow_m3 = 0`` (the mark of a
point light: a projection's last row is never zero).  The runtimes draw each tile with the
float32 roundings of ``view`` and ``projection`` (as they upload a camera).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Optional

import numpy as np

SPOT_MARGIN_DEG = 1.0       # the frustum's half-angle exceeds the outer cone by this
SPOT_MAX_OUTER_DEG = 84.0   # wider spots cannot cast shadows (a frustum near 180 degrees)
SPOT_NEAR_FRACTION = 0.02   # near plane of a spot's frustum, as a fraction of its radius
ORTHO_MARGIN = 0.01         # directional boxes: widened by this fraction of their extent
# Point-light faces: tan(half-angle) = 1 + this (half-angle 46.7 degrees).  A point whose major
# axis picks a face projects inside NDC [-1/(1+m), 1/(1+m)], i.e. at least tile * m / (2 (1+m))
# texels (tile / 34: 3.8 texels in a 128-texel tile) from the tile's edge, which covers the PCF
# taps' reach (<= 2.5 texels for 16 taps, 1.5 for the jittered 4) from tiles of 86 texels up;
# smaller tiles clamp the outer taps to the tile (the face's own depths, never a neighbour's).
POINT_FACE_MARGIN = 0.0625
# The faces of a point light's cube, in tile order: (axis, right s, up u) of the view rotation
# (rows s, u, -axis), GL's cube-map orientation: the shader's shadow_face() mirrors this.
POINT_FACES = (
    ((1, 0, 0), (0, 0, -1), (0, -1, 0)),
    ((-1, 0, 0), (0, 0, 1), (0, -1, 0)),
    ((0, 1, 0), (1, 0, 0), (0, 0, 1)),
    ((0, -1, 0), (1, 0, 0), (0, 0, -1)),
    ((0, 0, 1), (1, 0, 0), (0, -1, 0)),
    ((0, 0, -1), (-1, 0, 0), (0, -1, 0)),
)

SHADOW_FIELDS = ("shadow_tile", "shadow_m0", "shadow_m1", "shadow_m2", "shadow_m3")


def casts_shadows(light) -> bool:
    return bool(getattr(light, "shadows", False))


def shadow_lights(lights) -> list[int]:
    """Indices of the shadow-casting lights, in table order (``first_tiles``: their atlas tiles)."""
    return [i for i, l in enumerate(lights) if casts_shadows(l)]


def casters_from(lights, first: int) -> list[int]:
    """The shadow-casting lights at index ``first`` or later: those a technique whose shadow
    maps take only light indices below ``first`` (``draw … from lights first K``; 0: every
    index) draws unshadowed."""
    return [i for i in shadow_lights(lights) if first and i >= first]


def casting_below(scene, first: int):
    """``scene`` as a technique drawing shadow maps for light indices below ``first`` only sees
    it: the lights from ``first`` on cast none (their ``shadow_tile`` is -1, they take no atlas
    tile); ``scene`` itself when none of them casts (or ``first`` is 0: every index may)."""
    late = set(casters_from(scene.lights, first))
    if not late:
        return scene
    return dataclasses.replace(scene, lights=tuple(
        dataclasses.replace(l, shadows=False) if i in late else l
        for i, l in enumerate(scene.lights)))


def tile_count(light) -> int:
    """Atlas tiles a shadow-casting light takes: six for a point light (a cube), else one."""
    return 6 if light.type == "point" else 1


def first_tiles(lights) -> dict[int, int]:
    """Per shadow-casting light index: its first atlas tile (consecutive, in table order)."""
    out, k = {}, 0
    for i in shadow_lights(lights):
        out[i] = k
        k += tile_count(lights[i])
    return out


def tiles_needed(lights) -> int:
    """Atlas tiles the scene's shadow-casting lights take together."""
    return sum(tile_count(lights[i]) for i in shadow_lights(lights))


def tile_of(lights, index: int) -> int:
    """The (first) atlas tile of light ``index`` (-1: it casts no shadow)."""
    return first_tiles(lights).get(index, -1)


def tile_owner(lights, tile: int) -> tuple[int, int]:
    """(light index, face) of atlas tile ``tile`` (face 0 for a spot or directional light)."""
    for i, k in first_tiles(lights).items():
        if k <= tile < k + tile_count(lights[i]):
            return i, tile - k
    raise ValueError(f"atlas tile {tile} belongs to no shadow-casting light")


def tile_rect(k: int, tiles: int, width: int, height: int) -> tuple[int, int, int, int]:
    """Tile ``k`` of a ``tiles x tiles`` atlas of ``width x height`` texels: (x, y, w, h)."""
    tiles = max(1, int(tiles))
    w, h = int(width) // tiles, int(height) // tiles
    return ((k % tiles) * w, (k // tiles) * h, w, h)


def _look_along(eye, direction) -> np.ndarray:
    """World -> view: the eye at ``eye`` looking along ``direction`` (its -z), y up unless
    the direction is (nearly) vertical, then z up."""
    f = np.asarray(direction, np.float64)
    f = f / np.linalg.norm(f)
    up = np.array([0.0, 1.0, 0.0]) if abs(f[1]) < 0.99 else np.array([0.0, 0.0, 1.0])
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ np.asarray(eye, np.float64)
    return m


def scene_bounds(scene) -> tuple[np.ndarray, np.ndarray]:
    """The world-space bounding box (lo, hi) of every object (float64)."""
    pts = [o.positions for o in scene.objects if len(o.positions)]
    if not pts:
        return np.zeros(3), np.zeros(3)
    lo = np.min([p.min(axis=0) for p in pts], axis=0).astype(np.float64)
    hi = np.max([p.max(axis=0) for p in pts], axis=0).astype(np.float64)
    return lo, hi


def spot_view_proj(light) -> tuple[np.ndarray, np.ndarray]:
    view = _look_along(light.position, light.direction)
    half = math.radians(min(float(light.outer_deg) + SPOT_MARGIN_DEG, 89.0))
    t = 1.0 / math.tan(half)
    far = float(light.radius)
    near = far * SPOT_NEAR_FRACTION
    p = np.zeros((4, 4))
    p[0, 0] = p[1, 1] = t
    p[2, 2] = (far + near) / (near - far)
    p[2, 3] = 2.0 * far * near / (near - far)
    p[3, 2] = -1.0
    return view, p


def point_face_view_proj(light, face: int) -> tuple[np.ndarray, np.ndarray]:
    """Face ``face`` (0..5, ``POINT_FACES``) of a point light's cube: (view, projection)."""
    axis, right, up = (np.asarray(v, np.float64) for v in POINT_FACES[face])
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = right, up, -axis
    view[:3, 3] = -view[:3, :3] @ np.asarray(light.position, np.float64)
    t, p22, p23 = point_projection(light)
    p = np.zeros((4, 4))
    p[0, 0] = p[1, 1] = t
    p[2, 2], p[2, 3], p[3, 2] = p22, p23, -1.0
    return view, p


def point_projection(light) -> tuple[float, float, float]:
    """(t, p22, p23): the entries of a point light's face projection (``shadow_m0``)."""
    far = float(light.radius)
    near = far * SPOT_NEAR_FRACTION
    return 1.0 / (1.0 + POINT_FACE_MARGIN), (far + near) / (near - far), 2.0 * far * near / (near - far)


def directional_view_proj(light, bounds) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = (np.asarray(b, np.float64) for b in bounds)
    centre = 0.5 * (lo + hi)
    view = _look_along(centre, light.direction)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    v = corners @ view[:3, :3].T + view[:3, 3]
    a, b = v.min(axis=0), v.max(axis=0)
    pad = np.maximum((b - a) * ORTHO_MARGIN, 1e-3)
    a, b = a - pad, b + pad
    near, far = -b[2], -a[2]                    # view space looks down -z
    p = np.eye(4)
    p[0, 0] = 2.0 / (b[0] - a[0])
    p[1, 1] = 2.0 / (b[1] - a[1])
    p[2, 2] = -2.0 / (far - near)
    p[0, 3] = -(b[0] + a[0]) / (b[0] - a[0])
    p[1, 3] = -(b[1] + a[1]) / (b[1] - a[1])
    p[2, 3] = -(far + near) / (far - near)
    return view, p


def light_view_proj(scene, light, bounds=None, face: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The (view, projection) float64 matrices a shadow-casting light's tile (a point light's
    ``face``) is drawn with."""
    if light.type == "point":
        return point_face_view_proj(light, face)
    if light.type == "spot":
        return spot_view_proj(light)
    if light.type == "directional":
        return directional_view_proj(light, bounds if bounds is not None
                                     else scene_bounds(scene))
    raise ValueError(f"{light.type} lights cast no shadows")


def point_rows(light) -> np.ndarray:
    """A point light's ``shadow_m0..3`` (4x4 float64): (t, p22, p23, 0), (position, 1), 0, 0."""
    m = np.zeros((4, 4))
    m[0, :3] = point_projection(light)
    m[1, :3], m[1, 3] = light.position, 1.0
    return m


def shadow_table(scene) -> dict[int, tuple[int, np.ndarray]]:
    """Per shadow-casting light index: (first tile, float64 shadow_m0..3 rows: projection @
    view, or a point light's ``point_rows``)."""
    out = {}
    bounds = None
    for i, k in first_tiles(scene.lights).items():
        light = scene.lights[i]
        if light.type == "point":
            out[i] = (k, point_rows(light))
            continue
        if light.type == "directional" and bounds is None:
            bounds = scene_bounds(scene)
        v, p = light_view_proj(scene, light, bounds)
        out[i] = (k, p @ v)
    return out


def light_fields(scene, name: str, table: Optional[dict] = None) -> np.ndarray:
    """float64 (lights, 4): the light-table field ``name`` (one of ``SHADOW_FIELDS``) of every
    light: ``shadow_tile`` (k or -1) in x; ``shadow_mR`` row R of projection @ view (zero for
    lights that cast no shadow).  ``table``: ``shadow_table(scene)`` when the caller has it."""
    table = shadow_table(scene) if table is None else table
    out = np.zeros((len(scene.lights), 4))
    for i in range(len(scene.lights)):
        if name == "shadow_tile":
            out[i, 0] = table[i][0] if i in table else -1.0
        elif i in table:
            out[i] = table[i][1][int(name[-1])]
    return out


def taps_side(pcf_taps: int) -> int:
    """PCF taps per side: 1 -> 1, 4 -> 2, 9 -> 3, 16 -> 4."""
    side = int(round(math.sqrt(int(pcf_taps))))
    if side * side != int(pcf_taps) or not 1 <= side <= 4:
        raise ValueError(f"pcf_taps must be 1, 4, 9 or 16, got {pcf_taps}")
    return side
