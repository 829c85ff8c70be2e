"""GLPipeline end to end on hand-written PLAN dicts (docs/internals.md "Compiled plan").

Shaders here are written by hand following the GLSL conventions, so these tests exercise the
runtime alone: targets and clears, per-pass framebuffers, uniforms and the light table, scene
VBOs, instanced light volumes and their light lists (types, CPU-sorted slot sets, scissor),
``repeat_group`` loops, reads (nearest / linear), MSAA resolves, d24s8 readback and pass
captures.  Renders are tiny (16x16 to 32x24).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
import pytest

from pipegen.ir.nodes import Size
from pipegen.reference import fixed_function as FF
from pipegen.runtime import draws

try:
    from pipegen.runtime.gl.context import get_context
    from pipegen.runtime.gl.pipeline import GLPipeline
    _CTX = get_context()
    _ERR = None
except Exception as e:  # pragma: no cover - machines without EGL
    _CTX, _ERR = None, e

pytestmark = [pytest.mark.gl, pytest.mark.skipif(_CTX is None, reason=f"no EGL/GL context: {_ERR}")]

HEADER = "#version 330 core\n"
UNIFORMS = """
uniform mat4 u_view; uniform mat4 u_proj; uniform mat4 u_inv_view; uniform mat4 u_inv_proj;
uniform vec3 u_camera_pos; uniform vec3 u_ambient; uniform vec2 u_output_size;
uniform uint u_num_lights; uniform sampler2D u_lights;
"""
VS_FULL = HEADER + UNIFORMS + """
void main() {
    vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
    gl_Position = vec4(p, 1.0, 1.0);
}"""
VS_SCENE = HEADER + UNIFORMS + """
layout(location = 0) in vec3 a_position;
layout(location = 2) in vec3 a_albedo;
layout(location = 4) in vec2 a_ids;
out vec3 v_albedo;
flat out uvec2 v_ids;
void main() {
    v_albedo = a_albedo;
    v_ids = uvec2(a_ids + 0.5);
    gl_Position = u_proj * (u_view * vec4(a_position, 1.0));
}"""
VS_LIGHTS = HEADER + UNIFORMS + """
layout(location = 0) in vec3 a_position;
layout(location = 1) in float a_light;
flat out uint v_light;
void main() {
    int i = int(a_light);
    v_light = uint(i);
    vec4 row0 = texelFetch(u_lights, ivec2(0, i), 0);   // position + radius (ir/light_layout.py)
    vec3 centre = row0.xyz;
    float radius = row0.w;
    gl_Position = u_proj * (u_view * vec4(centre + a_position * radius, 1.0));
}"""


def fs(outputs: str, body: str, extra: str = "") -> str:
    return HEADER + UNIFORMS + extra + outputs + "\nvoid main() {\n" + body + "\n}"


# ---------------------------------------------------------------------------------------------
# a tiny scene with the Scene API (pipegen.scene), independent of scene files
# ---------------------------------------------------------------------------------------------


@dataclass
class FakeLight:
    position: tuple
    radius: float
    color: tuple = (1.0, 1.0, 1.0)
    type: str = "point"


@dataclass
class FakeGeometry:
    positions: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray
    material: np.ndarray
    ids: np.ndarray

    def interleaved(self):
        return np.concatenate([self.positions, self.normals, self.albedo, self.material,
                               self.ids], axis=1).astype(np.float32)


class OrthoCamera:
    """Looks down -z from z = 10 at the square [-1, 1]^2 (orthographic: easy to predict)."""

    position = (0.0, 0.0, 10.0)
    near, far = 1.0, 20.0

    def view_matrix(self):
        m = np.eye(4)
        m[2, 3] = -10.0
        return m

    def projection(self, aspect):
        n, f = self.near, self.far
        p = np.eye(4)
        p[0, 0] = 1.0 / aspect
        p[2, 2] = -2.0 / (f - n)
        p[2, 3] = -(f + n) / (f - n)
        return p


@dataclass
class FakeScene:
    width: int = 16
    height: int = 16
    ambient: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.2, 0.3]))
    quads: list = field(default_factory=list)     # (x0, y0, x1, y1, z, albedo, object id, kind)
    lights: list = field(default_factory=list)
    camera: OrthoCamera = field(default_factory=OrthoCamera)

    def geometry(self, material=()):
        pos, alb, ids = [], [], []
        for x0, y0, x1, y1, z, albedo, oid, kind in self.quads:
            if material and kind not in material:
                continue
            a, b, c, d = (x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)
            pos += [a, b, c, a, c, d]
            alb += [albedo] * 6
            ids += [(oid, 0)] * 6
        n = len(pos)
        z3 = np.zeros((n, 3), np.float32)
        return FakeGeometry(np.array(pos, np.float32).reshape(n, 3), z3 + [0, 0, 1],
                            np.array(alb, np.float32).reshape(n, 3), z3,
                            np.array(ids, np.float32).reshape(n, 2))

    def light_table(self, fields, capacity):
        t = np.zeros((capacity, len(fields), 4), np.float32)
        for i, l in enumerate(self.lights):
            for k, (name, _) in enumerate(fields):
                v = np.atleast_1d(np.asarray(getattr(l, name), np.float32))
                t[i, k, :len(v)] = v
        return t


# ---------------------------------------------------------------------------------------------
# PLAN helpers
# ---------------------------------------------------------------------------------------------


def target(name, fmt, clear_color=None, clear_depth=None, clear_stencil=None, scale=1.0,
           width=0, height=0, samples=1):
    if clear_color is None and fmt not in ("d24s8", "d32f"):
        clear_color = [0, 0, 0, 0]
    return {"name": name, "format": fmt, "scale": scale, "width": width, "height": height,
            "samples": samples, "clear_color": clear_color, "clear_depth": clear_depth,
            "clear_stencil": clear_stencil}


def state(**kw):
    s = {"depth": {"func": "always", "write": False, "clamp": False},
         "stencil": {"front": {"func": "always", "ref": 0, "read_mask": 255, "write_mask": 255,
                               "fail": "keep", "zfail": "keep", "zpass": "keep"}},
         "blend": {}, "blend_constant": [0, 0, 0, 0], "cull": "none", "polygon_offset": None}
    s["stencil"]["back"] = dict(s["stencil"]["front"])
    s.update(kw)
    return s


def add_blend(*names, rgb=("add", "one", "one"), alpha=("add", "one", "one")):
    return {n: {"enabled": True, "rgb": list(rgb), "alpha": list(alpha),
                "write_mask": [True] * 4} for n in names}


def pass_(name, vertex, fragment, writes=(), reads=(), depth_target=None, kind="fullscreen",
          material=(), volume=None, light_types=(), light_set=None, scissor=False,
          repeat_group=None, clears=(), st=None, sampled=()):
    return {"name": name,
            "draw": {"kind": kind, "material": list(material), "volume": volume,
                     "light_types": list(light_types), "light_set": light_set,
                     "scissor": scissor},
            "repeat_group": repeat_group, "clears": list(clears), "writes": list(writes),
            "reads": list(reads), "depth_target": depth_target, "state": st or state(),
            "vertex": vertex, "fragment": fragment, "sampled": list(sampled)}


def plan(targets, passes, fields=(("position", "vec3"), ("radius", "float")), capacity=8,
         light_sets=None, output=None):
    return {"technique": "test", "title": "test", "backend": "gl", "params": {"k": 1},
            "lights": {"capacity": capacity, "fields": [list(f) for f in fields]},
            "output": output or targets[0]["name"], "targets": targets, "passes": passes,
            "light_sets": light_sets or {}}


def render(p, scene, **kw):
    pipe = GLPipeline(p, kw.pop("size", None))
    try:
        return pipe.render(scene, **kw)
    finally:
        pipe.release()


# ---------------------------------------------------------------------------------------------
# tests
# ---------------------------------------------------------------------------------------------


def test_fullscreen_constant_colour_and_formats():
    """One full-screen pass writes a constant to targets of several formats (4 attachments)."""
    outs = ("layout(location = 0) out vec4 o_a;\nlayout(location = 1) out vec4 o_b;\n"
            "layout(location = 2) out vec4 o_c;\nlayout(location = 3) out uvec4 o_d;\n")
    body = ("o_a = vec4(0.25, 0.5, 0.75, 1.0); o_b = vec4(70000.0, -1.5, 1e-6, 0.1);\n"
            "o_c = vec4(0.3, 0.6, 0.9, 1.0); o_d = uvec4(7u, 300u, 1u, 2u);")
    p = plan([target("a", "rgba8"), target("b", "rgba16f"), target("c", "rgb10a2"),
              target("d", "r32ui")],
             [pass_("fill", VS_FULL, fs(outs, body), writes=["a", "b", "c", "d"])])
    out = render(p, FakeScene(width=5, height=3))       # odd sizes: no row padding issues
    assert out["a"].shape == (3, 5, 4) and out["a"].dtype == np.uint8
    assert (out["a"] == [64, 128, 191, 255]).all()      # 0.75*255 = 191.25
    assert out["b"].dtype == np.float16
    assert (out["b"][..., :2] == np.array([65504, -1.5], np.float16)).all()
    assert (out["b"][..., 2:] == FF.half_store(np.array([1e-6, 0.1]))).all()
    assert out["c"].dtype == np.uint16 and (np.abs(out["c"].astype(int)
                                               - [307, 614, 921, 3]) <= 1).all()
    assert out["d"].shape == (3, 5) and out["d"].dtype == np.uint32 and (out["d"] == 7).all()


def test_clear_values_and_d24s8_readback():
    """Targets start at their clear values; a pass without draws into them leaves them."""
    p = plan([target("c", "rgba8", clear_color=[0.5, 0, 1, 0.2]),
              target("f", "rg32f", clear_color=[1.5, -2.0, 0, 0]),
              target("ds", "d24s8", clear_depth=0.5, clear_stencil=7),
              target("z", "d32f", clear_depth=0.25)],
             [pass_("noop", VS_FULL, fs("", "discard;"), depth_target="ds")])
    out = render(p, FakeScene())
    assert (out["c"] == [128, 0, 255, 51]).all()
    assert (out["f"] == np.array([1.5, -2.0], np.float32)).all()
    assert set(out) == {"c", "f", "ds", "ds.stencil", "z"}
    assert out["ds"].dtype == np.uint32 and (out["ds"] == 8388608).all()
    assert out["ds.stencil"].dtype == np.uint8 and (out["ds.stencil"] == 7).all()
    assert out["z"].dtype == np.float32 and (out["z"] == 0.25).all()


def test_reads_nearest_and_linear():
    """Pass 2 reads pass 1's target: texelFetch (load) and bilinear texture() (sample)."""
    gradient = fs("layout(location = 0) out vec4 o_g;\n",
                  "o_g = vec4(floor(gl_FragCoord.x) / 15.0, 0.0, 0.0, 1.0);")
    reader = fs("layout(location = 0) out vec4 o_n;\nlayout(location = 1) out vec4 o_l;\n",
                "ivec2 p = ivec2(gl_FragCoord.xy);\n"
                "o_n = texelFetch(t_g, p, 0);\n"
                "o_l = texture(t_g, vec2((float(p.x) + 1.0) / 16.0, 0.5));",
                extra="uniform sampler2D t_g;\n")
    p = plan([target("g", "rgba32f"), target("n", "rgba32f"), target("l", "rgba32f")],
             [pass_("grad", VS_FULL, gradient, writes=["g"]),
              pass_("read", VS_FULL, reader, writes=["n", "l"], reads=["g"], sampled=["g"])])
    out = render(p, FakeScene())
    x = np.arange(16) / 15.0
    assert np.allclose(out["n"][0, :, 0], x)
    # u = (x+1)/16 falls on the border between texels x and x+1: their mean (clamped at 15)
    expect = (x + np.minimum(np.arange(16) + 1, 15) / 15.0) / 2
    assert np.allclose(out["l"][0, :, 0], expect, atol=1e-3)
    # without "sampled", the same texture() call is nearest
    p2 = copy.deepcopy(p)
    p2["passes"][1]["sampled"] = []
    out2 = render(p2, FakeScene())
    assert np.allclose(out2["l"][0, :, 0], np.minimum(np.arange(16) + 1, 15) / 15.0)


