"""The CL runtime's geometry: vertex kernels, clipping, triangle set-up (on the device,
``cl_setup_device``, where it can; else the numpy ``cl_setup``) and binning of each pass's
draw, cached and shared (see ``cl_pipeline``'s docstring for the sharing rules).

``DrawGeometry(device, plan, tile).pass_triangles(k, pass, width, height, timing, lights)``
returns the set-up triangles (``Geo``: host arrays and device buffers) and the pass's tile
bins (``cl_bin.DeviceBins``, binned on the device; ``group_bins.LightBins`` for the lights of
a ``repeat per light`` group, binned in numpy at once; ``Bins`` where numpy bins a draw on its
own, every one with ``$PIPEGEN_CL_DEVICE_BIN=0``), or None
when the pass draws no triangle (bins may still hold no tile: the raster launch checks).
``begin_frame(state)`` drops the per-frame caches and takes the frame's ``FrameState``;
``use_scene()`` drops the scene's attribute buffers.  The geometry sees the pipeline only
through what it is given: the ``device.Device`` it runs on, the plan, the tile size and each
frame's ``FrameState`` (so it does not import the pipeline, which imports it).

``$PIPEGEN_CL_SHARE_SETUP=0`` (read when a pipeline is made; ``DrawGeometry.share``) turns the
sharing off, for comparisons: every pass execution then runs its own vertex kernel, set-up
and binning, of its own varyings only (a light draw still sets up its light list at once), and
its own raster launch (``CLPipeline._batched``), and nothing is kept from one execution or
frame to the next.  Sharing changes no value:
``tests/test_cl_setup_reuse.py`` renders every shipped technique both ways.
"""

from __future__ import annotations

import dataclasses
import os
import time
from typing import Optional

import numpy as np

from pipegen.ir import nodes as ir
from pipegen.backends.opencl import abi as cl_abi
from pipegen.backends.plan import PassPlan, Plan
from pipegen.runtime.cl import (
    bin as cl_bin, context as cl_context, setup_device as cl_setup_device)
from pipegen.runtime import draws
from pipegen.runtime.cl.device import Device
from pipegen.runtime.cl.group_bins import GroupBins
from pipegen.runtime.cl.setup import bin_pairs, bin_triangles, bins_from_pairs, setup_triangles
from pipegen.runtime.cl.transfers import write


def f4(a: np.ndarray) -> np.ndarray:
    """Rows of up to 4 floats as float4 rows (zero-padded)."""
    a = np.asarray(a, np.float32)
    out = np.zeros((len(a), 4), np.float32)
    out[:, :a.shape[1]] = a
    return out


class Geo:
    """Set-up triangles of a draw, on the host (``tris``) and on the device (``bufs``, the
    raster kernel's per-triangle arrays and the varyings; triangle i in row ``index[i]`` of
    the buffers, or row i without an index); ``ranges``: light -> its triangles ``[lo, hi)``
    for a light draw; ``front``: the front-facing triangles."""

    def __init__(self, tris, bufs: dict, index: Optional[np.ndarray] = None):
        self.tris = tris
        self.bufs = bufs
        self.index = index        # the buffers' row of each triangle (None: the same)
        self.ranges: dict = {}
        self.front = (tris.flat[:, 0] & 1).astype(bool)
        self._fronts: Optional[np.ndarray] = None
        self.ncoef = tris.coef.shape[1]
        self.names: list = []        # scene draws: the varyings set up, in slot order
        self.flats: list = []
        self.setup_cull = "none"     # the faces the set-up culled (a light draw: _light_cull)

    def fronts_before(self) -> np.ndarray:
        """(count + 1,): how many front faces precede each triangle (and all of them last),
        found once: each pass drawing a light range counts its culled faces from it."""
        if self._fronts is None:
            self._fronts = np.concatenate([[0], np.cumsum(self.front)])
        return self._fronts


class _Vertices:
    """A draw's queued vertex work (``DrawGeometry._vertices``): the kernel events, the
    non-blocking read-backs into ``clip``/``clip64``/``outs``, and what set-up needs besides."""


@dataclasses.dataclass(frozen=True)
class ShadowView:
    """One atlas tile of a shadow-map draw: the tile's index (``light``: the schedule's
    ``light`` slot holds it; a point light has six), its rectangle (x, y, w, h) in the depth
    target, and the frame structs (f32, and f64 or None) with the light's view and
    projection in place of the camera's (``draws.shadow_view``)."""
    light: int
    rect: tuple
    frame_buf: object
    frame64_buf: object


@dataclasses.dataclass(frozen=True)
class FrameState:
    """What the draws of a frame read of the pipeline's frame, made by ``CLPipeline.render``
    for each frame (``DrawGeometry.begin_frame``): the scene and its light selection
    (``draws.LightSelection``), the camera's ``view`` and ``proj`` matrices (float64, as
    ``draws`` takes them), the device's frame structs (``pg_frame``; ``pg_frame64`` with the
    float64 evaluation, else None), the scene's light table, and each pass's viewport
    (width, height), by pass index (set-ups are shared by passes whose raster state,
    viewport included, is the same)."""
    scene: object
    selection: draws.LightSelection
    view: np.ndarray
    proj: np.ndarray
    frame_buf: object
    frame64_buf: object
    lights_buf: object
    pass_sizes: tuple


def _scene_union(plan: Plan, ks: list) -> tuple:
    """The set-up the scene passes ``ks`` share (``DrawGeometry._scene_group``): the union of
    their varyings (SCENE_VARYINGS order), their flat flags, the passes whose vertex kernels
    compute the union (k, [their varying names]), and whether any needs the 1/w plane."""
    members = [(k, cl_abi.varying_slots(plan.passes[k]),
                "frag_coord" in plan.passes[k].code.inputs) for k in ks]
    union = {v["name"]: v["flat"] for _, slots, _ in members for v in slots}
    names = [n for n in cl_abi.SCENE_VARYINGS if n in union]
    providers, missing = [], set(names)
    for k, slots, _ in sorted(members, key=lambda m: -len(m[1])):
        have = [v["name"] for v in slots]
        if missing & set(have):
            providers.append((k, have))
            missing -= set(have)
    return names, [union[n] for n in names], providers, any(m[2] for m in members)


