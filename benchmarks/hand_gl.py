"""pipegen's generated GL pipeline vs a hand-written moderngl + PyOpenGL loop (issue 14).

    python benchmarks/hand_gl.py [--frames 15] [--sizes 320x180,1280x720]
        [--scenes many_lights,small] [--techniques deferred,lidr_bitplanes,forward]
        [--threads 2] [--calls] [--all]

For ``deferred`` and ``lidr_bitplanes`` this file holds the loop a programmer would write by
hand for that technique: the GLSL, target formats, clear values and blend constants come from
the compiled technique's GL plan (so the GPU work is the same), but everything the runtime
decides is written out here for the one technique: which framebuffer each pass draws into (one
per distinct set of attachments), which state changes between passes (set when it changes,
by someone who knows the pass order), which textures are bound, which lights are drawn.
Nothing of ``pipegen.runtime``'s pipeline code is used: only ``gl_context`` (the shared EGL
context) and ``gl_formats`` (texture creation, read-back).  The light table is uploaded in the
rows the compiler lays it out in (``ir/light_layout.py``), which the generated shaders read.

``forward`` (issue 26 item 6) has a hand-written *shader* too: one loop over the lights, each
light's four packed rows fetched once (position + radius, colour + type, direction + cos_inner,
cos_outer + shadow tile; the shadow matrix rows only for a light casting a shadow), the view
vector normalised once per pixel, Blinn-Phong as ``common/lighting.pipe`` writes it, and the
shadow lookup of every light type forward.pipe draws shadows for (a point light: the cube face
its major axis picks; spot and sun: the light's projection), one tap, bias 0.1 (forward's
defaults).  Its light table is packed by hand here (``pack_lights``).  The scenes have no
shadow-casting lights (the hand loop refuses one: it draws no shadow maps), as pipegen, which
then runs no shadow pass; its shadow lookup, given pipegen's drawn atlas, matched pipegen's
colour bit for bit on tests/data/point_shadow.toml, shadows.toml and overlapping_spot_shadows
at 160x90 (a one-off check, with the tile count 3 where a point light needs six tiles).
Measured (README, issue 26 item 6; ``--techniques forward --sizes 320x180,640x360 --frames 15``,
four runs, load 4-6): the generated shader's CPU time 1.02x-1.09x of this one's, median frames
0.98x-1.14x (one 1.31x on 20 ms frames).

For every technique x scene x size it

1. renders one frame with each and asserts that *every* target (depth and stencil included) is
   bit-identical to pipegen's (``GLPipeline.render``);
2. counts the PyOpenGL calls of one frame of each (every ``OpenGL.GL`` function wrapped for
   that frame: counts do not depend on the machine's load);
3. times ``--frames`` frames of each, interleaved (pipegen, hand, hand, pipegen, ...: the
   order alternates) after a warm-up, each frame ending with ``glFinish`` and no read-back
   (``GLPipeline.frame``), and prints the medians and their ratio pipegen/hand (``ratio``),
   the ratio of the fastest frames (``min``: the least disturbed by other load) and of the
   process CPU time spent in each (``cpu``: host thread plus llvmpipe's threads, the least
   sensitive to load; ``getrusage``'s resolution is coarse, so use enough frames).

``--all`` only counts the PyOpenGL calls of one frame of every shipped technique, with state
transitions and with all state set before every pass (``GLPipeline(transitions=False)``).

The machine is shared and noisy: compare ratios from one run, never absolute times across runs
(``uptime`` is printed with the figures).  ``LP_NUM_THREADS`` is set to ``--threads`` before
the GL context exists.  The file also runs against an older pipegen (``PYTHONPATH`` pointing at
another checkout) for before/after figures.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
import statistics
import subprocess
import sys
from collections import Counter

import numpy as np

from common import ROOT, compile_spec, interleaved, scene_at

SCENES = {"many_lights": "examples/scenes/many_lights.toml", "small": "examples/scenes/small.toml"}
SCENE_ATTRIBUTES = [("a_position", 3), ("a_normal", 3), ("a_albedo", 3), ("a_material", 3),
                    ("a_ids", 2), ("a_layer", 1)]


class HandLoop:
    """What both hand loops share: programs, targets, framebuffers, the scene's buffers."""

    def __init__(self, plan, scene):
        from pipegen.runtime.gl import formats as GF
        from pipegen.runtime.gl.context import GL, get_context
        self.GL, self.GF = GL, GF
        self.ctx = ctx = get_context()
        self.plan, self.scene = plan, scene
        self.w, self.h = w, h = scene.width, scene.height
        self.programs = {p.name: ctx.program(vertex_shader=p.code.vertex,
                                             fragment_shader=p.code.fragment or None)
                         for p in plan.passes}
        self.state = {p.name: p.state for p in plan.passes}
        self.tex, self.clear_words = {}, {}
        self.sizes = {t.name: t.resolve(w, h) for t in plan.targets}   # the shadow atlas: its own
        for t in plan.targets:
            self.tex[t.name] = GF.create_texture(t.format.name, *self.sizes[t.name])
            c = t.clear
            self.clear_words[t.name] = GF.clear_codes(t.format.name, c.color, c.depth, c.stencil)
        self.formats = {t.name: t.format for t in plan.targets}
        self.cleared = list(self.tex)           # targets cleared every frame
        # the light table: a texel column per row of a light, a line per light
        cap = max(1, plan.lights.capacity)
        table = self.light_table(cap)
        self.light_tex = GF.create_texture("rgba32f", table.shape[1], cap)
        GF.write_texture(self.light_tex, "rgba32f", table)
        ids = np.zeros(1, np.uint32)
        GL.glCreateSamplers(1, ids)
        self.sampler = int(ids[0])
        for pname, v in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_NEAREST),
                         (GL.GL_TEXTURE_MAG_FILTER, GL.GL_NEAREST),
                         (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE),
                         (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
            GL.glSamplerParameteri(self.sampler, pname, v)
        # the scene: one VBO, 15 floats a vertex (pipegen's layout)
        g = scene.geometry(("opaque",))
        data = np.concatenate([np.asarray(g.interleaved(), np.float32),
                               np.asarray(g.layer, np.float32).reshape(-1, 1)], axis=1)
        self.scene_count = len(data)
        self.scene_vbo = ctx.buffer(np.ascontiguousarray(data, np.float32).tobytes())
        from pipegen.scene.meshes import light_volume
        self.meshes = {v: ctx.buffer(np.ascontiguousarray(light_volume(v), np.float32).tobytes())
                       for v in ("sphere", "cone", "quad")}
        self.instances = ctx.buffer(reserve=4 * cap)
        self.lights = {kind: [i for i, l in enumerate(scene.lights) if l.type == kind]
                       for kind in ("point", "spot", "directional")}
        self.vaos = {}
        # uniforms: texture units are fixed; the camera's are set every frame
        for name, prog in self.programs.items():
            if "u_lights" in prog:
                prog["u_lights"].value = 0
            reads = next(p.reads for p in plan.passes if p.name == name)
            for k, r in enumerate(reads):
                prog["t_" + r].value = k + 1

    def light_table(self, cap: int) -> np.ndarray:
        """(cap, rows, 4) float32: the generated shaders' light table, each field in the row
        and components the compiler placed it (``ir/light_layout.py``)."""
        from pipegen.ir.light_layout import schema_layout
        fields = [tuple(f) for f in self.plan.lights.fields]
        layout = schema_layout(fields)
        slots = np.asarray(self.scene.light_table([list(f) for f in fields], cap), np.float32)
        rows = np.zeros((cap, layout.rows, 4), np.float32)
        for k, (name, _) in enumerate(fields):
            p = layout.place(name)
            rows[:, p.row, p.offset:p.offset + p.size] = slots[:, k, :p.size]
        return rows

    # -- building blocks ---------------------------------------------------------------------
    def fbo(self, colors, depth=None) -> int:
        GL = self.GL
        ids = np.zeros(1, np.uint32)
        GL.glCreateFramebuffers(1, ids)
        f = int(ids[0])
        for k, c in enumerate(colors):
            GL.glNamedFramebufferTexture(f, GL.GL_COLOR_ATTACHMENT0 + k, self.tex[c], 0)
        if depth:
            GL.glNamedFramebufferTexture(f, GL.GL_DEPTH_STENCIL_ATTACHMENT, self.tex[depth], 0)
        bufs = [GL.GL_COLOR_ATTACHMENT0 + k for k in range(len(colors))] or [GL.GL_NONE]
        GL.glNamedFramebufferDrawBuffers(f, len(bufs), bufs)
        assert GL.glCheckNamedFramebufferStatus(f, GL.GL_FRAMEBUFFER) == GL.GL_FRAMEBUFFER_COMPLETE
        return f

    def scene_vao(self, pass_name: str):
        prog = self.programs[pass_name]
        fmt, names = [], []
        for name, comps in SCENE_ATTRIBUTES:
            if name in prog:
                fmt.append(f"{comps}f")
                names.append(name)
            else:
                fmt.append(f"{4 * comps}x")
        return self.ctx.vertex_array(prog, [(self.scene_vbo, " ".join(fmt), *names)])

    def light_vao(self, pass_name: str, volume: str):
        prog = self.programs[pass_name]
        content = [(self.meshes[volume], "3f", "a_position")]
        if "a_light" in prog:
            content.append((self.instances, "1f/i", "a_light"))
        return self.ctx.vertex_array(prog, content)

    def begin_frame(self) -> None:
        """The frame's uniforms, the clears, and the state no pass changes."""
        GL, scene = self.GL, self.scene
        cam = scene.camera
        view = np.asarray(cam.view_matrix(), np.float64)
        proj = np.asarray(cam.projection(self.w / self.h), np.float64)
        mats = {"u_view": view, "u_proj": proj, "u_inv_view": np.linalg.inv(view),
                "u_inv_proj": np.linalg.inv(proj)}
        data = {k: np.ascontiguousarray(m.T, np.float32).tobytes() for k, m in mats.items()}
        data["u_camera_pos"] = np.asarray(cam.position, np.float32).tobytes()
        data["u_ambient"] = np.asarray(scene.ambient, np.float32)[:3].tobytes()
        data["u_output_size"] = np.array([self.w, self.h], np.float32).tobytes()
        data["u_num_lights"] = np.uint32(len(scene.lights)).tobytes()
        for prog in self.programs.values():
            for k, v in data.items():
                if k in prog:
                    prog[k].write(v)
        for name in self.cleared:
            tex = self.tex[name]
            g = self.GF.gl_format(self.formats[name].name)
            GL.glClearTexImage(tex, 0, g.format, g.type, self.clear_words[name])
        # the switches nothing here turns on (the context is shared with pipegen)
        for cap in (GL.GL_DITHER, GL.GL_FRAMEBUFFER_SRGB, GL.GL_SCISSOR_TEST,
                    GL.GL_POLYGON_OFFSET_FILL, GL.GL_DEPTH_CLAMP, GL.GL_STENCIL_TEST):
            GL.glDisable(cap)
        GL.glColorMaski(0, True, True, True, True)
        GL.glDisablei(GL.GL_BLEND, 0)
        GL.glViewport(0, 0, self.w, self.h)
        GL.glBindTextureUnit(0, self.light_tex)
        for unit in range(4):
            GL.glBindSampler(unit, self.sampler)

    def draw_lights(self, vao, indices) -> None:
        if indices:
            self.instances.write(np.asarray(indices, np.float32).tobytes())
            vao.render(instances=len(indices))

    def read(self) -> dict[str, np.ndarray]:
        out = {}
        for name, tex in self.tex.items():
            data = self.GF.read_texture(tex, self.formats[name].name, *self.sizes[name])
            if self.formats[name].has_stencil:
                out[name], out[name + ".stencil"] = self.GF.split_depth_stencil(data)
            else:
                out[name] = data
        return out


class HandDeferred(HandLoop):
    """deferred.pipe: G-buffer, ambient, directional quads, per light stencil mark + shade."""

    def __init__(self, plan, scene):
        super().__init__(plan, scene)
        self.f_gbuffer = self.fbo(["galbedo", "gnormal", "gpos"], "ds")
        self.f_accum = self.fbo(["accum"])
        self.f_mark = self.fbo([], "ds")
        self.f_shade = self.fbo(["accum"], "ds")
        self.f_color = self.fbo(["color"])
        self.v = {"gbuffer": self.scene_vao("gbuffer"),
                  "ambient_pass": self.ctx.vertex_array(self.programs["ambient_pass"], []),
                  "directional_lights": self.light_vao("directional_lights", "quad"),
                  "mark": self.light_vao("mark", "sphere"),
                  "shade_light_volume": self.light_vao("shade_light_volume", "sphere"),
                  "mark_cone": self.light_vao("mark_cone", "cone"),
                  "shade_cone": self.light_vao("shade_cone", "cone"),
                  "resolve": self.ctx.vertex_array(self.programs["resolve"], [])}
        self.zero = np.zeros(1, np.int32)        # the stencil clear between lights

    def frame(self) -> None:
        GL, v, tex = self.GL, self.v, self.tex
        self.begin_frame()
        # gbuffer: depth less + write, back faces culled
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_gbuffer)
        for i in (1, 2):
            GL.glColorMaski(i, True, True, True, True)
            GL.glDisablei(GL.GL_BLEND, i)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        v["gbuffer"].render(vertices=self.scene_count)
        # ambient: full screen into accum
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_accum)
        GL.glDisable(GL.GL_DEPTH_TEST)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glBindTextureUnit(1, tex["galbedo"])
        GL.glBindTextureUnit(2, tex["gnormal"])
        GL.glBindTextureUnit(3, tex["gpos"])
        v["ambient_pass"].render(vertices=3)
        # directional lights: additive
        GL.glEnablei(GL.GL_BLEND, 0)
        GL.glBlendEquationSeparatei(0, GL.GL_FUNC_ADD, GL.GL_FUNC_ADD)
        GL.glBlendFuncSeparatei(0, GL.GL_ONE, GL.GL_ONE, GL.GL_ZERO, GL.GL_ONE)
        self.draw_lights(v["directional_lights"], self.lights["directional"])
        # point and spot lights, in light order: stencil mark, then shade where marked
        GL.glEnable(GL.GL_STENCIL_TEST)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_FALSE)
        GL.glStencilMask(0xFF)
        GL.glCullFace(GL.GL_FRONT)
        kinds = {"point": (v["mark"], v["shade_light_volume"]),
                 "spot": (v["mark_cone"], v["shade_cone"])}
        for i, light in enumerate(self.scene.lights):
            if light.type not in kinds:
                continue
            mark, shade = kinds[light.type]
            for vao in (mark, shade):
                if "u_light" in vao.program:
                    vao.program["u_light"].value = i
            GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_mark)   # (clear the bound one:
            GL.glClearNamedFramebufferiv(self.f_mark, GL.GL_STENCIL, 0, self.zero)  # no flush)
            GL.glDepthFunc(GL.GL_LEQUAL)
            GL.glDisable(GL.GL_CULL_FACE)
            GL.glStencilFunc(GL.GL_ALWAYS, 0, 0xFF)
            GL.glStencilOpSeparate(GL.GL_BACK, GL.GL_KEEP, GL.GL_INCR_WRAP, GL.GL_KEEP)
            GL.glStencilOpSeparate(GL.GL_FRONT, GL.GL_KEEP, GL.GL_DECR_WRAP, GL.GL_KEEP)
            self.draw_lights(mark, [i])
            GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_shade)
            GL.glDepthFunc(GL.GL_ALWAYS)
            GL.glEnable(GL.GL_CULL_FACE)
            GL.glStencilFunc(GL.GL_NOTEQUAL, 0, 0xFF)
            GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_KEEP)
            self.draw_lights(shade, [i])
        GL.glDisable(GL.GL_STENCIL_TEST)
        GL.glDisable(GL.GL_DEPTH_TEST)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glDisablei(GL.GL_BLEND, 0)
        # resolve accum into color
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_color)
        GL.glBindTextureUnit(1, tex["accum"])
        v["resolve"].render(vertices=3)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glFinish()