def test_scene_pass_depth_ids_and_uniforms():
    """Scene geometry through u_view/u_proj with a depth test: nearest quad wins per pixel;
    object ids land in an integer target; u_ambient / u_output_size / u_num_lights arrive."""
    scene = FakeScene(quads=[(-1, -1, 0, 1, 0.0, (1, 0, 0), 1, "opaque"),
                             (-0.5, -1, 1, 0, 2.0, (0, 1, 0), 2, "opaque"),     # nearer
                             (-1, -1, 1, 1, 5.0, (0, 0, 1), 3, "translucent")],
                      lights=[FakeLight((0, 0, 0), 1.0)] * 3)
    frag = fs("in vec3 v_albedo;\nflat in uvec2 v_ids;\n"
              "layout(location = 0) out vec4 o_c;\nlayout(location = 1) out uvec4 o_id;\n"
              "layout(location = 2) out vec4 o_u;\n",
              "o_c = vec4(v_albedo, 1.0); o_id = uvec4(v_ids.x, 0u, 0u, 0u);\n"
              "o_u = vec4(u_ambient.z, u_output_size / 100.0, float(u_num_lights) / 10.0);")
    st = state(depth={"func": "less", "write": True, "clamp": False}, cull="back")
    p = plan([target("c", "rgba8"), target("id", "r32ui"), target("u", "rgba32f"),
              target("ds", "d24s8", clear_depth=1.0, clear_stencil=0)],
             [pass_("geo", VS_SCENE, frag, writes=["c", "id", "u"], depth_target="ds",
                    kind="scene", material=["opaque"], st=st)])
    out = render(p, scene)
    ids = out["id"]
    ys, xs = np.mgrid[0:16, 0:16]
    nearer = (xs >= 4) & (ys < 8)              # quad 2 covers x in [-0.5, 1], y in [-1, 0]
    left = xs < 8
    assert (ids[nearer] == 2).all()
    assert (ids[left & ~nearer] == 1).all()
    assert (ids[~left & ~nearer] == 0).all()   # the translucent quad is filtered out
    assert (out["c"][nearer] == [0, 255, 0, 255]).all()
    # world z = 2 is view z = -8: clip z = (-2/19)(-8) - 21/19 = -5/19, window z = 7/19
    z = FF.depth_codes("d24s8", 7 / 19)
    assert abs(int(out["ds"][0, 15]) - int(z)) <= 1
    assert (out["ds"][~left & ~nearer] == 0xFFFFFF).all()
    assert np.allclose(out["u"][0, 4], [0.3, 0.16, 0.16, 0.3])


