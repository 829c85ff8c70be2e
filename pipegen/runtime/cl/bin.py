"""Binning set-up triangles into screen tiles on the OpenCL device.

``cl_setup.bin_pairs`` and ``bins_from_pairs`` in numpy cost ~0.2 us a triangle in a dozen
passes over small arrays (light_prepass at 640x360: its 7,022 scene and 14,009 light-volume
triangles 3-4 ms a frame, on the host before the first raster kernel, with the edge tests'
rows of the set-up read back for them), while per triangle binning is a loop over its box's
tiles.  ``templates/cl_bin.cl.j2`` runs that loop where the set-up triangles already are, and
gives the same tile lists: the same (triangle, tile) pairs, each tile's triangles in
submission order (tests/test_cl_bin.py compares them with the numpy binning's).

``DeviceBinner(ctx, queue).bin(...)`` queues the kernels and a read of two numbers (the tiles
with triangles, the entries), and returns ``DeviceBins``: the host reads them when it
launches the raster kernel, which needs the number of tiles (on PoCL 3.0 the read itself
waits for the queue: ``transfers``'s docstring).  ``$PIPEGEN_CL_DEVICE_BIN=0``
bins every draw in numpy instead, for comparisons.
"""

from __future__ import annotations

import os
from typing import Optional

import numpy as np

from pipegen.backends.opencl import programs as cl_programs
from pipegen.backends.opencl.abi import SUBPIXEL
from pipegen.runtime.cl import context as cl_context
from pipegen.runtime.cl.setup import edge_test_lists

__all__ = ["DeviceBinner", "DeviceBins", "band_for", "box_tile_counts", "box_tiles", "enabled",
           "tiles_with"]

_PER_RUN = 1024        # triangles a work-item bins, at most 8 work-items (PoCL: 2 threads)
_RUNS = 8


