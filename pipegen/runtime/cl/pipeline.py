"""Run a compiled plan on the OpenCL software reference (pyopencl on PoCL's CPU device).

``CLPipeline(plan, size=None).render(scene) -> {target: codes}`` returns the same arrays as
``GLPipeline``: GL row order (row 0 = window y 0, the bottom row), ``formats.Format.dtype``
codes, ``(H, W)`` for one channel and ``(H, W, C)`` otherwise; a d24s8 target ``ds`` gives
24-bit depth codes under ``"ds"`` and the stencil under ``"ds.stencil"``.  ``frame(scene)``
renders the same frame and reads nothing back (timings, as ``GLPipeline.frame``).
``render(..., capture_passes=True)`` returns ``(targets, captures)`` with one entry
``{"pass", "light", "targets", "blend_counts"}`` after every executed pass (per light inside
repeat groups).

``last_blend_counts`` (after ``render``): ``{target: (H, W) uint32}`` in GL row order, for every
colour target some pass blended into this frame, how many fragments were blended into each
pixel (counted by the raster kernel where it applies the blend: after discard, depth and
stencil; once per fragment whatever its samples), read from the device when first asked
for after a frame (a frame's count buffers stay until the next frame's first blended pass
zeroes them; a frame nobody asks about does not read them).  ``pipegen check`` allows 1 + P
codes/ulps per pixel from it (DESIGN.md §7).

``last_clamps`` (after ``render``): the fragment outputs outside what their targets' formats
hold, counted per pass and target by the raster kernel (``runtime/cl/clamps.py``); a frame
rendered inside ``clamps.collect()`` gives them to it.

Per pass (see ``backends/opencl/`` for the program, ``setup_device.py`` and ``bin.py`` for
the set-up and binning kernels, ``setup.py`` for the numpy set-up and binning they replace):

    pg_vertex (CL) -> pg_setup, pg_clip_setup (CL) -> pg_bin_* (CL) -> pg_raster (CL)

Every vertex and set-up kernel of a frame is queued before its first raster kernel
(``render``), so no host stage waits behind a raster kernel on the in-order queue.

Targets live in device buffers in GL row order for the whole frame; clears write the codes of
``Format.quantize`` (the same the GL runtime clears with).  Passes of one ``repeat_group`` run
once per light in turn (the group's passes for light 0, then for light 1, ...; a pass whose
light filter or ``repeat_types`` excludes the light is skipped for it), the light index
reaching the fragment function as ``in->light``; light draws instance the pass's light list
(``draws.LightSelection``: types, CPU-sorted ``light_set`` via
``packing.light_index.sort_lights_into_slots``), ``scissor`` light draws clip each
light's triangles to ``draws.scissor_rect``, ``cull auto`` light draws keep
each light's front or back faces as ``draws.light_runs`` chooses.  All as ``GLPipeline`` does
(``draws.schedule`` orders the passes of both).

Multisampled targets (4 samples, llvmpipe's positions) keep one plane per sample; the passes
that read them, and ``render``'s result, see the resolve llvmpipe's blit computes (colour: the
average of the samples stored like a fragment output; depth, stencil, integers: sample 0,
d24 depth codes through llvmpipe's float round trip, ``d24_resolve``).

Set-up triangles are cached per frame and shared by the passes that draw the same geometry
under the same raster state (``_geometry``): a scene draw is set up once for every pass of
the plan drawing it under that state, with the union of their varyings (a pass reading fewer
gets varying and plane buffers cut from the shared ones); a light draw sets up all lights of
its light list at once (light passes outside repeat groups drawing under one raster state:
their lists together, ``DrawGeometry._shared_lights``), culled only where every pass drawing
them culls the same faces, and each pass (each light of a repeat group) draws its lights'
consecutive range of triangles with its own cull mode; the full-screen triangle is kept across frames.  Per-triangle
results do not depend on which other triangles or varyings are set up with them, so sharing
changes no value.  A pass alone in its ``repeat per light`` group that draws the scene,
clears nothing and writes no depth or stencil (``programs.batches_lights``: multi-pass
forward's light pass) draws the whole run of its lights in one raster launch, each light's
draw in turn, as launches per light would (``_batched``; bit-identical, tested).  A repeat group
whose passes draw light volumes and read nothing the group writes (deferred's stencil-marked
volumes) runs all its lights' executions as one launch of a fused kernel
(``group_launch.py``, ``backends/opencl/group.py``; bit-identical, tested).  Bins are
per pass, built on the device from the triangles the pass draws (its lights' ranges, the
faces its cull mode keeps); an unfused ``repeat per light`` group's bins are found for all
its lights in one numpy sort and uploaded in three buffers, each light's bins views into them
(``group_bins.py``).
A frame queues every vertex and set-up kernel first, then each pass execution in turn: its
host work (set-up read-backs, queuing the binning), then its clears, resolves and raster
kernel, without waiting for them, so that the device rasterises a pass while the host
prepares the next (``$PIPEGEN_CL_HOST_FIRST=1``: every pass's host work first, as before
device binning, for comparison); target and blend-count buffers are reused from frame to
frame (cleared as before).

The float64 evaluation (a plan emitted with ``precision="f64"``, ``Compiled.pipeline("cl",
precision="f64")``): the same schedule, coverage and primitive order, the technique's
arithmetic in double and every target stored unquantised (``cl_targets``); ``render``
returns ``{target: float64 values}`` (docs/internals.md, "The float64 evaluation").  The
frame's matrices, camera and ambient reach the fragment function in double
(``FRAME64_DTYPE``), the light table as doubles of the scene's float32 table.

``CLPipeline(..., dynamic_state=True)`` is for tests: every pass program reads its
fixed-function state from a kernel argument instead of baked constants, so one compiled program
serves all the states a parametrised test sweeps (production plans bake the state).
``last_timings`` holds per-pass times (ms) of the latest render: ``vertex``, ``setup``,
``bin``, ``raster`` (kernel times from OpenCL profiling events, read at the end of the frame;
host stages from the clock; a pass that reused cached geometry or bins has no
vertex/setup or bin entry), ``triangles`` and ``tile_entries``; a run of lights drawn in one
launch has one entry, with ``lights`` (their number).  ``profile = []`` makes the
next frames append ``(pass, light, host_s, device_s)`` per pass execution, draining the queue
around each pass as ``GLPipeline.profile`` drains the GPU: ``host_s`` from the start of the
pass to its raster kernel's launch (the first pass of a frame also waits there for the
frame's vertex and set-up kernels), ``device_s`` from there until the queue is empty.  ``preset(name, codes)``
starts later renders with a target holding given codes (tests).

"""

