"""Run a compiled PLAN (docs/internals.md) with moderngl + PyOpenGL on the shared EGL context.

``GLPipeline(plan, size=None).render(scene) -> {target: codes}`` builds, once per output size,
one texture per target (multisampled targets get a single-sample *resolve* texture that later
passes read and that is returned), one framebuffer per pass, and compiles every pass's program
once.  Per render it uploads the scene (one interleaved VBO per material filter, the light table
texture; cached while the same ``Scene`` object is rendered again), clears every target to its
clear value, then runs the passes in order:

* ``clears`` of the pass (exact codes through ``glClearTexImage``, so scissor/masks don't apply);
* all fixed-function state, set explicitly (``gl_state.apply_state``);
* reads bound as textures: unit 0 is ``u_lights``, ``reads[k]`` is unit ``k + 1``; a sampler
  object per unit, nearest, or linear for the pass's ``"sampled"`` targets (integer and depth
  formats always nearest), clamp to edge;
* the draw: scene geometry of the material filter (one VBO per filter: the 14 floats of
  ``Geometry.interleaved()`` plus ``Geometry.layer``, attributes ``a_position`` … ``a_layer``);
  light volumes instanced over the light list
  with a per-instance ``a_light`` (all lights, the pass's ``light_types``, or the CPU-sorted
  set ``light_sets[pack][k]`` from ``packing.light_index.sort_lights_into_slots``); ``scissor`` light draws
  go one light at a time under ``draws.scissor_rect``; full-screen
  draws are one 3-vertex triangle.

Consecutive passes with the same ``repeat_group`` run as a group once per light (``u_light`` set;
a light draw inside the group draws only that light, and a pass whose light filter or
``repeat_types`` excludes the light is skipped for it, clears included).

``cull auto`` light draws are split into consecutive runs of lights (in light order) that
``draws.light_runs`` gives the same face (back faces where the camera may be
inside the volume, front faces elsewhere), each run drawn under its own cull state.

Results are in GL row order (row 0 = window y 0, the bottom row), as codes (``gl_formats``); a
d24s8 target ``ds`` yields ``"ds"`` (uint32 24-bit depth codes) and ``"ds.stencil"`` (uint8).
``render(..., capture_passes=True)`` returns ``(targets, captures)`` with one entry
``{"pass", "light", "targets"}`` after every executed pass (per light inside repeat groups).

``GLPipeline(..., alias=True)`` (or ``pipe.alias = True``) hands a texture on from a target
whose lifetime is over to a later target of the same format, size and samples (slot reuse,
``ir.lifetimes``; textures cannot alias memory): the later target is cleared where its
lifetime starts (``runtime/aliasing.py``) instead of at the start of the frame, and ``render``
leaves out the targets whose texture a later one took over (``memory.aliased``); captures hold
the targets the textures hold after each pass.
"""

from __future__ import annotations

import ctypes
import time
from dataclasses import replace
from typing import Any, Optional, Sequence

import numpy as np

from pipegen.core import formats as F
from pipegen.ir import nodes as ir
from pipegen.ir.light_layout import schema_layout
from pipegen.backends.plan import PassPlan, Plan, TargetPlan, plan_from_dict
from pipegen.ir.lifetimes import MemoryPlan, Sharing, memory_plan
from pipegen.runtime import draws
from pipegen.runtime.aliasing import FrameClears
from pipegen.runtime.gl import formats as GF
from pipegen.runtime.gl import state as GS
from pipegen.runtime.gl import names
from pipegen.runtime.gl import transitions as GT
from pipegen.runtime.common import check_param_overrides, check_scene, scene_as_drawn
from pipegen.runtime.light_table import light_rows, table_records
from pipegen.runtime.gl.context import (
    GL, check_error, clear_stale_errors, ctrl_c_unwrapped, debug_enabled, get_context)

import moderngl

__all__ = ["GLPipeline"]

SCENE_ATTRIBUTES = [("a_position", 3), ("a_normal", 3), ("a_albedo", 3), ("a_material", 3),
                    ("a_ids", 2), ("a_layer", 1)]
SCENE_STRIDE = 4 * sum(n for _, n in SCENE_ATTRIBUTES)    # bytes per vertex (15 floats)
# uniforms set once per frame (``_frame_uniforms``), written only to programs declaring them
FRAME_UNIFORMS = ("u_view", "u_proj", "u_inv_view", "u_inv_proj", "u_prev_view", "u_prev_proj",
                  "u_camera_pos", "u_ambient", "u_output_size", "u_num_lights")