def _count_plan(light_types=(), light_set=None, scissor=False, light_sets=None, volume="sphere"):
    """Lights as instanced spheres, additive count of lights per pixel (1/255 per light)."""
    frag = fs("flat in uint v_light;\nlayout(location = 0) out vec4 o_n;\n",
              "o_n = vec4(1.0 / 255.0, float(v_light + 1u) / 255.0, 0.0, 0.0);")
    st = state(blend=add_blend("n"), cull="back")
    return plan([target("n", "rgba8")],
                [pass_("count", VS_LIGHTS, frag, writes=["n"], kind="lights", volume=volume,
                       light_types=light_types, light_set=light_set, scissor=scissor, st=st)],
                light_sets=light_sets)


def _lights_scene():
    return FakeScene(lights=[FakeLight((-0.5, -0.5, 0), 0.3), FakeLight((0.5, 0.5, 0), 0.3),
                             FakeLight((0.3, 0.3, 0), 0.4, type="spot"),
                             FakeLight((-0.5, 0.5, 0), 0.2)])


def _disc(light, size=16, scale=1.0):
    ys, xs = (np.mgrid[0:size, 0:size] + 0.5) / size * 2 - 1
    r = light.radius * scale
    return (xs - light.position[0]) ** 2 + (ys - light.position[1]) ** 2 < r ** 2