from __future__ import annotations

import itertools
import os
import time
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from pipegen.ir import nodes as ir
from pipegen.ir.builtins import nudge_site, reads_nudges
from pipegen.ir.light_layout import schema_layout
from pipegen.backends.opencl import abi as cl_abi, programs as cl_programs
from pipegen.backends.plan import CLPassCode, PassPlan, Plan, plan_from_dict
from pipegen.runtime.cl import clamps as cl_clamps, context as cl_context
from pipegen.runtime import draws
from pipegen.runtime.cl.group_launch import GroupLauncher
from pipegen.runtime.common import check_param_overrides, check_scene, scene_as_drawn
from pipegen.runtime.light_table import light_rows
from pipegen.runtime.cl.device import Device
from pipegen.runtime.cl.geometry import DrawGeometry, FrameState, ShadowView
from pipegen.runtime.cl.targets import TargetStore, d24_resolve

__all__ = ["CLPipeline", "FRAME_DTYPE", "d24_resolve"]

# host image of the prelude's pg_frame struct
FRAME_DTYPE = np.dtype([("view", "<f4", (16,)), ("proj", "<f4", (16,)),
                        ("inv_view", "<f4", (16,)), ("inv_proj", "<f4", (16,)),
                        ("camera_pos", "<f4", (4,)), ("ambient", "<f4", (4,)),
                        ("output_size", "<f4", (4,)), ("num_lights", "<u4"), ("light", "<u4"),
                        ("light_rows", "<u4"), ("pad", "<u4"),
                        # the previous frame's camera: in the struct of programs that read it
                        ("prev_view", "<f4", (16,)), ("prev_proj", "<f4", (16,))])
assert FRAME_DTYPE.itemsize == 448
# host image of the prelude's pg_frame64 (the float64 evaluation), padded to its alignment
FRAME64_DTYPE = np.dtype([("view", "<f8", (16,)), ("proj", "<f8", (16,)),
                          ("inv_view", "<f8", (16,)), ("inv_proj", "<f8", (16,)),
                          ("camera_pos", "<f8", (4,)), ("ambient", "<f8", (4,)),
                          ("output_size", "<f8", (4,)), ("num_lights", "<u4"), ("light", "<u4"),
                          ("light_rows", "<u4"), ("pad", "<u4"), ("pad2", "<u4", (4,)),
                          ("prev_view", "<f8", (16,)), ("prev_proj", "<f8", (16,))])
assert FRAME64_DTYPE.itemsize == 896