class HandBitplanes(HandLoop):
    """lidr_bitplanes.pipe: depth pre-pass, light indices blended into bit planes, shade."""

    def __init__(self, plan, scene):
        super().__init__(plan, scene)
        self.f_prepass = self.fbo(["zcopy"], "ds")
        self.f_indices = self.fbo(["lightidx"], "ds")
        self.f_dirs = self.fbo(["diridx"])
        self.f_shade = self.fbo(["color"], "ds")
        self.v = {"depth_prepass": self.scene_vao("depth_prepass"),
                  "light_indices": self.light_vao("light_indices", "sphere"),
                  "spot_indices": self.light_vao("spot_indices", "cone"),
                  "directional_indices": self.light_vao("directional_indices", "quad"),
                  "shade": self.scene_vao("shade")}
        self.slots_constant = tuple(float(c) for c in self.state["light_indices"].blend_constant)
        self.dirs_constant = tuple(float(c)
                                   for c in self.state["directional_indices"].blend_constant)

    def frame(self) -> None:
        GL, v, tex = self.GL, self.v, self.tex
        self.begin_frame()
        # depth pre-pass: depth less + write, back faces culled, window z into zcopy
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_prepass)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        v["depth_prepass"].render(vertices=self.scene_count)
        # light indices: front faces behind the surface, blend ONE, CONSTANT_COLOR
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_indices)
        GL.glDepthFunc(GL.GL_GEQUAL)
        GL.glDepthMask(GL.GL_FALSE)
        GL.glCullFace(GL.GL_FRONT)
        GL.glEnablei(GL.GL_BLEND, 0)
        GL.glBlendEquationSeparatei(0, GL.GL_FUNC_ADD, GL.GL_FUNC_ADD)
        GL.glBlendFuncSeparatei(0, GL.GL_ONE, GL.GL_CONSTANT_COLOR, GL.GL_ONE,
                                GL.GL_CONSTANT_COLOR)
        GL.glBlendColor(*self.slots_constant)
        GL.glBindTextureUnit(1, tex["zcopy"])
        self.draw_lights(v["light_indices"], self.lights["point"])
        self.draw_lights(v["spot_indices"], self.lights["spot"])
        # directional lights: their own index target, no depth
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_dirs)
        GL.glDisable(GL.GL_DEPTH_TEST)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glBlendColor(*self.dirs_constant)
        self.draw_lights(v["directional_indices"], self.lights["directional"])
        # shade: the scene again at equal depth, reading both index targets
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_shade)
        GL.glDisablei(GL.GL_BLEND, 0)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_EQUAL)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glBindTextureUnit(1, tex["lightidx"])
        GL.glBindTextureUnit(2, tex["diridx"])
        v["shade"].render(vertices=self.scene_count)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glFinish()