class _Target:
    def __init__(self, spec: TargetPlan, size: tuple[int, int],
                 share: Optional["_Target"] = None):
        """``share``: an earlier target of the same format, size and samples whose textures
        this one takes over (slot reuse: their lifetimes are disjoint)."""
        self.name = spec.name
        self.spec = spec
        self.fmt = spec.format
        self.format = spec.format.name
        self.size = size
        self.samples = spec.samples
        self.owner = share is None       # the textures are this target's to delete
        self.dirty = False           # multisampled contents newer than ``resolved``
        self.fbo_clear = None
        self._clear_words: dict[tuple, Any] = {}     # clear value -> GL words, quantised once
        self._gl = GF.gl_format(self.format)
        if share is not None:
            self.tex, self.resolved = share.tex, share.resolved
            self.fbo_ms, self.fbo_resolved = share.fbo_ms, share.fbo_resolved
            return
        self.tex = GF.create_texture(self.format, *size, samples=self.samples)
        self.resolved = self.tex
        self.fbo_ms = self.fbo_resolved = None
        if self.samples > 1:
            self.resolved = GF.create_texture(self.format, *size)
            self.fbo_ms = _framebuffer([(self._attachment(0), self.tex)])
            self.fbo_resolved = _framebuffer([(self._attachment(0), self.resolved)])

    def _attachment(self, k: int) -> int:
        g = GF.gl_format(self.format)
        return g.attachment + k if self.fmt.is_color else g.attachment

    def clear(self, color=None, depth=None, stencil=None, partial: bool = False,
              fbo: Optional[int] = None) -> None:
        """Clear to the given values (None -> 0).  With ``partial``, a d24s8 clear that names
        only depth or only stencil keeps the other aspect (a framebuffer clear, since
        ``glClearTexImage`` writes whole texels): through ``fbo`` when given (a framebuffer
        with this target as its depth attachment, bound: llvmpipe then records the clear with
        the pass's draws instead of flushing them), else through a framebuffer of its own."""
        if partial and self.fmt.kind is F.Kind.DEPTH_STENCIL and (depth is None) != (
                stencil is None):
            if fbo is None and self.fbo_clear is None:
                self.fbo_clear = _framebuffer([(self._attachment(0), self.tex)])
                GL.glNamedFramebufferDrawBuffers(self.fbo_clear, 1, [GL.GL_NONE])
            target_fbo = self.fbo_clear if fbo is None else fbo
            # framebuffer clears obey the scissor test and the depth / stencil write masks
            GT.TRACKER.scissor(None)
            key = ("partial", depth, stencil)
            value = self._clear_words.get(key)
            if value is None:    # a ctypes value for the unwrapped call (PyOpenGL's array
                value = self._clear_words[key] = (   # handling costs ~30 us a call)
                    (ctypes.c_int * 1)(int(stencil)) if stencil is not None
                    else (ctypes.c_float * 1)(float(depth)))
            if stencil is not None:
                GT.TRACKER.apply(GT.CLEAR_STENCIL)
                _CLEAR_FBO_IV(target_fbo, GL.GL_STENCIL, 0, value)
            else:
                GT.TRACKER.apply(GT.CLEAR_DEPTH)
                _CLEAR_FBO_FV(target_fbo, GL.GL_DEPTH, 0, value)
            self.dirty = self.samples > 1
            return
        key = self.fmt.clear_key(color, depth, stencil)
        words = self._clear_words.get(key)
        if words is None:        # Format.quantize once per clear value (exact codes)
            codes = np.ascontiguousarray(GF.clear_codes(self.format, color, depth, stencil))
            words = self._clear_words[key] = (
                codes, (ctypes.c_ubyte * codes.nbytes).from_buffer(codes))  # (array kept alive)
        g = self._gl
        _CLEAR_TEX(self.tex, 0, g.format, g.type, words[1])
        if self.samples > 1:
            _CLEAR_TEX(self.resolved, 0, g.format, g.type, words[1])
            self.dirty = False

    def resolve(self) -> None:
        if not self.dirty:
            return
        if self.fmt.is_color:
            mask = GL.GL_COLOR_BUFFER_BIT
            GL.glNamedFramebufferReadBuffer(self.fbo_ms, GL.GL_COLOR_ATTACHMENT0)
            GL.glNamedFramebufferDrawBuffers(self.fbo_resolved, 1, [GL.GL_COLOR_ATTACHMENT0])
        else:
            mask = GL.GL_DEPTH_BUFFER_BIT | (GL.GL_STENCIL_BUFFER_BIT if self.fmt.has_stencil
                                              else 0)
        # blits obey the scissor test and (on some drivers) colour masks: neutral state first
        GT.TRACKER.apply(_BLIT_COLOR if self.fmt.is_color else _BLIT_DEPTH)
        GT.TRACKER.scissor(None)
        w, h = self.size
        GL.glBlitNamedFramebuffer(self.fbo_ms, self.fbo_resolved, 0, 0, w, h, 0, 0, w, h, mask,
                                  GL.GL_NEAREST)
        self.dirty = False

    def read(self) -> dict[str, np.ndarray]:
        self.resolve()
        w, h = self.size
        data = GF.read_texture(self.resolved, self.format, w, h)
        if self.fmt.kind is F.Kind.DEPTH_STENCIL:
            depth, stencil = GF.split_depth_stencil(data)
            return {self.name: depth, self.name + ".stencil": stencil}
        return {self.name: data}

    def release(self) -> None:
        if self.fbo_clear is not None:
            names.delete_framebuffers(self.fbo_clear)
        if not self.owner:
            return
        GF.delete_texture(self.tex)
        if self.samples > 1:
            GF.delete_texture(self.resolved)
            names.delete_framebuffers(self.fbo_ms, self.fbo_resolved)


