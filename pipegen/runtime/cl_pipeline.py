"""Run a compiled plan on the OpenCL software reference (pyopencl on PoCL's CPU device).

``CLPipeline(plan, size=None).render(scene) -> {target: codes}`` returns the same arrays as
``GLPipeline``: GL row order (row 0 = window y 0, the bottom row), ``formats.Format.dtype``
codes, ``(H, W)`` for one channel and ``(H, W, C)`` otherwise; a d24s8 target ``ds`` gives
24-bit depth codes under ``"ds"`` and the stencil under ``"ds.stencil"``.
``render(..., capture_passes=True)`` returns ``(targets, captures)`` with one entry
``{"pass", "light", "targets", "blend_counts"}`` after every executed pass (per light inside
repeat groups).

``last_blend_counts`` (after ``render``): ``{target: (H, W) uint32}`` in GL row order, for every
colour target some pass blended into this frame, how many fragments were blended into each
pixel (counted by the raster kernel where it applies the blend: after discard, depth and
stencil; once per fragment whatever its samples).  ``pipegen check`` allows 1 + P codes/ulps
per pixel from it (DESIGN.md §7).

Per pass (see ``backends/opencl.py`` for the program and ``cl_setup.py`` for the host stages):

    pg_vertex (CL) -> clip + setup + binning (numpy) -> pg_raster (CL)

Targets live in device buffers in GL row order for the whole frame; clears write the codes of
``Format.quantize`` (the same the GL runtime clears with).  Passes of one ``repeat_group`` run
once per light in turn (the group's passes for light 0, then for light 1, ...; a pass whose
light filter or ``repeat_types`` excludes the light is skipped for it), the light index
reaching the fragment function as ``in->light``; light draws instance the pass's light list
(``light_table.light_list``: types, CPU-sorted ``light_set`` via
``packing.sort_lights_into_slots``), ``scissor`` light draws clip each
light's triangles to ``fixed_function.light_scissor_rect``, ``cull auto`` light draws keep
each light's front or back faces as ``fixed_function.cull_runs`` chooses.  All as
``GLPipeline`` does.

Multisampled targets (4 samples, llvmpipe's positions) keep one plane per sample; the passes
that read them, and ``render``'s result, see the resolve llvmpipe's blit computes (colour: the
average of the samples stored like a fragment output; depth, stencil, integers: sample 0,
d24 depth codes through llvmpipe's float round trip, ``d24_resolve``).

Set-up triangles are cached per frame and shared by the passes that draw the same geometry
under the same raster state (``_geometry``): a scene draw is set up once for every pass of
the plan drawing it under that state, with the union of their varyings (a pass reading fewer
gets varying and plane buffers cut from the shared ones); a light draw sets up all lights of
its light list at once, without culling, and each pass (each light of a repeat group) draws
its lights' consecutive range of triangles with its own cull mode; the full-screen triangle
is kept across frames.  Per-triangle results do not depend on which other triangles or
varyings are set up with them, so sharing changes no value.  Bins are per pass (light
draws cut them from the (triangle, tile) pairs of all their lights).  Raster kernels are
queued without waiting (the host sets up the next pass meanwhile); target and blend-count
buffers are reused from frame to frame (cleared as before).

``CLPipeline(..., dynamic_state=True)`` is for tests: every pass program reads its
fixed-function state from a kernel argument instead of baked constants, so one compiled program
serves all the states a parametrised test sweeps (production plans bake the state).
``last_timings`` holds per-pass times (ms) of the latest render: ``vertex``, ``setup``,
``bin``, ``raster`` (kernel times from OpenCL profiling events, read at the end of the frame;
host stages from the clock; a pass that reused cached geometry or bins has no
vertex/setup or bin entry), ``triangles`` and ``tile_entries``.  ``preset(name, codes)``
starts later renders with a target holding given codes (tests).

"""

from __future__ import annotations

import time
from typing import Optional

import numpy as np

from .. import formats as F
from ..backends import opencl as clgen
from ..ir import Size
from . import cl_context
from .common import (check_light_capacity, check_param_overrides, light_filter, light_list,
                     light_type)
from .cl_setup import bin_pairs, bin_triangles, bins_from_pairs, setup_triangles

__all__ = ["CLPipeline", "FRAME_DTYPE", "d24_resolve"]

# host image of the prelude's pg_frame struct
FRAME_DTYPE = np.dtype([("view", "<f4", (16,)), ("proj", "<f4", (16,)),
                        ("inv_view", "<f4", (16,)), ("inv_proj", "<f4", (16,)),
                        ("camera_pos", "<f4", (4,)), ("ambient", "<f4", (4,)),
                        ("output_size", "<f4", (4,)), ("num_lights", "<u4"), ("light", "<u4"),
                        ("light_fields", "<u4"), ("pad", "<u4")])
assert FRAME_DTYPE.itemsize == 320


def d24_resolve(codes: np.ndarray) -> np.ndarray:
    """d24 codes as llvmpipe's multisample depth resolve writes them back: its blit reads
    sample 0 as a float and stores it as a d24 code again, ``code * (float)(1/(2^24-1))``,
    then ``* (2^24-1)`` rounded to nearest even, all float32 (measured on Mesa 22.3: moves
    about a third of the codes by one)."""
    f32 = np.float32
    v = (np.asarray(codes).astype(f32) * f32(1.0 / 16777215.0)).astype(f32)
    return np.rint((v * f32(16777215.0)).astype(f32)).astype(np.uint32)


def _colmajor(m: np.ndarray) -> np.ndarray:
    return np.asarray(m, np.float64).astype(np.float32).T.reshape(16)


def _f4(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, np.float32)
    out = np.zeros((len(a), 4), np.float32)
    out[:, :a.shape[1]] = a
    return out