def test_light_volumes_instanced_with_types():
    scene = _lights_scene()
    out = render(_count_plan(), scene)["n"]
    count = sum(_disc(l).astype(int) for l in scene.lights)
    # the mesh circumscribes the sphere: every pixel inside a disc is covered
    assert (out[..., 0] >= count).all() and out[..., 0].max() <= 2
    assert (out[..., 0][count == 0] <= 1).all()
    ids = sum(np.where(_disc(l), i + 1, 0) for i, l in enumerate(scene.lights))
    inside_one = count == 1
    assert (out[..., 1][inside_one] == ids[inside_one]).all()
    points = render(_count_plan(light_types=["point"]), scene)["n"]
    assert (points[..., 1] != 3).all() and (points[..., 1] == 1).any()
    spots = render(_count_plan(light_types=["spot"]), scene)["n"]
    assert set(np.unique(spots[..., 1])) == {0, 3}


def test_light_sets_from_cpu_sort():
    """``in slots[k]``: passes draw only the lights of set k of sort_lights_into_slots."""
    from pipegen.packing.light_index import sort_lights_into_slots
    scene = _lights_scene()
    sets, dropped = sort_lights_into_slots([l.position for l in scene.lights],
                                           [l.radius for l in scene.lights], 2)
    seen = []
    for k in range(2):
        pipe = GLPipeline(_count_plan(light_set=["slots", k], light_sets={"slots": 2}))
        try:
            out = pipe.render(scene)["n"]
            assert pipe.light_sets(scene)["slots"] == [list(s) for s in sets]
            assert pipe.dropped_lights["slots"] == list(dropped)
        finally:
            pipe.release()
        drawn = set(np.unique(out[..., 1])) - {0}
        assert drawn <= {i + 1 for i in sets[k]} and out[..., 0].max() <= 1  # no overlap
        seen += sorted(drawn)
    assert sorted(seen) == sorted(i + 1 for s in sets for i in s)