# forward's shade pass as written by hand: the light table in packed rows, each read once
FORWARD_FRAGMENT = """#version 330 core
uniform vec3 u_camera_pos;
uniform vec3 u_ambient;
uniform uint u_num_lights;
uniform sampler2D u_lights;        // per light: 4 rows, then 4 shadow matrix rows (pack_lights)
uniform sampler2D t_shadow_atlas;  // 2 x 2 tiles
in vec3 v_world_pos;
in vec3 v_normal;
flat in vec3 v_albedo;
flat in vec3 v_material;           // specular, shininess, alpha
layout(location = 0) out vec4 o_color;

// 1 where light i's shadow map sees p lit (one depth compare), 1 for lights without one;
// p moves 0.1 towards the light first (spot, sun: along -direction; point: to its position)
float shadow(int i, float tile, vec3 p, vec3 dir) {
    if (tile < 0.0) {
        return 1.0;
    }
    vec4 m0 = texelFetch(u_lights, ivec2(4, i), 0);
    vec4 m1 = texelFetch(u_lights, ivec2(5, i), 0);
    vec4 m3 = texelFetch(u_lights, ivec2(7, i), 0);
    int k = int(tile);
    vec4 c;
    if (dot(m3, m3) == 0.0) {      // a point light: rows (t, p22, p23, 0), (position, 1), 0, 0
        vec3 d = p - m1.xyz;
        float dist = length(d);
        if (dist <= 0.0) {
            return 1.0;
        }
        d = p - d * (0.1 / dist) - m1.xyz;
        vec3 a = abs(d);
        vec3 v;                    // d in the view of the cube face its major axis picks
        if (a.x >= a.y && a.x >= a.z) {
            k += d.x >= 0.0 ? 0 : 1;
            v = d.x >= 0.0 ? vec3(-d.z, -d.y, -d.x) : vec3(d.z, -d.y, d.x);
        } else if (a.y >= a.z) {
            k += d.y >= 0.0 ? 2 : 3;
            v = d.y >= 0.0 ? vec3(d.x, d.z, -d.y) : vec3(d.x, -d.z, d.y);
        } else {
            k += d.z >= 0.0 ? 4 : 5;
            v = d.z >= 0.0 ? vec3(d.x, -d.y, -d.z) : vec3(-d.x, -d.y, d.z);
        }
        c = vec4(m0.x * v.xy, m0.y * v.z + m0.z, -v.z);
    } else {                       // spot, sun: the light's projection @ view
        vec4 q = vec4(p - dir * 0.1, 1.0);
        c = vec4(dot(m0, q), dot(m1, q), dot(texelFetch(u_lights, ivec2(6, i), 0), q),
                 dot(m3, q));
    }
    if (c.w <= 0.0) {
        return 1.0;
    }
    float z = c.z / c.w * 0.5 + 0.5;
    ivec2 ts = textureSize(t_shadow_atlas, 0) / 2;
    vec2 uv = (c.xy / c.w * 0.5 + 0.5) * vec2(ts);
    ivec2 t = clamp(ivec2(clamp(floor(uv), vec2(-8.0), vec2(ts) + 8.0)), ivec2(0), ts - 1);
    return z <= texelFetch(t_shadow_atlas, ivec2(k % 2, k / 2) * ts + t, 0).x ? 1.0 : 0.0;
}

void main() {
    vec3 p = v_world_pos;
    vec3 n = normalize(v_normal);
    vec3 v = normalize(u_camera_pos - p);
    vec3 c = u_ambient * v_albedo;
    for (uint i = 0u; i < u_num_lights; i++) {
        int li = int(i);
        vec4 pos_radius = texelFetch(u_lights, ivec2(0, li), 0);
        vec4 color_type = texelFetch(u_lights, ivec2(1, li), 0);
        vec4 dir_inner = texelFetch(u_lights, ivec2(2, li), 0);
        vec4 outer_tile = texelFetch(u_lights, ivec2(3, li), 0);
        vec3 l = -dir_inner.xyz;           // directional (type 2)
        float att = 1.0;
        if (color_type.w != 2.0) {         // point (0) and spot (1)
            vec3 to_light = pos_radius.xyz - p;
            float d = length(to_light);
            l = to_light / max(d, 1e-06);
            float x = clamp(1.0 - d * d / (pos_radius.w * pos_radius.w), 0.0, 1.0);
            att = x * x;
        }
        float ndl = max(dot(n, l), 0.0);
        vec3 h = normalize(l + v);
        float spec = ndl > 0.0 ? pow(max(dot(n, h), 1e-06), v_material.y) : 0.0;
        vec3 lit = color_type.xyz * att * (v_albedo * ndl + vec3(v_material.x * spec));
        if (color_type.w == 1.0) {
            lit *= smoothstep(outer_tile.x, dir_inner.w, dot(-l, dir_inner.xyz));
        }
        c += lit * shadow(li, outer_tile.y, p, dir_inner.xyz);
    }
    o_color = vec4(c, 1.0);
}
"""