class Bins:
    """A pass's tile lists on the device: the tiles with triangles (``tile_list``, one
    work-group each), ``tile_start``/``tile_tris`` (CSR, triangle indices into the geometry),
    one list per ``band`` rows of a tile (``tile``: the tiles' side; ``band`` None: one list
    per tile)."""

    def __init__(self, device: Device, tile_start, tile_tris, tiles_x: int, triangles: int,
                 active: Optional[np.ndarray] = None, index: Optional[np.ndarray] = None,
                 tile: int = cl_abi.TILE, band: Optional[int] = None):
        self.band = tile if band is None else band
        if active is None:
            active = np.flatnonzero(cl_bin.tiles_with(np.diff(tile_start) > 0, tiles_x,
                                                      tile // self.band))
        active = active.astype(np.int32)
        self.ntiles = len(active)
        self.tiles_x = tiles_x
        self.triangles = triangles
        self.entries = int(tile_start[-1])
        self.host = (active, tile_start, tile_tris)      # triangle indices (tests)
        self.tile_list = device.buffer(active)
        self.tile_start = device.buffer(tile_start)
        # the raster kernel reads buffer rows: the geometry's ``index`` of each triangle
        self.tile_tris = device.buffer(tile_tris if index is None or not len(index)
                                       else np.take(index, tile_tris))


def homogeneous_planes(clip64: np.ndarray, parent: np.ndarray, width: int, height: int,
                       polygon_offset=None, depth_format: Optional[str] = None,
                       viewport=None) -> np.ndarray:
    """The float64 evaluation's per-triangle planes (N, 4, 4) float64, from the clip positions
    in double (``clip64`` (V, 4), the vertex kernel's ``o_clip64``) of each set-up triangle's
    *parent* (the input triangle ``parent[n]``, vertices 3p, 3p + 1, 3p + 2: clipping makes
    pieces of it, and interpolating over the parent is what clipping then interpolating
    means).

    With M = [[x0, x1, x2], [y0, y1, y2], [w0, w1, w2]] (clip x, y, w of the vertices), the
    window point (x, y) has NDC (xn, yn) = (2x/W - 1, 2y/H - 1) and u = M^-1 (xn, yn, 1):
    the perspective-correct weights are u / (u0 + u1 + u2), 1/w = u0 + u1 + u2 and NDC depth
    u . (z0, z1, z2) (homogeneous rasterisation: no division by a vertex's w, so vertices
    behind the eye are fine).  Rows 0-2: u_k = A x + B y + C as (A, B, C, 0); row 3: the
    window depth 0.5 u . z + 0.5 as (A, B, C, polygon offset), the offset ``factor * max(|dz/dx|,
    |dz/dy|) + units * r`` in double with the format's r (d24: 2/(2^24 - 1), as the float32
    run; d32f: 2^(e - 23), e the exponent of the parent's largest |window z|)."""
    p = np.asarray(parent, np.int64)
    n = len(p)
    out = np.zeros((n, 4, 4), np.float64)
    if n == 0:
        return out
    v = np.asarray(clip64, np.float64)[(3 * p)[:, None] + np.arange(3)[None, :]]   # (N, 3, 4)
    x, y, z, w = v[..., 0], v[..., 1], v[..., 2], v[..., 3]
    m = np.stack([x, y, w], axis=1)                                 # (N, 3 rows, 3 vertices)
    cof = np.empty_like(m)                  # the adjugate's transpose, row by row
    for i in range(3):
        for j in range(3):
            r0, r1 = [k for k in range(3) if k != i]
            c0, c1 = [k for k in range(3) if k != j]
            cof[:, i, j] = (-1) ** (i + j) * (m[:, r0, c0] * m[:, r1, c1]
                                              - m[:, r0, c1] * m[:, r1, c0])
    det = np.einsum("nj,nj->n", m[:, 0, :], cof[:, 0, :])
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(det[:, None, None] != 0,
                       np.transpose(cof, (0, 2, 1)) / det[:, None, None], 0.0)
    # a viewport (x0, y0, w, h) inside the target (shadow tiles): NDC 2 (x - x0) / w - 1
    x0, y0, vw, vh = viewport if viewport is not None else (0, 0, width, height)
    a = inv[:, :, 0] * (2.0 / vw)
    b = inv[:, :, 1] * (2.0 / vh)
    c = (inv[:, :, 2] - inv[:, :, 0] * (1.0 + 2.0 * x0 / vw)
         - inv[:, :, 1] * (1.0 + 2.0 * y0 / vh))
    out[:, :3, 0], out[:, :3, 1], out[:, :3, 2] = a, b, c
    zx = 0.5 * np.einsum("nk,nk->n", a, z)
    zy = 0.5 * np.einsum("nk,nk->n", b, z)
    out[:, 3, 0], out[:, 3, 1] = zx, zy
    out[:, 3, 2] = 0.5 * np.einsum("nk,nk->n", c, z) + 0.5
    if polygon_offset is not None:
        factor, units = float(polygon_offset[0]), float(polygon_offset[1])
        if depth_format == "d32f":
            with np.errstate(divide="ignore", invalid="ignore"):
                zmax = np.max(np.abs(0.5 * z / w + 0.5), axis=1)
                e = np.where(zmax > 0, np.floor(np.log2(np.where(zmax > 0, zmax, 1.0))), -126)
            r = np.exp2(np.maximum(e, -126) - 23)
        else:
            r = 2.0 / 16777215.0
        out[:, 3, 3] = factor * np.maximum(np.abs(zx), np.abs(zy)) + units * r
    return out


def select_triangles(tris, index: np.ndarray):
    """The set-up triangles ``index`` names (int indices, in that order): per-triangle arrays
    are indexed; the varyings, which the triangles index, are kept whole."""
    index = np.asarray(index)
    assert index.dtype.kind in "iu", "select_triangles takes triangle indices, not a mask"
    n = tris.count
    changes = {}
    for f in dataclasses.fields(tris):
        if f.name in ("vary", "nverts"):
            continue
        v = getattr(tris, f.name)
        if isinstance(v, np.ndarray) and v.ndim >= 1 and len(v) == n:
            changes[f.name] = cl_setup_device.rows_of(v, index)
        elif isinstance(v, cl_setup_device.DeviceRows):     # stays on the device
            changes[f.name] = v.rows(index)
    return dataclasses.replace(tris, **changes)


class DrawGeometry:
    """Set-up and binning of a ``CLPipeline``'s draws, with its caches: the draws of
    ``plan`` (its passes' programs on ``device``) in ``tile``-pixel tiles."""

    def __init__(self, device: Device, plan: Plan, tile: int):
        self.device = device
        self.plan = plan
        self.tile = tile
        self.f64 = plan.precision == "f64"     # the float64 evaluation
        self.frame_state: Optional[FrameState] = None     # the current frame's (``begin_frame``)
        self.frame: dict = {}          # per frame: set-ups, bins, (triangle, tile) pairs
        self.pending: dict = {}        # per frame: queued vertex work (``prefetch``)
        self.static: dict = {}         # full-screen draws: the same every frame
        self.scene_attrs: dict = {}    # per material filter, for the current scene
        self.meshes: dict = {}         # unit light-volume meshes
        # the per-frame geometry's buffers, reused by the next frames (not the static draws')
        self.pool = cl_context.FramePool(device.ctx)
        self.device_setup = cl_setup_device.DeviceSetup(device.ctx, device.queue, self.pool)
        self.clip_seen: dict = {}      # per draw (cache key): triangles its last set-up clipped
        self.binner = cl_bin.DeviceBinner(device.ctx, device.queue)
        # share set-ups and bins between pass executions (the module docstring)
        self.share = os.environ.get("PIPEGEN_CL_SHARE_SETUP", "1") != "0"
        self.only: Optional[int] = None    # unshared: the pass whose set-up is being made
        self.raster_keys: dict = {}    # (id(pass), width, height) -> ``_raster_key``

    def begin_frame(self, state: FrameState) -> None:
        """A new frame, ``state``: the last frame's set-ups and bins are dropped and their
        buffers recycled (``CLPipeline.render`` finished that frame on the device)."""
        self.frame_state = state
        self.frame = {}
        self.pending = {}
        self.pool.recycle()

    def use_scene(self) -> None:
        self.scene_attrs = {}

    # -- inputs -------------------------------------------------------------------------------
    def mesh(self, volume: str):
        if volume not in self.meshes:
            from pipegen.scene.meshes import light_volume
            mesh = light_volume(volume)
            self.meshes[volume] = (len(mesh), self.device.buffer(f4(mesh)))
        return self.meshes[volume]

    def attributes(self, draw: ir.Draw, light: Optional[int] = None) -> Optional[tuple]:
        """A scene draw's vertex attributes, in its object order (``draws.scene_geometry``;
        a ``shadow_volumes`` draw: light ``light``'s volumes)."""
        material = draws.scene_key(draw, light)
        if material not in self.scene_attrs:
            g = draws.scene_geometry(self.frame_state.scene, draw, light)
            n = g.vertex_count
            if n == 0:
                self.scene_attrs[material] = None
            else:
                flat = np.zeros((n // 3, 4), np.uint32)
                flat[:, 1:3] = draws.triangle_ids(g)             # uvec2(a_ids + 0.5), flat
                layer = getattr(g, "layer", None)          # uint(a_layer + 0.5), flat
                if layer is not None:
                    flat[:, 3] = np.floor(np.asarray(layer, np.float32)[2::3].astype(np.float64)
                                          + 0.5).astype(np.uint32)
                attrs = [self.device.buffer(f4(a)) for a in (g.positions, g.normals, g.albedo,
                                                               g.material)]
                self.scene_attrs[material] = (n, attrs, flat)
        return self.scene_attrs[material]

    # -- per pass -----------------------------------------------------------------------------
    def pass_triangles(self, k: int, p: PassPlan, width: int, height: int, timing: dict,
                       lights: Optional[list], shadow: Optional["ShadowView"] = None,
                       volume: Optional[int] = None):
        """(geometry, tile bins) a pass draws, or None when it draws no triangle.

        Geometry (vertex kernel, clipping and setup, on the device) is cached per frame and
        shared by the passes that draw the same triangles under the same raster state.  A
        light draw sets up every light of its light list at once (culled only where every
        pass sharing the set-up culls the same faces, ``_light_cull``), and each
        pass draws the range of its light(s) (the instances are consecutive in submission
        order), keeping the faces its cull mode keeps: inside a repeat group one set-up
        serves all lights and every pass of the group with the same raster state.  Bins are
        per pass (cached per frame too) and index the shared triangles; for light draws they
        are cut from the (triangle, tile) pairs of all their lights, found once.  Unshared
        (``share`` off), the execution starts from empty caches and draws only its own.
        ``volume``: the light whose shadow volumes a ``shadow_volumes`` draw draws (set up on
        their own, as a shadow-map tile is)."""
        if not self.share:
            self.frame, self.only = {}, k
        if p.draw.kind is ir.DrawKind.LIGHTS:
            return self._light_triangles(k, p, width, height, timing, lights)
        if shadow is not None or volume is not None:   # one light's tile of a shadow map, or
            key = self._own_key(p, width, height, shadow, volume)    # one light's volumes
            if key not in self.frame:
                self._set_up(k, p, width, height, timing, key, None, shadow, volume)
            geo = self.frame[key]
            return None if geo is None else self._bins(geo, self.frame, width, height, timing)
        geo = self._geometry(k, p, width, height, timing, None)
        if geo is None:
            return None
        kept = p.draw.kind is not ir.DrawKind.SCENE and self.share   # the full-screen draw's
        return self._bins(geo, self.static if kept else self.frame, width, height, timing)

    def _light_triangles(self, k: int, p: PassPlan, width: int, height: int, timing: dict,
                         lights: list):
        cache = self.frame
        if len(lights) == 1:
            # a repeat group's next light: its bins were made with the first's (_group_bins),
            # under the geometry and cull mode the first found (deferred: 162 a frame)
            seen = cache.get(("light pass", k, width, height))
            if seen is not None:
                tb = cache.get(("bins", id(seen[0].tris), (int(lights[0]),), seen[1], width,
                                height))
                if tb is not None:
                    return seen[0], tb
        batch = self._light_batch(k, p, lights)
        geo = self._geometry(k, p, width, height, timing, batch)
        if geo is None:
            return None
        ranges = [geo.ranges[int(l)] for l in lights]
        cull = p.state.cull
        if geo.setup_cull != "none":     # culled at set-up: every triangle is drawn
            cull = ir.CullMode.NONE
        elif p.cull_auto:
            key = ("auto", id(geo), tuple(lights))
            sub = cache.get(key)
            if sub is None:
                sel = None
                if tuple(lights) != batch:        # these lights' triangles, in light order
                    sel = np.concatenate([np.arange(a, b) for a, b in ranges]).astype(np.int64)
                sub = cache[key] = self._cull_auto(geo, sel, p, lights)
            return self._bins(sub, cache, width, height, timing)
        key = ("bins", id(geo.tris), tuple(lights), cull.value, width, height)
        tb = cache.get(key)
        if tb is None and p.repeat_group is not None and len(lights) == 1 and len(batch) > 1 \
                and int(lights[0]) in geo.ranges:
            self._group_bins(geo, batch, cull, width, height, timing)
            tb = cache.get(key)
            cache[("light pass", k, width, height)] = (geo, cull.value)
        if tb is None and len(lights) > 1 and cl_bin.enabled():
            self._shared_bins(p, geo, batch, width, height, timing)
            tb = cache.get(key)
        if tb is None:
            t0 = time.perf_counter()
            band = self._band(geo, width, height)
            if cl_bin.enabled():
                subset, n = self._light_subset(geo, lights, batch, cull)
                tb = self._device_bins(geo, subset, width, height, n, self.pool, band)
            else:
                n = int(_drawn(geo, np.array(ranges, np.int64).reshape(-1, 2), cull).sum())
                tri, tile_id, tiles_x, tiles_y = self._pairs(geo, width, height, cull, band)
                if tuple(lights) != batch:       # the pairs of these lights' triangles
                    cut = [np.searchsorted(tri, r) for r in ranges]
                    tri = np.concatenate([tri[a:b] for a, b in cut])
                    tile_id = np.concatenate([tile_id[a:b] for a, b in cut])
                tile_start, tile_tris = bins_from_pairs(tri, tile_id, tiles_x * tiles_y)
                tb = Bins(self.device, tile_start, tile_tris, tiles_x, n, index=geo.index,
                          tile=self.tile, band=band)
            cache[key] = tb
            timing["bin"] = (time.perf_counter() - t0) * 1e3
        return geo, tb

    @staticmethod
    def _light_subset(geo: Geo, lights, batch: tuple, cull: ir.CullMode):
        """(the triangles of ``geo`` a draw of ``lights`` under ``cull`` bins, increasing
        indices or None for all of them; how many)."""
        ranges = [geo.ranges[int(l)] for l in lights]
        n = int(_drawn(geo, np.array(ranges, np.int64).reshape(-1, 2), cull).sum())
        keep = _KEEPS_FRONT.get(cull)
        subset = None
        if tuple(lights) != batch:       # these lights' triangles, in light order
            subset = np.concatenate([np.arange(a, b) for a, b in ranges])
        if keep is not None:
            kept = np.flatnonzero(geo.front == keep)
            subset = kept if subset is None else subset[geo.front[subset] == keep]
        return subset, n

    def _shared_bins(self, p: PassPlan, geo: Geo, batch: tuple, width: int, height: int,
                     timing: dict) -> None:
        """The bins of every pass drawing its light list from set-up ``geo`` (outside repeat
        groups, ``_shared_lights``: LIDR's light-index slots draw four disjoint light sets of
        one set-up; or the members of ``p``'s repeat group drawn in one launch,
        ``group_launch``: deferred's marking and shading of every light, all faces and back
        faces), binned in one device call (``DeviceBinner.bin_segments``) when the first of
        them is prepared, each cached under the key its own pass looks up: three kernels,
        their launches and one read of the tile counts for all of them, instead of per pass
        (the read a pass's raster launch waits for: the later passes find it done)."""
        t0 = time.perf_counter()
        sizes, selection = self.frame_state.pass_sizes, self.frame_state.selection
        raster_key = self._raster_key(p, width, height)
        passes = []          # (lights, cull, key) of each pass to bin, found first: cheap
        for j, q in enumerate(self.plan.passes):
            if q.draw.kind is not ir.DrawKind.LIGHTS or q.repeat_group != p.repeat_group \
                    or q.cull_auto or self.only not in (None, j) or sizes[j] != (width, height) \
                    or self._raster_key(q, width, height) != raster_key:
                continue
            lights = tuple(selection.of(q.draw))
            cull = q.state.cull if geo.setup_cull == "none" else ir.CullMode.NONE
            key = ("bins", id(geo.tris), lights, cull.value, width, height)
            if lights and key not in self.frame and all(k != key for _, _, k in passes):
                passes.append((lights, cull, key))
        if len(passes) < 2:
            return
        passes = [(lights, cull, key) for lights, cull, key in passes
                  if all(int(l) in geo.ranges for l in lights)]
        band = self._band(geo, width, height)
        per_triangle = cl_bin.box_tile_counts(geo.tris.bbox, self.tile, band)
        keys, rows, drawn = [], [], []
        capacity = 0
        for lights, cull, key in passes:
            subset, n = self._light_subset(geo, lights, batch, cull)
            if subset is None:
                subset = np.arange(geo.tris.count)
            if not len(subset):
                continue
            keys.append(key)
            rows.append(subset.astype(np.int32) if geo.index is None else geo.index[subset])
            capacity += int(per_triangle[subset].sum())
            drawn.append(n)
        if len(keys) < 2:
            return
        got = self.binner.bin_segments(geo.bufs, rows, capacity, geo.tris.samples, width,
                                       height, self.tile, drawn, geo.index, self.pool,
                                       tile_h=band)
        self.frame.update(zip(keys, got))
        timing["bin"] = (time.perf_counter() - t0) * 1e3

    def _pairs(self, geo: Geo, width: int, height: int, cull: ir.CullMode,
               band: Optional[int] = None):
        """``bin_pairs`` of the faces of ``geo`` the cull mode keeps (light volumes are set up
        without culling where their passes cull differently: binning only the kept faces
        halves a sphere's pairs), once per frame, cull mode and ``band``."""
        keep = _KEEPS_FRONT.get(cull)
        key = ("pairs", id(geo.tris), width, height, band, keep)
        pairs = self.frame.get(key)
        if pairs is None:
            every = self.frame.get(key[:-1] + (None,))
            if keep is not None and every is not None:
                # the pairs of every face, binned for a pass that culls none, filtered: a
                # triangle's tiles depend on it alone, and both are in triangle order
                # (deferred's shading pass after its marking pass)
                tri, tile_id, tiles_x, tiles_y = every
                kept = geo.front[tri] == keep
                pairs = self.frame[key] = (tri[kept], tile_id[kept], tiles_x, tiles_y)
            else:
                subset = None if keep is None else np.flatnonzero(geo.front == keep)
                pairs = self.frame[key] = bin_pairs(geo.tris, width, height, self.tile,
                                                    subset=subset, tile_h=band)
        return pairs

    def _group_bins(self, geo: Geo, batch: tuple, cull: ir.CullMode, width: int, height: int,
                    timing: dict) -> None:
        """The bins of every light of ``batch`` drawn on its own (``repeat per light``: one pass
        run per light), found in one go and cached under each light's own key: one stable
        sort of the group's (light, tile) entries instead of a sort, a count and a sum per
        light (deferred on many_lights: 162 per frame).  Each light's tile lists hold its
        triangles in submission order, exactly as binning its own pairs gives them."""
        t0 = time.perf_counter()
        band = self._band(geo, width, height)
        tri, tile_id, tiles_x, bands = self._pairs(geo, width, height, cull, band)
        ntiles = tiles_x * bands          # lists: tile_id is a list's (one per band of rows)
        spans = np.array([geo.ranges[int(light)] for light in batch], np.int64).reshape(-1, 2)
        # the light of each pair (pairs are in triangle order, each light a range of them)
        light_pos = np.zeros(len(tri), np.uint16 if len(batch) < 1 << 16 else np.int64)
        for j, (lo, hi) in enumerate(np.searchsorted(tri, spans)):
            light_pos[lo:hi] = j
        # by light, then tile, then submission order: two stable sorts, the less significant
        # key first (both keys are small integers: numpy's radix sort)
        tiles = tile_id.astype(np.uint16) if ntiles < 1 << 16 else tile_id
        order = np.argsort(tiles, kind="stable")
        order = order[np.argsort(light_pos[order], kind="stable")]
        tile_tris = tri[order].astype(np.int32)
        counts = np.bincount(light_pos.astype(np.int64) * ntiles + tile_id,
                             minlength=len(batch) * ntiles).reshape(len(batch), ntiles)
        starts = np.zeros((len(batch), ntiles + 1), np.int32)
        np.cumsum(counts, axis=1, out=starts[:, 1:])
        first = np.concatenate([[0], np.cumsum(starts[:, -1])])
        # one upload of each of the group's arrays, each light's bins views into them
        occupied = cl_bin.tiles_with(counts > 0, tiles_x, self.tile // band)
        group = GroupBins(self.device, starts, first, occupied, tile_tris, geo.index, band)
        drawn = _drawn(geo, spans, cull)
        for j, light in enumerate(batch):
            self.frame[("bins", id(geo.tris), (int(light),), cull.value, width, height)] = \
                group.light(j, tiles_x, int(drawn[j]))
        timing["bin"] = (time.perf_counter() - t0) * 1e3

    def _bins(self, geo: Geo, cache: dict, width: int, height: int, timing: dict):
        """(geo, bins of all its triangles), the bins cached in ``cache`` (built on the
        device unless ``cl_bin.enabled()`` says no).
        The set-up triangles already hold the pass's culling (scene and full-screen draws
        are set up per cull mode, ``cull auto`` light draws filtered per light)."""
        key = ("bins", id(geo.tris), width, height)
        tb = cache.get(key)
        if tb is None:
            t0 = time.perf_counter()
            band = self._band(geo, width, height)
            if cl_bin.enabled():
                tb = self._device_bins(geo, None, width, height, geo.tris.count,
                                       self.pool if cache is self.frame else None, band)
            else:
                tile_start, tile_tris, tiles_x, _ = bin_triangles(geo.tris, width, height,
                                                                  self.tile, tile_h=band)
                tb = Bins(self.device, tile_start, tile_tris, tiles_x, geo.tris.count,
                          index=geo.index, tile=self.tile, band=band)
            cache[key] = tb
            timing["bin"] = (time.perf_counter() - t0) * 1e3
        return geo, tb

    def _band(self, geo: Geo, width: int, height: int) -> int:
        """The height of the tile lists ``geo``'s draws are binned into (``cl_bin.band_for``),
        once per set-up and frame: the device and the numpy binning agree on it."""
        key = ("band", id(geo.tris), width, height)
        band = self.frame.get(key)
        if band is None:
            band = self.frame[key] = cl_bin.band_for(geo.tris.bbox, self.tile, width, height)
        return band

    def _device_bins(self, geo: Geo, subset: Optional[np.ndarray], width: int, height: int,
                     triangles: int, pool, band: Optional[int] = None):
        """Queue the binning of ``geo``'s triangles ``subset`` (increasing indices; None: all)
        on the device (``cl_bin``: ``DeviceBins``; empty ``Bins`` when there is none);
        ``pool``: None for bins kept across frames; ``band``: the bins' height (None: a
        tile's)."""
        tris = geo.tris
        if subset is None:
            rows = np.arange(tris.count, dtype=np.int32) if geo.index is None else geo.index
            bbox = tris.bbox
        else:
            rows = subset.astype(np.int32) if geo.index is None else geo.index[subset]
            bbox = tris.bbox[subset]
        if not len(rows):   # nothing to bin (no zero-sized OpenCL buffers): numpy's empty lists
            tile_start, tile_tris, tiles_x, _ = bin_triangles(tris, width, height,
                                                              self.tile, subset=subset,
                                                              tile_h=band)
            return Bins(self.device, tile_start, tile_tris, tiles_x, triangles, index=geo.index,
                        tile=self.tile, band=band)
        return self.binner.bin(geo.bufs, rows, bbox, tris.samples, width, height,
                               self.tile, triangles, geo.index, pool, tile_h=band)

    def _raster_key(self, p: PassPlan, width: int, height: int) -> tuple:
        """What the set-up triangles of a pass's draw depend on besides its varyings (a
        function of the pass and the size: kept, by the pass's identity, as the plan keeps
        its passes; deferred asked ~330 times a frame, 40 us each)."""
        got = self.raster_keys.get((id(p), width, height))
        if got is None:
            got = self.raster_keys[(id(p), width, height)] = self._make_raster_key(
                p, width, height)
        return got

    def _make_raster_key(self, p: PassPlan, width: int, height: int) -> tuple:
        draw = p.draw
        depth_clamp = p.state.depth.clamp
        dfmt = p.depth_target and self.plan.target(p.depth_target).format.name
        # llvmpipe folds the pixel centre into the planes' a0 unless the pass is multisampled
        center = 0.0 if self.plan.pass_samples(p) > 1 else 0.5
        offset = str(_offset(p))
        if draw.kind is ir.DrawKind.LIGHTS:
            # culling is per pass (``_light_cull``: at set-up where all its passes agree)
            return ("lights", (draw.volume or ir.Volume.SPHERE).value, draw.scissor,
                    offset, depth_clamp, width, height, dfmt, center)
        return (draw.kind.value, draw.material, draw.order, p.state.cull.value, offset,
                depth_clamp, width, height, dfmt, center, draw.shadow_tiles, draw.shadow_volumes)

    def _own_key(self, p: PassPlan, width: int, height: int, shadow: Optional["ShadowView"],
                 volume: Optional[int]) -> tuple:
        """The cache key of a draw set up per light: a shadow-map tile, a light's volumes."""
        own = ("shadow", shadow.light) if shadow is not None else ("volumes", volume)
        return self._raster_key(p, width, height) + own

    def _light_batch(self, k: int, p: PassPlan, lights: list) -> tuple:
        """The lights a light draw of pass ``k`` sets up at once (found once a frame per pass):
        its light list this frame (``selection.of``), or for a pass outside a repeat group the
        lights of every such pass drawing under the same raster key (``_shared_lights``), or
        ``lights`` where they are not all in it."""
        got = self.frame.get(("light list", k))
        if got is None:
            batch = self._shared_lights(k, p) if p.repeat_group is None else None
            batch = batch or tuple(self.frame_state.selection.of(p.draw))
            got = self.frame[("light list", k)] = (batch, frozenset(batch))
        batch, members = got
        return batch if members.issuperset(lights) else tuple(lights)

    def _shared_lights(self, k: int, p: PassPlan) -> Optional[tuple]:
        """The light lists of the passes outside repeat groups that draw lights under pass
        ``k``'s raster key, merged in table order: one set-up for all of them (LIDR's
        light-index slots draw four disjoint light sets of the same spheres: one vertex and
        set-up kernel instead of four), each pass drawing its lights' ranges as a repeat
        group's passes do.  None where a pass's list is not in table order: a set-up's
        triangles must come by increasing light (``_set_up`` finds each light's range by
        bisection) and a pass's own must be an increasing run of them (binning)."""
        sizes, selection = self.frame_state.pass_sizes, self.frame_state.selection
        key = self._raster_key(p, *sizes[k])
        lists = [selection.of(q.draw) for j, q in enumerate(self.plan.passes)
                 if q.draw.kind is ir.DrawKind.LIGHTS and q.repeat_group is None
                 and self.only in (None, j) and self._raster_key(q, *sizes[j]) == key]
        if any(any(a >= b for a, b in zip(own, own[1:])) for own in lists):
            return None
        return tuple(sorted({light for own in lists for light in own}))

    def _scene_group(self, key: tuple) -> tuple:
        """The passes of the plan drawing the scene under raster key ``key`` share one set-up:
        with the union of their varyings (SCENE_VARYINGS order) and the 1/w plane if any of
        them needs it.  Returns (names, flat flags, providers, w_plane); ``providers``: the
        passes whose vertex kernels compute the union (k, [their varying names])."""
        got = self.frame.get(("group", key))
        if got is not None:
            return got
        sizes = self.frame_state.pass_sizes
        got = _scene_union(self.plan, [k for k, q in enumerate(self.plan.passes)
                                       if q.draw.kind is ir.DrawKind.SCENE
                                       and self._raster_key(q, *sizes[k]) == key
                                       and self.only in (None, k)])
        self.frame[("group", key)] = got
        return got

    def vertex_unions(self) -> list[tuple[str, ...]]:
        """The varyings of scene passes that share a set-up at any one size (their raster keys
        alike but for it) where no one pass's vertex kernel computes them all: what
        ``_vertices`` runs one vertex kernel for (``Device.scene_vertex_kernel``), for the
        pipeline to build with its programs.  A frame whose sizes split such passes
        differently builds its union when it first meets it."""
        groups: dict = {}
        for k, q in enumerate(self.plan.passes):
            if q.draw.kind is ir.DrawKind.SCENE and \
                    cl_setup_device.supports(_offset(q), self.f64):
                groups.setdefault(self._make_raster_key(q, 1, 1), []).append(k)
        out = []
        for ks in groups.values():
            names, _, providers, _ = _scene_union(self.plan, ks)
            if len(providers) > 1:
                out.append(tuple(names))
        return out

    def _light_cull(self, key: tuple) -> str:
        """The cull mode a light draw's set-up (raster key ``key``) can apply: that of every
        pass of the plan drawing lights under that key when they all cull alike (the light
        pre-pass's spheres: their front faces, half the triangles, dropped before binning;
        ``auto``: each light's faces as ``draws.light_runs`` chooses, the same for every pass
        with the key), else none (each pass culls its own)."""
        got = self.frame.get(("light cull", key))
        if got is None:
            sizes = self.frame_state.pass_sizes
            modes = {q.state.cull for k, q in enumerate(self.plan.passes)
                     if q.draw.kind is ir.DrawKind.LIGHTS and self.only in (None, k)
                     and self._raster_key(q, *sizes[k]) == key}
            mode = modes.pop() if len(modes) == 1 else None
            got = mode.value if mode in (ir.CullMode.BACK, ir.CullMode.FRONT,
                                         ir.CullMode.AUTO) else "none"
            self.frame[("light cull", key)] = got
        return got

    def _inside_bits(self, p: PassPlan, lights: np.ndarray) -> np.ndarray:
        """Per light of a ``cull auto`` draw, 4 (the set-up's flat bit 2) where it is drawn
        with its back faces, else 0 (``draws.auto_inside``, as the GL runtime draws it)."""
        scene = self.frame_state.scene
        inside = draws.auto_inside(p.draw.volume, list(scene.lights), lights.tolist(),
                                   scene.camera.position, self.frame_state.proj)
        return np.array([4 if inside[int(i)] else 0 for i in lights], np.uint32)

    def _geometry(self, k: int, p: PassPlan, width: int, height: int, timing: dict,
                  lights: Optional[tuple]):
        """Vertex kernel, clipping and setup of a pass's draw (``lights``: every light a light
        draw sets up); cached per frame.  Scene draws are set up once for every pass drawing
        them under the same raster state (``_scene_group``); a pass reading fewer varyings
        gets its own varying and plane buffers cut from the shared ones."""
        kind = p.draw.kind
        key = self._raster_key(p, width, height)
        if kind is ir.DrawKind.LIGHTS:
            key = key + (lights,)
        elif kind is ir.DrawKind.SCENE:
            names = [v["name"] for v in cl_abi.varying_slots(p)]
            pkey = key + (tuple(names),)
            if pkey in self.frame:
                return self.frame[pkey]
            base = self.frame.get(key, False)
            if base is False:
                base = self._set_up(k, p, width, height, timing, key, lights)
            geo = base if base is None else self._cut(base, names)
            self.frame[pkey] = geo
            return geo
        if key in self.frame:
            return self.frame[key]
        if kind is ir.DrawKind.LIGHTS or not self.share:
            return self._set_up(k, p, width, height, timing, key, lights)
        # the full-screen triangle depends on nothing of the frame: kept across frames, in
        # buffers of its own (never recycled)
        if key not in self.static:
            self.pool.enabled = False
            try:
                self.static[key] = self._set_up(k, p, width, height, timing, key, lights)
            finally:
                self.pool.enabled = True
        geo = self.frame[key] = self.static[key]
        return geo

    def _cut(self, geo: Geo, names: list) -> Geo:
        """The shared scene set-up ``geo`` as a pass reading varyings ``names`` sees it: its
        varyings in slot order (only the flat ones are read from ``vary``) and the planes of
        its smooth ones."""
        if names == geo.names:
            return geo
        if not names:
            return geo          # reads no varying: nothing indexes vary or coef
        import pyopencl as cl
        queue = self.device.queue
        tris = geo.tris
        flat = dict(zip(geo.names, geo.flats))
        pos = {n: i for i, n in enumerate(geo.names)}
        smooth_pos = {n: i for i, n in enumerate(n for n in geo.names if not flat[n])}
        sel = [smooth_pos[n] for n in names if not flat[n]]
        # copied on the device: the flat varyings' slots (the smooth ones are not read from
        # vary), and the smooth ones' planes, column by column of the (rows, K, 3, 4) array
        nv = tris.nverts
        vary = self.pool.buffer(len(names) * nv * 16)
        for i, n in enumerate(names):
            if flat[n]:
                cl.enqueue_copy(queue, vary, geo.bufs["vary"], byte_count=nv * 16,
                                src_offset=pos[n] * nv * 16, dst_offset=i * nv * 16)
        K, plane = geo.ncoef, 3 * 16
        rows = len(tris.coef) if geo.index is None or not len(geo.index) \
            else int(geo.index.max()) + 1
        coef = self.pool.buffer(rows * len(sel) * plane)
        for j, col in enumerate(sel):
            if rows:
                cl.enqueue_copy(queue, coef, geo.bufs["coef"], src_origin=(col * plane, 0),
                                dst_origin=(j * plane, 0), region=(plane, rows),
                                src_pitches=(K * plane,), dst_pitches=(len(sel) * plane,))
        cut = Geo(tris, dict(geo.bufs, vary=vary, coef=coef), geo.index)
        cut.ncoef = len(sel)
        cut.names = list(names)
        return cut

    def prefetch(self, k: int, p: PassPlan, width: int, height: int,
                 lights: Optional[list], shadow: Optional["ShadowView"] = None,
                 volume: Optional[int] = None) -> None:
        """Queue the vertex kernels (and non-blocking read-backs) of the set-up pass ``k``
        will need, unless this frame has it already.  ``CLPipeline.render`` calls this for
        every pass execution of the frame before queueing any raster kernel: on an in-order
        queue a pass's vertex read-back would otherwise wait behind the raster kernels of
        the passes before it, and the host would sit idle while the device rasterises
        (deferred_calver at 640x360: 14 ms of a 73 ms frame).  Full-screen draws are kept
        across frames and need none; nor does an unshared pass (``share`` off), which queues
        its own when it runs."""
        if not self.share:
            return
        kind = p.draw.kind
        key = self._raster_key(p, width, height)
        if kind is ir.DrawKind.LIGHTS:
            batch = self._light_batch(k, p, lights)
            key, lights = key + (batch,), batch
        elif shadow is not None or volume is not None:
            key = self._own_key(p, width, height, shadow, volume)
        elif kind is not ir.DrawKind.SCENE:
            return
        if key not in self.frame and key not in self.pending:
            self.pending[key] = self._vertices(k, p, width, height, key, lights, shadow, volume)

    def clip_pending(self) -> None:
        """Queue the clipping of every prefetched device set-up (``DeviceSetup.clip``: it waits
        for the set-up's status; done already for a set-up that was followed by another),
        before any raster kernel.  Each set-up is clipped before the next set-up is queued
        (``_vertices``), so that a first pass's bins can be queued while the device still sets
        up the others, instead of after all of them and the host's wait for the last."""
        for v in self.pending.values():
            if v is not None and v.job is not None:
                self.device_setup.clip(v.job)

    def _vertices(self, k: int, p: PassPlan, width: int, height: int, key: tuple,
                  lights: Optional[tuple], shadow: Optional["ShadowView"],
                  volume: Optional[int] = None):
        """Queue the vertex kernel(s) of a draw and the read-back of clip positions and
        varyings (not waited for): a ``_Vertices``, or None when the draw has no vertex."""
        import pyopencl as cl
        dev, frame_state = self.device, self.frame_state
        draw = p.draw
        v = _Vertices()
        v.names, v.flats, providers = [], [], [(k, [])]
        v.flat = v.scissor = None
        if shadow is not None or volume is not None:     # depth or stencil only: no varyings
            v.w_plane = False
            v.cull = p.state.cull.value
        elif draw.kind is ir.DrawKind.SCENE:
            v.names, v.flats, providers, v.w_plane = self._scene_group(key)
            providers = providers or [(k, [])]
            v.cull = p.state.cull.value
        else:
            # light volumes and the full-screen triangle have no varyings; their 1/w plane
            # (frag_coord.w) is set up always, so that every pass drawing them shares one
            # set-up (light draws are culled per pass, or at set-up where all cull alike)
            v.w_plane = True
            v.cull = (self._light_cull(key[:-1]) if draw.kind is ir.DrawKind.LIGHTS
                      else p.state.cull.value)
        mesh_verts = 1
        zeros = dev.zeros4
        attrs = [zeros] * 4
        v.inst = np.zeros(1, np.uint32)
        if draw.kind is ir.DrawKind.SCENE:
            got = self.attributes(draw, volume)
            if got is None:
                return None
            nverts, attrs, v.flat = got
            if shadow is not None:      # the tile: its viewport, and a scissor on it
                x, y, w, h = shadow.rect
                v.scissor = np.tile(np.array([x, y, x + w, y + h], np.int32), (nverts // 3, 1))
        elif draw.kind is ir.DrawKind.LIGHTS:
            mesh_verts, mesh_buf = self.mesh((draw.volume or ir.Volume.SPHERE).value)
            nverts = mesh_verts * len(lights)
            attrs = [mesh_buf] + [zeros] * 3
            v.inst = np.asarray(lights, np.uint32)
            v.flat = np.zeros((nverts // 3, 4), np.uint32)
            v.flat[:, 3] = np.repeat(v.inst, mesh_verts // 3)
            if v.cull == "auto":        # which lights the set-up keeps the back faces of
                v.flat[:, 0] = np.repeat(self._inside_bits(p, v.inst), mesh_verts // 3)
            if draw.scissor:
                v.scissor = self._light_scissors(v.inst, width, height, mesh_verts // 3)
        else:
            nverts = 3
        inst_buf = dev.buffer(v.inst)
        frame_buf = frame_state.frame_buf if shadow is None else shadow.frame_buf
        frame64_buf = frame_state.frame64_buf if shadow is None else shadow.frame64_buf
        v.nverts = nverts
        # set up on the device (``cl_setup_device``): the clip positions and varyings stay
        # there, nothing is read back; else the host copies the numpy set-up takes
        on_device = cl_setup_device.supports(_offset(p), self.f64)
        # on the device, each varying slot leaves room for the clipper's vertices after the
        # draw's own, as many as this draw's last frame made (the clipper appends them in
        # place instead of copying every slot: inferred's scene pass, 42,834 vertices a
        # slot, 1.3 ms of device time in a profiled frame at 160x90); a frame that needs more
        # copies as before
        v.vstride = nverts + (cl_setup_device.clip_room(self.clip_seen.get(key, 0))
                              if on_device and v.names else 0)
        v.clip = v.clip64 = v.vary = None
        if not on_device:
            v.clip = np.empty((nverts, 4), np.float32)
            v.clip64 = np.empty((nverts, 4), np.float64) if self.f64 else None
            v.vary = np.empty((len(v.names), nverts, 4), np.float32) if v.names else None
        v.vary_buf = None
        v.kernels, v.copies, v.outs, v.vbufs = [], [], [], []
        clip_bufs = []
        if on_device and len(providers) > 1:
            # one vertex kernel for the union of the passes' varyings: each pass's own would
            # compute the clip positions again and its varyings be copied into one buffer
            # (light pre-pass: a vertex kernel and four copies a frame, 0.45 ms at 160x90)
            providers = [(None, list(v.names))]
        for i, (kp, have) in enumerate(providers):
            S = len(have)
            clip_buf = self.pool.buffer(nverts * 16)
            clip_bufs.append(clip_buf)
            vbuf = self.pool.buffer(S * v.vstride * 16)
            kern = dev.kernel(kp, "pg_vertex") if kp is not None else \
                dev.scene_vertex_kernel(tuple(have))
            extra = []
            if self.f64:      # the float64 evaluation: clip positions in double too
                clip64_buf = self.pool.buffer(nverts * 32)
                extra = [frame64_buf, clip64_buf]
            # one kernel object per pass is shared by every draw it provides for: it is
            # enqueued (which takes the arguments) before the next draw sets them
            cl_context.set_args(kern, np.int32(nverts), np.int32(mesh_verts),
                                np.int32(v.vstride), *attrs, inst_buf,
                                frame_buf, frame_state.lights_buf, clip_buf, vbuf, *extra)
            gsize = ((nverts + 63) // 64) * 64
            v.kernels.append(cl.enqueue_nd_range_kernel(dev.queue, kern, (gsize,), (64,)))
            if i == 0 and not on_device:
                v.copies.append(cl.enqueue_copy(dev.queue, v.clip, clip_buf, is_blocking=False))
                if self.f64:
                    v.copies.append(cl.enqueue_copy(dev.queue, v.clip64, clip64_buf,
                                                    is_blocking=False))
            if S:
                out = None
                if not on_device:
                    out = np.empty((S, nverts, 4), np.float32)
                    v.copies.append(cl.enqueue_copy(dev.queue, out, vbuf, is_blocking=False))
                v.outs.append((have, out))
                v.vbufs.append(vbuf)
                if have == v.names:
                    v.vary_buf = vbuf
        if v.vary_buf is None and v.names:
            # several passes' vertex kernels made the varyings: gather them into one buffer on
            # the device (slot-major, as the set-up and raster kernels read them)
            stride = v.vstride
            v.vary_buf = self.pool.buffer(len(v.names) * stride * 16)
            done = set()
            for (have, _), vbuf in zip(v.outs, v.vbufs):
                for i, n in enumerate(have):
                    if n in v.names and n not in done:
                        done.add(n)
                        cl.enqueue_copy(dev.queue, v.vary_buf, vbuf, byte_count=nverts * 16,
                                        src_offset=i * stride * 16,
                                        dst_offset=v.names.index(n) * stride * 16)
        v.job = None
        if on_device:     # queued behind the vertex kernels
            center = 0.0 if self.plan.pass_samples(p) > 1 else 0.5
            v.job = self.device_setup.enqueue(
                clip_bufs[0], v.vary_buf, nverts // 3, nverts, width, height, cull=v.cull,
                depth_clamp=p.state.depth.clamp, flat=v.flat, scissor=v.scissor,
                samples=_box_samples(center),
                smooth=tuple(i for i, f in enumerate(v.flats) if not f), pixel_center=center,
                w_plane=v.w_plane, viewport=None if shadow is None else shadow.rect,
                with_zq=center == 0.0, slots=len(v.names), stride=v.vstride,
                # the set-ups queued before this one clipped first (``clip_pending``: it waits
                # for their statuses while the device runs them and this draw's vertex
                # kernels), once this one's host work is done: their clippers then run before
                # this set-up, not after every set-up of the frame
                before_queue=self.clip_pending)
        return v

    def _set_up(self, k: int, p: PassPlan, width: int, height: int, timing: dict, key: tuple,
                lights: Optional[tuple], shadow: Optional["ShadowView"] = None,
                volume: Optional[int] = None):
        """Wait for the draw's vertices (queued by ``prefetch``, or now), clip and set up on
        the host, upload the triangles (cached under ``key``; None: nothing to draw)."""
        v = self.pending.pop(key, False)
        if v is False:
            v = self._vertices(k, p, width, height, key, lights, shadow, volume)
        if v is None:
            self.frame[key] = None
            return None
        for ev in v.copies + v.kernels:
            ev.wait()
        if v.job is None:
            for have, out in v.outs:
                for i, n in enumerate(have):
                    if n in v.names:
                        v.vary[v.names.index(n)] = out[i]
        timing["vertex"] = sum((ev.profile.end - ev.profile.start) * 1e-6 for ev in v.kernels)
        dfmt = p.depth_target and self.plan.target(p.depth_target).format.name
        center = 0.0 if self.plan.pass_samples(p) > 1 else 0.5
        viewport = None if shadow is None else shadow.rect
        t0 = time.perf_counter()
        dev = None
        if v.job is not None:
            tris, dev, index = self.device_setup.finish(v.job)
            if len(self.clip_seen) > 4096:      # draws of scenes long gone (sweeps)
                self.clip_seen.clear()
            self.clip_seen[key] = len(v.job.clipping["hard"])
        else:
            tris = setup_triangles(v.clip, width, height, cull=v.cull, polygon_offset=_offset(p),
                                   depth_clamp=p.state.depth.clamp, depth_format=dfmt,
                                   flat=v.flat, vary=v.vary, scissor=v.scissor,
                                   samples=_box_samples(center),
                                   smooth=[i for i, f in enumerate(v.flats) if not f],
                                   pixel_center=center, w_plane=v.w_plane, viewport=viewport,
                                   with_zp=self.f64, with_zq=self.f64 or center == 0.0)
        if self.f64:
            tris.h = homogeneous_planes(v.clip64, tris.parent, width, height, _offset(p), dfmt,
                                        viewport)
        timing["setup"] = (time.perf_counter() - t0) * 1e3
        if tris.count == 0:
            self.frame[key] = None
            return None
        vary_buf = v.vary_buf
        if dev is not None and "vary" in dev:     # with the device clipper's vertices
            vary_buf = dev.pop("vary")
        elif tris.vary is None:
            vary_buf = self.device.zeros4
        elif vary_buf is None:
            vary_buf = self.device.buffer(tris.vary)
        elif tris.vary.shape[1] != v.vstride:     # the clipper's new vertices appended
            vary_buf = self._grown_varyings(vary_buf, tris.vary, v.nverts, v.vstride)
        if dev is None:
            geo = self._upload(tris, vary_buf)
        else:       # the device set-up's buffers, rows through ``index``
            none = self.device.dummy
            geo = Geo(tris, dict(dev, zp=none, zq=dev.get("zq", none), vary=vary_buf), index)
        self.frame[key] = geo
        geo.names, geo.flats = v.names, v.flats
        geo.setup_cull = v.cull
        if p.draw.kind is ir.DrawKind.LIGHTS:
            light_of = tris.flat[:, 3]
            lo = np.searchsorted(light_of, v.inst, "left")
            hi = np.searchsorted(light_of, v.inst, "right")
            geo.ranges = {int(l): (int(a), int(b)) for l, a, b in zip(v.inst, lo, hi)}
        return geo

    def _grown_varyings(self, buf, vary: np.ndarray, nverts: int, stride: int):
        """The device varyings ``buf`` (slot-major, ``nverts`` vertices a slot, ``stride``
        apart) with the vertices ``vary`` has after them (the clipper's): each slot copied on
        the device, the new vertices written from the host, instead of uploading all of
        ``vary``."""
        import pyopencl as cl
        queue = self.device.queue
        S, total = vary.shape[:2]
        grown = self.pool.buffer(S * total * 16)
        new = np.ascontiguousarray(vary[:, nverts:])
        for k in range(S):
            cl.enqueue_copy(queue, grown, buf, byte_count=nverts * 16,
                            src_offset=k * stride * 16, dst_offset=k * total * 16)
            write(queue, grown, new[k], dst_offset=(k * total + nverts) * 16)
        return grown

    def _upload(self, tris, vary_buf) -> Geo:
        buf = self.device.buffer
        # zp and zq are only set up where read (``_set_up``: zq for multisampled passes, whose
        # raster kernel reads zq.z; no kernel reads zp): a placeholder buffer otherwise
        none = self.device.dummy
        bufs = {"a": buf(tris.a), "b": buf(tris.b), "c": buf(tris.c), "z": buf(tris.z),
                "w": buf(tris.w), "coef": buf(tris.coef),
                "zp": none if tris.zp is None else buf(tris.zp),
                "zq": none if tris.zq is None else buf(tris.zq),
                "flat": buf(tris.flat), "vtx": buf(tris.vtx),
                "scissor": buf(tris.scissor), "bbox": buf(tris.bbox), "vary": vary_buf}
        if tris.h is not None:       # the float64 evaluation's planes and parent triangles
            bufs["h"] = buf(np.ascontiguousarray(tris.h))
            bufs["parent"] = buf(np.asarray(tris.parent, np.int32))
        return Geo(tris, bufs)

    def _cull_auto(self, geo: Geo, sel: Optional[np.ndarray], p: PassPlan,
                   lights: list) -> Geo:
        """``cull auto``: of ``geo``'s triangles ``sel`` (None: all), keep each light's front
        or back faces as ``draws.light_runs`` chooses (the GL runtime draws the same runs).
        Filtering the set-up triangles keeps their submission order, so per pixel the lights
        still arrive in light order.  The result shares ``geo``'s device buffers (its triangles
        are rows of them) but for the facing words, which it changes."""
        scene = self.frame_state.scene
        inside = draws.auto_inside(p.draw.volume, list(scene.lights), lights,
                                   scene.camera.position, self.frame_state.proj)
        draw_front = np.zeros(max(lights) + 1, bool)
        for i, back in inside.items():
            draw_front[i] = not back        # culling back faces: front drawn
        flat = geo.tris.flat if sel is None else geo.tris.flat[sel]
        front = (flat[:, 0] & 1).astype(bool)
        by_front = draw_front[flat[:, 3]]
        keep = np.flatnonzero(front == by_front)
        chosen = keep if sel is None else sel[keep]
        tris = select_triangles(geo.tris, chosen)
        # bit 1 of flat.x: a light drawn with its back faces (`pg_inside`, `depth … inside`)
        tris.flat[:, 0] |= np.where(by_front[keep], 0, 2).astype(np.uint32)
        rows = chosen.astype(np.int32) if geo.index is None else geo.index[chosen]
        flat_rows = np.zeros((int(rows.max()) + 1 if len(rows) else 1, 4), np.uint32)
        flat_rows[rows] = tris.flat
        sub = Geo(tris, dict(geo.bufs, flat=self.device.buffer(flat_rows)), rows)
        sub.ncoef = geo.ncoef
        return sub

    def _light_scissors(self, lights: np.ndarray, width: int, height: int, tris_per: int):
        """Per-triangle scissor rectangles (x0, y0, x1, y1) of each light's screen rectangle."""
        fs = self.frame_state
        rects = draws.scissor_rects([fs.scene.lights[int(i)] for i in lights], fs.view, fs.proj,
                                    width, height)
        rects[:, 2:] += rects[:, :2]
        return np.repeat(rects.astype(np.int32), tris_per, axis=0)


# the facing a cull mode keeps (front: True); none or auto cull nothing per pass here
_KEEPS_FRONT = {ir.CullMode.BACK: True, ir.CullMode.FRONT: False}


def _drawn(geo: Geo, spans: np.ndarray, cull: ir.CullMode) -> np.ndarray:
    """Per (start, end) triangle range of ``geo``, how many triangles the cull mode keeps."""
    drawn = spans[:, 1] - spans[:, 0]
    keep = _KEEPS_FRONT.get(cull)
    if keep is None:
        return drawn
    fronts = geo.fronts_before()
    front = fronts[spans[:, 1]] - fronts[spans[:, 0]]
    return front if keep else drawn - front


def _box_samples(center: float) -> Optional[int]:
    """The samples per pixel a set-up's boxes are for: 1 for the single-sampled passes (pixel
    centre 0.5: the raster key keeps them apart), whose boxes then hold pixel centres and whose
    small triangles covering none are dropped (``abi.SMALL_BOX``); None for the multisampled
    ones, which share a set-up whatever their sample count (any sample position)."""
    return 1 if center == 0.5 else None


def _offset(p: PassPlan):
    """The pass's polygon offset as ``setup_triangles`` takes it: [factor, units] or None."""
    o = p.state.polygon_offset
    return None if o is None else [o.factor, o.units]