def test_scissor_light_draws():
    """Scissored light draws only touch pixels in each light's screen rectangle."""
    scene = _lights_scene()
    frag = fs("flat in uint v_light;\nlayout(location = 0) out vec4 o_n;\n",
              "o_n = vec4(1.0 / 255.0, 0.0, 0.0, 0.0);")
    # a quad "volume" 3x the light's size: without the scissor it spills outside the rect
    vs = VS_LIGHTS.replace("a_position * radius", "a_position * radius * 3.0")
    base = plan([target("n", "rgba8")],
                [pass_("q", vs, frag, writes=["n"], kind="lights", volume="quad",
                       st=state(blend=add_blend("n")))])
    free = render(base, scene)["n"][..., 0]
    sc = copy.deepcopy(base)
    sc["passes"][0]["draw"]["scissor"] = True
    clipped = render(sc, scene)["n"][..., 0]
    cam = scene.camera
    rects = np.zeros((16, 16), int)
    for l in scene.lights:
        x, y, w, h = draws.scissor_rect(l, cam.view_matrix(), cam.projection(1.0), 16, 16)
        rects[y:y + h, x:x + w] += 1
    assert (clipped <= rects).all() and (clipped < free).any()
    assert clipped.sum() > 0


def test_repeat_group_per_light_with_partial_stencil_clear():
    """Two passes repeat per light: ``mark`` clears stencil only (depth kept) and sets it
    where the light's disc is; ``add`` accumulates u_light + 1 where the stencil is set."""
    scene = _lights_scene()
    mark_st = state(depth={"func": "lequal", "write": False, "clamp": False})
    face = {"func": "always", "ref": 1, "read_mask": 255, "write_mask": 255, "fail": "keep",
            "zfail": "keep", "zpass": "replace"}
    mark_st["stencil"] = {"front": face, "back": face}
    add_st = state(blend=add_blend("acc"))
    eq = {"func": "equal", "ref": 1, "read_mask": 255, "write_mask": 0, "fail": "keep",
          "zfail": "keep", "zpass": "keep"}
    add_st["stencil"] = {"front": eq, "back": eq}
    add_fs = fs("uniform uint u_light;\nlayout(location = 0) out vec4 o_acc;\n",
                "o_acc = vec4(float(u_light + 1u) / 255.0, 1.0 / 255.0, 0.0, 0.0);")
    # the depth buffer holds 0.1 on the left half (set by a first pass writing depth)
    depth_fs = fs("", "if (gl_FragCoord.x > 8.0) discard; gl_FragDepth = 0.1;")
    p = plan([target("acc", "rgba8"), target("ds", "d24s8", clear_depth=1.0, clear_stencil=9)],
             [pass_("depth", VS_FULL, depth_fs, depth_target="ds",
                    st=state(depth={"func": "always", "write": True, "clamp": False})),
              pass_("mark", VS_LIGHTS, fs("", ""), depth_target="ds", kind="lights",
                    volume="sphere", repeat_group=0, st=mark_st,
                    clears=[{"target": "ds", "clear_color": None, "clear_depth": None,
                             "clear_stencil": 0}]),
              pass_("add", VS_FULL.replace("vec4(p, 1.0, 1.0)", "vec4(p, 0.0, 1.0)"), add_fs,
                    writes=["acc"], depth_target="ds", repeat_group=0, st=add_st)])
    pipe = GLPipeline(p)
    try:
        out, captures = pipe.render(scene, capture_passes=True)
    finally:
        pipe.release()
    assert [(c["pass"], c["light"]) for c in captures] == \
        [("depth", None)] + [(n, i) for i in range(4) for n in ("mark", "add")]
    # left half depth 0.1 survives every stencil-only clear; right half stays at 1.0
    assert (out["ds"][:, :8] == FF.depth_codes("d24s8", 0.1)).all()
    assert (out["ds"][:, 8:] == 0xFFFFFF).all()
    # the light spheres sit near window depth 0.47 (world z = 0): 'lequal' passes on the
    # right half only, so only there do the marks (and the additions) happen
    acc = out["acc"].astype(int)
    assert (acc[:, :8] == 0).all()
    right = np.mgrid[0:16, 0:16][1] >= 8
    inside = [_disc(l, scale=0.97) & right for l in scene.lights]
    outside = [~_disc(l, scale=1.05) | ~right for l in scene.lights]
    sure = np.logical_and.reduce([a | b for a, b in zip(inside, outside)])
    expect = sum(np.where(a, i + 1, 0) for i, a in enumerate(inside))
    assert sure.sum() > 100 and (expect[sure] > 0).sum() > 20
    assert np.array_equal(acc[..., 0][sure], expect[sure])
    assert np.array_equal(acc[..., 1][sure], sum(a.astype(int) for a in inside)[sure])
    # after light 3's mark the stencil holds only light 3's marks
    last_mark = captures[-2]["targets"]["ds.stencil"]
    assert set(np.unique(last_mark)) <= {0, 1} and (last_mark[:, :8] == 0).all()