def pack_lights(scene, cap: int) -> np.ndarray:
    """(cap, 8, 4) float32: the rows ``FORWARD_FRAGMENT`` reads, packed by hand."""
    names = ["position", "radius", "color", "type", "direction", "cos_inner", "cos_outer",
             "shadow_tile", "shadow_m0", "shadow_m1", "shadow_m2", "shadow_m3"]
    types = {"position": "vec3", "color": "vec3", "direction": "vec3", "type": "uint"}
    types.update({f"shadow_m{k}": "vec4" for k in range(4)})
    f = np.asarray(scene.light_table([[n, types.get(n, "float")] for n in names], cap),
                   np.float32)
    field = {n: f[:, k] for k, n in enumerate(names)}
    rows = np.zeros((cap, 8, 4), np.float32)
    for r, (vec, one) in enumerate((("position", "radius"), ("color", "type"),
                                    ("direction", "cos_inner"))):
        rows[:, r, :3], rows[:, r, 3] = field[vec][:, :3], field[one][:, 0]
    rows[:, 3, 0], rows[:, 3, 1] = field["cos_outer"][:, 0], field["shadow_tile"][:, 0]
    for k in range(4):
        rows[:, 4 + k] = field[f"shadow_m{k}"]
    return rows


class HandForward(HandLoop):
    """forward.pipe: every fragment loops over the light table, with the shader above."""

    def __init__(self, plan, scene):
        if any(getattr(l, "shadows", False) for l in scene.lights):
            raise SystemExit("hand_gl.py: the hand-written forward draws no shadow maps; "
                             "use a scene without shadow-casting lights")
        super().__init__(plan, scene)
        # the hand shader replaces the generated one (the vertex shader stays: same varyings)
        shade = next(p for p in plan.passes if p.name == "shade")
        self.programs["shade"].release()
        self.programs["shade"] = prog = self.ctx.program(vertex_shader=shade.code.vertex,
                                                         fragment_shader=FORWARD_FRAGMENT)
        prog["u_lights"].value = 0
        prog["t_shadow_atlas"].value = 1
        self.f_shade = self.fbo(["color"], "ds")
        self.v_shade = self.scene_vao("shade")
        # no shadow maps are drawn: the atlas keeps its clear value, set once
        self.cleared.remove("shadow_atlas")
        g = self.GF.gl_format(self.formats["shadow_atlas"].name)
        self.GL.glClearTexImage(self.tex["shadow_atlas"], 0, g.format, g.type,
                                self.clear_words["shadow_atlas"])

    def light_table(self, cap: int) -> np.ndarray:
        return pack_lights(self.scene, cap)

    def frame(self) -> None:
        GL = self.GL
        self.begin_frame()
        # shade: depth less + write, back faces culled, the shadow atlas (cleared) on unit 1
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.f_shade)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glBindTextureUnit(1, self.tex["shadow_atlas"])
        self.v_shade.render(vertices=self.scene_count)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glFinish()