def _put_matrices(fr: np.ndarray, f8: Optional[np.ndarray], **mats) -> None:
    """Write 4x4 matrices (row-major as numpy holds them) into the frame structs: ``fr``
    (``FRAME_DTYPE``) as float32, ``f8`` (``FRAME64_DTYPE``, or None without the float64
    evaluation) as float64, both column-major as the prelude's ``mat4`` reads them."""
    for name, m in mats.items():
        m = np.asarray(m, np.float64)
        fr[name] = m.astype(np.float32).T.reshape(16)
        if f8 is not None:
            f8[name] = m.T.reshape(16)


def _frame_structs(view, proj, prev_view, prev_proj, camera_pos, ambient,
                   output_size: tuple[int, int], num_lights: int, light: int,
                   light_rows: int, f64: bool) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """The ``pg_frame`` struct of a camera, and its ``pg_frame64`` with ``f64`` (else None):
    ``inv_view``/``inv_proj`` are the inverses of ``view``/``proj``, ``prev_*`` the previous
    frame's camera."""
    fr = np.zeros((), FRAME_DTYPE)
    f8 = np.zeros((), FRAME64_DTYPE) if f64 else None
    _put_matrices(fr, f8, view=view, proj=proj, inv_view=np.linalg.inv(view),
                  inv_proj=np.linalg.inv(proj), prev_view=prev_view, prev_proj=prev_proj)
    for s, t in ((fr, np.float32), (f8, np.float64)):
        if s is None:
            continue
        s["camera_pos"][:3] = np.asarray(camera_pos, t)
        s["ambient"][:3] = np.asarray(ambient, t)
        s["output_size"][:2] = output_size
        s["num_lights"], s["light"], s["light_rows"] = num_lights, light, light_rows
    return fr, f8


@dataclass(eq=False)
class PassRun:
    """A pass execution's host work, done (``CLPipeline._prepare_pass``: its set-up triangles
    and bins, ``drawn``); calling it queues its device work: clears, then the raster kernel.
    ``light``: the light drawn, the first of ``batch`` for a run drawn in one launch."""
    pipe: "CLPipeline"
    k: int
    p: PassPlan
    light: Optional[int]
    batch: Optional[tuple]
    timing: dict
    width: int
    height: int
    drawn: Optional[tuple]
    frame_buf: object
    frame64_buf: object

    @property
    def scheduled(self):
        """The schedule's light entry: the light, or the tuple of a batched run."""
        return self.batch if self.batch is not None else self.light

    def __call__(self) -> None:
        store = self.pipe.store
        store.begin_pass(self.k)        # targets sharing storage start here (alias)
        for name, c in self.p.clears:
            store.clear_for_pass(name, c)
        if self.drawn is not None:
            self.pipe._launch(self.k, self.p, self.light, self.timing, self.width, self.height,
                              self.drawn, self.frame_buf, self.frame64_buf, self.batch)


