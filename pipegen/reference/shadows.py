"""Shadow maps and percentage-closer filtering in float64: what ``common/shadows.pipe``'s
``shadow_factor`` computes, with exact arithmetic.

``shadow_maps(scene, tiles, width, height)`` rasterises the scene's opaque objects from every
shadow-casting light (``pipegen.scene.shadows``: the same projections and tiles as the runtimes) into
a float64 depth map of its tile's size (``reference/raster.py``: GL coverage, depth ``less``
against 1.0, no culling, as the shadow passes draw); ``shadow_factor(smap, P, pcf_taps, bias)``
is the fraction of the PCF taps that see ``P`` lit:

    q = P - direction * offset                     (scene units, towards the light)
    offset = bias + slope_bias * min(tan(theta), 10)                        (``shadow_offset``)
    c = M @ (q, 1),  M = projection @ view          (the light table's rows, float32 values)
    c.w <= 0: 1 (behind a spot: unlit anyway)
    z = c.z / c.w * 0.5 + 0.5;  uv = (c.xy / c.w * 0.5 + 0.5) * (tile w, tile h)
    side = sqrt(pcf_taps);  base = floor(uv - (side - 1) / 2)
    factor = mean over a, b in [0, side) of  [ z <= map[clamp(base + (a, b), 0, tile - 1)] ]

theta is the angle between the unit normal N and the direction to the light (a spot's or point
light's position, a sun's -direction); without a normal (None) or with ``slope_bias`` 0 the
offset is ``bias``: ``tan = sqrt(max(1 - c^2, 0)) / max(c, 1e-6)``, c = N.l, as the shader
writes it.  ``pattern = "jittered"`` (``pcf_pattern``) takes Calver's four jittered taps instead:
``floor(uv + side / 8 * o)`` for o in (1, 3), (3, -1), (-1, -3), (-3, 1) (a rotated grid).  A point
light (six tiles, ``ShadowMap.faces``): ``d = (P - (P - L) * bias / |P - L|) - L`` (moved towards
the light, by the offset), the face its major axis picks (``face_of``), the face's view coordinates ``v`` (an
axis permutation, ``shadows.POINT_FACES``) and ``c = (t v.x, t v.y, p22 v.z + p23, -v.z)`` from
the light-table rows (``shadows.point_rows``), then the same filter in that face's tile.

The light's parameters are read as the light table stores them (float32), like the rest of the
reference; the map's depths are float64 (the runtimes store float32, ``d32f``).

``lighting.shade(..., shadows=)`` takes one of two ``Shadows``: ``MappedShadows(maps, pcf_taps,
bias)`` (each light with a map scaled by its ``shadow_factor``) or ``ExactShadows()`` (each
shadow-casting light scaled by its exact ``visibility``: ray casting, the hard shadows shadow
maps approximate).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from pipegen.scene import shadows as S
from pipegen.reference.rounding import as_float32
from pipegen.reference.raster import rasterize_triangles


@dataclass
class ShadowMap:
    light: int                 # index into scene.lights
    tile: int                  # k: the atlas tile (a point light: its first)
    rect: tuple[int, int, int, int]   # (x, y, w, h) in the atlas, y up
    matrix: np.ndarray         # float64 4x4: projection @ view as the light table holds it
    direction: np.ndarray      # float64 (3,): the light's direction as the table holds it
    depth: np.ndarray          # float64 (h, w), GL row order (row 0 = the tile's bottom row)
    # a point light: its six faces' maps (+x -x +y -y +z -z, tiles k .. k+5; the first is this
    # map's rect and depth) and its light-table rows (float32 values: shadows.point_rows)
    faces: tuple = ()
    rows: Optional[np.ndarray] = None
    # a spot light's position as the table holds it (float32 values): its slope term's l
    position: Optional[np.ndarray] = None

    def tiles(self) -> list["ShadowMap"]:
        """The maps of every tile the light owns (one, or a point light's six faces)."""
        return list(self.faces) or [self]


def _draw_tile(pos, nrm, view, proj, w: int, h: int) -> np.ndarray:
    """A float64 depth map (GL row order) of the triangles seen through view, proj."""
    depth = np.ones((h, w))
    if len(pos):
        # drawn with the float32 matrices the runtimes upload
        frags = rasterize_triangles(pos, nrm, as_float32(proj) @ as_float32(view), w, h, "none")
        depth.reshape(-1)[frags.pixel] = frags.depth
    return np.flipud(depth)


def shadow_maps(scene, tiles: int, width: int, height: int,
                material: tuple[str, ...] = ("opaque",)) -> dict[int, ShadowMap]:
    """The float64 shadow map of every shadow-casting light whose tiles fit the atlas's
    ``tiles x tiles`` capacity: ``{light index: ShadowMap}``."""
    geo = scene.geometry(tuple(material))
    pos = geo.positions.astype(np.float64).reshape(-1, 3, 3)
    nrm = geo.normals.astype(np.float64).reshape(-1, 3, 3)
    bounds = S.scene_bounds(scene)
    out = {}
    for i, k in S.first_tiles(scene.lights).items():
        light = scene.lights[i]
        if k + S.tile_count(light) > tiles * tiles:
            break
        direction = as_float32(light.direction)
        maps = []
        for face in range(S.tile_count(light)):
            view, proj = S.light_view_proj(scene, light, bounds, face)
            x, y, w, h = S.tile_rect(k + face, tiles, width, height)
            maps.append(ShadowMap(i, k + face, (x, y, w, h), as_float32(proj @ view), direction,
                                  _draw_tile(pos, nrm, view, proj, w, h)))
        if light.type == "point":
            first = maps[0]
            out[i] = ShadowMap(i, k, first.rect, first.matrix, direction, first.depth,
                               tuple(maps), as_float32(S.point_rows(light)))
        else:
            out[i] = maps[0]
            if light.type == "spot":
                out[i].position = as_float32(light.position)
    return out


class Shadows:
    """How ``lighting.shade`` shadows the scene's lights: ``factor(scene, i, light, P, N)`` is
    the fraction (n,) of light ``i`` reaching the points ``P`` (n, 3) with unit normals ``N``
    (n, 3; None: not known), or None: not shadowed."""

    def factor(self, scene, i: int, light, P: np.ndarray,
               N: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
        raise NotImplementedError


@dataclass(frozen=True)
class MappedShadows(Shadows):
    """Shadow maps with percentage-closer filtering (``shadow_factor``): the lights with a map
    in ``maps`` (``shadow_maps``) are shadowed, the others are not."""
    maps: dict[int, ShadowMap]
    pcf_taps: int
    bias: float
    pattern: str = "grid"          # pcf_pattern: grid or jittered
    slope_bias: float = 0.0        # shadow_slope_bias

    def factor(self, scene, i: int, light, P: np.ndarray,
               N: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
        smap = self.maps.get(i)
        return None if smap is None else shadow_factor(smap, P, self.pcf_taps, self.bias,
                                                       self.pattern, N, self.slope_bias)


@dataclass(frozen=True)
class ExactShadows(Shadows):
    """Every shadow-casting light (``shadows = true``) by its exact ``visibility``."""

    def factor(self, scene, i: int, light, P: np.ndarray,
               N: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
        return visibility(scene, light, P) if S.casts_shadows(light) else None


def shadow_factor(smap: ShadowMap, P: np.ndarray, pcf_taps: int, bias: float,
                  pattern: str = "grid", N: Optional[np.ndarray] = None,
                  slope_bias: float = 0.0) -> np.ndarray:
    """(n,) float64 in [0, 1]: the lit fraction of the PCF taps at surface points P (n, 3)
    with unit normals N (n, 3; None: the constant bias alone)."""
    P = np.asarray(P, np.float64)
    if smap.rows is not None:
        return _point_factor(smap, P, pcf_taps, bias, pattern, N, slope_bias)
    if smap.position is None:            # a sun
        to_light = np.broadcast_to(-smap.direction, P.shape)
    else:
        L = smap.position - P
        to_light = L / np.maximum(np.linalg.norm(L, axis=1), 1e-300)[:, None]
    q = P - smap.direction * shadow_offset(N, to_light, bias, slope_bias)[:, None]
    c = np.concatenate([q, np.ones((len(q), 1))], axis=1) @ smap.matrix.T
    return pcf(smap, c, pcf_taps, pattern)


TAN_MAX = 10.0          # the slope term's tan(theta) clamp (84 degrees)


def shadow_offset(N: Optional[np.ndarray], to_light: np.ndarray, bias: float,
                  slope_bias: float) -> np.ndarray:
    """(n,): how far each point moves towards the light: ``bias`` plus ``slope_bias`` times
    tan(theta) (clamped to ``TAN_MAX``), theta between the unit normal and ``to_light``
    (n, 3, unit); the parameters are float32 values, as the shader holds them."""
    b = np.full(len(to_light), float(np.float32(bias)))
    slope = float(np.float32(slope_bias))
    if N is None or slope == 0.0:
        return b
    N = np.asarray(N, np.float64)
    known = np.einsum("ij,ij->i", N, N) > 0
    c = np.einsum("ij,ij->i", N, to_light)
    tan = np.minimum(np.sqrt(np.maximum(1.0 - c * c, 0.0)) / np.maximum(c, 1e-6), TAN_MAX)
    return np.where(known, b + slope * tan, b)


def face_of(d: np.ndarray) -> np.ndarray:
    """(n,) int: the cube face (0..5: +x -x +y -y +z -z) of directions d (n, 3) from a point
    light, by major axis (ties: x, then y, then z), as ``shadow_face`` picks it."""
    a = np.abs(d)
    x = (a[:, 0] >= a[:, 1]) & (a[:, 0] >= a[:, 2])
    y = ~x & (a[:, 1] >= a[:, 2])
    axis = np.where(x, 0, np.where(y, 1, 2))
    negative = d[np.arange(len(d)), axis] < 0
    return 2 * axis + negative


def _point_factor(smap: ShadowMap, P: np.ndarray, pcf_taps: int, bias: float,
                  pattern: str, N: Optional[np.ndarray], slope_bias: float) -> np.ndarray:
    """A point light: the point moved ``shadow_offset`` towards the light, the face its major
    axis picks, its view coordinates by the face's axis permutation, then ``pcf`` in that
    tile."""
    t, p22, p23 = smap.rows[0, :3]
    light = smap.rows[1, :3]
    d = P - light
    dist = np.linalg.norm(d, axis=1)
    ok = dist > 0
    safe = np.where(ok, dist, 1.0)
    offset = shadow_offset(N, -d / safe[:, None], bias, slope_bias)
    d = (P - d * (offset / safe)[:, None]) - light
    face = face_of(d)
    out = np.ones(len(P))
    for f, fmap in enumerate(smap.faces):
        sel = ok & (face == f)
        if not sel.any():
            continue
        axis, right, up = (np.asarray(v, np.float64) for v in S.POINT_FACES[f])
        v = np.stack([d[sel] @ right, d[sel] @ up, -(d[sel] @ axis)], axis=1)
        c = np.stack([t * v[:, 0], t * v[:, 1], p22 * v[:, 2] + p23, -v[:, 2]], axis=1)
        out[sel] = pcf(fmap, c, pcf_taps, pattern)
    return out


# Calver's jittered 4-tap PCF: a rotated grid, in eighths of the n x n footprint (texels)
JITTER = ((1.0, 3.0), (3.0, -1.0), (-1.0, -3.0), (-3.0, 1.0))


def pcf(smap: ShadowMap, c: np.ndarray, pcf_taps: int, pattern: str = "grid") -> np.ndarray:
    """(n,): the lit fraction of the taps of ``pattern`` (``grid``: the n x n texels around the
    point, n = sqrt(pcf_taps); ``jittered``: the four ``JITTER`` offsets times n / 8) in the
    tile of ``smap`` at clip positions c (n, 4); 1 where c.w <= 0."""
    side = S.taps_side(pcf_taps)
    w = c[:, 3]
    ok = w > 0
    ws = np.where(ok, w, 1.0)
    z = c[:, 2] / ws * 0.5 + 0.5
    _, _, tw, th = smap.rect
    with np.errstate(invalid="ignore"):
        u = np.clip(np.nan_to_num((c[:, 0] / ws * 0.5 + 0.5) * tw, nan=0.0), -8.0, tw + 8.0)
        v = np.clip(np.nan_to_num((c[:, 1] / ws * 0.5 + 0.5) * th, nan=0.0), -8.0, th + 8.0)
    if pattern == "jittered":
        r = 0.125 * side
        taps = [(np.floor(u + a * r), np.floor(v + b * r)) for a, b in JITTER]
    elif pattern == "grid":
        bu, bv = np.floor(u - 0.5 * (side - 1)), np.floor(v - 0.5 * (side - 1))
        taps = [(bu + a, bv + b) for a in range(side) for b in range(side)]
    else:
        raise ValueError(f"pcf_pattern must be grid or jittered, got {pattern!r}")
    lit = np.zeros(len(c))
    for tu, tv in taps:
        tx = np.clip(tu, 0, tw - 1).astype(np.int64)
        ty = np.clip(tv, 0, th - 1).astype(np.int64)
        lit += z <= smap.depth[ty, tx]
    return np.where(ok, lit / len(taps), 1.0)


# ---- the truth: exact visibility ------------------------------------------------------------

RAY_EPS = 1e-3       # scene units: hits closer than this to the receiver are its own surface
RAY_CHUNK = 1 << 21  # (points x triangles) pairs per block


def visibility(scene, light, P: np.ndarray, material: tuple[str, ...] = ("opaque",)) -> np.ndarray:
    """(n,) float64 in {0, 1}: whether the segment from each point of P (n, 3) to the light
    (a spot's position; a directional light: along -direction, unbounded) misses every
    triangle of the scene's ``material`` objects, beyond ``RAY_EPS`` of the point (Moeller and
    Trumbore, float64).  The hard shadows a shadow map approximates: what ``pipegen sweep``'s
    scene reference lights with (``accuracy.scene_reference``)."""
    geo = scene.geometry(tuple(material))
    tri = geo.positions.astype(np.float64).reshape(-1, 3, 3)
    P = np.asarray(P, np.float64)
    out = np.ones(len(P))
    if not len(tri) or not len(P):
        return out
    if light.type == "directional":
        d = -as_float32(light.direction)
        D = np.broadcast_to(d / np.linalg.norm(d), P.shape)
        tmax = np.full(len(P), np.inf)
    else:
        L = as_float32(light.position) - P
        tmax = np.linalg.norm(L, axis=1)
        D = L / np.maximum(tmax, 1e-300)[:, None]
    v0 = tri[:, 0]
    e1, e2 = tri[:, 1] - v0, tri[:, 2] - v0
    step = max(1, RAY_CHUNK // len(tri))
    for a in range(0, len(P), step):
        o, d, tm = P[a:a + step, None, :], D[a:a + step, None, :], tmax[a:a + step, None]
        h = np.cross(d, e2[None])
        det = np.einsum("ntk,tk->nt", h, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = o - v0[None]
            u = np.einsum("ntk,ntk->nt", s, h) * inv
            q = np.cross(s, e1[None])
            v = np.einsum("ntk,ntk->nt", d, q) * inv
            t = np.einsum("ntk,tk->nt", q, e2) * inv
        hit = (np.abs(det) > 1e-300) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > RAY_EPS) & (t < tm)
        out[a:a + step] = np.where(hit.any(axis=1), 0.0, 1.0)
    return out
