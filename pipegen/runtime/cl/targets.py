"""The CL runtime's render targets: device buffers in GL row order, cleared, resolved, read
back and preset through their ``formats.Format`` (which says how codes are stored: one element
per channel, or channels packed into one word).

``TargetStore(ctx, queue, plan).prepare(out_w, out_h)`` allocates (or reuses) and clears
every target for a frame; ``targets[name]`` is a ``Target``.  ``TargetStore(..., alias=True)``
shares storage between targets whose lifetimes are disjoint (``ir.lifetimes``, true aliasing:
one device buffer per slot, sized for its largest target, and each target's buffers views into
it); a target whose storage it shares with an earlier one is cleared where its lifetime starts
(``begin_pass``, ``end_frame``: ``runtime/aliasing.py``), and ``read_all`` reads the
targets their storage holds (after ``end_frame``: all but ``memory.aliased``).  Multisampled
targets keep one plane per sample and a resolved plane that reads and read-back see
(``resolve``).
``blend_count(t)`` is the per-pixel count of fragments blended into a colour target this
frame, which ``pipegen check`` turns into a per-pixel tolerance.

The float64 evaluation (a plan of precision "f64") stores every non-integer target as doubles
(one per channel; depth: the window depth), unquantised: clears write the clear values in the
format's range ([0, 1] unorm, [-1, 1] snorm, finite half values within +-65504), the
multisample resolve averages the samples in double, and ``read`` gives float64 values (integer
targets their codes as float64; stencil stays uint8 codes).
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from pipegen.core import formats as F
from pipegen.backends.plan import Plan, TargetPlan
from pipegen.ir.lifetimes import MemoryPlan, Sharing, memory_plan
from pipegen.runtime.aliasing import FrameClears
from pipegen.runtime.cl import context as cl_context


def device_buffer(ctx, array: np.ndarray):
    """A read-write device buffer holding a copy of ``array`` (at least 16 bytes)."""
    import pyopencl as cl
    a = np.ascontiguousarray(array)
    if a.nbytes == 0:
        a = np.zeros(16, np.uint8)
    return cl.Buffer(ctx, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)


def value_range(fmt: F.Format, values: np.ndarray) -> np.ndarray:
    """Values (float64) limited to what format ``fmt`` can hold, without quantising: the float64
    evaluation's stores and clears (unorm [0, 1], snorm [-1, 1], NaN to the low end; half:
    finite values within +-65504; depth [0, 1]; float32: unchanged)."""
    v = np.asarray(values, np.float64)
    if fmt.kind is F.Kind.UNORM or fmt.has_depth:
        return np.clip(np.nan_to_num(v, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    if fmt.kind is F.Kind.SNORM:
        return np.clip(np.nan_to_num(v, nan=-1.0, posinf=1.0, neginf=-1.0), -1.0, 1.0)
    if fmt.kind is F.Kind.FLOAT and max(fmt.bits) == 16:
        return np.where(np.isfinite(v), np.clip(v, -65504.0, 65504.0), v)
    return v


def d24_resolve(codes: np.ndarray) -> np.ndarray:
    """d24 codes as llvmpipe's multisample depth resolve writes them back: its blit reads
    sample 0 as a float and stores it as a d24 code again, ``code * (float)(1/(2^24-1))``,
    then ``* (2^24-1)`` rounded to nearest even, all float32 (measured on Mesa 22.3: moves
    about a third of the codes by one)."""
    f32 = np.float32
    v = (np.asarray(codes).astype(f32) * f32(1.0 / 16777215.0)).astype(f32)
    return np.rint((v * f32(16777215.0)).astype(f32)).astype(np.uint32)


def _resolved_default(bufs: list) -> tuple:
    """(buf, stencil, res, res_stencil) with a single-sample target's resolved planes its
    own."""
    buf, stencil, res, res_stencil = bufs
    return (buf, stencil, buf if res is None else res,
            stencil if res_stencil is None else res_stencil)


class Target:
    def __init__(self, spec: TargetPlan, width: int, height: int):
        self.spec = spec
        self.name = spec.name
        self.fmt = spec.format
        self.width, self.height = width, height
        self.samples = spec.samples
        self.buf = None           # colour or depth codes, one plane per sample
        self.stencil = None       # d24s8 stencil, one plane per sample
        self.res = None           # the resolved (single-sample) planes: reads and readback
        self.res_stencil = None
        self.dirty = False        # samples newer than the resolved planes

    @property
    def pixels(self) -> int:
        return self.width * self.height


class TargetStore:
    def __init__(self, ctx, queue, plan: Plan, alias: bool = False):
        self.ctx, self.queue = ctx, queue
        self.plan = plan
        self.alias = alias
        self.device_resolve = True      # False: every resolve in numpy (tests compare both)
        self._resolvers: dict = {}
        self.specs = {t.name: t for t in plan.targets}
        self.f64 = plan.precision == "f64"
        self.targets: dict[str, Target] = {}
        self.memory: Optional[MemoryPlan] = None    # the last frame's lifetimes and slots
        self._clears: Optional[FrameClears] = None
        self._storage: tuple = ((), {})     # (layout key, {target: its buffers})
        self.blend_counts: dict = {}        # target name -> this frame's count buffer
        self._count_pool: dict = {}         # count buffers, reused every frame
        self._clear_patterns: dict = {}     # (format, clear value) -> the bytes to fill with

    # -- a frame ------------------------------------------------------------------------------
    def prepare(self, out_w: int, out_h: int, pinned=()) -> None:
        """Allocate (or reuse the last frame's buffers) and clear every target, or with
        ``alias`` the first of each slot (``pinned``: targets given contents before the frame,
        live from its start)."""
        sharing = Sharing.BYTES if self.alias else Sharing.NONE
        key = (out_w, out_h, sharing, frozenset(pinned))
        if self.memory is None or self._storage[0] != key:
            p = self.plan
            self.memory = memory_plan(p.passes, p.targets, p.output, out_w, out_h, sharing,
                                      pinned)
        self.targets = {}
        self.blend_counts = {}
        for name, spec in self.specs.items():
            self.targets[name] = Target(spec, *spec.resolve(out_w, out_h))
        if self._storage[0] != key:
            self._storage = ((), {})            # the last layout's buffers go first
            self._storage = (key, self._allocate())
        for name, bufs in self._storage[1].items():
            t = self.targets[name]
            t.buf, t.stencil, t.res, t.res_stencil = bufs
        self._clears = FrameClears(self.memory)
        self._clear_targets(self._clears.start())

    def begin_pass(self, k: int) -> None:
        """Before an execution of pass ``k``: clear the targets whose lifetime starts there
        (storage shared with an earlier target; nothing to do without ``alias``)."""
        self._clear_targets(self._clears.before_pass(k))

    def end_frame(self) -> None:
        """After a frame's last pass: clear the targets no pass execution reached."""
        self._clear_targets(self._clears.finish())

    def _clear_targets(self, names) -> None:
        for name in names:
            c = self.specs[name].clear
            self.clear(self.targets[name], c.color, c.depth, c.stencil)

    def _parts(self, t: Target) -> tuple[int, int, int, int]:
        """Bytes of a target's buffers: (codes, stencil, resolved codes, resolved stencil);
        0 where it has none (a single-sample target reads its codes as resolved)."""
        fmt = t.fmt
        per_pixel = fmt.element_dtype.itemsize * fmt.elements     # stencil: a buffer apart
        if self._doubles(fmt):
            per_pixel = 8 * (1 if fmt.has_depth else fmt.channels)
        ds = fmt.kind is F.Kind.DEPTH_STENCIL
        multi = t.samples > 1
        return (t.pixels * per_pixel * t.samples, t.pixels * t.samples if ds else 0,
                t.pixels * per_pixel if multi else 0, t.pixels if ds and multi else 0)

    def _allocate(self) -> dict[str, tuple]:
        """{target: (buf, stencil, res, res_stencil)}: without ``alias`` a buffer each; with
        it one buffer per slot of ``memory`` and views into it (sub-buffers at offsets of the
        device's base address alignment)."""
        import pyopencl as cl
        rw = cl.mem_flags.READ_WRITE
        out = {}
        if not self.alias:
            for name, t in self.targets.items():
                bufs = [cl.Buffer(self.ctx, rw, size=max(16, n)) if n else None
                        for n in self._parts(t)]
                out[name] = _resolved_default(bufs)
            return out
        align = max(16, self.ctx.devices[0].mem_base_addr_align // 8)
        for slot in self.memory.slots:
            layouts = {}
            for name in slot.targets:
                offsets, at = [], 0
                for n in self._parts(self.targets[name]):
                    offsets.append((at, max(16, n)) if n else None)
                    at += -(-max(16, n) // align) * align if n else 0
                layouts[name] = (offsets, at)
            whole = cl.Buffer(self.ctx, rw, size=max(at for _, at in layouts.values()))
            for name, (offsets, _) in layouts.items():
                out[name] = _resolved_default([whole.get_sub_region(*o) if o else None
                                               for o in offsets])
        return out

    # -- clears -------------------------------------------------------------------------------
    def clear(self, t: Target, color=None, depth=None, stencil=None,
              depth_given: bool = True, stencil_given: bool = True) -> None:
        n = t.pixels
        if t.samples > 1:          # keep the resolved plane current for a partial clear
            self.resolve(t)
        self._fill(t, t.buf, t.stencil, t.samples * n, color, depth, stencil, depth_given,
                   stencil_given)
        if t.samples > 1:
            self._fill(t, t.res, t.res_stencil, n, color, depth, stencil, depth_given,
                       stencil_given)
        t.dirty = False

    def clear_for_pass(self, name: str, c) -> None:
        """A pass's ``clears`` entry (an ``ir.Clear``): a d24s8 clear naming only depth or
        only stencil keeps the other aspect."""
        t = self.targets[name]
        partial = t.fmt.kind is F.Kind.DEPTH_STENCIL and (c.depth is None) != (c.stencil is None)
        self.clear(t, c.color, c.depth, c.stencil,
                   depth_given=not partial or c.depth is not None,
                   stencil_given=not partial or c.stencil is not None)

    def _doubles(self, fmt: F.Format) -> bool:
        """Whether the target's values live as doubles (the float64 evaluation, non-integer)."""
        return self.f64 and not fmt.is_integer

    def _fill(self, t: Target, buf, sbuf, n: int, color, depth, stencil, depth_given: bool,
              stencil_given: bool) -> None:
        """Fill ``n`` pixels of ``buf`` (and of the stencil buffer ``sbuf``) with the clear
        value, normalised by ``Format.clear_*`` as the GL runtime's clears are."""
        import pyopencl as cl
        main, st = self._patterns(t.fmt, color, depth, stencil, depth_given, stencil_given)
        if main is not None:
            if len(main) in (1, 2, 4, 8, 16, 32, 64, 128):     # clEnqueueFillBuffer's sizes
                cl.enqueue_fill_buffer(self.queue, buf, main, 0, n * len(main))
            else:
                cl.enqueue_copy(self.queue, buf, np.tile(main, n))
        if st is not None:
            cl.enqueue_fill_buffer(self.queue, sbuf, st, 0, n)

    def _patterns(self, fmt: F.Format, color, depth, stencil, depth_given: bool,
                  stencil_given: bool) -> tuple:
        """(a pixel's bytes of the clear value or None, the stencil byte or None), found once
        per format and clear value (clears run every frame, the same values each time)."""
        key = (fmt.name, fmt.clear_key(color, depth, stencil), depth_given, stencil_given)
        got = self._clear_patterns.get(key)
        if got is None:
            got = self._clear_patterns[key] = self._clear_bytes(fmt, color, depth, stencil,
                                                                depth_given, stencil_given)
        return got

    def _clear_bytes(self, fmt: F.Format, color, depth, stencil, depth_given: bool,
                     stencil_given: bool) -> tuple:
        if fmt.has_depth:
            main = st = None
            if depth_given:
                if self._doubles(fmt):
                    v = np.float64(value_range(fmt, fmt.clear_depth(depth)))
                elif fmt.kind is F.Kind.DEPTH_STENCIL:
                    v = np.uint32(fmt.clear_codes(depth=depth))
                else:
                    v = np.float32(fmt.clear_codes(depth=depth))
                main = np.frombuffer(v.tobytes(), np.uint8)
            if fmt.kind is F.Kind.DEPTH_STENCIL and stencil_given:
                st = np.uint8(fmt.clear_stencil(stencil))
            return main, st
        if self._doubles(fmt):
            pattern = value_range(fmt, fmt.clear_channels(color)).astype(np.float64)
            return np.ascontiguousarray(pattern).view(np.uint8).reshape(-1), None
        codes = fmt.clear_codes(color)
        pixel = fmt.pack(np.asarray(codes).reshape(1, 1, -1) if fmt.channels > 1
                         else np.asarray(codes).reshape(1, 1))
        return np.ascontiguousarray(pixel).view(np.uint8).reshape(-1), None

    # -- reading ------------------------------------------------------------------------------
    def _read_planes(self, t: Target, buf, sbuf, planes: int):
        """(codes (planes, H, W[, C]), stencil (planes, H, W) or None) of a buffer pair."""
        import pyopencl as cl
        fmt = t.fmt
        h, w = t.height, t.width
        doubles = self._doubles(fmt)
        if doubles or fmt.kind in (F.Kind.DEPTH_STENCIL, F.Kind.DEPTH):
            if doubles:
                shape = (planes, h, w) + ((fmt.channels,) if fmt.channels > 1 and fmt.is_color
                                          else ())
                d = np.empty(shape, np.float64)
            else:
                d = np.empty((planes, h, w), np.uint32 if fmt.kind is F.Kind.DEPTH_STENCIL
                             else np.float32)
            cl.enqueue_copy(self.queue, d, buf)
            st = None
            if fmt.kind is F.Kind.DEPTH_STENCIL:
                st = np.empty((planes, h, w), np.uint8)
                cl.enqueue_copy(self.queue, st, sbuf)
            return d, st
        per_pixel = () if fmt.elements == 1 else (fmt.elements,)
        raw = np.empty((planes, h, w) + per_pixel, fmt.element_dtype)
        cl.enqueue_copy(self.queue, raw, buf)
        return fmt.unpack(raw), None

    def resolve(self, t: Target) -> None:
        """Resolve the samples like llvmpipe's blit (measured): colour = the average of the
        sample values, stored like a fragment output (unorm: round half to even, half:
        toward zero); depth, stencil and integer formats take sample 0, d24 depth through
        llvmpipe's float round trip (``d24_resolve``).  Unorm, half and d24 targets resolve on
        the device (``templates/cl_resolve.cl.j2``, the same float32 operations: queued, not
        waited for); the rest, and every target with ``device_resolve`` off, here in numpy."""
        import pyopencl as cl
        if t.samples == 1 or not t.dirty:
            return
        kern = self._resolve_kernel(t) if self.device_resolve else None
        if kern is not None:
            args = [np.int32(t.pixels), t.buf, t.res]
            if t.stencil is not None:
                args += [t.stencil, t.res_stencil]
            cl_context.set_args(kern, *args)
            cl.enqueue_nd_range_kernel(self.queue, kern, (((t.pixels + 63) // 64) * 64,), (64,))
            t.dirty = False
            return
        codes, st = self._read_planes(t, t.buf, t.stencil, t.samples)
        fmt = t.fmt
        if self._doubles(fmt):
            # the float64 evaluation: colour the mean of the samples, depth sample 0
            res = codes[0] if fmt.has_depth else codes.sum(axis=0) / t.samples
            cl.enqueue_copy(self.queue, t.res, np.ascontiguousarray(res, np.float64))
            if st is not None:
                cl.enqueue_copy(self.queue, t.res_stencil, np.ascontiguousarray(st[0]))
            t.dirty = False
            return
        if fmt.kind in (F.Kind.UNORM, F.Kind.FLOAT):
            if fmt.kind is F.Kind.UNORM:
                top = np.array([(1 << b) - 1 for b in fmt.bits], np.float32)
                rcp = (np.float32(1.0) / top).astype(np.float32)
                vals = codes.astype(np.float32) * (rcp if fmt.channels > 1 else rcp[0])
            else:
                vals = codes.astype(np.float32)
            acc = vals[0].copy()
            for k in range(1, t.samples):
                acc = (acc + vals[k]).astype(np.float32)
            avg = (acc * np.float32(1.0 / t.samples)).astype(np.float32)
            if fmt.kind is F.Kind.UNORM:
                m = top if fmt.channels > 1 else top[0]
                res = np.rint(np.clip(avg, 0, 1) * m).astype(fmt.dtype)
            elif fmt.dtype == np.float16:
                res = F.half_toward_zero(avg)
            else:
                res = avg
            res = res[None]
        elif fmt.kind is F.Kind.DEPTH_STENCIL:
            res = d24_resolve(codes[0])[None]
        else:
            res = codes[:1]
        cl.enqueue_copy(self.queue, t.res, np.ascontiguousarray(fmt.pack(res[0])))
        if st is not None:
            cl.enqueue_copy(self.queue, t.res_stencil, np.ascontiguousarray(st[0]))
        t.dirty = False

    def _resolve_kernel(self, t: Target):
        """The device resolve of ``t``'s format (built once per format and sample count), or
        None where it stays on the host (float32, snorm, integer formats, the float64
        evaluation)."""
        import pyopencl as cl
        fmt = t.fmt
        key = (fmt.name, t.samples)
        if key in self._resolvers:
            return self._resolvers[key]
        kern = None
        if not self.f64:
            from pipegen.backends.opencl import programs as cl_programs
            src = cl_programs.resolve_program(fmt.name, t.samples)
            if src is not None:
                kern = cl.Kernel(cl_context.build_program(src), "pg_resolve")
        self._resolvers[key] = kern
        return kern

    def read(self, t: Target) -> dict:
        self.resolve(t)
        codes, st = self._read_planes(t, t.res, t.res_stencil, 1)
        out = {t.name: codes[0].astype(np.float64) if self.f64 else codes[0]}
        if st is not None:
            out[t.name + ".stencil"] = st[0]
        return out

    def read_all(self) -> dict:
        """Every target's codes; with ``alias``, those of the targets their storage holds
        now (``FrameClears.holding``)."""
        holding = set(self._clears.holding()) if self._clears else set(self.targets)
        out = {}
        for name, t in self.targets.items():
            if name in holding:
                out.update(self.read(t))
        return out

    def write(self, name: str, codes: np.ndarray, stencil: Optional[np.ndarray] = None):
        """Overwrite a target of the current frame with codes (GL row order): every sample."""
        import pyopencl as cl
        t = self.targets[name]
        if self._doubles(t.fmt):     # the float64 evaluation: values, not codes
            data = np.ascontiguousarray(value_range(t.fmt, codes), np.float64)
        else:
            data = np.ascontiguousarray(t.fmt.pack(np.asarray(codes)))
        cl.enqueue_copy(self.queue, t.buf, np.ascontiguousarray(
            np.broadcast_to(data, (t.samples,) + data.shape)))
        if t.res is not t.buf:
            cl.enqueue_copy(self.queue, t.res, data)
        if stencil is not None and t.stencil is not None:
            st = np.ascontiguousarray(np.asarray(stencil, np.uint8))
            cl.enqueue_copy(self.queue, t.stencil, np.ascontiguousarray(
                np.broadcast_to(st, (t.samples,) + st.shape)))
            if t.res_stencil is not t.stencil:
                cl.enqueue_copy(self.queue, t.res_stencil, st)
        t.dirty = False

    # -- blend counts -------------------------------------------------------------------------
    def blend_count(self, t: Target):
        """The per-pixel count of fragments blended into colour target ``t`` this frame (a
        uint32 per pixel, zeroed at the first blended pass; the raster kernel adds its
        pixel's count at the end of every blended pass)."""
        import pyopencl as cl
        buf = self.blend_counts.get(t.name)
        if buf is None:
            buf = self._count_pool.get((t.name, t.pixels))
            if buf is None:
                buf = self._count_pool[(t.name, t.pixels)] = cl.Buffer(
                    self.ctx, cl.mem_flags.READ_WRITE, size=t.pixels * 4)
            cl.enqueue_fill_buffer(self.queue, buf, np.uint32(0), 0, t.pixels * 4)
            self.blend_counts[t.name] = buf
        return buf

    def read_blend_counts(self, bufs: Optional[dict] = None) -> dict:
        """``{target: (H, W) uint32}`` of the count buffers ``bufs`` (this frame's: default)."""
        import pyopencl as cl
        out = {}
        for name, buf in (self.blend_counts if bufs is None else bufs).items():
            t = self.targets[name]
            a = np.empty((t.height, t.width), np.uint32)
            cl.enqueue_copy(self.queue, a, buf)
            out[name] = a
        return out