def _runs(n: int) -> int:
    """The work-items (runs of consecutive triangles) binning ``n`` triangles."""
    return max(1, min(_RUNS, (n + _PER_RUN - 1) // _PER_RUN))


def enabled() -> bool:
    """Whether draws are binned on the device (``$PIPEGEN_CL_DEVICE_BIN=0``: in numpy)."""
    return os.environ.get("PIPEGEN_CL_DEVICE_BIN", "1") != "0"


def box_tiles(bbox: np.ndarray, tile: int, tile_h: Optional[int] = None) -> int:
    """The tiles (``tile`` wide, ``tile_h`` tall: default ``tile``) the boxes (N, 4:
    inclusive x0, y0, x1, y1) cover, summed: at least the entries binning makes (the edge
    tests drop some)."""
    x, y = _box_spans(bbox, tile, tile_h)
    return int(np.dot(x.astype(np.int64), y))


def box_tile_counts(bbox: np.ndarray, tile: int, tile_h: Optional[int] = None) -> np.ndarray:
    """``box_tiles`` per box (N,): summed over a subset, that subset's bound."""
    x, y = _box_spans(bbox, tile, tile_h)
    return x * y


def _box_spans(bbox: np.ndarray, tile: int, tile_h: Optional[int]) -> tuple:
    """The tiles each box spans across and down."""
    bbox = np.asarray(bbox)
    t = bbox // tile                      # one int32 pass (an int64 copy first: 8x slower)
    y = t if tile_h is None or tile_h == tile else bbox if tile_h == 1 else bbox // tile_h
    return t[:, 2] - t[:, 0] + 1, y[:, 3] - y[:, 1] + 1


# what binning costs, in raster kernel box tests (of a triangle against a tile row): an entry
# (triangle, list) counted and written, and a list's count per run of triangles (zeroed,
# summed by the one work-item of pg_bin_starts).  Fitted to the wall time a frame of
# deferred and light pre-pass on many_lights took at 160x90 (lists a row tall fastest, by
# 10%) and 1280x720 (4 rows: a row 6-10% slower than 4 or 16)
ENTRY_COST = 0.5
LIST_COST = 0.5


def band_for(bbox: np.ndarray, tile: int, width: int, height: int) -> int:
    """The lists' height in rows for binning triangles with boxes ``bbox`` (N, 4: inclusive
    x0, y0, x1, y1) into ``tile``-wide lists for a ``width`` x ``height`` pass: a divisor of
    ``tile``.

    Each work-item of a raster kernel draws one tile row, walking its list and testing each
    triangle's box against its row.  With one list per tile every row of the tile walks every
    triangle of the tile, and a light volume at a small size is many triangles a few rows tall
    (deferred on many_lights at 160x90: 25,920, 3 rows on average): each row rejected nearly
    all of them (0.8 million box tests a frame against 130,000 entries with a list per row;
    its fused light kernel 5.0 -> 3.7 ms).  But a list per row bins a tall triangle once per
    row, and a large pass has many lists.  A triangle h + 1 rows tall is in about h / b + 1
    lists b rows tall and tested in h + b rows: the height chosen minimises, for the boxes'
    mean h and N triangles, (h + b) + ENTRY_COST (h / b + 1) + LIST_COST lists(b) / N."""
    n = len(bbox)
    if not n:
        return tile
    bbox = np.asarray(bbox)
    h = int(np.add.reduce(bbox[:, 3] - bbox[:, 1], dtype=np.int64)) / n
    runs = _runs(n)
    lists = runs * -(-width // tile)

    def cost(b: int) -> float:
        return (h + b) + ENTRY_COST * (h / b + 1) + LIST_COST * lists * -(-height // b) / n
    return min((b for b in range(1, tile + 1) if tile % b == 0), key=cost)


def tiles_with(has: np.ndarray, tiles_x: int, per_tile: int) -> np.ndarray:
    """Whether each tile has triangles (``(..., ntiles)`` bool), from whether each of its
    lists has (``has``, ``(..., nlists)``: ``per_tile`` lists a tile, row-major by band of
    rows; the last tile row may have fewer)."""
    if per_tile == 1:
        return has
    rows = has.reshape(has.shape[:-1] + (-1, tiles_x))
    pad = -rows.shape[-2] % per_tile
    if pad:
        rows = np.concatenate([rows, np.zeros(rows.shape[:-2] + (pad, tiles_x), bool)], -2)
    bands = rows.reshape(rows.shape[:-2] + (-1, per_tile, tiles_x))
    return bands.any(axis=-2).reshape(has.shape[:-1] + (-1,))


def _shift(n: int) -> int:
    """log2(n) where n is a power of two, else -1 (the kernels divide instead)."""
    return n.bit_length() - 1 if n & (n - 1) == 0 else -1


class DeviceBins:
    """A pass's tile lists built on the device: ``tile_list`` (the tiles with triangles, one
    work-group each), ``tile_start``/``tile_tris`` (CSR, rows of the geometry's buffers), as
    ``cl_geometry.Bins`` has them; ``ntiles`` and ``entries`` wait for the binning.  One of
    the segments of a ``DeviceBinner.bin_segments`` call: its starts hold absolute offsets
    into the call's one ``tile_tris``, its summary is ``summary[2 seg: 2 seg + 2]``."""

    def __init__(self, queue, tiles_x: int, triangles: int, tile_list, tile_start, tile_tris,
                 summary: np.ndarray, event, index: Optional[np.ndarray], ntiles_all: int,
                 band: int, seg: int = 0):
        self.queue = queue
        self.tiles_x = tiles_x
        self.triangles = triangles
        self.tile_list, self.tile_start, self.tile_tris = tile_list, tile_start, tile_tris
        self._summary, self._event = summary, event
        self._index = index
        self._ntiles_all = ntiles_all
        self.band = band              # the lists' rows: tiles_x lists per band of rows
        self._seg = seg

    def _counts(self) -> np.ndarray:
        if self._event is not None:
            self._event.wait()
            self._event = None
        return self._summary

    @property
    def ntiles(self) -> int:
        return int(self._counts()[2 * self._seg])

    @property
    def entries(self) -> int:
        return int(self._counts()[2 * self._seg + 1])

    @property
    def host(self) -> tuple:
        """(tiles with triangles, tile_start, tile_tris as triangle indices), read back (tests
        compare them with the numpy binning's ``Bins.host``)."""
        import pyopencl as cl
        n, m = self.ntiles, self.entries
        active = np.empty(max(n, 1), np.int32)
        start = np.empty(self._ntiles_all + 1, np.int32)
        cl.enqueue_copy(self.queue, active, self.tile_list)
        cl.enqueue_copy(self.queue, start, self.tile_start)
        base = int(start[0])
        rows = np.empty(max(base + m, 1), np.int32)
        cl.enqueue_copy(self.queue, rows, self.tile_tris)
        start = start - base
        tris = rows[base:base + m]
        if self._index is not None and len(self._index):
            triangle_of = np.full(int(self._index.max()) + 1, -1, np.int32)
            triangle_of[self._index] = np.arange(len(self._index), dtype=np.int32)
            tris = triangle_of[tris]
        return active[:n], start, tris if m else np.zeros(1, np.int32)


class DeviceBinner:
    """Queues ``cl_bin.cl.j2``'s kernels (built once) for a draw's triangles."""

    def __init__(self, ctx, queue):
        self.ctx, self.queue = ctx, queue
        self._kernels = None

    def _kernels_once(self):
        import pyopencl as cl
        if self._kernels is None:
            self._no_segments = cl.Buffer(self.ctx, cl.mem_flags.READ_ONLY, size=16)
            prog = cl_context.build_program(cl_programs.bin_program())
            self._kernels = tuple(cl.Kernel(prog, name) for name in
                                  ("pg_bin_count", "pg_bin_starts", "pg_bin_write"))
        return self._kernels

    def bin(self, bufs: dict, rows: np.ndarray, bbox: np.ndarray, samples: Optional[int],
            width: int, height: int, tile: int, triangles: int,
            index: Optional[np.ndarray] = None, pool=None, edge_test_tiles: int = 4,
            tile_h: Optional[int] = None) -> DeviceBins:
        """Queue the binning of the triangles in buffer rows ``rows`` (int32, submission
        order; ``bbox``: their boxes on the host, to size the lists) of the set-up buffers
        ``bufs`` (``a``, ``b``, ``c``, ``bbox``) for a ``width`` x ``height`` pass with
        ``samples`` per pixel (None: any); ``index``: the row of each triangle of the
        geometry (``host`` maps rows back through it).  ``pool``: a ``FramePool`` for bins
        that last one frame (None: buffers of their own).  ``tile_h``: the tiles' height
        (default ``tile``: square tiles)."""
        return self.bin_segments(bufs, [rows], box_tiles(bbox, tile, tile_h), samples, width,
                                 height, tile, [triangles], index, pool, edge_test_tiles,
                                 tile_h)[0]

    def bin_segments(self, bufs: dict, rows: list, capacity: int, samples: Optional[int],
                     width: int, height: int, tile: int, triangles: list,
                     index: Optional[np.ndarray] = None, pool=None,
                     edge_test_tiles: int = 4, tile_h: Optional[int] = None) -> list:
        """``bin`` of several passes' triangles of one set-up at once (``rows[s]`` and
        ``triangles[s]`` for pass s; ``capacity``: the entries the lists must hold, at least
        their boxes' ``box_tiles``): three kernels and one read for all of them, each pass's
        ``DeviceBins`` views (sub-buffers) of the call's buffers."""
        import pyopencl as cl
        mf = cl.mem_flags
        count_k, starts_k, write_k = self._kernels_once()
        th = tile if tile_h is None else tile_h
        assert tile % th == 0, (tile, th)
        nseg = len(rows)
        tiles_x = (width + tile - 1) // tile
        ntiles = tiles_x * ((height + th - 1) // th)
        tiles = tiles_x * -(-height // tile)
        if nseg == 1:           # the kernels read no segment starts
            n, seg_buf = len(rows[0]), self._no_segments
        else:
            seg_start = np.zeros(nseg + 1, np.int32)
            np.cumsum([len(r) for r in rows], out=seg_start[1:])
            n = int(seg_start[-1])
            seg_buf = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=seg_start)
        runs = _runs(n)
        per = (n + runs - 1) // runs
        # each segment's starts and tiles at sub-buffer origins (the device's base address
        # alignment) when there are several
        ints = 1 if nseg == 1 else max(1, self.ctx.devices[0].mem_base_addr_align // 32)
        start_row, active_row = -(-(ntiles + 1) // ints) * ints, -(-tiles // ints) * ints

        def buf(nbytes, flags=mf.READ_WRITE):
            return pool.buffer(nbytes, flags) if pool is not None else \
                cl.Buffer(self.ctx, flags, size=max(16, int(nbytes)))

        all_rows = rows[0] if nseg == 1 else np.concatenate(rows)
        rows_buf = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                             hostbuf=np.ascontiguousarray(all_rows, np.int32))
        counts = buf(runs * nseg * ntiles * 4)
        tile_start = buf(nseg * start_row * 4)
        tile_list = buf(nseg * active_row * 4)
        tile_tris = buf(capacity * 4)
        summary_buf = buf(nseg * 8)
        # the corners that maximise an edge function: the pixel centre with one sample, else
        # the extreme sample positions any pattern could use (as bin_pairs)
        lo, hi = (SUBPIXEL // 2, SUBPIXEL // 2) if samples == 1 else (1, SUBPIXEL - 1)
        head = [np.int32(n), np.int32(per), np.int32(tiles_x), np.int32(ntiles),
                np.int32(width), np.int32(height), np.int32(tile), np.int32(th),
                np.int32(_shift(tile)), np.int32(_shift(th)),
                np.int32(edge_test_lists(edge_test_tiles, tile, th)),
                np.int32(lo), np.int32(hi), rows_buf, bufs["bbox"], bufs["a"], bufs["b"],
                bufs["c"], np.int32(nseg), seg_buf]
        cl_context.set_args(count_k, *head, counts)
        cl.enqueue_nd_range_kernel(self.queue, count_k, (runs,), (1,))
        cl_context.set_args(starts_k, np.int32(runs), np.int32(ntiles), np.int32(tiles_x),
                            np.int32(tile // th), np.int32(nseg), np.int32(start_row),
                            np.int32(active_row), counts, tile_start, tile_list, summary_buf)
        cl.enqueue_nd_range_kernel(self.queue, starts_k, (1,), (1,))
        cl_context.set_args(write_k, *head, counts, tile_tris)
        cl.enqueue_nd_range_kernel(self.queue, write_k, (runs,), (1,))
        summary = np.zeros(2 * nseg, np.int32)
        event = cl.enqueue_copy(self.queue, summary, summary_buf, is_blocking=False)
        if nseg == 1:
            return [DeviceBins(self.queue, tiles_x, triangles[0], tile_list, tile_start,
                               tile_tris, summary, event, index, ntiles, th)]
        return [DeviceBins(self.queue, tiles_x, triangles[s],
                           tile_list.get_sub_region(s * active_row * 4, active_row * 4),
                           tile_start.get_sub_region(s * start_row * 4, start_row * 4),
                           tile_tris, summary, event, index, ntiles, th, seg=s)
                for s in range(nseg)]