class _Target:
    def __init__(self, spec: dict, width: int, height: int):
        self.spec = spec
        self.name = spec["name"]
        self.fmt = F.get(spec["format"])
        self.cl = clgen.cl_format(self.fmt.name)
        self.width, self.height = width, height
        self.samples = max(1, int(spec.get("samples") or 1))
        self.buf = None           # colour or depth codes, one plane per sample
        self.stencil = None       # d24s8 stencil, one plane per sample
        self.res = None           # the resolved (single-sample) planes: reads and readback
        self.res_stencil = None
        self.dirty = False        # samples newer than the resolved planes

    @property
    def pixels(self) -> int:
        return self.width * self.height


class CLPipeline:
    def __init__(self, plan: dict, size: Optional[tuple[int, int]] = None,
                 cache_dir: Optional[str] = None, dynamic_state: bool = False,
                 tile: int = clgen.TILE):
        assert plan.get("backend") in ("cl", None), "CLPipeline needs a plan from emit_cl"
        self.plan = plan
        self.size = size
        self.dynamic_state = dynamic_state
        self.tile = tile
        self.ctx, self.queue = cl_context.get_context(
            cache_dir, key=f"{plan.get('technique', '')}:{plan.get('source', '')}")
        self.targets_spec = {t["name"]: t for t in plan["targets"]}
        self._programs: dict[int, object] = {}
        self.last_timings: list[dict] = []
        self.last_blend_counts: dict[str, np.ndarray] = {}
        self._blend_counts: dict = {}
        self._geometry_cache: dict = {}
        self._static_geometry: dict = {}   # full-screen draws: the same every frame
        self._count_pool: dict = {}         # blend-count buffers, reused every frame
        self._presets: dict = {}
        self._scene = None
        self._scene_attrs: dict = {}
        self._light_sets: dict = {}
        self.dropped_lights: dict = {}   # per channel_slots pack, last scene
        self._dummy = self._buffer(np.zeros(4, np.int32))
        self._zeros4 = self._buffer(np.zeros((1, 4), np.float32))
        self._events: list = []
        self._kernels: dict = {}
        self._meshes: dict = {}
        for k in range(len(plan["passes"])):
            self._program(k)

    # -- programs ---------------------------------------------------------------------------------
    def _program(self, k: int):
        prog = self._programs.get(k)
        if prog is None:
            src = self.source(k)
            prog = cl_context.build_program(src)
            self._programs[k] = prog
        return prog

    def _kernel(self, k: int, name: str):
        """Kernel objects are cached: pyopencl builds an argument invoker per Kernel object."""
        import pyopencl as cl
        kern = self._kernels.get((k, name))
        if kern is None:
            kern = self._kernels[(k, name)] = cl.Kernel(self._program(k), name)
        return kern

    def source(self, k: int) -> str:
        p = self.plan["passes"][k]
        if self.dynamic_state or not p.get("kernel") or self.tile != clgen.TILE:
            return clgen.pass_program(self.plan, p, dynamic=self.dynamic_state, tile=self.tile)
        return p["kernel"]

    # -- buffers ----------------------------------------------------------------------------------
    def _buffer(self, array: np.ndarray):
        import pyopencl as cl
        a = np.ascontiguousarray(array)
        if a.nbytes == 0:
            a = np.zeros(16, np.uint8)
        return cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)

    def _clear_target(self, t: _Target, color=None, depth=None, stencil=None,
                      depth_given: bool = True, stencil_given: bool = True) -> None:
        n = t.pixels
        if t.samples > 1:          # keep the resolved plane current for a partial clear
            self._resolve(t)
        self._fill(t, t.buf, t.stencil, t.samples * n, color, depth, stencil, depth_given,
                   stencil_given)
        if t.samples > 1:
            self._fill(t, t.res, t.res_stencil, n, color, depth, stencil, depth_given,
                       stencil_given)
        t.dirty = False

    def _fill(self, t: _Target, buf, sbuf, n: int, color, depth, stencil, depth_given: bool,
              stencil_given: bool) -> None:
        import pyopencl as cl
        fmt = t.fmt
        if fmt.kind is F.Kind.DEPTH_STENCIL:
            if depth_given:
                code = np.uint32(fmt.quantize(np.float64(depth if depth is not None else 0.0)))
                cl.enqueue_fill_buffer(self.queue, buf, code, 0, n * 4)
            if stencil_given:
                s = np.uint8(int(stencil or 0) & 0xFF)
                cl.enqueue_fill_buffer(self.queue, sbuf, s, 0, n)
            return
        if fmt.kind is F.Kind.DEPTH:
            if depth_given:
                v = np.float32(fmt.quantize(np.float64(depth if depth is not None else 0.0)))
                cl.enqueue_fill_buffer(self.queue, buf, v, 0, n * 4)
            return
        col = np.zeros(4) if color is None else np.asarray(color, np.float64)
        if col.ndim == 0:
            col = np.full(4, float(col))
        col = np.concatenate([col, np.zeros(4)])[:4]
        if fmt.kind is F.Kind.UINT:
            codes = col[:fmt.channels].astype(np.uint64).astype(fmt.dtype)
        else:
            codes = fmt.quantize(col[:fmt.channels])
        pixel = self._pack(t, np.asarray(codes).reshape(1, 1, -1) if fmt.channels > 1
                           else np.asarray(codes).reshape(1, 1))
        pattern = np.ascontiguousarray(pixel).view(np.uint8).reshape(-1)
        if len(pattern) in (1, 2, 4, 8, 16, 32, 64, 128):     # clEnqueueFillBuffer's sizes
            cl.enqueue_fill_buffer(self.queue, buf, pattern, 0, n * len(pattern))
        else:
            cl.enqueue_copy(self.queue, buf, np.tile(pattern, n))

    def _pack(self, t: _Target, codes: np.ndarray) -> np.ndarray:
        """Format codes (H, W[, C]) -> device layout."""
        fmt = t.fmt
        if fmt.name == "rgb10a2":
            c = codes.astype(np.uint32)
            return ((c[..., 0] & 1023) | ((c[..., 1] & 1023) << 10) | ((c[..., 2] & 1023) << 20)
                    | ((c[..., 3] & 3) << 30)).astype(np.uint32)
        return np.ascontiguousarray(codes.astype(fmt.dtype))

    def _unpack(self, t: _Target, raw: np.ndarray) -> np.ndarray:
        fmt = t.fmt
        if fmt.name == "rgb10a2":
            w = raw.astype(np.uint32)
            return np.stack([w & 1023, (w >> 10) & 1023, (w >> 20) & 1023, w >> 30],
                            axis=-1).astype(fmt.dtype)
        return raw

    def _read_planes(self, t: _Target, buf, sbuf, planes: int):
        """(codes (planes, H, W[, C]), stencil (planes, H, W) or None) of a buffer pair."""
        import pyopencl as cl
        fmt = t.fmt
        h, w = t.height, t.width
        if fmt.kind in (F.Kind.DEPTH_STENCIL, F.Kind.DEPTH):
            d = np.empty((planes, h, w), np.uint32 if fmt.kind is F.Kind.DEPTH_STENCIL
                         else np.float32)
            cl.enqueue_copy(self.queue, d, buf)
            st = None
            if fmt.kind is F.Kind.DEPTH_STENCIL:
                st = np.empty((planes, h, w), np.uint8)
                cl.enqueue_copy(self.queue, st, sbuf)
            return d, st
        if fmt.name == "rgb10a2":
            raw = np.empty((planes, h, w), np.uint32)
        else:
            raw = np.empty((planes,) + fmt.array_shape(w, h), fmt.dtype)
        cl.enqueue_copy(self.queue, raw, buf)
        return self._unpack(t, raw), None

    def _resolve(self, t: _Target) -> None:
        """Resolve the samples like llvmpipe's blit (measured): colour = the average of the
        sample values, stored like a fragment output (unorm: round half to even, half:
        toward zero); depth, stencil and integer formats take sample 0, d24 depth through
        llvmpipe's float round trip (``d24_resolve``)."""
        import pyopencl as cl
        if t.samples == 1 or not t.dirty:
            return
        codes, st = self._read_planes(t, t.buf, t.stencil, t.samples)
        fmt = t.fmt
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
                from ..reference.fixed_function import half_store
                res = half_store(avg, "rtz")
            else:
                res = avg
            res = res[None]
        elif fmt.kind is F.Kind.DEPTH_STENCIL:
            res = d24_resolve(codes[0])[None]
        else:
            res = codes[:1]
        cl.enqueue_copy(self.queue, t.res, np.ascontiguousarray(self._pack(t, res[0])))
        if st is not None:
            cl.enqueue_copy(self.queue, t.res_stencil, np.ascontiguousarray(st[0]))
        t.dirty = False

    def _read(self, t: _Target) -> dict:
        self._resolve(t)
        codes, st = self._read_planes(t, t.res, t.res_stencil, 1)
        out = {t.name: codes[0]}
        if st is not None:
            out[t.name + ".stencil"] = st[0]
        return out

    def preset(self, name: str, codes: np.ndarray, stencil: Optional[np.ndarray] = None) -> None:
        """Start the next renders with target ``name`` holding ``codes`` (GL row order, like
        the arrays ``render`` returns) instead of its clear value; ``stencil`` for d24s8."""
        self._presets[name] = (np.asarray(codes), None if stencil is None else np.asarray(stencil))

    def write_target(self, name: str, codes: np.ndarray, stencil: Optional[np.ndarray] = None):
        """Overwrite a target of the current frame with codes (GL row order): every sample."""
        import pyopencl as cl
        t = self._targets[name]
        data = np.ascontiguousarray(self._pack(t, np.asarray(codes)))
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

    # -- frame --------------------------------------------------------------------------------------
    def output_size(self, scene) -> tuple[int, int]:
        if self.size is not None:
            return int(self.size[0]), int(self.size[1])
        return int(scene.width), int(scene.height)

    def target_size(self, name: str, out_w: int, out_h: int) -> tuple[int, int]:
        t = self.targets_spec[name]
        return Size(float(t.get("scale") or 1.0), int(t.get("width") or 0),
                    int(t.get("height") or 0)).resolve(out_w, out_h)

    def prepare(self, scene) -> None:
        """Allocate and clear every target for a frame of ``scene``."""
        out_w, out_h = self.output_size(scene)
        self._out = (out_w, out_h)
        last = getattr(self, "_targets", {})
        self._targets = {}
        for name, spec in self.targets_spec.items():
            w, h = self.target_size(name, out_w, out_h)
            t = _Target(spec, w, h)
            old = last.get(name)
            if old is not None and (old.width, old.height) == (w, h):
                # the last frame's buffers (its results were read back): cleared below
                t.buf, t.stencil = old.buf, old.stencil
                t.res, t.res_stencil = old.res, old.res_stencil
            else:
                t.buf = t.res = self._alloc(t, t.samples)
                if t.fmt.kind is F.Kind.DEPTH_STENCIL:
                    t.stencil = t.res_stencil = self._buffer(
                        np.zeros(w * h * t.samples, np.uint8))
                if t.samples > 1:
                    t.res = self._alloc(t, 1)
                    if t.stencil is not None:
                        t.res_stencil = self._buffer(np.zeros(w * h, np.uint8))
            self._targets[name] = t
            self._clear_target(t, spec.get("clear_color"), spec.get("clear_depth"),
                               spec.get("clear_stencil"))

    def _alloc(self, t: _Target, planes: int):
        import pyopencl as cl
        fmt = t.fmt
        if fmt.kind in (F.Kind.DEPTH_STENCIL, F.Kind.DEPTH) or fmt.name == "rgb10a2":
            nbytes = 4
        else:
            nbytes = fmt.dtype.itemsize * fmt.channels
        return cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE,
                         size=max(16, t.pixels * nbytes * planes))

    def _frame(self, scene, light: int = 0) -> np.ndarray:
        out_w, out_h = self._out
        cam = scene.camera
        view = cam.view_matrix()
        proj = cam.projection(out_w / out_h)
        fr = np.zeros((), FRAME_DTYPE)
        fr["view"] = _colmajor(view)
        fr["proj"] = _colmajor(proj)
        fr["inv_view"] = _colmajor(np.linalg.inv(view))
        fr["inv_proj"] = _colmajor(np.linalg.inv(proj))
        fr["camera_pos"][:3] = np.asarray(cam.position, np.float32)
        fr["ambient"][:3] = np.asarray(scene.ambient, np.float32)
        fr["output_size"][:2] = (out_w, out_h)
        fr["num_lights"] = len(scene.lights)
        self._view, self._proj = view, proj
        fr["light"] = light
        fr["light_fields"] = len(self.plan["lights"]["fields"])
        return fr

    # -- rendering ----------------------------------------------------------------------------------
    def render(self, scene, params: Optional[dict] = None, capture_passes: bool = False):
        """Render one frame: ``{target: codes}``, or ``(targets, captures)`` with
        ``capture_passes`` (see the module docstring)."""
        check_param_overrides(self.plan, params)
        self._use_scene(scene)
        self.prepare(scene)
        for name, (codes, stencil) in self._presets.items():
            self.write_target(name, codes, stencil)
        self.last_timings = []
        self._blend_counts = {}
        self._geometry_cache = {}
        self._events = []
        self._frame_np = self._frame(scene)
        self._frame_buf = self._buffer(self._frame_np)
        captures: list[dict] = []
        passes = self.plan["passes"]
        k = 0
        while k < len(passes):
            group = passes[k].get("repeat_group")
            if group is None:
                self._run_pass(k, None)
                if capture_passes:
                    captures.append({"pass": passes[k]["name"], "light": None,
                                     "targets": self._read_all(),
                                     "blend_counts": self._read_blend_counts()})
                k += 1
                continue
            end = k
            while end < len(passes) and passes[end].get("repeat_group") == group:
                end += 1
            lists = {j: set(self._light_list(passes[j]["draw"])) for j in range(k, end)
                     if light_filter(passes[j]["draw"])}
            for light in range(len(scene.lights)):
                for j in range(k, end):
                    if j in lists and light not in lists[j]:
                        continue
                    types = passes[j].get("repeat_types") or []
                    if types and light_type(scene.lights[light]) not in types:
                        continue
                    self._run_pass(j, light)
                    if capture_passes:
                        captures.append({"pass": passes[j]["name"], "light": light,
                                         "targets": self._read_all(),
                                         "blend_counts": self._read_blend_counts()})
            k = end
        result = self._read_all()
        self.last_blend_counts = self._read_blend_counts()
        self.queue.finish()
        for timing, ev in self._events:          # raster kernels run while the host goes on
            timing["raster"] = (ev.profile.end - ev.profile.start) * 1e-6
        self._events = []
        return (result, captures) if capture_passes else result

    def _use_scene(self, scene) -> None:
        if self._scene is scene:
            return
        self._scene = scene
        self._light_sets = {}
        self.dropped_lights = {}
        self._scene_attrs = {}
        capacity = max(1, int(self.plan["lights"]["capacity"]))
        if self.plan["lights"]["fields"]:
            check_light_capacity(len(scene.lights), capacity, self.plan)
        fields = [list(f) for f in self.plan["lights"]["fields"]]
        table = (np.asarray(scene.light_table(fields, capacity), np.float32) if fields
                 else np.zeros((0, 4), np.float32))
        self._lights_buf = self._buffer(table.reshape(-1, 4) if table.size
                                        else np.zeros((1, 4), np.float32))

    def _read_all(self) -> dict:
        out = {}
        for t in self._targets.values():
            out.update(self._read(t))
        return out

    def _blend_count_buffer(self, t: _Target):
        """The per-pixel count of fragments blended into colour target ``t`` this frame (a
        uint32 per pixel, zeroed at the first blended pass; the raster kernel adds its
        pixel's count at the end of every blended pass)."""
        import pyopencl as cl
        buf = self._blend_counts.get(t.name)
        if buf is None:
            buf = self._count_pool.get((t.name, t.pixels))
            if buf is None:
                buf = self._count_pool[(t.name, t.pixels)] = cl.Buffer(
                    self.ctx, cl.mem_flags.READ_WRITE, size=t.pixels * 4)
            cl.enqueue_fill_buffer(self.queue, buf, np.uint32(0), 0, t.pixels * 4)
            self._blend_counts[t.name] = buf
        return buf

    def _read_blend_counts(self) -> dict:
        import pyopencl as cl
        out = {}
        for name, buf in self._blend_counts.items():
            t = self._targets[name]
            a = np.empty((t.height, t.width), np.uint32)
            cl.enqueue_copy(self.queue, a, buf)
            out[name] = a
        return out

    def _run_pass(self, k: int, light: Optional[int]) -> None:
        import pyopencl as cl
        p = self.plan["passes"][k]
        for c in p.get("clears") or []:
            t = self._targets[c["target"]]
            partial = t.fmt.kind is F.Kind.DEPTH_STENCIL and (
                (c.get("clear_depth") is None) != (c.get("clear_stencil") is None))
            self._clear_target(t, c.get("clear_color"), c.get("clear_depth"),
                               c.get("clear_stencil"),
                               depth_given=not partial or c.get("clear_depth") is not None,
                               stencil_given=not partial or c.get("clear_stencil") is not None)
        attached = list(p.get("writes") or []) + ([p["depth_target"]] if p.get("depth_target") else [])
        if attached:
            first = self._targets[attached[0]]
            width, height = first.width, first.height
        else:
            width, height = self._out
        timing = {"pass": p["name"], "light": light}
        self.last_timings.append(timing)
        draw = p["draw"]
        lights = None
        if draw["kind"] == "lights":
            if light is not None:
                lights = [light] if (not light_filter(draw)
                                     or light in self._light_list(draw)) else []
            else:
                lights = self._light_list(draw)
            if not lights:
                return
        drawn = self._pass_triangles(k, p, width, height, timing, lights)
        if drawn is None:
            return
        geo, tb = drawn
        bufs = geo.bufs
        st = self._dummy
        if self.dynamic_state:
            st = self._buffer(np.asarray(clgen.state_words(p), np.int32))
        args = [np.int32(width), np.int32(height), np.int32(tb.tiles_x), tb.tile_list,
                tb.tile_start, tb.tile_tris, bufs["a"], bufs["b"], bufs["c"],
                bufs["z"], bufs["w"], bufs["coef"], np.int32(geo.ncoef),
                bufs["zp"], bufs["zq"], bufs["flat"], bufs["vtx"], bufs["scissor"],
                bufs["bbox"], bufs["vary"], np.int32(geo.tris.nverts), self._frame_buf,
                self._lights_buf, st, np.uint32(light or 0)]
        for name in p.get("writes") or []:
            args.append(self._targets[name].buf)
        blend = (p.get("state") or {}).get("blend") or {}
        for name in p.get("writes") or []:
            t = self._targets[name]
            if t.cl["cls"] != "uint":
                on = bool((blend.get(name) or {}).get("enabled"))
                args.append(self._blend_count_buffer(t) if on else self._dummy)
        if p.get("depth_target"):
            dt = self._targets[p["depth_target"]]
            args.append(dt.buf)
            if dt.stencil is not None:
                args.append(dt.stencil)
        for name in p.get("reads") or []:
            rt = self._targets[name]
            self._resolve(rt)                     # reads see the resolved texture, like GL
            args += [rt.res, cl.cltypes.make_int2(rt.width, rt.height)]
        kern = self._kernel(k, "pg_raster")
        kern.set_args(*args)
        T = self.tile
        ev = cl.enqueue_nd_range_kernel(self.queue, kern, (tb.ntiles * T,), (T,))
        self._events.append((timing, ev))
        for name in attached:
            if self._targets[name].samples > 1:
                self._targets[name].dirty = True
        timing["triangles"] = tb.triangles
        timing["tile_entries"] = tb.entries

    # -- geometry ----------------------------------------------------------------------------------
    def _light_list(self, draw: dict) -> list[int]:
        """The lights a light draw instances, in table order (light_table.light_list)."""
        return light_list(draw, list(self._scene.lights), self.plan, self._light_sets,
                          self.dropped_lights)

    def _mesh(self, volume: str):
        if volume not in self._meshes:
            from ..meshes import light_volume
            mesh = light_volume(volume)
            self._meshes[volume] = (len(mesh), self._buffer(_f4(mesh)))
        return self._meshes[volume]

    def _attributes(self, material: tuple) -> tuple:
        if material not in self._scene_attrs:
            g = self._scene.geometry(material)
            n = g.vertex_count
            if n == 0:
                self._scene_attrs[material] = None
            else:
                ids = np.floor(np.asarray(g.ids, np.float32)[2::3].astype(np.float64)
                               + 0.5).astype(np.uint32)            # uvec2(a_ids + 0.5), flat
                flat = np.zeros((n // 3, 4), np.uint32)
                flat[:, 1:3] = ids
                layer = getattr(g, "layer", None)          # uint(a_layer + 0.5), flat
                if layer is not None:
                    flat[:, 3] = np.floor(np.asarray(layer, np.float32)[2::3].astype(np.float64)
                                          + 0.5).astype(np.uint32)
                attrs = [self._buffer(_f4(a)) for a in (g.positions, g.normals, g.albedo,
                                                         g.material)]
                self._scene_attrs[material] = (n, attrs, flat)
        return self._scene_attrs[material]

    def _pass_triangles(self, k: int, p: dict, width: int, height: int, timing: dict,
                        lights: Optional[list]):
        """(geometry, tile bins) a pass draws, or None when it draws no triangle.

        Geometry (vertex kernel, clipping and setup, on the device) is cached per frame and
        shared by the passes that draw the same triangles under the same raster state.  A
        light draw sets up every light of its light list at once, with no culling, and each
        pass draws the range of its light(s) (the instances are consecutive in submission
        order), keeping the faces its cull mode keeps: inside a repeat group one set-up
        serves all lights and every pass of the group with the same raster state.  Bins are
        per pass (cached per frame too) and index the shared triangles; for light draws they
        are cut from the (triangle, tile) pairs of all lights, found once."""
        draw = p["draw"]
        st = p.get("state") or {}
        cull = st.get("cull") or "none"
        static = draw["kind"] not in ("scene", "lights")
        cache = self._static_geometry if static else self._geometry_cache
        if draw["kind"] == "lights":
            batch = tuple(self._light_list(draw))
            if not set(lights) <= set(batch):
                batch = tuple(lights)
            geo = self._geometry(k, p, width, height, timing, batch)
            if geo is None:
                return None
            if cull == "auto":
                key = ("auto", id(geo), tuple(lights))
                sub = cache.get(key)
                if sub is None:
                    tris = geo.tris
                    if tuple(lights) != batch:
                        tris = _select_triangles(tris, np.concatenate(
                            [np.arange(*geo.ranges[int(l)]) for l in lights]))
                    tris = self._cull_auto(tris, draw.get("volume") or "sphere", lights)
                    sub = cache[key] = self._upload(tris, geo.bufs["vary"])
                geo = sub
            else:
                key = ("bins", id(geo.tris), tuple(lights), cull, width, height)
                tb = cache.get(key)
                if tb is None:
                    t0 = time.perf_counter()
                    pairs = cache.get(("pairs", id(geo.tris), width, height))
                    if pairs is None:
                        pairs = cache[("pairs", id(geo.tris), width, height)] = bin_pairs(
                            geo.tris, width, height, self.tile)
                    tri, tile_id, tiles_x, tiles_y = pairs
                    if tuple(lights) != batch:       # the pairs of these lights' triangles
                        cut = [np.searchsorted(tri, geo.ranges[int(l)]) for l in lights]
                        tri = np.concatenate([tri[a:b] for a, b in cut])
                        tile_id = np.concatenate([tile_id[a:b] for a, b in cut])
                    if cull in ("back", "front"):
                        keep = geo.front[tri] == (cull == "back")
                        tri, tile_id = tri[keep], tile_id[keep]
                    tile_start, tile_tris = bins_from_pairs(tri, tile_id, tiles_x * tiles_y)
                    timing["bin"] = (time.perf_counter() - t0) * 1e3
                    n = sum(b - a for a, b in (geo.ranges[int(l)] for l in lights))
                    if cull in ("back", "front"):
                        front = sum(int(np.count_nonzero(geo.front[a:b]))
                                    for a, b in (geo.ranges[int(l)] for l in lights))
                        n = front if cull == "back" else n - front
                    tb = cache[key] = _Bins(self, tile_start, tile_tris, tiles_x, n)
                return (geo, tb) if tb.ntiles else None
        else:
            geo = self._geometry(k, p, width, height, timing, None)
            if geo is None:
                return None
        key = ("bins", id(geo.tris), cull, width, height)
        tb = cache.get(key)
        if tb is None:
            t0 = time.perf_counter()
            tile_start, tile_tris, tiles_x, _ = bin_triangles(geo.tris, width, height, self.tile)
            timing["bin"] = (time.perf_counter() - t0) * 1e3
            tb = cache[key] = _Bins(self, tile_start, tile_tris, tiles_x, geo.tris.count)
        if tb.ntiles == 0:
            return None
        return geo, tb

    def _pass_size(self, p: dict) -> tuple[int, int]:
        """The viewport of a pass: its first attachment's size, else the output size."""
        attached = list(p.get("writes") or []) + (
            [p["depth_target"]] if p.get("depth_target") else [])
        if attached:
            t = self._targets[attached[0]]
            return t.width, t.height
        return self._out

    def _raster_key(self, p: dict, width: int, height: int) -> tuple:
        """What the set-up triangles of a pass's draw depend on besides its varyings."""
        draw = p["draw"]
        st = p.get("state") or {}
        depth_clamp = bool((st.get("depth") or {}).get("clamp"))
        dfmt = p.get("depth_target") and self._targets[p["depth_target"]].fmt.name
        # llvmpipe folds the pixel centre into the planes' a0 unless the pass is multisampled
        center = 0.0 if self._pass_samples(p) > 1 else 0.5
        if draw["kind"] == "lights":
            # culling is per pass (light draws are set up without it)
            return ("lights", draw.get("volume") or "sphere", bool(draw.get("scissor")),
                    str(st.get("polygon_offset")), depth_clamp, width, height, dfmt, center)
        return (draw["kind"], tuple(draw.get("material") or ()), st.get("cull") or "none",
                str(st.get("polygon_offset")), depth_clamp, width, height, dfmt, center)

    def _scene_group(self, key: tuple) -> tuple:
        """The passes of the plan drawing the scene under raster key ``key`` share one set-up:
        with the union of their varyings (SCENE_VARYINGS order) and the 1/w plane if any of
        them needs it.  Returns (names, flat flags, providers, w_plane); ``providers``: the
        passes whose vertex kernels compute the union (k, [their varying names])."""
        got = self._geometry_cache.get(("group", key))
        if got is not None:
            return got
        members = []
        for k, q in enumerate(self.plan["passes"]):
            if q["draw"]["kind"] != "scene":
                continue
            if self._raster_key(q, *self._pass_size(q)) != key:
                continue
            members.append((k, clgen.varying_slots(q),
                            "frag_coord" in ((q.get("cl") or {}).get("inputs") or ())))
        union = {v["name"]: v["flat"] for _, slots, _ in members for v in slots}
        names = [n for n in clgen.SCENE_VARYINGS if n in union]
        providers, missing = [], set(names)
        for k, slots, _ in sorted(members, key=lambda m: -len(m[1])):
            have = [v["name"] for v in slots]
            if missing & set(have):
                providers.append((k, have))
                missing -= set(have)
        got = (names, [union[n] for n in names], providers, any(m[2] for m in members))
        self._geometry_cache[("group", key)] = got
        return got

    def _geometry(self, k: int, p: dict, width: int, height: int, timing: dict,
                  lights: Optional[tuple]):
        """Vertex kernel, clipping and setup of a pass's draw (``lights``: every light a light
        draw sets up); cached per frame.  Scene draws are set up once for every pass drawing
        them under the same raster state (``_scene_group``); a pass reading fewer varyings
        gets its own varying and plane buffers cut from the shared ones."""
        draw = p["draw"]
        key = self._raster_key(p, width, height)
        if draw["kind"] == "lights":
            key = key + (lights,)
        elif draw["kind"] == "scene":
            names = [v["name"] for v in clgen.varying_slots(p)]
            pkey = key + (tuple(names),)
            if pkey in self._geometry_cache:
                return self._geometry_cache[pkey]
            base = self._geometry_cache.get(key, False)
            if base is False:
                base = self._set_up(k, p, width, height, timing, key, lights)
            geo = base if base is None else self._cut(base, names)
            self._geometry_cache[pkey] = geo
            return geo
        if key in self._geometry_cache:
            return self._geometry_cache[key]
        if draw["kind"] == "lights":
            return self._set_up(k, p, width, height, timing, key, lights)
        # the full-screen triangle depends on nothing of the frame: kept across frames
        if key not in self._static_geometry:
            self._static_geometry[key] = self._set_up(k, p, width, height, timing, key, lights)
        geo = self._geometry_cache[key] = self._static_geometry[key]
        return geo

    def _cut(self, geo: "_Geo", names: list) -> "_Geo":
        """The shared scene set-up ``geo`` as a pass reading varyings ``names`` sees it: its
        varyings in slot order (only the flat ones are read from ``vary``) and the planes of
        its smooth ones."""
        if names == geo.names:
            return geo
        if not names:
            return geo          # reads no varying: nothing indexes vary or coef
        tris = geo.tris
        flat = dict(zip(geo.names, geo.flats))
        pos = {n: i for i, n in enumerate(geo.names)}
        smooth_pos = {n: i for i, n in enumerate(n for n in geo.names if not flat[n])}
        vary = np.zeros((len(names), tris.nverts, 4), np.float32)
        for i, n in enumerate(names):
            if flat[n]:
                vary[i] = tris.vary[pos[n]]
        coef = np.ascontiguousarray(tris.coef[:, [smooth_pos[n] for n in names if not flat[n]]])
        cut = _Geo(tris, dict(geo.bufs, vary=self._buffer(vary), coef=self._buffer(coef)))
        cut.ncoef = coef.shape[1]
        cut.names = list(names)
        return cut

    def _set_up(self, k: int, p: dict, width: int, height: int, timing: dict, key: tuple,
                lights: Optional[tuple]):
        """Run the vertex kernel(s), read back clip positions and varyings, clip and set up
        on the host, upload the triangles (cached under ``key``; None: nothing to draw)."""
        import pyopencl as cl
        draw = p["draw"]
        st = p.get("state") or {}
        depth_clamp = bool((st.get("depth") or {}).get("clamp"))
        dfmt = p.get("depth_target") and self._targets[p["depth_target"]].fmt.name
        center = 0.0 if self._pass_samples(p) > 1 else 0.5
        names, flats, providers = [], [], [(k, [])]
        if draw["kind"] == "scene":
            names, flats, providers, w_plane = self._scene_group(key)
            providers = providers or [(k, [])]
            cull = st.get("cull") or "none"
        else:
            # light volumes and the full-screen triangle have no varyings; their 1/w plane
            # (frag_coord.w) is set up always, so that every pass drawing them shares one
            # set-up (light draws are culled per pass)
            w_plane = True
            cull = "none" if draw["kind"] == "lights" else st.get("cull") or "none"
        mesh_verts = 1
        zeros = self._zeros4
        attrs = [zeros] * 4
        inst = np.zeros(1, np.uint32)
        flat = None
        scissor = None
        if draw["kind"] == "scene":
            got = self._attributes(tuple(draw.get("material") or ()))
            if got is None:
                self._geometry_cache[key] = None
                return None
            nverts, attrs, flat = got
        elif draw["kind"] == "lights":
            mesh_verts, mesh_buf = self._mesh(draw.get("volume") or "sphere")
            nverts = mesh_verts * len(lights)
            attrs = [mesh_buf] + [zeros] * 3
            inst = np.asarray(lights, np.uint32)
            flat = np.zeros((nverts // 3, 4), np.uint32)
            flat[:, 3] = np.repeat(inst, mesh_verts // 3)
            if draw.get("scissor"):
                scissor = self._light_scissors(inst, width, height, mesh_verts // 3)
        else:
            nverts = 3
        inst_buf = self._buffer(inst)
        clip = None
        vary = np.empty((len(names), nverts, 4), np.float32) if names else None
        vary_buf = None
        vertex_ms = 0.0
        for kp, have in providers:
            S = len(have)
            clip_buf = cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE, size=nverts * 16)
            vbuf = cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE, size=max(16, S * nverts * 16))
            kern = self._kernel(kp, "pg_vertex")
            kern.set_args(np.int32(nverts), np.int32(mesh_verts), *attrs, inst_buf,
                          self._frame_buf, self._lights_buf, clip_buf, vbuf)
            gsize = ((nverts + 63) // 64) * 64
            ev = cl.enqueue_nd_range_kernel(self.queue, kern, (gsize,), (64,))
            if clip is None:
                clip = np.empty((nverts, 4), np.float32)
                cl.enqueue_copy(self.queue, clip, clip_buf)
            if S:
                out = np.empty((S, nverts, 4), np.float32)
                cl.enqueue_copy(self.queue, out, vbuf)
                for i, n in enumerate(have):
                    if n in names:
                        vary[names.index(n)] = out[i]
                if have == names:
                    vary_buf = vbuf
            ev.wait()
            vertex_ms += (ev.profile.end - ev.profile.start) * 1e-6
        timing["vertex"] = vertex_ms
        t0 = time.perf_counter()
        tris = setup_triangles(clip, width, height, cull=cull,
                               polygon_offset=st.get("polygon_offset"), depth_clamp=depth_clamp,
                               depth_format=dfmt, flat=flat, vary=vary, scissor=scissor,
                               smooth=[i for i, f in enumerate(flats) if not f],
                               pixel_center=center, w_plane=w_plane)
        timing["setup"] = (time.perf_counter() - t0) * 1e3
        if tris.count == 0:
            self._geometry_cache[key] = None
            return None
        if vary_buf is None or tris.vary.shape[1] != nverts:
            vary_buf = self._buffer(tris.vary) if tris.vary is not None else self._zeros4
        geo = self._geometry_cache[key] = self._upload(tris, vary_buf)
        geo.names, geo.flats = names, flats
        if draw["kind"] == "lights":
            light_of = tris.flat[:, 3]
            lo = np.searchsorted(light_of, inst, "left")
            hi = np.searchsorted(light_of, inst, "right")
            geo.ranges = {int(l): (int(a), int(b)) for l, a, b in zip(inst, lo, hi)}
        return geo

    def _upload(self, tris, vary_buf) -> "_Geo":
        bufs = {"a": self._buffer(tris.a), "b": self._buffer(tris.b), "c": self._buffer(tris.c),
                "z": self._buffer(tris.z), "w": self._buffer(tris.w),
                "coef": self._buffer(tris.coef),
                "zp": self._buffer(tris.zp), "zq": self._buffer(tris.zq),
                "flat": self._buffer(tris.flat), "vtx": self._buffer(tris.vtx),
                "scissor": self._buffer(tris.scissor), "bbox": self._buffer(tris.bbox),
                "vary": vary_buf}
        return _Geo(tris, bufs)

    def _pass_samples(self, p: dict) -> int:
        """Samples per pixel of a pass's attachments (as backends/opencl.pass_program)."""
        attached = list(p.get("writes") or []) + (
            [p["depth_target"]] if p.get("depth_target") else [])
        return max([int(self.targets_spec[n].get("samples") or 1) for n in attached] or [1])

    def _cull_auto(self, tris, volume: str, lights: list):
        """``cull auto``: keep each light's front faces or back faces as
        ``fixed_function.cull_runs`` chooses (the GL runtime draws the same runs).  Filtering
        the set-up triangles keeps their submission order, so per pixel the lights still
        arrive in light order."""
        from ..reference.fixed_function import cull_runs
        runs = cull_runs("auto", volume, list(self._scene.lights), lights,
                         self._scene.camera.position, self._proj)
        draw_front = np.zeros(max(lights) + 1, bool)
        for mode, run in runs:
            draw_front[run] = mode == "back"          # culling back faces draws front faces
        front = (tris.flat[:, 0] & 1).astype(bool)
        by_front = draw_front[tris.flat[:, 3]]
        tris = _select_triangles(tris, front == by_front)
        # bit 1 of flat.x: a light drawn with its back faces (`pg_inside`, `depth … inside`)
        tris.flat[:, 0] |= np.where(by_front[front == by_front], 0, 2).astype(np.uint32)
        return tris

    def _light_scissors(self, lights: np.ndarray, width: int, height: int, tris_per: int):
        """Per-triangle scissor rectangles (x0, y0, x1, y1) of each light's screen rectangle."""
        from ..reference.fixed_function import light_scissor_rect
        view, proj = self._view, self._proj
        rects = []
        for i in lights:
            light = self._scene.lights[int(i)]
            x, y, w, h = light_scissor_rect(light.position, light.radius, view, proj, width,
                                            height)
            rects.append((x, y, x + w, y + h))
        return np.repeat(np.asarray(rects, np.int32).reshape(-1, 4), tris_per, axis=0)


class _Geo:
    """Set-up triangles of a draw, on the host (``tris``) and on the device (``bufs``, the
    raster kernel's per-triangle arrays and the varyings); ``ranges``: light -> its
    triangles ``[lo, hi)`` for a light draw; ``front``: the front-facing triangles."""

    def __init__(self, tris, bufs: dict):
        self.tris = tris
        self.bufs = bufs
        self.ranges: dict = {}
        self.front = (tris.flat[:, 0] & 1).astype(bool)
        self.ncoef = tris.coef.shape[1]
        self.names: list = []        # scene draws: the varyings set up, in slot order
        self.flats: list = []


class _Bins:
    """A pass's tile lists on the device: the tiles with triangles (``tile_list``, one
    work-group each), ``tile_start``/``tile_tris`` (CSR, triangle indices into the geometry)."""

    def __init__(self, pipe: "CLPipeline", tile_start, tile_tris, tiles_x: int, triangles: int):
        active = np.flatnonzero(np.diff(tile_start) > 0).astype(np.int32)
        self.ntiles = len(active)
        self.tiles_x = tiles_x
        self.triangles = triangles
        self.entries = int(tile_start[-1])
        self.tile_list = pipe._buffer(active)
        self.tile_start = pipe._buffer(tile_start)
        self.tile_tris = pipe._buffer(tile_tris)


def _select_triangles(tris, keep: np.ndarray):
    """The set-up triangles where ``keep`` holds, in their order (per-triangle arrays are
    indexed; the varyings, which the triangles index, are kept whole)."""
    import dataclasses
    n = tris.count
    idx = np.flatnonzero(keep)
    changes = {}
    for f in dataclasses.fields(tris):
        if f.name in ("vary", "nverts"):
            continue
        v = getattr(tris, f.name)
        if isinstance(v, np.ndarray) and v.ndim >= 1 and len(v) == n:
            changes[f.name] = v[idx]
    return dataclasses.replace(tris, **changes)