def _unwrapped(fn):
    """PyOpenGL's ctypes function under its Python array-handling wrapper (pointer arguments
    passed as ctypes values or addresses)."""
    return getattr(fn, "wrappedOperation", fn)


_CLEAR_TEX = _unwrapped(GL.glClearTexImage)
_CLEAR_FBO_IV = _unwrapped(GL.glClearNamedFramebufferiv)
_CLEAR_FBO_FV = _unwrapped(GL.glClearNamedFramebufferfv)

_BLIT_COLOR = GT.pass_vector(ir.PassState(), ["_"], label="blit colour")
_BLIT_DEPTH = GT.pass_vector(ir.PassState(), [], label="blit depth")


def _framebuffer(attachments: Sequence[tuple[int, int]]) -> int:
    fbo = names.create_framebuffer()
    for point, tex in attachments:
        GL.glNamedFramebufferTexture(fbo, point, tex, 0)
    return fbo


_STATUS = {
    0x8CD6: "INCOMPLETE_ATTACHMENT", 0x8CD7: "INCOMPLETE_MISSING_ATTACHMENT",
    0x8CDB: "INCOMPLETE_DRAW_BUFFER", 0x8CDC: "INCOMPLETE_READ_BUFFER", 0x8CDD: "UNSUPPORTED",
    0x8D56: "INCOMPLETE_MULTISAMPLE", 0x8DA8: "INCOMPLETE_LAYER_TARGETS",
}


class _Pass:
    def __init__(self, ctx: moderngl.Context, spec: PassPlan, index: int):
        assert spec.code is not None, f"pass '{spec.name}' has no GLSL (a plan from emit_gl)"
        self.spec = spec
        self.index = index
        self.name = spec.name
        self.draw = spec.draw
        self.kind = spec.draw.kind
        self.writes = list(spec.writes)
        self.reads = list(spec.reads)
        self.sampled = set(spec.sampled)
        self.depth_target = spec.depth_target
        self.state = spec.state
        try:
            self.program = ctx.program(vertex_shader=spec.code.vertex,
                                       fragment_shader=spec.code.fragment or None)
        except Exception as e:
            raise RuntimeError(f"pass '{self.name}': GLSL compile/link failed:\n{e}") from None
        self.fbo: Optional[int] = None
        self.viewport = (0, 0)
        self.vaos: dict[Any, moderngl.VertexArray] = {}
        self.instance_buffer: Optional[moderngl.Buffer] = None
        # texture units never change: u_lights is unit 0, reads[k] unit k + 1
        self.set_uniform("u_lights", 0)
        for k, r in enumerate(self.reads):
            self.set_uniform("t_" + r, k + 1)
        # the per-frame uniforms this program declares, and the bytes last written to each
        self.frame_uniforms = {n: self.program[n] for n in FRAME_UNIFORMS if self.has(n)}
        self.uploaded: dict[str, bytes] = {}
        self.u_light = self.program.get("u_light", None)
        self.vector: Optional[GT.StateVector] = None        # set by GLPipeline
        self.auto_vectors: dict[tuple, GT.StateVector] = {}  # cull auto: per (cull, inside)

    def has(self, name: str) -> bool:
        return self.program.get(name, None) is not None

    def set_uniform(self, name: str, value) -> None:
        u = self.program.get(name, None)
        if u is None:
            return
        if isinstance(value, np.ndarray):
            u.write(np.ascontiguousarray(value, dtype=np.float32).tobytes())
        else:
            u.value = value

    def release(self) -> None:
        for vao in self.vaos.values():
            vao.release()
        if self.instance_buffer is not None:
            self.instance_buffer.release()
        self.program.release()
        if self.fbo is not None:
            names.delete_framebuffers(self.fbo)