def test_msaa_target_is_resolved():
    """A 4x multisampled target: full coverage resolves to the colour, a diagonal edge to
    intermediate values; a later pass reads the resolved texture."""
    tri = fs("layout(location = 0) out vec4 o_m;\n", "o_m = vec4(1.0, 0.5, 0.0, 1.0);")
    vs = HEADER + """
void main() {
    vec2 p = vec2(gl_VertexID == 1 ? 1.0 : -1.0, gl_VertexID == 2 ? 1.0 : -1.0);
    gl_Position = vec4(p, 0.0, 1.0);
}"""
    copy_fs = fs("uniform sampler2D t_m;\nlayout(location = 0) out vec4 o_c;\n",
                 "o_c = texelFetch(t_m, ivec2(gl_FragCoord.xy), 0);")
    p = plan([target("m", "rgba8", samples=4), target("c", "rgba8")],
             [pass_("tri", vs, tri, writes=["m"]),
              pass_("copy", VS_FULL, copy_fs, writes=["c"], reads=["m"])])
    out = render(p, FakeScene())
    m = out["m"][..., 0].astype(int)
    assert m[0, 0] == 255 and m[15, 15] == 0
    partial = (m > 0) & (m < 255)
    assert partial.any()                                       # the diagonal's pixels
    assert np.array_equal(out["c"], out["m"])


