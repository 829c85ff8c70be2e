"""Shadow maps: which lights cast shadows, their projections and their tiles in the atlas.

The one place both runtimes and the float64 reference take these from (so a shadow map drawn by
GL, by OpenCL and by ``reference/shadows.py`` is the same picture of the same frustum):

- ``shadow_lights(lights)``: the indices of the shadow-casting lights (``shadows = true`` in the
  scene), in light-table order; light ``shadow_lights(...)[k]`` owns **tile k** of the atlas;
- ``light_view_proj(scene, light)``: the light's (view, projection) as float64 4x4 matrices,
  GL conventions (column vectors, clip z in [-w, w], window depth 0 near, 1 far):

  - spot: a look-at from the light's position along its direction and a square perspective
    frustum of full angle ``2 * (outer_deg + SPOT_MARGIN_DEG)``, near ``radius *
    SPOT_NEAR_FRACTION``, far ``radius`` (nothing beyond the radius is lit);
  - directional: an orthographic box along the light's direction fitted to the bounding box of
    every object of the scene (the box's eight corners in light view space, widened by
    ``ORTHO_MARGIN`` of its extent on each side), so every object both casts and receives;

- ``tile_rect(k, tiles, width, height)``: tile k of an atlas of ``tiles x tiles`` tiles of a
  ``width x height`` depth target: ``(x, y, w, h)`` in texels, column ``k % tiles``, row
  ``k // tiles`` (window coordinates, y up), ``w = width // tiles``, ``h = height // tiles``.

The light table carries what a shader needs to look a shadow up (``Scene.light_table``):
``shadow_tile`` (k, or -1 for a light that casts none) and ``shadow_m0`` .. ``shadow_m3``, the
rows of ``projection @ view`` rounded to float32.  The runtimes draw the tile with the float32
roundings of ``view`` and ``projection`` (as they upload a camera).

Point lights cannot cast shadows (a cube map of six faces is not implemented): the scene
loader refuses ``shadows = true`` on them.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

SPOT_MARGIN_DEG = 1.0       # the frustum's half-angle exceeds the outer cone by this
SPOT_MAX_OUTER_DEG = 84.0   # wider spots cannot cast shadows (a frustum near 180 degrees)
SPOT_NEAR_FRACTION = 0.02   # near plane of a spot's frustum, as a fraction of its radius
ORTHO_MARGIN = 0.01         # directional boxes: widened by this fraction of their extent

SHADOW_FIELDS = ("shadow_tile", "shadow_m0", "shadow_m1", "shadow_m2", "shadow_m3")


def casts_shadows(light) -> bool:
    return bool(getattr(light, "shadows", False))


def shadow_lights(lights) -> list[int]:
    """Indices of the shadow-casting lights, in table order (light k of this list: tile k)."""
    return [i for i, l in enumerate(lights) if casts_shadows(l)]


def tile_of(lights, index: int) -> int:
    """The atlas tile of light ``index`` (-1: it casts no shadow)."""
    order = shadow_lights(lights)
    return order.index(index) if index in order else -1


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


def light_view_proj(scene, light, bounds=None) -> tuple[np.ndarray, np.ndarray]:
    """The (view, projection) float64 matrices a shadow-casting light's tile is drawn with."""
    if light.type == "spot":
        return spot_view_proj(light)
    if light.type == "directional":
        return directional_view_proj(light, bounds if bounds is not None
                                     else scene_bounds(scene))
    raise ValueError(f"{light.type} lights cast no shadows")


def shadow_table(scene) -> dict[int, tuple[int, np.ndarray]]:
    """Per shadow-casting light index: (tile k, float64 projection @ view)."""
    out = {}
    bounds = None
    for k, i in enumerate(shadow_lights(scene.lights)):
        light = scene.lights[i]
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