HAND = {"deferred": HandDeferred, "lidr_bitplanes": HandBitplanes, "forward": HandForward}


@contextlib.contextmanager
def counting_gl_calls():
    """Count every ``OpenGL.GL`` call made inside the block (``Counter`` by function name).

    Wraps the module's functions, the unwrapped clear functions pipegen's GL pipeline holds,
    and gives pipegen's state tracker a fresh transition table (its transitions hold the GL
    functions they call) for the duration."""
    import OpenGL.GL as G
    counts: Counter = Counter()

    def wrap(name, f):
        def counted(*args, **kw):
            counts[name] += 1
            return f(*args, **kw)
        return counted

    saved = {n: getattr(G, n) for n in dir(G) if n.startswith("gl") and callable(getattr(G, n))}
    for n, f in saved.items():
        setattr(G, n, wrap(n, f))
    patched = []
    try:
        from pipegen.runtime.gl import pipeline as GP
        for n in ("_CLEAR_TEX", "_CLEAR_FBO_IV", "_CLEAR_FBO_FV"):
            if hasattr(GP, n):
                patched.append((GP, n, getattr(GP, n)))
                setattr(GP, n, wrap(n, getattr(GP, n)))
    except ImportError:      # pragma: no cover
        pass
    try:
        from pipegen.runtime.gl import transitions as GT
        patched.append((GT.TRACKER, "table", GT.TRACKER.table))
        GT.TRACKER.table = GT.TransitionTable()
    except ImportError:      # an older pipegen (before/after figures)
        pass
    try:
        yield counts
    finally:
        for n, f in saved.items():
            setattr(G, n, f)
        for obj, n, f in patched:
            setattr(obj, n, f)


def uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:      # pragma: no cover
        return "uptime unavailable"


def compare(tech: str, scene_name: str, size: str, frames: int) -> dict:
    from pipegen.runtime.gl.pipeline import GLPipeline
    compiled = compile_spec(tech)
    plan = compiled.plan("gl")
    scene = scene_at(str(ROOT / SCENES[scene_name]), size)
    pipe = GLPipeline(plan)
    hand = HAND[tech](plan, scene)
    # 1. every target bit-identical
    want = pipe.render(scene)
    hand.frame()
    got = hand.read()
    assert set(got) == set(want), (sorted(got), sorted(want))
    for k in want:
        if not np.array_equal(got[k], want[k]):
            bad = int(np.count_nonzero(got[k] != want[k]))
            raise AssertionError(f"{tech} {scene_name} {size}: target {k} differs from "
                                 f"pipegen's in {bad} values")
    # 2. PyOpenGL calls per frame
    pipe.frame(scene)
    with counting_gl_calls() as c_pipe:
        pipe.frame(scene)
    with counting_gl_calls() as c_hand:
        hand.frame()
    # 3. interleaved frame times, the order alternating (pipegen first on even frames)
    times = interleaved({"pipe": lambda: pipe.frame(scene), "hand": hand.frame}, frames,
                        cpu=_cpu)
    pipe.release()
    tp, th = times["pipe"], times["hand"]
    return {"tech": tech, "scene": scene_name, "size": size, "pipe_s": statistics.median(tp),
            "hand_s": statistics.median(th), "min_ratio": min(tp) / min(th),
            "cpu_ratio": sum(times["pipe_cpu"]) / max(sum(times["hand_cpu"]), 1e-9),
            "pipe_calls": sum(c_pipe.values()),
            "hand_calls": sum(c_hand.values()), "pipe_top": c_pipe.most_common(6)}