def test_relative_and_absolute_target_sizes():
    p = plan([target("full", "r8"), target("half", "r8", scale=0.5),
              target("fixed", "r8", width=3, height=5)],
             [pass_("h", VS_FULL, fs("layout(location = 0) out vec4 o_half;\n",
                                     "o_half = vec4(u_output_size.x / 255.0);"),
                    writes=["half"])])
    out = render(p, FakeScene(width=13, height=7))
    assert out["full"].shape == (7, 13) and out["half"].shape == (4, 7)
    assert out["fixed"].shape == (5, 3)
    assert (out["half"] == 13).all()
    assert Size(0.625).resolve(1280, 720) == (800, 450)
    # an explicit pipeline size overrides the scene's
    out = render(p, FakeScene(width=13, height=7), size=(8, 6))
    assert out["full"].shape == (6, 8) and (out["half"] == 8).all()


def test_pipeline_reuse_and_params():
    p = plan([target("c", "r8")],
             [pass_("f", VS_FULL, fs("layout(location = 0) out vec4 o_c;\n",
                                     "o_c = vec4(float(u_num_lights) / 255.0);"),
                    writes=["c"])])
    pipe = GLPipeline(p)
    try:
        a = pipe.render(_lights_scene())
        b = pipe.render(FakeScene(width=4, height=4))           # new size, new scene
        assert (a["c"] == 4).all() and a["c"].shape == (16, 16)
        assert (b["c"] == 0).all() and b["c"].shape == (4, 4)
        assert (pipe.render(_lights_scene(), params={"k": 1})["c"] == 4).all()
        with pytest.raises(ValueError, match="recompile"):
            pipe.render(_lights_scene(), params={"k": 2})
        with pytest.raises(ValueError, match="unknown parameter"):
            pipe.render(_lights_scene(), params={"nope": 2})
    finally:
        pipe.release()


def test_bad_shader_names_the_pass():
    p = plan([target("c", "r8")], [pass_("broken", VS_FULL, fs("", "this is not glsl;"))])
    with pytest.raises(RuntimeError, match="pass 'broken'"):
        GLPipeline(p)


def test_real_scene_if_available():
    """With pipegen.scene: the default scene's geometry and lights go through unchanged."""
    scene_mod = pytest.importorskip("pipegen.scene")
    scene = scene_mod.default_scene().with_size(32, 18)
    frag = fs("flat in uvec2 v_ids;\nlayout(location = 0) out uvec4 o_id;\n",
              "o_id = uvec4(v_ids.x, 0u, 0u, 0u);", extra="in vec3 v_albedo;\n")
    st = state(depth={"func": "less", "write": True, "clamp": False}, cull="back")
    p = plan([target("id", "r32ui"), target("ds", "d24s8", clear_depth=1.0, clear_stencil=0)],
             [pass_("geo", VS_SCENE, frag, writes=["id"], depth_target="ds", kind="scene",
                    st=st)],
             fields=(("position", "vec3"), ("radius", "float"), ("color", "vec3")),
             capacity=max(8, len(scene.lights)))
    out = render(p, scene)
    ids = set(np.unique(out["id"]).tolist())
    assert ids - {0} and ids - {0} <= {o.id for o in scene.objects}
    assert (out["ds"][out["id"] == 0] == 0xFFFFFF).all()
    assert (out["ds"][out["id"] != 0] < 0xFFFFFF).all()


