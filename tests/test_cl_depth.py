"""Window depth of the OpenCL reference against llvmpipe (Mesa 22.3.6), code for code.

llvmpipe's depth is not the exact plane through the three vertices rounded once: it is a float32
plane whose errors the reference reproduces (``pipegen/runtime/cl/setup.py``, ``depth_plane``,
``clip_triangles``, ``window_coords``; the raster kernel in ``templates/cl_pass.cl.j2``):

- window positions: ``fma(x * (1/w), W/2, W/2)`` for shader vertices (draw's LLVM path uses
  ``fmuladd``), ``x * oow * scale + trans`` rounded step by step for vertices the clipper made;
- clipping against the viewport planes |x|, |y| <= w (no guard band for triangles) and near/far
  in float32 as draw_pipe_clip.c, polygons emitted as fans (p[i-1], p[i], p0);
- setup (lp_state_setup.c): vertices in llvmpipe's counter-clockwise order (v1, v0, v2 when the
  GL-window area is positive), float32 ``dadx``, ``dady`` and ``a0 = z0 - (dadx (x0 - .5) +
  dady (y0 - .5))`` -- the value at the window *origin*, off by many d24 codes on steep planes;
- per fragment (lp_bld_interp.c): ``fma(dady, y, fma(dadx, x, a0)) + offset`` at the integer
  pixel, then ``rint(clamp(z) * 16777215.0f)``.

With FMA hardware (the fused multiply-adds above) the codes agree exactly; the tests require
that there and the d24 tolerance of ``pipegen check`` (2 codes) elsewhere.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyopencl")

pytestmark = [pytest.mark.gl, pytest.mark.cl]

from cl_util import TriScene, make_pass, make_plan, target  # noqa: E402
from pipegen.runtime.cl import setup as CS  # noqa: E402
from pipegen.runtime.cl.pipeline import CLPipeline  # noqa: E402

try:
    from pipegen.runtime.gl.context import get_context
    from pipegen.runtime.gl.pipeline import GLPipeline
    _CTX = get_context()
    _ERR = None
except Exception as e:  # pragma: no cover - machines without EGL
    _CTX, _ERR = None, e

needs_gl = pytest.mark.skipif(_CTX is None, reason=f"no EGL/GL context: {_ERR}")


def _host_has_fma() -> bool:
    try:
        return " fma " in f" {Path('/proc/cpuinfo').read_text()} ".replace("\n", " ")
    except OSError:  # pragma: no cover
        return False


# llvmpipe fuses its fmuladds only on FMA hardware; the reference always fuses
EXACT = _host_has_fma()
D24_TOLERANCE = 2
CLEAR24 = 16777215


# ---- plans ---------------------------------------------------------------------------------

HEADER = "#version 330 core\n"
UNIFORMS = ("uniform mat4 u_view; uniform mat4 u_proj; uniform mat4 u_inv_view; "
            "uniform mat4 u_inv_proj;\nuniform vec3 u_camera_pos; uniform vec3 u_ambient; "
            "uniform vec2 u_output_size;\nuniform uint u_num_lights; uniform sampler2D u_lights;\n")
VS = HEADER + UNIFORMS + """
layout(location = 0) in vec3 a_position;
void main() { gl_Position = u_proj * (u_view * vec4(a_position, 1.0)); }"""
FS_NONE = HEADER + UNIFORMS + "void main() { }"
CL_NONE = "static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n    return true;\n}\n"


def _fs(value: float) -> str:
    return (HEADER + UNIFORMS + "layout(location = 0) out vec4 o_color;\n"
            f"void main() {{ o_color = vec4({value:.6f}); }}")


def _cl_fs(value: float) -> str:
    return ("static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n"
            f"    out->o_color = (float4)({value:.6f}f);\n    return true;\n}}\n")


def _gl_state(func, write, offset=None, clamp=False):
    face = {"func": "always", "ref": 0, "read_mask": 255, "write_mask": 255,
            "fail": "keep", "zfail": "keep", "zpass": "keep"}
    return {"depth": {"func": func, "write": write, "clamp": clamp},
            "stencil": {"front": dict(face), "back": dict(face)}, "blend": {},
            "blend_constant": [0, 0, 0, 0], "cull": "none", "polygon_offset": offset}


def _gl_target(name, fmt, samples=1):
    depth = fmt in ("d24s8", "d32f")
    return {"name": name, "format": fmt, "scale": 1.0, "width": 0, "height": 0,
            "samples": samples, "clear_color": None if depth else [0, 0, 0, 0],
            "clear_depth": 1.0 if depth else None,
            "clear_stencil": 0 if fmt == "d24s8" else None}


def _gl_pass(name, fragment, writes, state):
    return {"name": name, "draw": {"kind": "scene", "material": [], "volume": None,
                                   "light_types": [], "light_set": None, "scissor": False},
            "repeat_group": None, "clears": [], "writes": list(writes), "reads": [],
            "depth_target": "ds", "state": state, "vertex": VS, "fragment": fragment,
            "sampled": []}


def _gl_plan(targets, passes):
    return {"technique": "test", "title": "test", "backend": "gl", "params": {},
            "lights": {"capacity": 8, "fields": [["color", "vec4"]]},
            "output": targets[0]["name"], "targets": targets, "passes": passes,
            "light_sets": {}}


_PIPES: dict = {}


def depth_pipes(fmt="d24s8", offset=None, clamp=False, samples=1):
    """(GL, CL) pipelines of one pass writing depth with ``always``."""
    key = ("depth", fmt, str(offset), clamp, samples)
    if key not in _PIPES:
        gl = _gl_plan([_gl_target("ds", fmt, samples)],
                      [_gl_pass("p", FS_NONE, (), _gl_state("always", True, offset, clamp))])
        cl = make_plan([target("ds", fmt, clear_depth=1.0,
                               clear_stencil=0 if fmt == "d24s8" else None, samples=samples)],
                       [make_pass(writes=(), depth_target="ds", fragment=CL_NONE, inputs=(),
                                  state={"depth": {"func": "always", "write": True,
                                                   "clamp": clamp},
                                         "polygon_offset": offset})])
        _PIPES[key] = (GLPipeline(gl), CLPipeline(cl))
    return _PIPES[key]


def render_depth(tris, W, H, proj=None, **kw):
    """Depth of ``tris`` (clip-space positions with w = 1 unless ``proj``) on both backends:
    d24 codes, or d32f bit patterns, as int64 arrays (GL, CL)."""
    gl, cl = depth_pipes(**kw)
    scene = TriScene(W, H, tris, proj=proj)
    g, c = gl.render(scene)["ds"], cl.render(scene)["ds"]
    if g.dtype == np.float32:
        return g.view(np.int32).astype(np.int64), c.view(np.int32).astype(np.int64)
    return g.astype(np.int64), c.astype(np.int64)


def thin_triangles(rng, n, W, H, kind):
    """Window-space thin (sub-pixel wide, long), grazing (steep depth) or generic triangles
    with random depths, as clip-space vertex lists (w = 1)."""
    out = []
    for _ in range(n):
        c = rng.uniform([0, 0], [W, H])
        if kind == "thin":
            d = rng.normal(size=2)
            d /= np.linalg.norm(d)
            length = rng.uniform(5, 3 * max(W, H))
            normal = np.array([-d[1], d[0]])
            apex = c + normal * rng.uniform(0.05, 2.0) + d * rng.uniform(-length, length) / 2
            v = np.array([c - d * length / 2, c + d * length / 2, apex])
            z = rng.uniform(-1, 1, 3)
        elif kind == "grazing":
            v = c + rng.normal(size=(3, 2)) * rng.uniform(2, 40)
            z = np.clip(rng.uniform(-1, 1) + rng.uniform(-1, 1, 3) * 0.9, -0.999, 0.999)
        else:
            v = c + rng.normal(size=(3, 2)) * rng.uniform(2, 40)
            z = rng.uniform(-1, 1, 3)
        out += np.stack([2 * v[:, 0] / W - 1, 2 * v[:, 1] / H - 1, z], axis=1).tolist()
    return out


def perspective(fovy_deg, aspect, near, far):
    t = 1.0 / np.tan(np.radians(fovy_deg) / 2)
    return np.array([[t / aspect, 0, 0, 0], [0, t, 0, 0],
                     [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
                     [0, 0, -1, 0]])


def assert_depth_agrees(g, c, clear=CLEAR24):
    """Same coverage, and codes equal (FMA hosts) or within the d24 tolerance."""
    np.testing.assert_array_equal(g != clear, c != clear)
    diff = int(np.abs(g - c).max()) if g.size else 0
    assert diff <= (0 if EXACT else D24_TOLERANCE), f"max depth difference {diff}"
    return diff


# ---- host-side arithmetic (no GL) ----------------------------------------------------------


def _round_f32(x: Fraction) -> np.float32:
    """Round an exact rational to the nearest float32 (ties to even)."""
    f = np.float32(float(x))
    cands = [f, np.nextafter(f, np.float32(np.inf)), np.nextafter(f, np.float32(-np.inf))]
    return min(cands, key=lambda v: (abs(Fraction(float(v)) - x),
                                     int(np.float32(v).view(np.uint32)) & 1))


def test_fma32_is_correctly_rounded():
    rng = np.random.default_rng(1)
    a = (rng.normal(size=3000) * 10.0 ** rng.integers(-3, 4, 3000)).astype(np.float32)
    b = (rng.normal(size=3000) * 10.0 ** rng.integers(-3, 4, 3000)).astype(np.float32)
    c = (-(a.astype(np.float64) * b)).astype(np.float32)          # heavy cancellation
    c[::2] = (rng.normal(size=1500) * 100).astype(np.float32)
    # (1 + 2^-12)^2 lies halfway between two float32: a c too small for float64 to keep
    # decides the rounding, which double rounding through float64 gets wrong
    a[:100], b[:100] = np.float32(1 + 2 ** -12), np.float32(1 + 2 ** -12)
    c[:100] = np.float32(2 ** -70) * np.arange(-50, 50, dtype=np.float32)
    got = CS.fma32(a, b, c)
    want = [_round_f32(Fraction(float(x)) * Fraction(float(y)) + Fraction(float(z)))
            for x, y, z in zip(a, b, c)]
    np.testing.assert_array_equal(got.view(np.uint32), np.array(want, np.float32).view(np.uint32))


def test_depth_plane_is_llvmpipes_float_plane():
    """The rule, written out for one counter-clockwise triangle (vertices v1, v0, v2 in
    llvmpipe's order), and the origin error it carries: far from the window origin a steep
    plane's a0 is huge and its float32 rounding shows as whole d24 codes."""
    f32 = np.float32
    xw = np.array([[300.25, 310.7, 302.1]], f32)
    yw = np.array([[200.5, 201.25, 240.8]], f32)
    zw = np.array([[0.31, 0.92, 0.55]], f32)
    area = np.array([1])                                          # counter-clockwise: swapped
    pz, off = CS.depth_plane(xw, yw, zw, area)
    x, y, z = xw[0, [1, 0, 2]], yw[0, [1, 0, 2]], zw[0, [1, 0, 2]]
    ooa = f32(1) / ((x[0] - x[1]) * (y[2] - y[0]) - (y[0] - y[1]) * (x[2] - x[0]))
    dadx = (z[0] - z[1]) * ((y[2] - y[0]) * ooa) - (z[2] - z[0]) * ((y[0] - y[1]) * ooa)
    dady = (z[2] - z[0]) * ((x[0] - x[1]) * ooa) - (z[0] - z[1]) * ((x[2] - x[0]) * ooa)
    a0 = z[0] - (dadx * (x[0] - f32(0.5)) + dady * (y[0] - f32(0.5)))
    np.testing.assert_array_equal(pz[0], np.array([a0, dadx, dady], f32))
    assert off[0] == 0
    assert abs(a0) > 5                      # the value at the window origin, far off [0, 1]
    # evaluated at the pixels the triangle covers, the float plane strays from the exact one
    P = np.stack([xw[0], yw[0], np.ones(3)], 1).astype(np.float64)
    exact = np.linalg.solve(P, zw[0].astype(np.float64))
    px, py = np.meshgrid(np.arange(300, 312), np.arange(200, 241))
    full = lambda v: np.full(px.shape, v, f32)  # noqa: E731
    zf = CS.fma32(full(dady), py.astype(f32), CS.fma32(full(dadx), px.astype(f32), full(a0)))
    ze = exact[0] * (px + 0.5) + exact[1] * (py + 0.5) + exact[2]
    assert np.abs(np.rint(zf.astype(np.float64) * 16777215) - np.rint(ze * 16777215)).max() >= 3


def test_clipping_follows_draw_pipe_clip():
    """A triangle crossing x = w and y = -w: one polygon, clipped plane by plane in draw's
    order, emitted as the fan (p[i-1], p[i], p0); new vertices are appended after the
    shader's and get the separately rounded viewport transform."""
    v = np.array([[0.968, 0.8807, 0.0, 1.0], [0.705, -1.0734, 0.0, 1.0],
                  [1.1439, 0.2751, 0.0, 1.0]], np.float32)
    clip, _, tri, parent = CS.clip_triangles(v, None)
    assert len(clip) == 3 + 4 and (parent == 0).all()
    np.testing.assert_array_equal(tri, [[3, 4, 0], [4, 5, 0], [5, 6, 0]])
    new = clip[3:]
    assert (new[:, 0] <= new[:, 3]).all() and (new[:, 1] >= -new[:, 3]).all()
    for want in ([1.0, -0.1671], [1.0, 0.7705], [0.7149, -1.0], [0.7289, -1.0]):
        assert np.isclose(new[:, :2], want, atol=2e-4).all(axis=1).any()
    win = CS.window_coords(clip, 24, 24, 3)
    np.testing.assert_array_equal(win[3:, 1], (new[:, 0] * (np.float32(1) / new[:, 3]))
                                  * np.float32(12) + np.float32(12))
    np.testing.assert_array_equal(win[:3, 1], CS.fma32(v[:, 0], np.float32(12), np.float32(12)))
    # the sliver along the right edge covers samples but no pixel centre: kept for MSAA
    tris = CS.setup_triangles(v, 24, 24)
    assert tris.count == 3
    assert CS.setup_triangles(v, 24, 24, samples=1).count == 2


# ---- against llvmpipe --------------------------------------------------------------------------


@needs_gl
@pytest.mark.parametrize("kind", ["thin", "grazing", "generic"])
def test_thin_and_grazing_triangles_match_llvmpipe(kind):
    """Random triangles, many crossing the viewport (clipped): same coverage, same codes."""
    W, H = 96, 64
    rng = np.random.default_rng({"thin": 11, "grazing": 12, "generic": 13}[kind])
    worst = 0
    for _ in range(6):          # 12 overlapping triangles per frame, the last one drawn wins
        g, c = render_depth(thin_triangles(rng, 12, W, H, kind), W, H)
        assert (g != CLEAR24).sum() > 20
        worst = max(worst, assert_depth_agrees(g, c))
    assert worst == 0 or not EXACT


@needs_gl
def test_perspective_near_far_and_grazing_floor_match_llvmpipe():
    """Perspective triangles crossing the near and far planes, and long floor-like triangles
    seen at grazing angles (clipped against the viewport sides)."""
    W, H = 96, 64
    proj = perspective(50, W / H, 0.5, 20)
    rng = np.random.default_rng(3)
    for kind in range(3):
        tris = []
        for _ in range(8):
            if kind == 0:      # through the near plane
                c = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-3, -0.6)])
                tris += (c + rng.normal(size=(3, 3)) * [2, 2, 1.5]).tolist()
            elif kind == 1:    # floor, nearly edge-on
                y = rng.uniform(-2, -0.5)
                tris += np.stack([rng.uniform(-30, 30, 3), y + rng.normal(size=3) * 0.01,
                                  rng.uniform(-25, 2, 3)], 1).tolist()
            else:              # through the far plane
                tris += (np.array([0, 0, -19.0]) + rng.normal(size=(3, 3)) * 3).tolist()
        g, c = render_depth(tris, W, H, proj=proj)
        assert (g != CLEAR24).sum() > 50
        assert_depth_agrees(g, c)