def _cpu() -> float:
    """CPU seconds of the whole process (the host thread and llvmpipe's threads)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def all_calls(scene_name: str, size: str) -> None:
    """``--all``: PyOpenGL calls per frame of every shipped technique, with state transitions
    (the default) and with all state set before every pass (``transitions=False``)."""
    from pipegen.runtime.gl.pipeline import GLPipeline
    scene = scene_at(str(ROOT / SCENES[scene_name]), size)
    print(f"PyOpenGL calls per frame, {scene_name} at {size}")
    print(f"{'technique':<20} {'passes run':>10} {'transitions':>11} {'full state':>10}")
    for path in sorted((ROOT / "pipelines").glob("*.pipe")):
        plan = compile_spec(path.stem).plan("gl")
        counts, runs = [], 0
        for transitions in (True, False):
            pipe = GLPipeline(plan, transitions=transitions)
            pipe.frame(scene)
            with counting_gl_calls() as c:
                pipe.frame(scene)
            pipe.profile = []
            pipe.frame(scene)
            runs = len(pipe.profile)
            pipe.release()
            counts.append(sum(c.values()))
        print(f"{path.stem:<20} {runs:>10} {counts[0]:>11} {counts[1]:>10}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--sizes", default="320x180,1280x720")
    ap.add_argument("--scenes", default="many_lights,small")
    ap.add_argument("--techniques", default="deferred,lidr_bitplanes,forward")
    ap.add_argument("--threads", default="2")
    ap.add_argument("--calls", action="store_true", help="list pipegen's most frequent calls")
    ap.add_argument("--all", action="store_true",
                    help="only count the calls of every shipped technique (first scene and "
                         "size), transitions vs full state")
    args = ap.parse_args()
    os.environ["LP_NUM_THREADS"] = args.threads
    from pipegen.runtime.gl import context as C
    print(f"{C.describe()}; PyOpenGL error checking "
          f"{'on' if getattr(C, 'ERROR_CHECKING', True) else 'off'}; "
          f"LP_NUM_THREADS={args.threads}; {args.frames} interleaved frames each",
          file=sys.stderr)
    if args.all:
        all_calls(args.scenes.split(",")[0], args.sizes.split(",")[0])
        return 0
    print(f"load before: {uptime()}")
    rows = []
    for tech in args.techniques.split(","):
        for scene_name in args.scenes.split(","):
            for size in args.sizes.split(","):
                r = compare(tech, scene_name, size, args.frames)
                rows.append(r)
                print(f"  {tech} {scene_name} {size}: bit-identical, "
                      f"{r['pipe_s'] * 1e3:.1f} vs {r['hand_s'] * 1e3:.1f} ms", file=sys.stderr)
    print(f"{'technique':<16} {'scene':<12} {'size':>9} {'pipegen ms':>10} {'hand ms':>8} "
          f"{'ratio':>6} {'min':>5} {'cpu':>5} {'pipegen calls':>13} {'hand calls':>10}")
    for r in rows:
        print(f"{r['tech']:<16} {r['scene']:<12} {r['size']:>9} {r['pipe_s'] * 1e3:>10.2f} "
              f"{r['hand_s'] * 1e3:>8.2f} {r['pipe_s'] / r['hand_s']:>6.2f} "
              f"{r['min_ratio']:>5.2f} {r['cpu_ratio']:>5.2f} "
              f"{r['pipe_calls']:>13} {r['hand_calls']:>10}")
        if args.calls:
            print("    pipegen's most frequent: "
                  + ", ".join(f"{n} {k}" for n, k in r["pipe_top"]))
    print(f"load after: {uptime()}")
    print("every target of every frame compared: bit-identical")
    return 0


if __name__ == "__main__":
    sys.exit(main())