class GLPipeline:
    """A PLAN ready to render with OpenGL (see the module docstring)."""

    @ctrl_c_unwrapped
    def __init__(self, plan: Plan | dict, size: Optional[tuple[int, int]] = None, *,
                 transitions: bool = True, debug: Optional[bool] = None, alias: bool = False):
        """``transitions=False`` sets all state before every pass (``gl_state.apply_state``)
        instead of the differences (``gl_transitions``): the reference the tests compare with.
        ``debug`` (default: ``PIPEGEN_GL_DEBUG`` set) checks GL errors after every pass
        instead of once per frame.  ``alias``: slot reuse of textures (module docstring)."""
        self.plan = plan = plan_from_dict(plan)
        self.ctx = get_context()
        clear_stale_errors()
        self.transitions = bool(transitions)
        self.debug = debug_enabled() if debug is None else bool(debug)
        self.profile: Optional[list] = None   # a list: per pass timings appended (_run_pass)
        self._auto_cull: dict = {}      # per frame: cull auto choices (``_light_runs``)
        self.size = None if size is None else (int(size[0]), int(size[1]))
        self.passes = [_Pass(self.ctx, p, k) for k, p in enumerate(plan.passes)]
        for p in self.passes:     # each pass's state, lowered once (gl_transitions)
            fmt = plan.target(p.depth_target).format if p.depth_target else None
            p.depth_format = fmt
            p.vector = GT.pass_vector(p.state, p.writes, depth_format=fmt, label=p.name)
            # reads: unit k + 1, linear only for the pass's "sampled" filterable targets;
            # a multisampled target read per sample (load_sample) binds its samples
            p.units = []
            for k, r in enumerate(p.reads):
                kind = plan.target(r).format.kind
                linear = r in p.sampled and kind in (F.Kind.UNORM, F.Kind.SNORM, F.Kind.FLOAT)
                p.units.append((k + 1, r, "linear" if linear else "nearest",
                                r in p.spec.sample_reads))
        GT.TRACKER.prime([p.vector for p in self.passes])
        self.targets: dict[str, _Target] = {}
        self._built_size: Optional[tuple[int, int]] = None
        self._alias = bool(alias)
        self.memory: Optional[MemoryPlan] = None     # lifetimes and slots at the built size
        self._clears: Optional[FrameClears] = None
        self.capacity = max(1, plan.lights.capacity)
        self.fields = list(plan.lights.fields)
        self.materials = plan.lights.materials
        # a texel column per row of a light's record, a line per light (ir/light_layout.py),
        # then the material records (ir/material_layout.py)
        self.light_tex = GF.create_texture("rgba32f", max(1, schema_layout(self.fields).rows),
                                           table_records(plan.lights))
        self._samplers = {mode: self._sampler(mode) for mode in ("nearest", "linear")}
        self._meshes: dict[str, moderngl.Buffer] = {}
        self._scene = None              # the scene as drawn (runtime/common.scene_as_drawn)
        self._given = None              # the scene it was given
        self._scene_vbos: dict[tuple, tuple[moderngl.Buffer, int]] = {}
        self._reach: dict[tuple, tuple] = {}    # within light radius: per draw, its light runs
        self._selection: Optional[draws.LightSelection] = None
        self._released = False
        if self.size is not None:
            self._build(self.size)

    # -- resources -------------------------------------------------------------------------
    @staticmethod
    def _sampler(mode: str) -> int:
        s = names.create_sampler()
        f = GL.GL_LINEAR if mode == "linear" else GL.GL_NEAREST
        GL.glSamplerParameteri(s, GL.GL_TEXTURE_MIN_FILTER, f)
        GL.glSamplerParameteri(s, GL.GL_TEXTURE_MAG_FILTER, f)
        GL.glSamplerParameteri(s, GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE)
        GL.glSamplerParameteri(s, GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)
        GL.glSamplerParameteri(s, GL.GL_TEXTURE_COMPARE_MODE, GL.GL_NONE)
        return s

    @property
    def alias(self) -> bool:
        """Slot reuse of same-descriptor textures between targets with disjoint lifetimes
        (module docstring; docs/memory.md); changing it rebuilds the targets."""
        return self._alias

    @alias.setter
    def alias(self, on: bool) -> None:
        if bool(on) != self._alias:
            self._alias = bool(on)
            self._built_size = None

    def _build(self, size: tuple[int, int]) -> None:
        """Targets and per-pass framebuffers for output ``size``."""
        for t in self.targets.values():
            t.release()
        self.targets = {}
        plan = self.plan
        self.memory = memory_plan(plan.passes, plan.targets, plan.output, *size,
                                  Sharing.DESCRIPTOR if self._alias else Sharing.NONE)
        first = {n: s.targets[0] for s in self.memory.slots for n in s.targets}
        for spec in plan.targets:       # a slot's first target in plan order creates it
            if first[spec.name] == spec.name:
                self.targets[spec.name] = _Target(spec, spec.resolve(*size))
        for spec in plan.targets:
            if first[spec.name] != spec.name:
                self.targets[spec.name] = _Target(spec, spec.resolve(*size),
                                                  share=self.targets[first[spec.name]])
        self.targets = {spec.name: self.targets[spec.name] for spec in plan.targets}
        for p in self.passes:
            if p.fbo is not None:
                names.delete_framebuffers(p.fbo)
            attached = [self.targets[w] for w in p.writes]
            att = [(GF.gl_format(t.format).attachment + k, t.tex) for k, t in enumerate(attached)]
            if p.depth_target:
                d = self.targets[p.depth_target]
                att.append((GF.gl_format(d.format).attachment, d.tex))
                attached.append(d)
            sizes = {t.size for t in attached}
            if len(sizes) > 1:
                raise RuntimeError(f"pass '{p.name}' attaches targets of different sizes: "
                                   + ", ".join(f"{t.name} {t.size[0]}x{t.size[1]}"
                                               for t in attached))
            samples = {t.samples for t in attached}
            if len(samples) > 1:
                raise RuntimeError(f"pass '{p.name}' attaches targets with different sample "
                                   f"counts: " + ", ".join(f"{t.name} x{t.samples}"
                                                          for t in attached))
            p.fbo = _framebuffer(att)
            bufs = [GL.GL_COLOR_ATTACHMENT0 + k for k in range(len(p.writes))] or [GL.GL_NONE]
            GL.glNamedFramebufferDrawBuffers(p.fbo, len(bufs), bufs)
            GL.glNamedFramebufferReadBuffer(p.fbo, GL.GL_NONE)
            p.viewport = attached[0].size if attached else size
            if attached:
                status = GL.glCheckNamedFramebufferStatus(p.fbo, GL.GL_DRAW_FRAMEBUFFER)
                if status != GL.GL_FRAMEBUFFER_COMPLETE:
                    raise RuntimeError(f"pass '{p.name}': framebuffer incomplete "
                                       f"({_STATUS.get(int(status), hex(int(status)))})")
        check_error(f"building targets at {size[0]}x{size[1]}")
        self._built_size = size

    def release(self) -> None:
        """Free every GL object (the pipeline is unusable afterwards)."""
        if self._released:
            return
        self._released = True
        for t in self.targets.values():
            t.release()
        for p in self.passes:
            p.release()
        for buf, _ in self._scene_vbos.values():
            buf.release()
        for buf in self._meshes.values():
            buf.release()
        GF.delete_texture(self.light_tex)
        names.delete_samplers(*self._samplers.values())

    # a pipeline is a resource: ``with compiled.pipeline("gl") as p:`` or ``p.close()``
    def close(self) -> None:
        """``release``: the GL objects are deleted now, not when the pipeline is collected."""
        self.release()

    def __enter__(self) -> "GLPipeline":
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __del__(self):  # pragma: no cover - best effort at interpreter exit
        try:
            self.release()
        except Exception:
            pass

    # -- scene data -------------------------------------------------------------------------
    def _use_scene(self, scene) -> None:
        if self._scene is not None and self._given is scene:
            return
        self._given, scene = scene, scene_as_drawn(self.plan, scene)
        check_scene(self.plan, scene)
        for p in self.passes:
            for key in [k for k in p.vaos if k[0] == "scene"]:
                p.vaos.pop(key).release()
        for buf, _ in self._scene_vbos.values():
            buf.release()
        self._scene_vbos = {}
        self._reach = {}
        lights = list(scene.lights)
        self._selection = draws.LightSelection(self.plan, lights)
        self._lights = lights
        if self.fields:
            GF.write_texture(self.light_tex, "rgba32f",
                             light_rows(scene, self.fields, self.capacity, self.materials))
        self._scene = scene

    def _scene_vbo(self, draw: ir.Draw, light: Optional[int] = None
                   ) -> tuple[moderngl.Buffer, int]:
        key = draws.scene_key(draw, light)
        if key not in self._scene_vbos:
            g = draws.scene_geometry(self._scene, draw, light)   # in the draw's object order
            if hasattr(g, "interleaved"):
                data = g.interleaved()
            else:
                data = np.concatenate([g.positions, g.normals, g.albedo, g.material, g.ids],
                                      axis=1)
            # the stipple layer is not part of ``interleaved()``: it is the last column here
            layer = getattr(g, "layer", None)
            if layer is None:
                layer = np.zeros(len(data), np.float32)
            data = np.concatenate([np.asarray(data, np.float32),
                                   np.asarray(layer, np.float32).reshape(-1, 1)], axis=1)
            data = np.ascontiguousarray(data, dtype=np.float32)
            buf = self.ctx.buffer(data.tobytes() if len(data) else b"\0" * SCENE_STRIDE)
            self._scene_vbos[key] = (buf, len(data))
        return self._scene_vbos[key]

    def _reached_runs(self, draw: ir.Draw, light: int) -> list[tuple[int, int]]:
        """``within light radius``: the runs of the draw's vertices that submit the objects
        light ``light`` reaches (``draws.reach_table``), once per scene, draw and light."""
        key = draws.scene_key(draw)
        if key not in self._reach:
            object_ids = draws.triangle_ids(draws.scene_geometry(self._scene, draw))[:, 0]
            self._reach[key] = (draws.reach_table(self._scene, draw), object_ids,
                                [None] * len(self._lights))
        table, object_ids, runs = self._reach[key]
        if runs[light] is None:
            runs[light] = draws.reached_runs(table, light, object_ids)
        return runs[light]

    def _mesh(self, volume: str) -> moderngl.Buffer:
        if volume not in self._meshes:
            from pipegen.scene.meshes import light_volume
            self._meshes[volume] = self.ctx.buffer(
                np.ascontiguousarray(light_volume(volume), dtype=np.float32).tobytes())
        return self._meshes[volume]

    @property
    def dropped_lights(self) -> dict[str, list[int]]:
        """Per channel_slots pack, the lights of the last scene no light set could take."""
        return self._selection.dropped if self._selection else {}

    def light_sets(self, scene) -> dict[str, list[list[int]]]:
        """The CPU-sorted light sets this pipeline draws for ``scene`` (for reports/tests)."""
        self._use_scene(scene)
        for p in self.passes:
            if p.draw.light_set:
                self._selection.of(p.draw)
        return dict(self._selection.sets)

    def _vao(self, p: _Pass, light: Optional[int]) -> Optional[moderngl.VertexArray]:
        if p.kind is ir.DrawKind.SCENE:
            key = ("scene",) + draws.scene_key(p.draw, light)
            if key not in p.vaos:
                buf, n = self._scene_vbo(p.draw, light)
                fmt, names = [], []
                for name, comps in SCENE_ATTRIBUTES:
                    if p.has(name):
                        fmt.append(f"{comps}f")
                        names.append(name)
                    else:
                        fmt.append(f"{4 * comps}x")
                p.vaos[key] = self.ctx.vertex_array(p.program, [(buf, " ".join(fmt), *names)])
            return p.vaos[key]
        if p.kind is ir.DrawKind.LIGHTS:
            volume = (p.draw.volume or ir.Volume.SPHERE).value
            key = ("lights", volume)
            if key not in p.vaos:
                if p.instance_buffer is None:
                    p.instance_buffer = self.ctx.buffer(reserve=4 * self.capacity)
                content = [(self._mesh(volume), "3f", "a_position")]
                if p.has("a_light"):
                    content.append((p.instance_buffer, "1f/i", "a_light"))
                p.vaos[key] = self.ctx.vertex_array(p.program, content)
            return p.vaos[key]
        key = ("fullscreen",)
        if key not in p.vaos:
            p.vaos[key] = self.ctx.vertex_array(p.program, [])
        return p.vaos[key]

    # -- rendering --------------------------------------------------------------------------
    @ctrl_c_unwrapped
    def render(self, scene, params: Optional[dict] = None, capture_passes: bool = False):
        """Render ``scene``; ``{target: codes}`` (and the per-pass captures, see module doc)."""
        captures = self._draw(scene, params, capture_passes)
        result = self._read_all()
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        return (result, captures) if capture_passes else result

    @ctrl_c_unwrapped
    def frame(self, scene, params: Optional[dict] = None) -> None:
        """Render ``scene`` and wait for the GPU (no read-back): what frame timings measure."""
        self._draw(scene, params, False)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glFinish()

    def _draw(self, scene, params: Optional[dict], capture_passes: bool) -> list[dict]:
        clear_stale_errors()
        if self._released:
            raise RuntimeError("GLPipeline used after release()")
        check_param_overrides(self.plan, params)
        size = self.size or (int(scene.width), int(scene.height))
        if self._built_size != size:
            self._build(size)
        self._use_scene(scene)
        self._frame_uniforms(scene, size)
        self._auto_cull: dict = {}      # this frame's cull auto choices (``_light_runs``)
        check_error("uploading the scene")
        GT.TRACKER.invalidate()       # the shared context: a frame starts from unknown state
        self._clears = FrameClears(self.memory)
        self._clear_targets(self._clears.start())
        captures: list[dict] = []
        for k, light in self._selection.schedule():
            p = self.passes[k]
            self._clear_targets(self._clears.before_pass(k))    # lifetimes starting (alias)
            self._run_pass(p, light)
            if self.debug:
                check_error(f"in pass '{p.name}'" + ("" if light is None else f" light {light}"),
                            hint=False)
            if capture_passes:
                captures.append({"pass": p.name, "light": light, "targets": self._read_all()})
        self._clear_targets(self._clears.finish())
        check_error("rendering a frame")
        return captures

    def _clear_targets(self, names) -> None:
        for name in names:
            c = self.plan.target(name).clear
            self.targets[name].clear(c.color, c.depth, c.stencil)

    def _frame_uniforms(self, scene, size) -> None:
        """The frame's uniforms, computed once and written only to the programs that declare
        them, and only when their bytes changed since the last frame (sampler units are set
        once, in ``_Pass``)."""
        cam = scene.camera
        view = np.asarray(cam.view_matrix(), np.float64)
        proj = np.asarray(cam.projection(size[0] / size[1]), np.float64)
        self._view, self._proj = view, proj
        prev = getattr(scene, "prev_camera", cam)   # previous frame (declared where read)

        def mat(m):   # GLSL mat4 uniforms are column-major: the transpose's row-major bytes
            return np.ascontiguousarray(np.asarray(m, np.float64).T, dtype=np.float32).tobytes()

        values = {
            "u_view": lambda: mat(view), "u_proj": lambda: mat(proj),
            "u_inv_view": lambda: mat(np.linalg.inv(view)),
            "u_inv_proj": lambda: mat(np.linalg.inv(proj)),
            "u_prev_view": lambda: mat(prev.view_matrix()),
            "u_prev_proj": lambda: mat(prev.projection(size[0] / size[1])),
            "u_camera_pos": lambda: np.asarray(cam.position, np.float32)[:3].tobytes(),
            "u_ambient": lambda: np.asarray(scene.ambient, np.float32)[:3].tobytes(),
            "u_output_size": lambda: np.array(size, np.float32).tobytes(),
            "u_num_lights": lambda: np.uint32(len(scene.lights)).tobytes(),
        }
        done: dict[str, bytes] = {}
        for p in self.passes:
            for name, u in p.frame_uniforms.items():
                data = done.get(name)
                if data is None:
                    data = done[name] = values[name]()
                if p.uploaded.get(name) != data:
                    u.write(data)
                    p.uploaded[name] = data

    def _shadow_view(self, p: _Pass, light: int, w: int, h: int) -> None:
        """A shadow-map draw of atlas tile ``light`` (the schedule's slot;
        ``draws.shadow_casters``): viewport and scissor on the tile, the owning light's view
        and projection in the pass's ``u_view``/``u_proj`` (``draws.shadow_view``)."""
        rect, view, proj = draws.shadow_view(self._scene, light, p.draw, w, h)
        for name, m in (("u_view", view), ("u_proj", proj)):
            u = p.frame_uniforms.get(name)
            if u is not None:
                data = np.ascontiguousarray(np.asarray(m, np.float64).T,
                                            dtype=np.float32).tobytes()
                u.write(data)
                p.uploaded[name] = data
        x, y, tw, th = rect
        GT.TRACKER.viewport(tw, th, x, y)
        GT.TRACKER.scissor(rect)

    def _run_pass(self, p: _Pass, light: Optional[int]) -> None:
        """One pass execution: clears, bindings and state (only what changed since the last
        pass: ``gl_transitions.TRACKER``), the draw.  With ``self.profile`` a list, the GPU is
        drained before the pass and after its draws: host set-up and draw time are appended
        as ``(pass, light, setup_s, draw_s)``."""
        tracker = GT.TRACKER
        if self.profile is not None:
            GL.glFinish()
            t0 = time.perf_counter()
        if not self.transitions:      # the reference: everything set again before every pass
            tracker.invalidate()
        if p.spec.clears:
            tracker.framebuffer(p.fbo)      # depth/stencil clears through the pass's own
            for name, c in p.spec.clears:
                self.targets[name].clear(c.color, c.depth, c.stencil, partial=True,
                                         fbo=p.fbo if name == p.depth_target else None)
        if light is not None and p.u_light is not None:
            p.u_light.value = int(light)
        # reads: unit 0 is the light table
        tracker.texture(0, self.light_tex, self._samplers["nearest"])
        for unit, r, mode, per_sample in p.units:
            t = self.targets[r]
            if per_sample:
                tracker.texture(unit, t.tex, self._samplers[mode])
                continue
            t.resolve()
            tracker.texture(unit, t.resolved, self._samplers[mode])
        tracker.framebuffer(p.fbo)
        w, h = p.viewport
        tracker.viewport(w, h)
        depth_format = p.depth_format
        if self.transitions:
            tracker.apply(p.vector)                                # cull auto: none here
            tracker.scissor(None)
        else:
            GS.apply_state(p.state, p.writes, depth_format=depth_format)
        vao = self._vao(p, light)
        if self.profile is not None:
            t1 = time.perf_counter()
        if p.kind is ir.DrawKind.SCENE:
            _, count = self._scene_vbo(p.draw, light)
            if p.draw.shadow:       # the light's tile of the atlas, seen from the light
                self._shadow_view(p, light, w, h)
            if count and p.draw.within and light is not None:
                for first, n in self._reached_runs(p.draw, light):
                    vao.render(moderngl.TRIANGLES, vertices=n, first=first)
            elif count:
                vao.render(moderngl.TRIANGLES, vertices=count)
            if p.draw.shadow:
                tracker.scissor(None)
                tracker.viewport(w, h)
        elif p.kind is ir.DrawKind.LIGHTS:
            lights = self._lights
            indices = self._selection.instance(p, light)
            runs = self._light_runs(p, indices)
            for run in runs:
                if p.spec.cull_auto:     # consecutive lights with the same choice, in order
                    depth = p.state.depth
                    if run.inside and depth.inside is not None:   # back faces: `inside FUNC`
                        depth = replace(depth, func=depth.inside)
                    if self.transitions:
                        key = (run.cull, depth.func)
                        v = p.auto_vectors.get(key)
                        if v is None:
                            v = p.auto_vectors[key] = GT.pass_vector(
                                replace(p.state, cull=run.cull, depth=depth), p.writes,
                                depth_format=depth_format, label=f"{p.name} {run.cull.value}")
                        tracker.apply(v)
                    else:
                        GS.apply_state(replace(p.state, cull=run.cull, depth=depth), p.writes,
                                       depth_format=depth_format)
                if p.draw.scissor:
                    rects = draws.scissor_rects([lights[i] for i in run.lights], self._view,
                                                self._proj, w, h)
                    for i, rect in zip(run.lights, rects.tolist()):
                        if rect[2] == 0 or rect[3] == 0:
                            continue
                        tracker.scissor(tuple(rect))
                        self._draw_lights(p, vao, [i])
                    tracker.scissor(None)
                else:
                    self._draw_lights(p, vao, run.lights)
        else:
            vao.render(moderngl.TRIANGLES, vertices=3)
        for name in p.writes + ([p.depth_target] if p.depth_target else []):
            t = self.targets[name]
            if t.samples > 1:
                t.dirty = True
        if self.profile is not None:
            GL.glFinish()
            self.profile.append((p.name, light, t1 - t0, time.perf_counter() - t1))

    def _light_runs(self, p: _Pass, indices: Sequence[int]) -> list:
        """``draws.light_runs`` of a light pass execution.  Under ``cull auto`` a pass run
        once per light asks for one light at a time (deferred on many_lights: 81 times a
        frame): every light of the draw's list is decided at once, once a frame (each light's
        choice is its own, so the same choices), and the light looks its own up."""
        eye, proj = self._scene.camera.position, self._proj
        if p.state.cull is not ir.CullMode.AUTO or len(indices) != 1:
            return draws.light_runs(p.state.cull, p.draw.volume, self._lights, indices, eye,
                                    proj)
        inside = self._auto_cull.get(p.draw)
        if inside is None:
            inside = self._auto_cull[p.draw] = draws.auto_inside(
                p.draw.volume, self._lights, self._selection.of(p.draw), eye, proj)
        i = int(indices[0])
        if i not in inside:
            return draws.light_runs(p.state.cull, p.draw.volume, self._lights, indices, eye,
                                    proj)
        return [draws.LightRun(ir.CullMode.FRONT if inside[i] else ir.CullMode.BACK, (i,))]

    def _draw_lights(self, p: _Pass, vao, indices: Sequence[int]) -> None:
        if p.instance_buffer is not None:
            p.instance_buffer.write(np.asarray(indices, np.float32).tobytes())
        vao.render(moderngl.TRIANGLES, instances=len(indices))

    def _read_all(self) -> dict[str, np.ndarray]:
        """Every target's codes; with ``alias``, those of the targets the textures hold now
        (``FrameClears.holding``)."""
        holding = set(self._clears.holding())
        out: dict[str, np.ndarray] = {}
        for name, t in self.targets.items():
            if name in holding:
                out.update(t.read())
        return out

