"""How many lights a light-index packing must hold at one pixel, fast, and honestly worded.

A light-index pass writes, at a pixel, every light whose *volume* it marks there (the
circumscribing sphere mesh, ``lighting.volume_marks``).  When more are marked than the packing
holds, some are dropped, which ones depending on the draw order; only when more lights than it
holds *reach the shaded surface* is a light that matters certainly dropped.  So three counts,
cheapest first:

- ``tile_marks``: per screen tile (``TILE`` pixels square), the lights whose circumscribing
  sphere meets the cone of view rays through the tile (a sphere/cone test, no rasterisation).
  It bounds the volumes marked at every pixel of the tile.  ``refined_bound`` splits the tiles
  whose count exceeds a capacity into 4-pixel, then 1-pixel tiles and tests their parent's
  lights again with the same cone test: a bound as conservative, much tighter where a tile's
  lights crowd only part of it.
- ``volume_bound``: the most volumes marked at one pixel, per pixel from the float64 visible
  surface (exactly what ``lighting.lights_per_pixel(conservative=True)`` gives), evaluated only
  in the tiles whose tile count can still raise the maximum.
- ``reaching``: per surface point, the lights that reach it: inside the light's radius and, for
  a spot, inside its outer cone (the reference's attenuation and cone factor are not zero);
  directional lights everywhere.

``load(...)`` combines them for one packing: the tile bound, refined, when it fits; else the
lights reaching the surface at a sample of pixels (every ``stride``-th pixel, about
``SAMPLE_PIXELS`` of them, a small rasterisation), which proves "will be dropped" when it
exceeds the capacity; else the full-resolution surface settles it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pipegen.reference.lighting import EPS_DIST, volume_grow, volume_marks
from pipegen.reference.raster import GBuffer, rasterize_triangles
from pipegen.reference.rounding import as_float32

TILE = 16                    # pixels per tile side
REFINE = (4, 1)              # the finer tiles an over-capacity tile is split into, in turn
REFINE_TESTS = 250_000       # the most sphere/cone tests one split may take (some 0.05 s)
SAMPLE_PIXELS = 320 * 180    # about this many pixels in the sampled surface
# Angular slack of the sphere/cone test, in radians: covers arccos's rounding near 0 (about
# 1.5e-8); a pixel at 1280x720 spans some 7e-4 rad, so the bound loosens by nothing visible.
ANGLE_SLACK = 1e-6
# The tile's cone reaches this far (in pixels) beyond its outermost pixel centres: a surface
# point's direction from the eye deviates from its pixel centre's by the vertex snapping,
# at most 1/512 pixel (raster.SUBPIXEL).
MARGIN = 1.0


# -- the visible surface -------------------------------------------------------------------------


@dataclass(frozen=True)
class Surface:
    """The nearest surface at the pixel centres of the scene's image, at every ``stride``-th
    pixel in both directions (stride 1: every pixel, as ``raster.rasterize`` gives it)."""

    stride: int
    rows: np.ndarray        # int (n,): image rows (row 0 on top) of the covered samples
    cols: np.ndarray        # int (n,)
    position: np.ndarray    # float64 (n, 3) world space

    @classmethod
    def from_gbuffer(cls, gbuffer: GBuffer) -> "Surface":
        rows, cols = np.nonzero(gbuffer.coverage)
        return cls(1, rows, cols, gbuffer.position[rows, cols])


def sample_stride(scene) -> int:
    """Every how many pixels the sampled surface takes one: about ``SAMPLE_PIXELS`` samples."""
    return max(1, math.ceil(math.sqrt(scene.width * scene.height / SAMPLE_PIXELS)))


def surface(scene, stride: int = 1) -> Surface:
    """Rasterise the scene's geometry (all objects, as ``raster.rasterize(scene)``) at the
    pixel centres (k*i + k//2) for k = ``stride``: an image ``stride`` times smaller whose pixel
    centres are mapped onto those of the full image by an affine map of the clip coordinates.
    Stride 1 gives exactly ``rasterize(scene)``'s positions; a larger stride snaps vertices
    to a coarser grid (1/256 of a sample, ``stride``/256 of a pixel), so positions differ from
    the full image's by that much at most."""
    W, H, k = scene.width, scene.height, stride
    j = k // 2
    ws, hs = (W - j + k - 1) // k, (H - j + k - 1) // k
    o = j + 0.5 - k / 2          # full-image pixel x = k * (sample x) + o
    ax, ay = W / (k * ws), H / (k * hs)
    to_samples = np.array([[ax, 0, 0, (W - 2 * o) / (k * ws) - 1],
                           [0, ay, 0, 1 - (H - 2 * o) / (k * hs)],
                           [0, 0, 1, 0],
                           [0, 0, 0, 1]], dtype=np.float64)
    mvp = scene.camera.projection(scene.aspect) @ scene.camera.view_matrix()
    if k > 1:
        mvp = to_samples @ mvp
    geo = scene.geometry(())
    tris = geo.positions.astype(np.float64).reshape(-1, 3, 3)
    frags = rasterize_triangles(tris, geo.normals.astype(np.float64).reshape(-1, 3, 3),
                                mvp, ws, hs)
    return Surface(k, frags.pixel // ws * k + j, frags.pixel % ws * k + j, frags.position)


class Surfaces:
    """The sampled and the full-resolution surface of one scene, each rasterised once, when
    first asked for (``gbuffer``: the caller's full-resolution rasterisation, if it has one)."""

    def __init__(self, scene, gbuffer: Optional[GBuffer] = None):
        self.scene = scene
        self._full = None if gbuffer is None else Surface.from_gbuffer(gbuffer)
        self._sampled: Optional[Surface] = None

    def full(self) -> Surface:
        if self._full is None:
            self._full = surface(self.scene)
        return self._full

    def sampled(self) -> Surface:
        if sample_stride(self.scene) == 1 or self._full is not None:
            return self.full()
        if self._sampled is None:
            self._sampled = surface(self.scene, sample_stride(self.scene))
        return self._sampled


# -- the counts ------------------------------------------------------------------------------------


def _unproject(scene, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Unit view-ray directions through image points (x right, y down, in pixels)."""
    ndc = np.stack([2 * x / scene.width - 1, 1 - 2 * y / scene.height, np.ones_like(x),
                    np.ones_like(x)], axis=-1)
    inv = np.linalg.inv(scene.camera.projection(scene.aspect) @ scene.camera.view_matrix())
    far = ndc @ inv.T
    d = far[:, :3] / far[:, 3:] - np.asarray(scene.camera.position, dtype=np.float64)
    return d / np.linalg.norm(d, axis=1)[:, None]


def tile_grid(scene) -> tuple[int, int]:
    """(tiles down, tiles across)."""
    return -(-scene.height // TILE), -(-scene.width // TILE)


def _cones(scene, x: np.ndarray, y: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """(unit axis, half angle) of the cone of view rays through each square tile of ``size``
    pixels whose top-left pixel is (``x``, ``y``), clipped to the image, ``MARGIN`` pixels
    beyond its outermost pixel centres.  The cone holds the rays through its corners, so (a
    circular cone being convex) every ray through the rectangle between them."""
    x0, y0 = x + 0.5 - MARGIN, y + 0.5 - MARGIN
    x1 = np.minimum(x + size, scene.width) - 0.5 + MARGIN
    y1 = np.minimum(y + size, scene.height) - 0.5 + MARGIN
    axis = _unproject(scene, (x0 + x1) / 2, (y0 + y1) / 2)
    half = np.zeros(len(axis))
    for cx, cy in ((x0, y0), (x1, y0), (x0, y1), (x1, y1)):
        corner = _unproject(scene, cx, cy)
        half = np.maximum(half, np.arccos(np.clip(np.einsum("ij,ij->i", axis, corner), -1, 1)))
    return axis, half


class _Spheres:
    """The circumscribing spheres of the point/spot lights of ``lights`` as seen from the eye:
    the unit direction to each centre, the half angle it subtends, whether it holds the eye."""

    def __init__(self, scene, lights):
        cam = np.asarray(scene.camera.position, dtype=np.float64)
        spheres = [l for l in lights if l.type != "directional"]
        oc = np.array([as_float32(l.position) for l in spheres]).reshape(-1, 3) - cam
        R = np.array([float(as_float32(l.radius)) for l in spheres]) * volume_grow()
        d = np.linalg.norm(oc, axis=1)
        self.inside = d <= R * (1 + 1e-9)
        self.seen = np.arcsin(np.minimum(R / np.maximum(d, 1e-300), 1.0))
        self.toward = oc / np.maximum(d, 1e-300)[:, None]

    def meet(self, axis: np.ndarray, half: np.ndarray, light: np.ndarray) -> np.ndarray:
        """bool per (cone, light index) pair: the sphere meets the cone."""
        cos = np.einsum("ij,ij->i", axis, self.toward[light])
        angle = np.arccos(np.clip(cos, -1, 1))
        return self.inside[light] | (angle <= half + self.seen[light] + ANGLE_SLACK)


def tile_marks(scene, lights) -> np.ndarray:
    """bool (tiles, point/spot lights of ``lights``): the light's circumscribing sphere meets
    the cone of view rays through the tile (tiles row-major, ``tile_grid``).  A ray of the
    tile that a light-volume pass marks for the light (either faces) meets the sphere at
    t >= 0, so it lies within asin(R/d) of the direction to the centre; the tile's rays lie
    within the cone around its centre ray (``_cones``)."""
    ty, tx = tile_grid(scene)
    y, x = np.divmod(np.arange(ty * tx), tx)
    axis, half = _cones(scene, x * TILE, y * TILE, TILE)
    s = _Spheres(scene, lights)
    if not len(s.seen):
        return np.zeros((len(axis), 0), dtype=bool)
    angle = np.arccos(np.clip(axis @ s.toward.T, -1, 1))
    return s.inside[None, :] | (angle <= half[:, None] + s.seen[None, :] + ANGLE_SLACK)


@dataclass
class _Tiles:
    """Square tiles of ``size`` pixels (top-left pixel ``x``, ``y``) and the lights each may
    meet: those of tile t are ``light[start[t]:start[t] + count[t]]``."""
    x: np.ndarray
    y: np.ndarray
    size: int
    light: np.ndarray
    count: np.ndarray

    def take(self, t: np.ndarray) -> "_Tiles":
        start = np.cumsum(self.count) - self.count
        n = self.count[t]
        first = np.cumsum(n) - n
        light = self.light[np.repeat(start[t] - first, n) + np.arange(int(n.sum()))]
        return _Tiles(self.x[t], self.y[t], self.size, light, n)

    def split(self, scene, child: int, spheres: "_Spheres") -> "_Tiles":
        """Each tile split into tiles of ``child`` pixels (clipped to the image), each child
        keeping the lights of its parent whose sphere meets its own cone."""
        k = self.size // child
        dy, dx = np.divmod(np.arange(k * k), k)
        cx = (self.x[:, None] + dx[None, :] * child).ravel()
        cy = (self.y[:, None] + dy[None, :] * child).ravel()
        parent = np.repeat(np.arange(len(self.x)), k * k)
        keep = (cx < scene.width) & (cy < scene.height)
        cx, cy, inherited = cx[keep], cy[keep], self.take(parent[keep])
        pair_child = np.repeat(np.arange(len(cx)), inherited.count)
        axis, half = _cones(scene, cx, cy, child)
        met = spheres.meet(axis[pair_child], half[pair_child], inherited.light)
        return _Tiles(cx, cy, child, inherited.light[met],
                      np.bincount(pair_child[met], minlength=len(cx)))


CHUNK = 256                  # tiles split to 1 pixel at a time, the most crowded first


def refined_bound(scene, lights, capacity: int, marks: Optional[np.ndarray] = None) -> int:
    """An upper bound of the volumes of ``lights`` a light-volume pass marks at one pixel,
    at most the tile bound: each tile whose count exceeds ``capacity`` is split into tiles of
    ``REFINE`` pixels in turn, each child tested (``_cones``, the same sphere/cone test) for
    the lights its parent meets; the maximum over the tiles where the splitting stopped.
    Tiles are split to the last size ``CHUNK`` at a time, the most crowded first, only until
    a last-size tile still exceeds the capacity (the packing then overflows whatever the
    rest gives: they keep the count of their size); a split that would take more than
    ``REFINE_TESTS`` sphere/cone tests is not made.  No rasterisation: pixels hidden behind
    the surface count as the tile bound counts them."""
    marks = tile_marks(scene, lights) if marks is None else marks
    directional = sum(l.type == "directional" for l in lights)
    counts = marks.sum(axis=1) + directional
    best = int(counts[counts <= capacity].max(initial=0))
    over = np.flatnonzero(counts > capacity)
    tx = tile_grid(scene)[1]
    tile, light = np.nonzero(marks[over])
    tiles = _Tiles(over % tx * TILE, over // tx * TILE, TILE, light,
                   np.bincount(tile, minlength=len(over)))
    spheres = _Spheres(scene, lights)
    for level, child in enumerate(REFINE):
        if not len(tiles.x) or int(tiles.count.sum()) * (tiles.size // child) ** 2 \
                > REFINE_TESTS:
            break
        last = level == len(REFINE) - 1
        order = np.argsort(-tiles.count, kind="stable") if last else np.arange(len(tiles.x))
        step = CHUNK if last else len(order)
        split = []
        for at in range(0, len(order), step):
            children = tiles.take(order[at:at + step]).split(scene, child, spheres)
            n = children.count + directional
            best = max(best, int(n[n <= capacity].max(initial=0)))
            split.append(children.take(np.flatnonzero(n > capacity)))
            if last and (n > capacity).any():       # overflows: the rest keep their count
                rest = tiles.count[order[at + step:]]
                return max(best, int(n.max()), int(rest.max(initial=0)) + directional)
        tiles = _Tiles(np.concatenate([t.x for t in split]),
                       np.concatenate([t.y for t in split]), child,
                       np.concatenate([t.light for t in split]),
                       np.concatenate([t.count for t in split]))
    return max(best, int(tiles.count.max(initial=0)) + directional)


def tile_counts(scene, lights, marks: Optional[np.ndarray] = None) -> np.ndarray:
    """int (tiles down, tiles across): an upper bound of the volumes of ``lights`` a
    light-volume pass marks at any pixel of each tile (directional lights: everywhere)."""
    marks = tile_marks(scene, lights) if marks is None else marks
    directional = sum(l.type == "directional" for l in lights)
    return (marks.sum(axis=1) + directional).reshape(tile_grid(scene))


class _ByTile:
    """Pixels (rows, cols of an image) grouped by tile, to visit only a light's tiles."""

    def __init__(self, scene, rows: np.ndarray, cols: np.ndarray):
        ntiles = tile_grid(scene)[0] * tile_grid(scene)[1]
        self.tile = rows // TILE * tile_grid(scene)[1] + cols // TILE
        self.order = np.argsort(self.tile, kind="stable")
        bounds = np.searchsorted(self.tile[self.order], np.arange(ntiles + 1))
        self.start, self.size = bounds[:-1], np.diff(bounds)

    def pixels(self, tiles: np.ndarray) -> np.ndarray:
        """Indices of the pixels in the tiles where ``tiles`` (bool per tile) is True."""
        t = np.flatnonzero(tiles)
        size = self.size[t]
        offset = np.repeat(self.start[t] - np.cumsum(size) + size, size)
        return self.order[offset + np.arange(int(size.sum()))]


def _rays(scene, surf: Surface, sky: bool):
    """(rows, cols, unit view directions, distance to the surface) at the surface's pixels;
    with ``sky``, its uncovered sample pixels too, along the ray through the pixel centre to
    infinity (as ``lighting.lights_per_pixel`` counts sky pixels)."""
    cam = np.asarray(scene.camera.position, dtype=np.float64)
    ray = surf.position - cam
    t_surface = np.linalg.norm(ray, axis=1)
    u = ray / np.maximum(t_surface, 1e-300)[:, None]
    rows, cols = surf.rows, surf.cols
    if sky:
        k, j = surf.stride, surf.stride // 2
        open_ = np.zeros((scene.height, scene.width), dtype=bool)
        open_[j::k, j::k] = True
        open_[rows, cols] = False
        sr, sc = np.nonzero(open_)
        rows, cols = np.concatenate([rows, sr]), np.concatenate([cols, sc])
        u = np.concatenate([u, _unproject(scene, sc + 0.5, sr + 0.5)])
        t_surface = np.concatenate([t_surface, np.full(len(sr), np.inf)])
    return rows, cols, u, t_surface


def volume_max(scene, lights, surf: Surface, faces: str = "back", sky: bool = False,
               marks: Optional[np.ndarray] = None) -> int:
    """The most volumes of ``lights`` a light-volume pass marks at one of the surface's
    pixels (``faces`` and ``sky`` as ``lighting.lights_per_pixel`` takes them).  On the full
    surface: that function's conservative count's maximum, the bound itself; on a sample, a
    count that some pixel reaches.  Evaluated per pixel only in the tiles whose tile count
    exceeds the best found so far (the tiles at the top count first)."""
    front = faces == "front"
    rows, cols, u, t_surface = _rays(scene, surf, front and sky)
    if not len(rows):
        return 0
    marks = tile_marks(scene, lights) if marks is None else marks
    by_tile = _ByTile(scene, rows, cols)
    counts = np.where(by_tile.size > 0, tile_counts(scene, lights, marks).ravel(), -1)
    cam = np.asarray(scene.camera.position, dtype=np.float64)
    spheres = [l for l in lights if l.type != "directional"]
    directional = len(lights) - len(spheres)
    grow = volume_grow()
    best, done = 0, np.zeros(len(counts), dtype=bool)
    n = np.full(len(rows), directional, dtype=np.int64)
    for first in (True, False):
        todo = ~done & (counts == counts.max() if first else counts > best)
        done |= todo
        if not todo.any():
            continue
        for i, light in enumerate(spheres):
            p = by_tile.pixels(todo & marks[:, i])
            n[p] += volume_marks(light, cam, u[p], t_surface[p], front, grow)
        best = max(best, int(n[by_tile.pixels(todo)].max(initial=0)))
    return best


def volume_bound(scene, lights, full: Surface, faces: str = "back", sky: bool = False,
                 marks: Optional[np.ndarray] = None) -> int:
    """The most volumes of ``lights`` a light-volume pass marks at one pixel: exactly the
    maximum of ``lighting.lights_per_pixel(conservative=True)`` (``full``: every pixel)."""
    assert full.stride == 1
    return volume_max(scene, lights, full, faces, sky, marks)


def reaching(position: np.ndarray, lights) -> np.ndarray:
    """int (n,): how many of ``lights`` reach each surface point: points and spots whose
    sphere strictly holds it (the reference's attenuation is zero at the radius and beyond),
    spots only inside the outer cone (the smoothstep is zero at and outside it), and every
    directional light.  Light parameters as the light table stores them (float32)."""
    n = np.zeros(len(position), dtype=np.int64)
    for light in lights:
        n += _reaches(light, position)
    return n


def _reaches(light, position: np.ndarray) -> np.ndarray:
    if light.type == "directional":
        return np.ones(len(position), dtype=bool)
    L = as_float32(light.position) - position
    d2 = np.einsum("ij,ij->i", L, L)
    r = float(as_float32(light.radius))
    lit = d2 < r * r
    if light.type == "spot":
        l = L / np.maximum(np.sqrt(d2), EPS_DIST)[:, None]
        lit &= -l @ as_float32(light.direction) > float(as_float32(light.cos_outer))
    return lit


def reaching_max(scene, lights, surf: Surface, marks: Optional[np.ndarray] = None) -> int:
    """``reaching``'s maximum over the surface's pixels, each light tested only in the tiles
    its volume meets (a point inside its sphere lies on a ray that meets the volume)."""
    if not len(surf.rows):
        return 0
    marks = tile_marks(scene, lights) if marks is None else marks
    by_tile = _ByTile(scene, surf.rows, surf.cols)
    spheres = [l for l in lights if l.type != "directional"]
    n = np.full(len(surf.rows), len(lights) - len(spheres), dtype=np.int64)
    for i, light in enumerate(spheres):
        p = by_tile.pixels(marks[:, i])
        n[p] += _reaches(light, surf.position[p])
    return int(n.max())


# -- one packing -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Load:
    """What one packing is asked to hold.  ``volumes``: an upper bound of the light volumes
    marked at one pixel (the tile bound, or the per-pixel maximum when the full surface was
    rasterised; None: not needed).  ``reaching``: the most lights found reaching the
    surface at one pixel (None: not counted); ``exact``: over every pixel (else over a
    sample of them, a lower bound of the maximum)."""

    volumes: Optional[int]
    reaching: Optional[int]
    exact: bool

    def verdict(self, capacity: int) -> str:
        """"will" (more lights reach a surface point than the packing holds), "may" (only
        the conservative bound exceeds it) or "fits"."""
        if self.reaching is not None and self.reaching > capacity:
            return "will"
        return "may" if self.volumes is not None and self.volumes > capacity else "fits"


def load(scene, lights, capacity: int, surfaces: Surfaces, faces: str = "back",
         sky: bool = False) -> Load:
    """How many of ``lights`` a packing holding ``capacity`` must hold at one pixel, computed
    only as far as the verdict needs: the tile bound, refined over the tiles it overflows
    (``refined_bound``), when it fits; the lights reaching the surface at the sampled pixels
    when they overflow it ("will"); the volumes marked at a sampled pixel when they overflow
    it ("may", with the refined tile bound); else the full surface's counts."""
    if not lights:
        return Load(0, 0, True)
    marks = tile_marks(scene, lights)
    tiles = int(tile_counts(scene, lights, marks).max())
    if tiles > capacity:
        tiles = refined_bound(scene, lights, capacity, marks)
    if tiles <= capacity:
        return Load(tiles, None, False)
    sampled = surfaces.sampled()
    found = reaching_max(scene, lights, sampled, marks)
    if found > capacity:
        return Load(None, found, sampled.stride == 1)
    if sampled.stride > 1:
        if volume_max(scene, lights, sampled, faces, sky, marks) > capacity:
            return Load(tiles, None, False)
        full = surfaces.full()
        found = reaching_max(scene, lights, full, marks)
        if found > capacity:
            return Load(None, found, True)
    return Load(volume_bound(scene, lights, surfaces.full(), faces, sky, marks), found, True)