@pytest.mark.parametrize("samples", [1, 4])
def test_depth_only_pass_without_fragment_shader(samples):
    """A pass with no fragment shader writes depth and stencil only; with MSAA both aspects
    are resolved for readback and a later depth test sees them."""
    st = state(depth={"func": "always", "write": True, "clamp": False})
    face = {"func": "always", "ref": 5, "read_mask": 255, "write_mask": 255, "fail": "keep",
            "zfail": "keep", "zpass": "replace"}
    st["stencil"] = {"front": face, "back": face}
    colour = fs("layout(location = 0) out vec4 o_c;\n", "o_c = vec4(1.0);")
    p = plan([target("c", "rgba8", samples=samples),
              target("ds", "d24s8", clear_depth=1.0, clear_stencil=0, samples=samples)],
             [pass_("z", VS_SCENE, None, depth_target="ds", kind="scene", st=st),
              pass_("c", VS_FULL, colour, writes=["c"], depth_target="ds",
                    st=state(depth={"func": "greater", "write": False, "clamp": False}))])
    scene = FakeScene(quads=[(-1, -1, 0, 1, 0.0, (1, 1, 1), 1, "opaque")])
    out = render(p, scene)
    left = np.arange(16) < 8          # the quad covers x in [-1, 0]
    z = int(FF.depth_codes("d24s8", 9 / 19))     # world z 0: clip z -1/19
    assert (np.abs(out["ds"][:, left].astype(np.int64) - z) <= 1).all()
    assert (out["ds"][:, ~left] == 0xFFFFFF).all()
    assert (out["ds.stencil"][:, left] == 5).all() and (out["ds.stencil"][:, ~left] == 0).all()
    assert (out["c"][:, left] == 255).all() and (out["c"][:, ~left] == 0).all()


def test_errors_left_by_other_moderngl_code_do_not_break_the_runtime():
    """moderngl never checks glGetError: an error a user's own call leaves pending must not
    surface from the runtime's next (PyOpenGL-checked) call."""
    from pipegen.compiler.driver import compile_source
    from pipegen.runtime.gl.context import GL, get_context
    from pipegen.scene import default_scene
    ctx = get_context()
    ctx.enable_direct(0xFFFF)            # GL_INVALID_ENUM, left pending by moderngl
    compiled = compile_source('technique t "x"\ntarget color : rgba8\n'
                              'pass p { draw fullscreen writes color '
                              'fragment { color = vec4(1.0); } }\n')
    out = compiled.pipeline("gl", size=(4, 4)).render(default_scene())
    assert (out["color"] == 255).all()
    assert GL.glGetError() == GL.GL_NO_ERROR


def test_ctrl_c_inside_a_pyopengl_argument_conversion_is_a_keyboard_interrupt(monkeypatch):
    """A SIGINT whose handler runs in PyOpenGL's ``from_param`` (Python code ctypes calls while
    converting a read-back's arguments) reaches Python as ``ctypes.ArgumentError``; ``render``
    raises it as KeyboardInterrupt, so ``stress`` and ``check`` exit 130 (CI saw the traceback);
    an ArgumentError of another cause stays what it is."""
    import ctypes
    from pipegen.runtime.gl import formats as GF

    def converting(cause):
        class Arg:                   # stands in for PyOpenGL's numpy array handler
            @classmethod
            def from_param(cls, obj):
                raise cause
        call = ctypes.CDLL(None).abs
        call.argtypes = [Arg]
        return lambda *a, **k: call(1)

    p = plan([target("c", "r8")],
             [pass_("f", VS_FULL, fs("layout(location = 0) out vec4 o_c;\n", "o_c = vec4(0.5);"),
                    writes=["c"])])
    pipe = GLPipeline(p)
    try:
        monkeypatch.setattr(GF, "read_texture", converting(KeyboardInterrupt()))
        with pytest.raises(KeyboardInterrupt):
            pipe.render(FakeScene(width=4, height=4))
        monkeypatch.setattr(GF, "read_texture", converting(TypeError("not an array")))
        with pytest.raises(ctypes.ArgumentError, match="TypeError: not an array"):
            pipe.render(FakeScene(width=4, height=4))
        monkeypatch.undo()
        assert (pipe.render(FakeScene(width=4, height=4))["c"] == 128).all()
    finally:
        pipe.release()