@needs_gl
@pytest.mark.parametrize("fmt, offset, clamp", [
    ("d24s8", [1.5, 2.0], False), ("d24s8", [-1.0, -1.0], False), ("d24s8", [0.0, 0.3], False),
    ("d32f", None, False), ("d32f", [1.5, 2.0], False), ("d24s8", None, True),
    ("d32f", None, True)])
def test_polygon_offset_float_depth_and_clamp_match_llvmpipe(fmt, offset, clamp):
    """Polygon offset (lp_do_offset_tri: factor * max |dz/dx|, |dz/dy| from the same float
    setup, plus units * 2/(2^24-1) for d24 or units * 2^(e-23) for d32f, added after the
    plane), d32f (compared as bit patterns) and depth clamp (z beyond the near/far planes)."""
    W, H = 64, 48
    rng = np.random.default_rng(21)
    proj = perspective(50, W / H, 0.5, 20)
    clear = CLEAR24 if fmt == "d24s8" else int(np.float32(1.0).view(np.int32))
    for k in range(4):
        if k % 2:
            tris = (np.array([0, 0, -5.0]) + rng.normal(size=(24, 3)) * 2).tolist()
            g, c = render_depth(tris, W, H, proj=proj, fmt=fmt, offset=offset, clamp=clamp)
        else:
            tris = np.array(thin_triangles(rng, 8, W, H, ["thin", "grazing"][k // 2]))
            if clamp:
                tris[:, 2] *= 2.0                   # beyond near and far: clamped, not clipped
            g, c = render_depth(tris.tolist(), W, H, fmt=fmt, offset=offset, clamp=clamp)
        assert_depth_agrees(g, c, clear)


@needs_gl
def test_msaa_sample_depth_matches_llvmpipe_through_its_resolve():
    """4x MSAA: per sample llvmpipe evaluates the plane with a0 for pixel centre 0 at (x + sx,
    y + sy); its depth resolve blit passes sample 0 through a float round trip (code *
    (1/(2^24-1)) then * (2^24-1), rounded), which moves a third of the codes by one; the
    reference's resolve (``cl_pipeline.d24_resolve``) does the same."""
    W, H = 64, 48
    rng = np.random.default_rng(5)
    for k in range(3):
        g, c = render_depth(thin_triangles(rng, 10, W, H, ["thin", "grazing", "generic"][k]),
                            W, H, samples=4)
        assert_depth_agrees(g, c)


def test_d24_resolve_round_trip():
    """The d24 resolve round trip is the identity on codes that survive float32 exactly and
    moves the others by at most one code."""
    from pipegen.runtime.cl.pipeline import d24_resolve
    codes = np.arange(0, 1 << 24, 97, dtype=np.uint32)
    out = d24_resolve(codes).astype(np.int64)
    assert np.abs(out - codes).max() == 1
    assert 0.2 < np.mean(out != codes) < 0.5
    assert d24_resolve(np.array([0, 16777215], np.uint32)).tolist() == [0, 16777215]


@needs_gl
def test_depth_equal_after_prepass_and_less_on_redraw():
    """A depth prepass (less, write) then the same geometry with ``equal`` (colour A) and again
    with ``less`` (colour B): equal passes on every visible pixel, less nowhere -- on both
    backends, for thin, grazing and clipped triangles (what lidr and forward rely on)."""
    W, H = 96, 64
    a, b = 0.25, 0.75
    gl = GLPipeline(_gl_plan(
        [_gl_target("color", "rgba8"), _gl_target("ds", "d24s8")],
        [_gl_pass("pre", FS_NONE, (), _gl_state("less", True)),
         _gl_pass("eq", _fs(a), ("color",), _gl_state("equal", False)),
         _gl_pass("lt", _fs(b), ("color",), _gl_state("less", False))]))
    cl = CLPipeline(make_plan(
        [target("color", "rgba8", clear_color=[0, 0, 0, 0]),
         target("ds", "d24s8", clear_depth=1.0, clear_stencil=0)],
        [make_pass("pre", writes=(), depth_target="ds", fragment=CL_NONE, inputs=(),
                   state={"depth": {"func": "less", "write": True, "clamp": False}}),
         make_pass("eq", depth_target="ds", fragment=_cl_fs(a), inputs=(),
                   state={"depth": {"func": "equal", "write": False, "clamp": False}}),
         make_pass("lt", depth_target="ds", fragment=_cl_fs(b), inputs=(),
                   state={"depth": {"func": "less", "write": False, "clamp": False}})]))
    rng = np.random.default_rng(8)
    proj = perspective(50, W / H, 0.5, 20)
    try:
        for k in range(4):
            if k < 3:
                tris, p = thin_triangles(rng, 16, W, H, ["thin", "grazing", "generic"][k]), None
            else:
                tris = (np.array([0, -1.0, -6.0]) + rng.normal(size=(30, 3)) * [6, 1, 5]).tolist()
                p = proj
            scene = TriScene(W, H, tris, proj=p)
            go, co = gl.render(scene), cl.render(scene)
            visible = go["ds"] != CLEAR24
            assert visible.sum() > 50
            np.testing.assert_array_equal(go["ds"], co["ds"])
            np.testing.assert_array_equal(go["color"], co["color"])
            assert (go["color"][visible, 0] == 64).all()          # equal passed everywhere
            assert (go["color"][~visible] == 0).all()
    finally:
        gl.release()
