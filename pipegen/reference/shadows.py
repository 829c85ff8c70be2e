"""Shadow maps and percentage-closer filtering in float64: what ``common/shadows.pipe``'s
``shadow_factor`` computes, with exact arithmetic.

``shadow_maps(scene, tiles, width, height)`` rasterises the scene's opaque objects from every
shadow-casting light (``pipegen.scene.shadows``: the same projections and tiles as the runtimes) into
a float64 depth map of its tile's size (``reference/raster.py``: GL coverage, depth ``less``
against 1.0, no culling, as the shadow passes draw); ``shadow_factor(smap, P, pcf_taps, bias)``
is the fraction of the PCF taps that see ``P`` lit:

    q = P - direction * bias                       (bias in scene units, towards the light)
    c = M @ (q, 1),  M = projection @ view          (the light table's rows, float32 values)
    c.w <= 0: 1 (behind a spot: unlit anyway)
    z = c.z / c.w * 0.5 + 0.5;  uv = (c.xy / c.w * 0.5 + 0.5) * (tile w, tile h)
    side = sqrt(pcf_taps);  base = floor(uv - (side - 1) / 2)
    factor = mean over a, b in [0, side) of  [ z <= map[clamp(base + (a, b), 0, tile - 1)] ]

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
    tile: int                  # k: the atlas tile
    rect: tuple[int, int, int, int]   # (x, y, w, h) in the atlas, y up
    matrix: np.ndarray         # float64 4x4: projection @ view as the light table holds it
    direction: np.ndarray      # float64 (3,): the light's direction as the table holds it
    depth: np.ndarray          # float64 (h, w), GL row order (row 0 = the tile's bottom row)


def shadow_maps(scene, tiles: int, width: int, height: int,
                material: tuple[str, ...] = ("opaque",)) -> dict[int, ShadowMap]:
    """The float64 shadow map of every shadow-casting light within the atlas's ``tiles x
    tiles`` capacity: ``{light index: ShadowMap}``."""
    geo = scene.geometry(tuple(material))
    pos = geo.positions.astype(np.float64).reshape(-1, 3, 3)
    nrm = geo.normals.astype(np.float64).reshape(-1, 3, 3)
    bounds = S.scene_bounds(scene)
    out = {}
    for k, i in enumerate(S.shadow_lights(scene.lights)):
        if k >= tiles * tiles:
            break
        light = scene.lights[i]
        view, proj = S.light_view_proj(scene, light, bounds)
        x, y, w, h = S.tile_rect(k, tiles, width, height)
        depth = np.ones((h, w))
        if len(pos):
            # drawn with the float32 matrices the runtimes upload
            frags = rasterize_triangles(pos, nrm, as_float32(proj) @ as_float32(view), w, h, "none")
            depth.reshape(-1)[frags.pixel] = frags.depth
        out[i] = ShadowMap(i, k, (x, y, w, h), as_float32(proj @ view), as_float32(light.direction),
                           np.flipud(depth))
    return out


class Shadows:
    """How ``lighting.shade`` shadows the scene's lights: ``factor(scene, i, light, P)`` is the
    fraction (n,) of light ``i`` reaching the points ``P`` (n, 3), or None: not shadowed."""

    def factor(self, scene, i: int, light, P: np.ndarray) -> Optional[np.ndarray]:
        raise NotImplementedError


@dataclass(frozen=True)
class MappedShadows(Shadows):
    """Shadow maps with percentage-closer filtering (``shadow_factor``): the lights with a map
    in ``maps`` (``shadow_maps``) are shadowed, the others are not."""
    maps: dict[int, ShadowMap]
    pcf_taps: int
    bias: float

    def factor(self, scene, i: int, light, P: np.ndarray) -> Optional[np.ndarray]:
        smap = self.maps.get(i)
        return None if smap is None else shadow_factor(smap, P, self.pcf_taps, self.bias)


@dataclass(frozen=True)
class ExactShadows(Shadows):
    """Every shadow-casting light (``shadows = true``) by its exact ``visibility``."""

    def factor(self, scene, i: int, light, P: np.ndarray) -> Optional[np.ndarray]:
        return visibility(scene, light, P) if S.casts_shadows(light) else None


def shadow_factor(smap: ShadowMap, P: np.ndarray, pcf_taps: int, bias: float) -> np.ndarray:
    """(n,) float64 in [0, 1]: the lit fraction of the PCF taps at surface points P (n, 3)."""
    side = S.taps_side(pcf_taps)
    q = np.asarray(P, np.float64) - smap.direction * float(np.float32(bias))
    c = np.concatenate([q, np.ones((len(q), 1))], axis=1) @ smap.matrix.T
    w = c[:, 3]
    ok = w > 0
    ws = np.where(ok, w, 1.0)
    z = c[:, 2] / ws * 0.5 + 0.5
    _, _, tw, th = smap.rect
    u = (c[:, 0] / ws * 0.5 + 0.5) * tw
    v = (c[:, 1] / ws * 0.5 + 0.5) * th
    with np.errstate(invalid="ignore"):
        bu = np.floor(u - 0.5 * (side - 1))
        bv = np.floor(v - 0.5 * (side - 1))
    bu = np.nan_to_num(bu, nan=0.0, posinf=tw, neginf=-1.0)
    bv = np.nan_to_num(bv, nan=0.0, posinf=th, neginf=-1.0)
    lit = np.zeros(len(q))
    for a in range(side):
        for b in range(side):
            tx = np.clip(bu + a, 0, tw - 1).astype(np.int64)
            ty = np.clip(bv + b, 0, th - 1).astype(np.int64)
            lit += z <= smap.depth[ty, tx]
    return np.where(ok, lit / (side * side), 1.0)


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