class CLPipeline:
    def __init__(self, plan: Plan | dict, size: Optional[tuple[int, int]] = None,
                 cache_dir: Optional[str] = None, dynamic_state: bool = False,
                 tile: int = cl_abi.TILE, alias: bool = False):
        plan = plan_from_dict(plan)
        assert plan.backend in ("cl", ""), "CLPipeline needs a plan from emit_cl"
        # a pass without code (a plan written by hand) has no fragment function
        self.plan = plan = replace(plan, passes=tuple(
            p if p.code is not None else replace(p, code=CLPassCode("", None))
            for p in plan.passes))
        self.size = size
        self.precision = plan.precision
        self.f64 = plan.precision == "f64"       # the float64 evaluation
        self.dynamic_state = dynamic_state
        self.tile = tile
        self.ctx, self.queue = cl_context.get_context(
            cache_dir, key=f"{plan.technique}:{plan.source}")
        self.targets_spec = {t.name: t for t in plan.targets}
        self._light_rows = schema_layout(plan.lights.fields).rows     # rows a light takes
        self.store = TargetStore(self.ctx, self.queue, plan, alias)
        self._timings: list[dict] = []      # ``last_timings``
        self._timings_pending = False       # raster times still to read from ``_events``
        self._blend_counts: Optional[dict[str, np.ndarray]] = {}
        self._blend_count_bufs: dict = {}
        # every pass's program is built here, none during a frame (a PoCL build takes 0.3-3 s)
        self.device = Device(self.ctx, self.queue, [
            cl_context.build_program(self.source(k)) for k in range(len(plan.passes))])
        self.geometry = DrawGeometry(self.device, plan, tile)
        for names in self.geometry.vertex_unions():     # built here too
            self.device.scene_vertex_kernel(names)
        # per pass: its raster kernel draws a run of lights in one launch (``_batched``)
        self._batches = [cl_programs.batches_lights(plan, p, dynamic_state)
                         for p in plan.passes]
        # per pass: its raster kernel skips the objects a light does not reach
        self._reaches = [cl_programs.reaches_by_object(plan, p) for p in plan.passes]
        # repeat groups whose passes run as one launch (``group_launch``), built here too
        self.groups = GroupLauncher(self)
        self._host_first = os.environ.get("PIPEGEN_CL_HOST_FIRST", "0") == "1"   # ``_draw``
        self.clamp_counters = cl_clamps.ClampCounters(self.ctx, self.queue, plan)
        self._clamps: Optional[list] = []
        self._presets: dict = {}
        self._scene = None              # the scene as drawn (runtime/common.scene_as_drawn)
        self._given = None              # the scene it was given
        self._frame_key = None          # ``_frame_for``: the scene and size its structs are for
        self._selection: Optional[draws.LightSelection] = None
        self._events: list = []
        # the float64 evaluation: the last frame's (depth target, set-up triangles, the pixel
        # centre their planes hold) of every pass execution writing depth
        # (``proof/depth_planes.py`` bounds their float32 planes)
        self.depth_draws: list = []
        self._int2s: dict = {}
        self._shadows: dict = {}        # per frame: (pass, light) -> ShadowView
        self._prefetched: set = set()   # per frame: the light passes whose set-up is queued
        self.profile: Optional[list] = None    # a list: per-pass drained times (docstring)
        # the float64 programs of the discontinuity search read run-time nudges (``nudges``)
        self._nudged = [self.f64 and reads_nudges(p.code.inputs) for p in plan.passes]
        sites = [nudge_site(n) for p in plan.passes for n in p.code.inputs]
        self._nudges = np.zeros(1 + max([k for k in sites if k is not None], default=-1),
                                np.float64)
        self._nudges_buf = None

    def nudge(self, amounts: dict) -> None:
        """Move step site ``k`` by ``amounts[k]`` in the next renders, every other site by 0
        (a float64 program compiled with run-time nudges, ``proof/discontinuity.py``)."""
        values = np.zeros_like(self._nudges)
        for k, amount in amounts.items():
            if 0 <= k < values.size:       # a site no pass of this program runs: nothing moves
                values[k] = amount
        self._nudges = values
        self._nudges_buf = None

    def release(self) -> None:
        """Drop the device buffers this pipeline holds (targets, blend counts, set-up geometry,
        frame and light tables) as ``GLPipeline.release`` does; the compiled programs stay in
        the process's cache.  The pipeline is unusable afterwards."""
        self.store = None
        self.geometry = None
        self.device = None
        self.clamp_counters = None
        self._events = []
        self._frame_key = None
        for name in ("_frame_buf", "_frame64_buf", "_lights_buf", "_lights64_buf",
                     "_nudges_buf"):
            if hasattr(self, name):
                setattr(self, name, None)
        self._scene = None
        from pipegen.runtime.cl.context import forget_invoker_sources
        forget_invoker_sources()

    # a pipeline is a resource: ``with compiled.pipeline("cl") as p:`` or ``p.close()``
    def close(self) -> None:
        """``release``: what a pipeline holds is freed now, not when it is collected."""
        self.release()

    def __enter__(self) -> "CLPipeline":
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __del__(self):  # pragma: no cover - best effort at collection / interpreter exit
        try:
            self.release()
        except Exception:
            pass

    # -- programs ---------------------------------------------------------------------------------
    @property
    def dropped_lights(self) -> dict[str, list[int]]:
        """Per channel_slots pack, the lights of the last scene no light set could take."""
        return self._selection.dropped if self._selection else {}

    def source(self, k: int) -> str:
        p = self.plan.passes[k]
        if self.dynamic_state or p.code is None or not p.code.kernel or self.tile != cl_abi.TILE:
            return cl_programs.pass_program(self.plan, p, dynamic=self.dynamic_state,
                                            tile=self.tile)
        return p.code.kernel

    # -- targets ----------------------------------------------------------------------------------
    @property
    def _targets(self) -> dict:
        return self.store.targets

    @property
    def alias(self) -> bool:
        """Targets with disjoint lifetimes share device memory (``TargetStore``; docs/memory.md):
        ``render`` then leaves out the targets a later one overwrote (``store.memory.aliased``)."""
        return self.store.alias

    @alias.setter
    def alias(self, on: bool) -> None:
        self.store.alias = bool(on)

    def preset(self, name: str, codes: np.ndarray, stencil: Optional[np.ndarray] = None) -> None:
        """Start the next renders with target ``name`` holding ``codes`` (GL row order, like
        the arrays ``render`` returns) instead of its clear value; ``stencil`` for d24s8.  In
        the float64 evaluation ``codes`` are values (as its ``render`` returns them)."""
        self._presets[name] = (np.asarray(codes), None if stencil is None else np.asarray(stencil))

    def prepare(self, scene) -> None:
        """Allocate and clear every target for a frame of ``scene``."""
        self._out = self.output_size(scene)
        self.store.prepare(*self._out, pinned=self._presets)
        for name, (codes, stencil) in self._presets.items():
            self.store.write(name, codes, stencil)

    # -- frame --------------------------------------------------------------------------------------
    def output_size(self, scene) -> tuple[int, int]:
        if self.size is not None:
            return int(self.size[0]), int(self.size[1])
        return int(scene.width), int(scene.height)

    def target_size(self, name: str, out_w: int, out_h: int) -> tuple[int, int]:
        return self.targets_spec[name].resolve(out_w, out_h)

    def _frame_for(self, scene) -> tuple:
        """(view, projection) of the frame's camera, its frame structs and their device
        buffers set: made again only when the scene or the output size changed since the last
        frame (a scene is immutable: ``_use_scene`` keeps its set-up by identity alike), else
        those of the last frame, read-only on the device (~0.15 ms of host work a frame)."""
        key = self._frame_key
        if key is not None and key[0] is scene and key[1] == self._out \
                and self._frame_buf is not None:
            return key[2]
        self._frame_np, self._frame64_np, view, proj = self._frame(scene)
        self._frame_buf = self.device.buffer(self._frame_np)
        self._frame64_buf = self.device.buffer(self._frame64_np) if self.f64 else None
        self._frame_key = (scene, self._out, (view, proj))
        return view, proj

    def _frame(self, scene, light: int = 0) -> tuple:
        """(``pg_frame`` struct, ``pg_frame64`` struct or None without the float64 evaluation,
        view matrix, projection matrix) of the frame's camera."""
        out_w, out_h = self._out
        cam = scene.camera
        view = cam.view_matrix()
        proj = cam.projection(out_w / out_h)
        prev = getattr(scene, "prev_camera", cam)
        prev_view, prev_proj = (view, proj) if prev is cam else (
            prev.view_matrix(), prev.projection(out_w / out_h))
        fr, f8 = _frame_structs(view, proj, prev_view, prev_proj, cam.position, scene.ambient,
                                (out_w, out_h), len(scene.lights), light, self._light_rows,
                                self.f64)
        return fr, f8, view, proj

    # -- rendering ----------------------------------------------------------------------------------
    def render(self, scene, params: Optional[dict] = None, capture_passes: bool = False):
        """Render one frame: ``{target: codes}``, or ``(targets, captures)`` with
        ``capture_passes`` (see the module docstring)."""
        captures = self._draw(scene, params, capture_passes)
        result = self.store.read_all()
        self._end_frame()
        return (result, captures) if capture_passes else result

    def frame(self, scene, params: Optional[dict] = None) -> None:
        """Render one frame and wait for the device, reading no target back: what frame
        timings measure, as ``GLPipeline.frame`` (at 160x90 the read-back of every target is
        a fixed cost GL's ``frame`` does not pay).  Blend counts and clamps are read on first
        use, as after ``render``."""
        self._draw(scene, params, False)
        self._end_frame()

    def _draw(self, scene, params: Optional[dict], capture_passes: bool) -> list[dict]:
        """Queue a frame's passes (the captures with ``capture_passes``, else [])."""
        check_param_overrides(self.plan, params)
        self._use_scene(scene)
        self.prepare(scene)
        self.clamp_counters.start_frame()
        self._timings, self._timings_pending = [], False
        self.depth_draws = []
        self._events = []
        view, proj = self._frame_for(scene)
        self.geometry.begin_frame(FrameState(
            scene=scene, selection=self._selection, view=view, proj=proj,
            frame_buf=self._frame_buf, frame64_buf=self._frame64_buf, lights_buf=self._lights_buf,
            pass_sizes=tuple(self._pass_size(p) for p in self.plan.passes)))
        captures: list[dict] = []
        runs = self._selection.schedule()
        self._shadows = {}
        self._prefetched = set()
        for k, light in runs:      # every vertex kernel before the first raster kernel
            self._prefetch(k, light)
        if self.profile is None and not capture_passes:
            # each pass execution's host work (set-up read-backs, bins) made when its turn comes,
            # right after the device work of the one before is queued: the device rasterises pass
            # k while the host prepares k + 1.  (Every pass's host work came first from d4cd3c8,
            # when binning was numpy work that a raster kernel's threads slowed 4-5x; with the
            # bins made on the device since, preparing first leaves the device idle meanwhile:
            # light_prepass at 320x180, ~3 of 12.6 ms.  ``$PIPEGEN_CL_HOST_FIRST=1`` restores that
            # order, for comparison: benchmarks/backends.py's docstring has the figures.)  A
            # fusable repeat group's pass executions are one launch (``group_launch``).
            prep = self.groups.prepare if self._host_first else self.groups.prepared
            prepared = iter(prep(self._batched(runs), self._prepare_pass))
            # the first execution's host work (its set-up finished, its bins queued) before
            # the last set-up is waited for and clipped: the device bins it right after
            # setting up, where it sat idle while the host did this work (inferred at 320x180:
            # 0.5 ms a frame); no raster kernel is queued before every set-up's clipper
            first = next(prepared, None)
            self.geometry.clip_pending()
            for run in itertools.chain([first] if first is not None else [], prepared):
                if isinstance(run, PassRun):
                    self._run_pass(run.k, run.scheduled, run)
                else:
                    run()
        else:       # pass by pass: drained around each (profile), or read after each
            for k, light in runs:
                self._run_pass_observed(k, light, captures if capture_passes else None)
        self.store.end_frame()
        return captures

    def _end_frame(self) -> None:
        """After a frame's passes (and its read-back): the blend counts and clamps to read on
        first use, the queue drained, the raster kernels' times."""
        self._blend_counts, self._blend_count_bufs = None, dict(self.store.blend_counts)
        self._clamps = None
        if cl_clamps.collecting():
            cl_clamps.note(self.last_clamps, self.precision)
        self.queue.finish()
        # the raster kernels' times are read when ``last_timings`` is first asked for: two
        # profiling queries per launch (~6 us each; deferred launches 165 a frame)
        self._timings_pending = True

    def _run_pass_observed(self, k: int, light: Optional[int], captures: Optional[list]):
        """One pass execution on its own: with ``profile``, the queue drained before and after
        it; with ``captures``, its targets and blend counts read after it."""
        if self.profile is None:
            self._run_pass(k, light)
        else:
            self.queue.finish()                 # each pass charged its own work
            t0 = time.perf_counter()
            self._run_pass(k, light)
            t1 = time.perf_counter()
            self.queue.finish()
            self.profile.append((self.plan.passes[k].name, light, t1 - t0,
                                 time.perf_counter() - t1))
        if captures is not None:
            captures.append({"pass": self.plan.passes[k].name, "light": light,
                             "targets": self.store.read_all(),
                             "blend_counts": self.store.read_blend_counts()})

    @property
    def last_scene(self):
        """The scene the last frame rendered (as given to ``render``), or None."""
        return self._given

    @property
    def last_timings(self) -> list[dict]:
        """The last frame's per-pass times (the module docstring), the raster kernels'
        read from their events on first use."""
        if self._timings_pending:
            for timing, ev in self._events:
                timing["raster"] = (ev.profile.end - ev.profile.start) * 1e-6
            self._events, self._timings_pending = [], False
        return self._timings

    @property
    def last_blend_counts(self) -> dict[str, np.ndarray]:
        """The last frame's blend counts (see the module docstring), read on first use."""
        if self._blend_counts is None:
            self._blend_counts = self.store.read_blend_counts(self._blend_count_bufs)
        return self._blend_counts

    @property
    def last_clamps(self) -> list:
        """The last frame's values clamped by their targets' formats (``clamps.Clamp`` per
        pass and target that had any), read on first use (``runtime/cl/clamps.py``)."""
        if self._clamps is None:
            self._clamps = self.clamp_counters.read()
        return self._clamps

    def _use_scene(self, scene) -> None:
        if self._scene is not None and self._given is scene:
            return
        self._given, scene = scene, scene_as_drawn(self.plan, scene)
        check_scene(self.plan, scene)
        self._scene = scene
        self._selection = draws.LightSelection(self.plan, list(scene.lights))
        self.geometry.use_scene()
        self._reach_bufs: dict = {}      # within light radius: per draw, its reach table
        capacity = max(1, self.plan.lights.capacity)
        fields = self.plan.lights.fields
        table = (light_rows(scene, fields, capacity, self.plan.lights.materials) if fields
                 else np.zeros((0, 4), np.float32))
        self._lights_buf = self.device.buffer(table.reshape(-1, 4) if table.size
                                              else np.zeros((1, 4), np.float32))
        if self.f64:     # the fragment function's light table in double
            self._lights64_buf = self.device.buffer(table.reshape(-1, 4).astype(np.float64)
                                                    if table.size else np.zeros((1, 4), np.float64))

    def _prefetch(self, k: int, light: Optional[int]) -> None:
        """Queue the vertex work of a pass execution (``DrawGeometry.prefetch``)."""
        p = self.plan.passes[k]
        lights = None
        if p.draw.kind is ir.DrawKind.LIGHTS:
            # a light draw sets up its pass's whole light list at once (an instance's lights
            # are in it: ``DrawGeometry._light_batch``): once per pass, not per light
            if k in self._prefetched:
                return
            lights = self._selection.instance(p, light)
            if not lights:
                return
            self._prefetched.add(k)
        width, height = self._pass_size(p)
        shadow = self._shadow_view(p, light, width, height) if p.draw.shadow else None
        volume = light if p.draw.shadow_volumes else None
        self.geometry.prefetch(k, p, width, height, lights, shadow, volume)

    def _run_pass(self, k: int, light: Optional[int], launch=None) -> None:
        """Queue a pass execution's device work (``launch``: its prepared host work, else
        prepared now).  Every pass execution of a frame goes through here, in order (the
        stress runner's read perturbation wraps it)."""
        (launch or self._prepare_pass(k, light))()

    def _batched(self, runs: list) -> list:
        """The schedule's pass executions ``(k, light)``, a run of consecutive executions of a
        pass whose kernel draws a run of lights in one launch (``programs.batches_lights``)
        as one ``(k, (light, ...))``; with sharing off (``$PIPEGEN_CL_SHARE_SETUP=0``,
        ``DrawGeometry.share``) every execution on its own."""
        if not self.geometry.share:
            return list(runs)
        out: list = []
        for k, light in runs:
            if self._batches[k] and out and out[-1][0] == k:
                out[-1] = (k, out[-1][1] + (light,))
            else:
                out.append((k, (light,) if self._batches[k] else light))
        return out

    def _prepare_pass(self, k: int, light):
        """The host work of a pass execution (its set-up triangles and bins); returns the
        function that queues its device work (clears, resolves, the raster kernel) in order.
        ``light``: a tuple of lights for a run drawn in one launch (``_batched``; its timing
        has ``lights``, their number)."""
        p = self.plan.passes[k]
        width, height = self._pass_size(p)
        batch = light if isinstance(light, tuple) else None
        if batch is not None:
            light = batch[0]
        timing = {"pass": p.name, "light": light}
        if batch is not None:
            timing["lights"] = len(batch)
        self._timings.append(timing)
        lights, drawn = None, None
        if p.draw.kind is ir.DrawKind.LIGHTS:
            lights = self._selection.instance(p, light)
        frame_buf, frame64_buf, shadow = self._frame_buf, self._frame64_buf, None
        if p.draw.kind is not ir.DrawKind.LIGHTS or lights:
            if p.draw.shadow:           # one light's tile, seen from the light
                shadow = self._shadow_view(p, light, width, height)
                frame_buf, frame64_buf = shadow.frame_buf, shadow.frame64_buf
            volume = light if p.draw.shadow_volumes else None    # that light's volumes
            drawn = self.geometry.pass_triangles(k, p, width, height, timing, lights, shadow,
                                                 volume)
            if self.f64 and drawn is not None and p.depth_target and p.state.depth.write:
                # the planes hold the pixel centre unless the pass is multisampled
                centre = 0.0 if self.plan.pass_samples(p) > 1 else 0.5
                self.depth_draws.append((p.depth_target, drawn[0].tris, centre))

        return PassRun(self, k, p, light, batch, timing, width, height, drawn, frame_buf,
                       frame64_buf)

    def _launch(self, k: int, p: PassPlan, light: Optional[int], timing: dict, width: int,
                height: int, drawn: tuple, frame_buf, frame64_buf,
                batch: Optional[tuple] = None) -> None:
        """Queue a pass's raster kernel (``drawn``: its geometry and bins; nothing when no
        tile has a triangle), for ``light`` or the lights of ``batch``.  Bins built on the
        device tell their number of tiles when their binning has run: this waits for it."""
        import pyopencl as cl
        geo, tb = drawn
        if not tb.ntiles:
            return
        args = self._raster_args(k, p, light, width, height, drawn, frame_buf, frame64_buf,
                                 batch)
        kern = self.device.kernel(k, "pg_raster")
        cl_context.set_args(kern, *args)     # scalar types declared (~90 us a launch else)
        T = self.tile
        ev = cl.enqueue_nd_range_kernel(self.queue, kern, (tb.ntiles * T,), (T,))
        self._events.append((timing, ev))
        for name in p.attached:
            if self._targets[name].samples > 1:
                self._targets[name].dirty = True
        timing["triangles"] = tb.triangles
        timing["tile_entries"] = tb.entries

    def _raster_args(self, k: int, p: PassPlan, light: Optional[int], width: int, height: int,
                     drawn: tuple, frame_buf, frame64_buf, batch: Optional[tuple] = None) -> list:
        """The arguments of pass ``k``'s raster kernel, in its parameters' order (queues the
        resolves of the targets it reads and the zeroing of blend counts it first uses)."""
        geo, tb = drawn
        bufs = geo.bufs
        dev = self.device
        st = dev.dummy
        if self.dynamic_state:
            st = dev.buffer(np.asarray(cl_abi.state_words(p), np.int32))
        args = [np.int32(width), np.int32(height), np.int32(tb.tiles_x), np.int32(tb.band),
                tb.tile_list,
                tb.tile_start, tb.tile_tris, bufs["a"], bufs["b"], bufs["c"],
                bufs["z"], bufs["w"], bufs["coef"], np.int32(geo.ncoef),
                bufs["zp"], bufs["zq"], bufs["flat"], bufs["vtx"], bufs["scissor"],
                bufs["bbox"], bufs["vary"], np.int32(geo.tris.nverts), frame_buf,
                self._lights_buf, st, np.uint32(light or 0)]
        if self._batches[k]:        # the run of lights (none: ``light`` alone)
            args += [dev.buffer(np.asarray(batch, np.uint32)) if batch else dev.dummy,
                     np.int32(len(batch) if batch else 0)]
        if self._reaches[k]:        # within light radius: the object ids each light reaches
            key = draws.scene_key(p.draw)
            buf = self._reach_bufs.get(key)
            if buf is None:
                table = draws.reach_table(self._scene, p.draw)
                buf = self._reach_bufs[key] = dev.buffer(table if table.size else
                                                         np.zeros((1, 1), np.uint32))
            args.append(buf)
        for name in p.writes:
            args.append(self._targets[name].buf)
        for name in p.writes:
            t = self._targets[name]
            if not t.fmt.is_integer:
                on = p.state.blend_for(name).enabled
                args.append(self.store.blend_count(t) if on else dev.dummy)
        args.append(self.clamp_counters.args[k])
        if p.depth_target:
            dt = self._targets[p.depth_target]
            args.append(dt.buf)
            if dt.stencil is not None:
                args.append(dt.stencil)
        for name in p.reads:
            rt = self._targets[name]
            if name in p.sample_reads:            # load_sample: the sample planes themselves
                args += [rt.buf, self._int2(rt.width, rt.height)]
                continue
            self.store.resolve(rt)                # reads see the resolved texture, like GL
            args += [rt.res, self._int2(rt.width, rt.height)]
        if self.f64:
            attrs = [dev.zeros4] * 4
            if p.draw.kind is ir.DrawKind.SCENE:    # a shadow_volumes draw: the light's
                volume = light if p.draw.shadow_volumes else None
                attrs = self.geometry.attributes(p.draw, volume)[1]
            args += [bufs["h"], bufs["parent"], frame64_buf, self._lights64_buf, *attrs]
            if self._nudged[k]:
                if self._nudges_buf is None:
                    self._nudges_buf = dev.buffer(self._nudges)
                args.append(self._nudges_buf)
        return args

    def _shadow_view(self, p: PassPlan, light: int, width: int, height: int) -> ShadowView:
        """A shadow-map draw of atlas tile ``light`` (the schedule's slot; ``draws.shadow_casters``):
        its rectangle and the frame structs with the owning light's view
        and projection in place of the camera's (``draws.shadow_view``; float32 as a camera's
        are uploaded); once per frame."""
        got = self._shadows.get((id(p), light))
        if got is not None:
            return got
        rect, view, proj = draws.shadow_view(self._scene, light, p.draw, width, height)
        fr = self._frame_np.copy()
        f8 = self._frame64_np.copy() if self.f64 else None
        _put_matrices(fr, f8, view=view, proj=proj)
        got = self._shadows[(id(p), light)] = ShadowView(
            int(light), tuple(int(v) for v in rect), self.device.buffer(fr),
            None if f8 is None else self.device.buffer(f8))
        return got

    def _int2(self, x: int, y: int):
        """An ``int2`` kernel argument (pyopencl's ``make_int2`` evaluates code per call:
        ~0.1 ms, a noticeable share of a light pass's host time)."""
        key = (int(x), int(y))
        v = self._int2s.get(key)
        if v is None:
            import pyopencl as cl
            v = self._int2s[key] = cl.cltypes.make_int2(*key)
        return v

    def _pass_size(self, p: PassPlan) -> tuple[int, int]:
        """The viewport of a pass: its first attachment's size, else the output size."""
        if p.attached:
            t = self._targets[p.attached[0]]
            return t.width, t.height
        return self._out
