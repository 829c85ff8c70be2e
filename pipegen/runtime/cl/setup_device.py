"""Triangle set-up on the OpenCL device: ``cl_setup.setup_triangles`` as a kernel.

The numpy set-up costs ~0.8 us a triangle in numpy passes over memory (a 7,000-triangle
scene draw ~6 ms per frame, on the host's critical path: the device waits for it), while
per triangle it is a few dozen float32 operations.  ``templates/cl_setup.cl.j2`` does them
on the device in the numpy set-up's order of operations (float32, unfused, the viewport's
fused multiply-adds as ``fma32``): ``pg_setup``, one work-item per input triangle, then
``pg_clip_setup`` for the triangles that need clipping (a vertex outside a clip plane the
others are not all outside of: draw_pipe_clip.c's clipper as ``cl_setup._clip_polygons``
has it), whose fans go after the input triangles' rows and are merged back in submission
order.  The clipper's new vertices are numbered ``nverts + 9 h + slot`` (h: the clipped
triangle's rank), not consecutively as the numpy set-up numbers them: the same vertices, ids
apart.  Triangles, tested field by field against the numpy set-up
(tests/test_cl_setup_device.py), are bit for bit the same.  A clipped triangle with a
non-finite window position sends all of a draw's clipped triangles to the numpy set-up; so
are draws with a polygon offset, and the float64 evaluation's (its homogeneous planes come
from the numpy set-up's parent triangles): ``supports``.

``DeviceSetup(ctx, queue).enqueue(...)`` queues the kernel and the read-back of its results
without waiting (``CLPipeline`` queues it with the vertex kernels, before any raster kernel);
``finish(job)`` waits and returns the ``cl_setup.Triangles`` (host copies of the boxes and
flat words, ``HOST_FIELDS``; the other fields and the varyings stay on the device,
``DeviceRows`` and ``DeviceVaryings``, read back on first use) with the device buffers the
raster kernel reads as they are (no upload): rows per input triangle, dropped ones
included, so tile lists index them through ``index``.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Optional

import numpy as np

from pipegen.backends.opencl import programs as cl_programs
from pipegen.runtime.cl import context as cl_context
from pipegen.runtime.cl.setup import Triangles, setup_triangles
from pipegen.runtime.cl.transfers import write

__all__ = ["DeviceRows", "DeviceSetup", "supports"]

_MAXV, _FANS = 9, 7     # a triangle clipped by six planes, its fan (cl_setup.cl.j2)
# per kept triangle: (field, dtype, trailing shape) as the kernel writes them
_FIELDS = (("a", np.int32, (4,)), ("b", np.int32, (4,)), ("c", np.int64, (4,)),
           ("z", np.float32, (4,)), ("w", np.float32, (4,)), ("flat", np.uint32, (4,)),
           ("vtx", np.int32, (4,)), ("scissor", np.int32, (4,)), ("bbox", np.int32, (4,)))
# the fields the host reads every frame (binning: boxes; facing, light and culling: flat
# words); the others stay on the device (``DeviceRows``) unless something asks for them:
# reading all back cost ~400 bytes a triangle (3-4 MB a frame of light_prepass, 1 ms of a
# PoCL thread) and as much again gathering them in submission order on the host
HOST_FIELDS = ("flat", "bbox")


def supports(polygon_offset, f64: bool) -> bool:
    """Whether a draw's set-up can run on the device (else the numpy set-up does it all;
    ``$PIPEGEN_CL_DEVICE_SETUP=0`` makes it do all of them, for comparisons)."""
    return (polygon_offset is None and not f64
            and os.environ.get("PIPEGEN_CL_DEVICE_SETUP", "1") != "0")


@dataclasses.dataclass
class _Job:
    """A queued set-up: its host arrays (filled when the read-back events complete) and the
    parameters the numpy set-up of the clipped triangles needs."""
    events: list
    buffers: list        # kept alive until the job is finished
    bufs: dict           # the per-triangle fields' device buffers, by Triangles field name
    rows: int            # rows each of them has room for
    status: np.ndarray   # per input triangle (its length: the input triangles)
    out: dict            # HOST_FIELDS' host copies (filled when the read-backs complete)
    layout: dict         # every field's (dtype, trailing shape) in its buffer
    params: dict         # ``setup_triangles``'s keywords (the numpy fallback)
    clip_kernel: object  # pg_clip_setup of the same program
    head: list           # the kernels' scalar arguments: the varyings' slot stride, W, H,
                         #   viewport, centre
    clip_buf: object     # the inputs: clip positions, varyings (``slots`` slot-major)
    vary_buf: object
    inputs: list         # flat values and scissor rectangles (or placeholders)
    slots: int
    clipping: Optional[dict] = None    # ``DeviceSetup.clip``'s queued work
    count: int = 0       # the input vertices

    @property
    def nverts(self) -> int:
        return self.count

    @property
    def stride(self) -> int:
        """Vertices a slot of ``vary_buf`` has room for: ``nverts``, and room for the
        clipper's vertices when the caller left some (``enqueue``'s ``stride``)."""
        return int(self.head[0])


def clip_room(clipped: int) -> int:
    """Vertices of room a varying slot keeps for the clipper's, for a draw whose last set-up
    clipped ``clipped`` triangles (``_MAXV`` each; counts rounded up to a power of two, at
    least 8, so that a few more next frame still fit; none for a draw that did not clip)."""
    if clipped <= 0:
        return 0
    return _MAXV * max(8, 1 << (int(clipped) - 1).bit_length())


@dataclasses.dataclass
class _HostBlock:
    """The buffer holding a set-up's read-back fields, and each one's byte offset in it."""
    buf: object
    offsets: dict


class DeviceSetup:
    def __init__(self, ctx, queue, pool: Optional["cl_context.FramePool"] = None):
        """``pool``: where the jobs' buffers come from (``DrawGeometry``'s frame pool; by
        default a pool that never recycles)."""
        self.ctx, self.queue = ctx, queue
        self.appended_in_place = 0     # clipper runs that needed no copy of the varyings
        self.pool = pool if pool is not None else cl_context.FramePool(ctx)
        self._kernels: dict = {}

    def _kernels_for(self, *switches):
        """(pg_setup, pg_clip_setup) of the program for these switches
        (``opencl.setup_program``'s arguments), built once."""
        import pyopencl as cl
        kerns = self._kernels.get(switches)
        if kerns is None:
            prog = cl_context.build_program(cl_programs.setup_program(*switches))
            kerns = self._kernels[switches] = (cl.Kernel(prog, "pg_setup"),
                                               cl.Kernel(prog, "pg_clip_setup"))
        return kerns

    def enqueue(self, clip_buf, vary_buf, ntris: int, nverts: int, width: int, height: int, *,
                cull: str = "none", depth_clamp: bool = False, flat: Optional[np.ndarray] = None,
                scissor: Optional[np.ndarray] = None, samples: Optional[int] = None,
                smooth: tuple = (), pixel_center: float = 0.5, w_plane: bool = True,
                viewport=None, with_zq: bool = False, slots: int = 0,
                stride: Optional[int] = None, before_queue=None) -> _Job:
        """Queue the set-up of ``ntris`` triangles whose clip positions (``3 * ntris``
        float4) are in ``clip_buf`` and ``slots`` varyings (slot-major, ``nverts`` per slot,
        ``stride`` >= ``nverts`` apart: room the clipper can append its vertices in) in
        ``vary_buf``; the keywords as ``setup_triangles`` takes them.  ``before_queue``:
        called once the host work is done, right before the kernel is queued."""
        import pyopencl as cl
        f32 = np.float32
        mf = cl.mem_flags
        W, H = int(width), int(height)
        vx, vy, vw, vh = viewport if viewport is not None else (0, 0, W, H)
        smooth = tuple(int(s) for s in smooth)
        K = len(smooth)
        if smooth and max(smooth) >= slots:
            raise ValueError(f"smooth varyings {smooth} of {slots} slots")
        kern, clip_kern = self._kernels_for(cull, depth_clamp, samples, flat is not None,
                                            scissor is not None, w_plane, with_zq, smooth,
                                            int(slots))
        # rows for every input triangle, and spare ones for the fans of clipped triangles
        # (``finish`` sets them up after the kernel's rows; more than this grows the buffers)
        n = int(ntris) + max(_FANS * 32, int(ntris) // 8)

        def buf(nbytes):
            return self.pool.buffer(nbytes, mf.WRITE_ONLY)

        def upload(a):
            return cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                             hostbuf=np.ascontiguousarray(a))

        # the fields the host reads back (HOST_FIELDS, then the statuses) share one buffer,
        # each a sub-buffer at an aligned offset: one read-back instead of three
        layout = {name: (np.dtype(dt), shape) for name, dt, shape in _FIELDS}
        block, views = self._host_block(n, layout)
        status_buf = views.pop("status")
        bufs = {name: views[name] if name in views
                else buf(n * np.dtype(dt).itemsize * int(np.prod(shape)))
                for name, dt, shape in _FIELDS}
        coef_buf = buf(n * K * 3 * 16)
        zq_buf = buf(n * 32 if with_zq else 16)
        dummy = buf(16)
        inputs = [upload(np.asarray(flat, np.uint32)) if flat is not None else dummy,
                  upload(np.asarray(scissor, np.int32)) if scissor is not None else dummy]
        stride = int(nverts) if stride is None else int(stride)
        head = [np.int32(stride), np.int32(W), np.int32(H), f32(vw * 0.5), f32(vh * 0.5),
                f32(vx + vw * 0.5), f32(vy + vh * 0.5), f32(pixel_center)]
        cl_context.set_args(kern, np.int32(ntris), *head, clip_buf,
                            vary_buf if vary_buf is not None else dummy, *inputs,
                            status_buf, bufs["a"], bufs["b"], bufs["c"], bufs["z"], bufs["w"],
                            coef_buf, bufs["flat"], bufs["vtx"], bufs["scissor"],
                            bufs["bbox"], zq_buf)
        events = []
        if before_queue is not None:
            before_queue()
        if ntris:
            events.append(cl.enqueue_nd_range_kernel(self.queue, kern,
                                                     (((ntris + 63) // 64) * 64,), (64,)))
        layout["coef"] = (np.dtype(f32), (K, 3, 4))
        if with_zq:
            layout["zq"] = (np.dtype(np.float64), (4,))
        host = np.empty(block.offsets["status"] + ntris, np.uint8)
        status = host[block.offsets["status"]:]
        out = {name: host[block.offsets[name]:block.offsets[name] + ntris * 16].view(
            layout[name][0]).reshape((ntris,) + layout[name][1]) for name in HOST_FIELDS}
        if ntris:
            events.append(cl.enqueue_copy(self.queue, host, block.buf, is_blocking=False))
        params = dict(width=W, height=H, cull=cull, depth_clamp=depth_clamp, flat=flat,
                      scissor=scissor, samples=samples, smooth=list(smooth),
                      pixel_center=pixel_center, w_plane=w_plane, viewport=viewport,
                      with_zq=with_zq)
        fields = dict(bufs, coef=coef_buf)
        if with_zq:
            fields["zq"] = zq_buf
        return _Job(events, [block.buf, status_buf, dummy], fields, n, status, out, layout,
                    params, clip_kern, head, clip_buf, vary_buf, inputs, int(slots),
                    count=int(nverts))

    def _host_block(self, rows: int, layout: dict):
        """One pool buffer for ``rows`` rows of each of ``HOST_FIELDS`` (16-byte rows), then
        ``rows`` status bytes, each at an offset of the device's base address alignment (what
        a sub-buffer's origin must be a multiple of): (``_HostBlock``, {name: its sub-buffer},
        "status" included)."""
        assert all(layout[name][0].itemsize * int(np.prod(layout[name][1])) == 16
                   for name in HOST_FIELDS)
        align = max(16, self.ctx.devices[0].mem_base_addr_align // 8)
        sizes = {**{name: rows * 16 for name in HOST_FIELDS}, "status": max(16, rows)}
        offsets, at = {}, 0
        for name, size in sizes.items():
            offsets[name] = at
            at += -(-size // align) * align
        block = _HostBlock(self.pool.buffer(at), offsets)
        return block, {name: block.buf.get_sub_region(offsets[name], size)
                       for name, size in sizes.items()}

    def finish(self, job: _Job):
        """Wait for ``job``, clip and set up its clipped triangles, and return ``(tris, bufs,
        index)``.  ``tris``: the ``Triangles`` in submission order (``HOST_FIELDS`` host
        copies; the other fields ``DeviceRows``, ``vary`` a ``DeviceVaryings``, read from the
        device on first use); ``bufs``: the device buffers of
        their per-triangle fields, one row per input triangle, then the clipped triangles'
        fans (``"vary"``: the varyings with the clipper's vertices, when it made some);
        ``index``: the row of
        ``bufs`` of each triangle of ``tris`` (int32), what tile lists must hold."""
        self.clip(job)
        status, out, prm = job.status, job.out, job.params
        kept = np.flatnonzero(status == 1)
        hard = job.clipping["hard"]
        parts = {name: rows_of(arr, kept) for name, arr in out.items()}
        parent = kept.astype(np.int64)
        index = kept.astype(np.int32)
        bufs = job.bufs             # the rows of clipped triangles' fans are added to these
        T, nverts = len(status), job.stride       # the raster reads slots this far apart
        vary_v = DeviceVaryings(self.queue, job.vary_buf, job.slots, nverts) if job.slots \
            else None
        if len(hard):
            got = self._clipped(job)
            if got is None:        # a window position the kernel left to numpy: all of them
                clip, vary = self._host_inputs(job)
                sub = _numpy_setup(hard, clip, vary, prm)
                rows, sub_parent = np.arange(T, T + sub.count, dtype=np.int32), sub.parent
                fields = {name: getattr(sub, name) for name in parts}
                vary_v, nverts = sub.vary, sub.nverts
                self._write_rows(job, bufs, {name: getattr(sub, name) for name in job.layout}, T)
            else:
                rows, sub_parent, fields, vary_v, nverts, bufs["vary"] = got
            m = len(rows)
            # in submission order: each clipped triangle's fan where its parent was
            at = np.searchsorted(kept, sub_parent) + np.arange(m)
            mine = np.ones(len(kept) + m, bool)
            mine[at] = False
            parent = _merged(parent, sub_parent, mine, at)
            index = _merged(index, rows, mine, at)
            for name in parts:
                parts[name] = _merged(parts[name], np.ascontiguousarray(fields[name]), mine, at)
        for name, (dtype, shape) in job.layout.items():    # the rest: rows of the buffers
            if name not in parts:
                parts[name] = DeviceRows(self.queue, bufs[name], dtype, shape, index)
        tris = Triangles(parts["a"], parts["b"], parts["c"], parts["z"], parts["w"],
                         parts["coef"], None, parts.get("zq"), parts["flat"], parts["vtx"],
                         parts["scissor"], parts["bbox"], vary_v, nverts, prm["samples"],
                         parent)
        return tris, bufs, index

    def _grow(self, job: _Job, bufs: dict, rows: int) -> None:
        """Make every field buffer hold ``rows`` rows (the kernel's rows copied over)."""
        import pyopencl as cl
        if rows <= job.rows:
            return
        T = len(job.status)
        for name, buf in list(bufs.items()):
            if name not in job.layout:
                continue
            dtype, shape = job.layout[name]
            row = dtype.itemsize * int(np.prod(shape))
            if not row:
                continue
            grown = self.pool.buffer(rows * row)
            cl.enqueue_copy(self.queue, grown, buf, byte_count=T * row)
            bufs[name] = grown
        job.rows = rows

    def _write_rows(self, job: _Job, bufs: dict, fields: dict, at: int) -> None:
        """Write host rows ``fields`` (per field name) into the field buffers from row ``at``."""
        m = len(next(iter(fields.values()))) if fields else 0
        self._grow(job, bufs, at + m)
        for name, extra in fields.items():
            extra = np.ascontiguousarray(extra)
            if extra.size:
                write(self.queue, bufs[name], extra, dst_offset=at * (extra.nbytes // m))

    def clip(self, job: _Job) -> None:
        """Wait for ``pg_setup``'s statuses and queue ``pg_clip_setup`` on the triangles that
        need clipping, with the read-back of its results, without waiting for it
        (``CLPipeline`` calls this for every set-up of the frame before its first raster
        kernel: on the queue the clipper would otherwise wait behind the raster kernels of
        the passes before; ``finish`` calls it when nobody did)."""
        import pyopencl as cl
        if job.clipping is not None:
            return
        for ev in job.events:
            ev.wait()
        hard = np.flatnonzero(job.status == 2)
        job.clipping = {"hard": hard}
        if not len(hard):
            return
        mf = cl.mem_flags
        S, T, nverts, inputs, vary_buf = job.slots, len(job.status), job.nverts, job.inputs, \
            job.vary_buf
        stride = job.stride
        nh = len(hard)
        bufs = job.bufs
        self._grow(job, bufs, T + _FANS * nh)
        if S and nverts + _MAXV * nh <= stride:
            # the vertex kernels left room after each slot's vertices: appended in place
            vary_out, nv_out = vary_buf, stride
            self.appended_in_place += 1
        else:
            nv_out = nverts + _MAXV * nh
            vary_out = self.pool.buffer(S * nv_out * 16)
            for k in range(S):     # the input vertices; pg_clip_setup appends the clipper's
                cl.enqueue_copy(self.queue, vary_out, vary_buf, byte_count=nverts * 16,
                                src_offset=k * stride * 16, dst_offset=k * nv_out * 16)
        fan_buf = self.pool.buffer(_FANS * nh)
        hard_buf = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                             hostbuf=hard.astype(np.int32))
        dummy = inputs[0] if S == 0 else vary_buf
        cl_context.set_args(
            job.clip_kernel, np.int32(nh), np.int32(T), np.int32(nverts), np.int32(nv_out),
            np.int32(stride), *job.head[1:], hard_buf, job.clip_buf, dummy, *inputs, fan_buf,
            vary_out, bufs["a"], bufs["b"], bufs["c"], bufs["z"], bufs["w"], bufs["coef"],
            bufs["flat"], bufs["vtx"], bufs["scissor"], bufs["bbox"], bufs.get("zq", inputs[0]))
        cl.enqueue_nd_range_kernel(self.queue, job.clip_kernel, (((nh + 63) // 64) * 64,),
                                   (64,))
        fan = np.empty(_FANS * nh, np.uint8)
        events = [cl.enqueue_copy(self.queue, fan, fan_buf, is_blocking=False)]
        fields = {}
        for name, arr in job.out.items():
            row = arr.nbytes // max(T, 1)
            host = np.empty((_FANS * nh,) + arr.shape[1:], arr.dtype)
            if host.size:
                events.append(cl.enqueue_copy(self.queue, host, bufs[name],
                                              src_offset=T * row, is_blocking=False))
            fields[name] = host
        job.clipping.update(events=events, fan=fan, fields=fields, nv_out=nv_out,
                            vary_out=vary_out, keep=[fan_buf, hard_buf])

    def _host_inputs(self, job: _Job):
        """The kernel's inputs read back: (clip positions, varyings or None)."""
        import pyopencl as cl
        clip = np.empty((job.nverts, 4), np.float32)
        cl.enqueue_copy(self.queue, clip, job.clip_buf)
        vary = None
        if job.slots:
            vary = np.empty((job.slots, job.stride, 4), np.float32)
            cl.enqueue_copy(self.queue, vary, job.vary_buf)
            vary = np.ascontiguousarray(vary[:, :job.nverts])
        return clip, vary

    def _clipped(self, job: _Job):
        """The clipper's results (``clip``): (their fans' rows, parents, host fields, host
        varyings, vertex count, device varyings), or None when a clipped triangle has a
        non-finite window position (the numpy set-up then does them all)."""
        c = job.clipping
        for ev in c["events"]:
            ev.wait()
        if (c["fan"] == 3).any():
            return None
        T = len(job.status)
        sel = np.flatnonzero(c["fan"] == 1)
        fields = {name: rows_of(a, sel) for name, a in c["fields"].items()}
        vary_v = (DeviceVaryings(self.queue, c["vary_out"], job.slots, c["nv_out"])
                  if job.slots else None)
        rows = (T + sel).astype(np.int32)
        return (rows, c["hard"][sel // _FANS].astype(np.int64), fields, vary_v, c["nv_out"],
                c["vary_out"])


class _OnDevice:
    """An array a set-up leaves on the device: ``shape``, ``dtype`` and ``ndim`` as numpy
    has them, the values read back the first time something asks for them as an array
    (``_read``), then kept."""

    shape: tuple
    dtype: np.dtype
    _host: Optional[np.ndarray] = None

    @property
    def ndim(self) -> int:
        return len(self.shape)

    def _read(self) -> np.ndarray:
        raise NotImplementedError

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        if self._host is None:
            self._host = self._read()
        return self._host if dtype is None else self._host.astype(dtype)

    def __getitem__(self, index):
        return np.asarray(self)[index]

    def __len__(self) -> int:
        return self.shape[0]


class DeviceVaryings(_OnDevice):
    """``Triangles.vary`` of a device set-up: the varyings stay in the device buffer the raster
    kernel reads (slot-major; the clipper's vertices after the input's), and are read back
    the first time something asks for them as an array (tests: the runtime never needs them
    on the host, and a scene draw's are megabytes a frame)."""

    dtype = np.dtype(np.float32)

    def __init__(self, queue, buf, slots: int, nverts: int):
        self.queue, self.buf = queue, buf
        self.shape = (int(slots), int(nverts), 4)

    def _read(self) -> np.ndarray:
        import pyopencl as cl
        host = np.empty(self.shape, np.float32)
        cl.enqueue_copy(self.queue, host, self.buf)
        return host


class DeviceRows(_OnDevice):
    """A per-triangle field of a device set-up that stays on the device (not in
    ``HOST_FIELDS``): rows ``index`` of its buffer, read back the first time something asks
    for it as an array (tests, ``cl_setup`` comparisons; the runtime does not).  A pipeline's
    next frame reuses the buffer (``cl_context.FramePool``): read it before then."""

    def __init__(self, queue, buf, dtype, shape: tuple, index: np.ndarray):
        self.queue, self.buf, self.index = queue, buf, np.asarray(index)
        self.dtype, self.row_shape = np.dtype(dtype), tuple(shape)
        self.shape = (len(self.index),) + self.row_shape
        self._whole: Optional[np.ndarray] = None

    def _buffer_rows(self) -> np.ndarray:
        """The buffer's rows up to the last one ``index`` names, read once."""
        if self._whole is None:
            import pyopencl as cl
            rows = int(self.index.max()) + 1 if len(self.index) else 0
            self._whole = np.empty((rows,) + self.row_shape, self.dtype)
            if self._whole.size:
                cl.enqueue_copy(self.queue, self._whole, self.buf)
        return self._whole

    def _read(self) -> np.ndarray:
        return rows_of(self._buffer_rows(), self.index)

    def rows(self, idx: np.ndarray) -> "DeviceRows":
        """Rows ``idx`` of this field (``select_triangles``), still on the device."""
        return DeviceRows(self.queue, self.buf, self.dtype, self.row_shape,
                          self.index[np.asarray(idx)])

    def __getitem__(self, key):
        """``a[t, k]`` with integer triangle indices ``t`` (binning's edge tests of the big
        triangles) reads those rows alone; anything else indexes the whole array."""
        if self._host is None and isinstance(key, tuple) and key and \
                isinstance(key[0], np.ndarray) and key[0].dtype.kind in "iu":
            return self._buffer_rows()[(self.index[key[0]],) + key[1:]]
        return super().__getitem__(key)


def rows_of(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``a[idx]`` along the first axis, each row moved as one opaque item (several times
    faster than fancy indexing rows of 4 numbers; cl_geometry.select_triangles uses it too)."""
    if a.ndim == 1 or not a.flags.c_contiguous or a.size == 0:
        return a[idx]
    return np.take(_items(a), idx).view(a.dtype).reshape((len(idx),) + a.shape[1:])


def _merged(a: np.ndarray, b: np.ndarray, from_a: np.ndarray, b_at: np.ndarray) -> np.ndarray:
    """Rows of ``a`` where ``from_a`` holds, in order, and rows of ``b`` at ``b_at``."""
    out = np.empty((len(from_a),) + a.shape[1:], a.dtype)
    if out.size == 0:
        return out
    rows = _items(out)          # each row one opaque item: numpy moves it in one go
    if len(a):
        rows[np.flatnonzero(from_a)] = _items(np.ascontiguousarray(a))
    if len(b):
        rows[b_at] = _items(np.ascontiguousarray(b))
    return out


def _items(a: np.ndarray) -> np.ndarray:
    """A view of ``a`` (C-contiguous, non-empty rows) with each row one void item."""
    row = np.dtype((np.void, a.itemsize * (a.size // len(a))))
    return a.reshape(len(a), -1).view(row)[:, 0]


def _numpy_setup(idx: np.ndarray, clip: np.ndarray, vary: Optional[np.ndarray],
                 prm: dict) -> Triangles:
    """The numpy set-up of input triangles ``idx`` (increasing) alone, in the whole draw's
    terms: parents and vertex indices refer to the draw's triangles and vertices, the
    clipper's new vertices appended after the draw's (``vary`` extended with them)."""
    corner = np.arange(3, dtype=np.int64)
    verts = (idx[:, None] * 3 + corner).reshape(-1)
    sub_vary = None if vary is None else np.asarray(vary, np.float32)[:, verts]
    flat, scissor = prm["flat"], prm["scissor"]
    tris = setup_triangles(
        np.asarray(clip, np.float32)[verts], prm["width"], prm["height"], cull=prm["cull"],
        depth_clamp=prm["depth_clamp"], flat=None if flat is None else flat[idx],
        vary=sub_vary, scissor=None if scissor is None else scissor[idx],
        samples=prm["samples"], smooth=prm["smooth"], pixel_center=prm["pixel_center"],
        w_plane=prm["w_plane"], viewport=prm["viewport"], with_zp=False,
        with_zq=prm["with_zq"])
    m = len(verts)
    vtx = tris.vtx.astype(np.int64)
    own = vtx < m                               # the draw's vertices; the rest were made here
    vtx[:, :3] = np.where(own[:, :3], verts[np.minimum(vtx[:, :3], m - 1)],
                          len(clip) + vtx[:, :3] - m)
    tris.vtx = vtx.astype(np.int32)
    tris.parent = idx[tris.parent]
    if vary is not None and tris.vary is not None and tris.vary.shape[1] > m:
        tris.vary = np.concatenate([np.asarray(vary, np.float32), tris.vary[:, m:]], axis=1)
    else:
        tris.vary = vary
    tris.nverts = len(clip) + (tris.nverts - m)
    return tris
