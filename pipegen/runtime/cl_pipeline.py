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
reaching the fragment function as ``in->light``; light draws instance the pass's light list (types, CPU-sorted
``light_set`` via ``packing.sort_lights_into_slots``), ``scissor`` light draws clip each
light's triangles to ``fixed_function.light_scissor_rect``, ``cull auto`` light draws keep
each light's front or back faces as ``fixed_function.cull_runs`` chooses.  All as
``GLPipeline`` does.

Multisampled targets (4 samples, llvmpipe's positions) keep one plane per sample; the passes
that read them, and ``render``'s result, see the resolve llvmpipe's blit computes (colour: the
average of the samples stored like a fragment output; depth, stencil, integers: sample 0,
d24 depth codes through llvmpipe's float round trip, ``d24_resolve``).

Vertex outputs, set-up triangles and bins are cached per frame and shared by the passes that
draw the same geometry under the same raster state (e.g. the passes of a repeat group).

``CLPipeline(..., dynamic_state=True)`` is for tests: every pass program reads its
fixed-function state from a kernel argument instead of baked constants, so one compiled program
serves all the states a parametrised test sweeps (production plans bake the state).
``last_timings`` holds per-pass times (ms) of the latest render: ``vertex``, ``setup``,
``bin``, ``raster`` (kernel times from OpenCL profiling events, host stages from the clock;
a pass that reused cached geometry has no vertex/setup/bin entries).  ``preset(name, codes)``
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
from .light_table import check_light_capacity
from .cl_setup import bin_triangles, setup_triangles

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
        self._presets: dict = {}
        self._scene = None
        self._scene_attrs: dict = {}
        self._light_sets: dict = {}
        self.dropped_lights: dict = {}   # per channel_slots pack, last scene
        self._dummy = self._buffer(np.zeros(4, np.int32))
        self._kernels: dict = {}
        self._meshes: dict = {}
        for k in range(len(plan["passes"])):
            self._program(k)

    # -- programs ---------------------------------------------------------------------------------
    def _program(self, k: int):
        prog = self._programs.get(k)
        if prog is None:
            p = self.plan["passes"][k]
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
        import pyopencl as cl
        fmt = t.fmt
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
        pattern = np.ascontiguousarray(pixel).view(np.uint8)
        data = np.tile(pattern.reshape(-1), n)
        cl.enqueue_copy(self.queue, buf, data)

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
        self._targets = {}
        for name, spec in self.targets_spec.items():
            w, h = self.target_size(name, out_w, out_h)
            t = _Target(spec, w, h)
            t.buf = t.res = self._alloc(t, t.samples)
            if t.fmt.kind is F.Kind.DEPTH_STENCIL:
                t.stencil = t.res_stencil = self._buffer(np.zeros(w * h * t.samples, np.uint8))
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
        self._check_params(params)
        self._use_scene(scene)
        self.prepare(scene)
        for name, (codes, stencil) in self._presets.items():
            self.write_target(name, codes, stencil)
        self.last_timings = []
        self._blend_counts = {}
        self._geometry_cache = {}
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
                     if _light_filter(passes[j]["draw"])}
            for light in range(len(scene.lights)):
                for j in range(k, end):
                    if j in lists and light not in lists[j]:
                        continue
                    types = passes[j].get("repeat_types") or []
                    if types and _light_type(scene.lights[light]) not in types:
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
        return (result, captures) if capture_passes else result

    def _check_params(self, params: Optional[dict]) -> None:
        if not params:
            return
        compiled = self.plan.get("params") or {}
        for name, value in params.items():
            if name not in compiled:
                raise ValueError(f"unknown parameter '{name}' (the technique has: "
                                 f"{', '.join(compiled) or 'none'})")
            if value != compiled[name]:
                raise ValueError(f"parameter '{name}' was compiled in as {compiled[name]!r}; "
                                 f"recompile with {name}={value!r} to change it")

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
        buf = self._blend_counts.get(t.name)
        if buf is None:
            buf = self._blend_counts[t.name] = self._buffer(np.zeros(t.pixels, np.uint32))
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
                lights = [light] if (not _light_filter(draw)
                                     or light in self._light_list(draw)) else []
            else:
                lights = self._light_list(draw)
            if not lights:
                return
        geo = self._draw_geometry(k, p, width, height, timing, lights)
        if geo is None:
            return
        tris, bins, bufs = geo
        tile_start, tile_tris, tiles_x, tiles_y = bins
        st = self._dummy
        if self.dynamic_state:
            st = self._buffer(np.asarray(clgen.state_words(p), np.int32))
        args = [np.int32(width), np.int32(height), np.int32(tiles_x), bufs["tile_list"],
                bufs["tile_start"], bufs["tile_tris"], bufs["a"], bufs["b"], bufs["c"],
                bufs["z"], bufs["w"], bufs["coef"], np.int32(tris.coef.shape[1]),
                bufs["zp"], bufs["zq"],
                bufs["flat"], bufs["vtx"],
                bufs["scissor"], bufs["vary"], np.int32(tris.nverts), self._frame_buf,
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
        ev = cl.enqueue_nd_range_kernel(self.queue, kern, (bufs["ntiles"] * T, T), (T, T))
        ev.wait()
        timing["raster"] = (ev.profile.end - ev.profile.start) * 1e-6
        for name in attached:
            if self._targets[name].samples > 1:
                self._targets[name].dirty = True
        timing["triangles"] = tris.count
        timing["tile_entries"] = int(tile_start[-1])

    # -- geometry ----------------------------------------------------------------------------------
    def _light_list(self, draw: dict) -> list[int]:
        """The lights a light draw instances, in table order (GLPipeline._light_list)."""
        lights = list(self._scene.lights)
        idx = list(range(len(lights)))
        types = draw.get("light_types") or []
        if types:
            idx = [i for i in idx if _light_type(lights[i]) in types]
        light_set = draw.get("light_set")
        if light_set:
            pack, k = light_set[0], int(light_set[1])
            if pack not in self._light_sets:
                from ..packing import sort_lights_into_slots
                slots = int((self.plan.get("light_sets") or {}).get(pack, 4))
                centers = [tuple(getattr(l, "position", (0.0, 0.0, 0.0))) for l in lights]
                radii = [float(getattr(l, "radius", 0.0)) for l in lights]
                sets, dropped = sort_lights_into_slots(centers, radii, slots)
                self._light_sets[pack] = [list(map(int, s)) for s in sets]
                self.dropped_lights[pack] = [int(i) for i in dropped]
            chosen = set(self._light_sets[pack][k]) if k < len(self._light_sets[pack]) else set()
            idx = [i for i in idx if i in chosen]
        return idx

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

    def _draw_geometry(self, k: int, p: dict, width: int, height: int, timing: dict,
                       lights: Optional[list]):
        """Vertex kernel, setup and binning of a pass's draw (cached per frame: passes that
        draw the same geometry under the same raster state share it)."""
        import pyopencl as cl
        draw = p["draw"]
        st = p.get("state") or {}
        depth_clamp = bool((st.get("depth") or {}).get("clamp"))
        dfmt = p.get("depth_target") and self._targets[p["depth_target"]].fmt.name
        slots = clgen.varying_slots(p)
        # llvmpipe folds the pixel centre into the planes' a0 unless the pass is multisampled
        center = 0.0 if self._pass_samples(p) > 1 else 0.5
        # the 1/w plane: for smooth varyings and frag_coord.w
        w_plane = "frag_coord" in ((p.get("cl") or {}).get("inputs") or ())
        key = (draw["kind"], tuple(draw.get("material") or ()), draw.get("volume"),
               None if lights is None else tuple(lights), bool(draw.get("scissor")),
               st.get("cull"), str(st.get("polygon_offset")), depth_clamp, width, height,
               tuple((v["name"], v["flat"]) for v in slots), dfmt, center, w_plane)
        if key in self._geometry_cache:
            return self._geometry_cache[key]
        mesh_verts = 1
        zeros = self._buffer(np.zeros((1, 4), np.float32))
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
        S = len(slots)
        clip_buf = cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE, size=nverts * 16)
        vary_buf = cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE, size=max(16, S * nverts * 16))
        inst_buf = self._buffer(inst)
        kern = self._kernel(k, "pg_vertex")
        kern.set_args(np.int32(nverts), np.int32(mesh_verts), *attrs, inst_buf, self._frame_buf,
                      self._lights_buf, clip_buf, vary_buf)
        gsize = ((nverts + 63) // 64) * 64
        ev = cl.enqueue_nd_range_kernel(self.queue, kern, (gsize,), (64,))
        clip = np.empty((nverts, 4), np.float32)
        cl.enqueue_copy(self.queue, clip, clip_buf)
        vary = None
        if S:
            vary = np.empty((S, nverts, 4), np.float32)
            cl.enqueue_copy(self.queue, vary, vary_buf)
        timing["vertex"] = (ev.profile.end - ev.profile.start) * 1e-6
        t0 = time.perf_counter()
        cull = st.get("cull") or "none"
        tris = setup_triangles(clip, width, height, cull="none" if cull == "auto" else cull,
                               polygon_offset=st.get("polygon_offset"), depth_clamp=depth_clamp,
                               depth_format=dfmt, flat=flat, vary=vary, scissor=scissor,
                               smooth=[v["slot"] for v in slots if not v["flat"]],
                               pixel_center=center, w_plane=w_plane)
        if cull == "auto":
            tris = self._cull_auto(tris, draw.get("volume") or "sphere", lights)
        t1 = time.perf_counter()
        bins = bin_triangles(tris, width, height, self.tile)
        t2 = time.perf_counter()
        timing["setup"] = (t1 - t0) * 1e3
        timing["bin"] = (t2 - t1) * 1e3
        if tris.count == 0:
            self._geometry_cache[key] = None
            return None
        if tris.vary is not None and tris.vary.shape[1] != nverts:
            vary_buf = self._buffer(tris.vary)
        active = np.flatnonzero(np.diff(bins[0]) > 0).astype(np.int32)
        bufs = {"tile_list": self._buffer(active), "ntiles": len(active),
                "tile_start": self._buffer(bins[0]), "tile_tris": self._buffer(bins[1]),
                "a": self._buffer(tris.a), "b": self._buffer(tris.b), "c": self._buffer(tris.c),
                "z": self._buffer(tris.z), "w": self._buffer(tris.w),
                "coef": self._buffer(tris.coef),
                "zp": self._buffer(tris.zp), "zq": self._buffer(tris.zq),
                "flat": self._buffer(tris.flat), "vtx": self._buffer(tris.vtx),
                "scissor": self._buffer(tris.scissor), "vary": vary_buf}
        self._geometry_cache[key] = (tris, bins, bufs)
        return self._geometry_cache[key]

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


def _light_filter(draw: dict) -> bool:
    return bool(draw.get("light_types") or draw.get("light_set"))


def _light_type(light) -> str:
    t = getattr(light, "type", "point")
    if isinstance(t, (int, np.integer)):
        return {0: "point", 1: "spot", 2: "directional"}.get(int(t), str(t))
    return str(t)
