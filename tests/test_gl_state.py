"""GL fixed-function state vs the numpy oracle (moderngl's tests/test_blend.py, generalised).

Every test renders a tiny target (16x16) through ``pipegen.runtime.gl.state`` and compares
the codes with ``pipegen.reference.fixed_function``: colours within ``Format.tolerance`` (one
blended pass), stencil exactly, depth exactly (the oracle models llvmpipe's d24 conversion).
Per-pixel random sources come from a float texture read with ``texelFetch`` by a full-screen
triangle, so one draw checks 256 (src, dst) pairs; depth and stencil are preset with random
codes through ``gl_formats.write_texture``.  Face tests draw counter-clockwise (front) and
clockwise (back) quads in one draw call.

Besides the spec oracle, ``blend_unorm8`` (llvmpipe's 8-bit fixed-point arithmetic) is checked
bit-exact on llvmpipe: it documents what the driver does.
"""

from __future__ import annotations

import itertools
import zlib

import numpy as np
import pytest

from pipegen.core import formats as F
from pipegen.backends.plan import state_from_dict
from pipegen.reference import fixed_function as FF

try:
    import moderngl
    from pipegen.runtime.gl.context import GL, get_context
    from pipegen.runtime.gl import formats as GF
    from pipegen.runtime.gl import state as GS
    _CTX = get_context()
    _ERR = None
except Exception as e:  # pragma: no cover - machines without EGL
    _CTX, _ERR = None, e

pytestmark = [pytest.mark.gl, pytest.mark.skipif(_CTX is None, reason=f"no EGL/GL context: {_ERR}")]

W = H = 16
LLVMPIPE = _CTX is not None and "llvmpipe" in _CTX.info["GL_RENDERER"]

FACTORS = ["zero", "one", "src_color", "one_minus_src_color", "dst_color", "one_minus_dst_color",
           "src_alpha", "one_minus_src_alpha", "dst_alpha", "one_minus_dst_alpha",
           "constant_color", "one_minus_constant_color", "constant_alpha",
           "one_minus_constant_alpha", "src_alpha_saturate"]
OPS = ["add", "sub", "revsub", "min", "max"]
FUNCS = ["never", "less", "equal", "lequal", "greater", "notequal", "gequal", "always"]
SOPS = ["keep", "zero", "replace", "incr", "decr", "incr_wrap", "decr_wrap", "invert"]

_VS_FULL = """#version 330 core
void main() {
    vec2 p = vec2(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID >> 1) * 4 - 1));
    gl_Position = vec4(p, 0.0, 1.0);
}"""
_FS_FULL = """#version 330 core
uniform sampler2D u_src;
uniform sampler2D u_z;
uniform bool u_write_z;
uniform bool u_discard;
layout(location = 0) out {T} o_c;
void main() {
    vec4 s = texelFetch(u_src, ivec2(gl_FragCoord.xy), 0);
    if (u_discard && s.x < -1e29) discard;
    o_c = {T}(s);
    if (u_write_z) gl_FragDepth = texelFetch(u_z, ivec2(gl_FragCoord.xy), 0).r;
}"""
_VS_QUAD = """#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_col;
out vec4 v_col;
void main() { v_col = a_col; gl_Position = vec4(a_pos, 1.0); }"""
_FS_QUAD = """#version 330 core
in vec4 v_col;
layout(location = 0) out {T} o_c;
void main() { o_c = {T}(v_col); }"""


class Rig:
    """A W x H framebuffer: colour target ``c`` (optional) + depth(/stencil) target ``ds``."""

    _programs: dict = {}

    def __init__(self, color: str | None = "rgba8", depth: str | None = None):
        self.ctx = _CTX
        self.color, self.depth = color, depth
        self.formats = {}
        self.tex = {}
        if color:
            self.tex["c"] = GF.create_texture(color, W, H)
            self.formats["c"] = color
        if depth:
            self.tex["ds"] = GF.create_texture(depth, W, H)
            self.formats["ds"] = depth
        ids = np.zeros(1, np.uint32)
        GL.glCreateFramebuffers(1, ids)
        self.fbo = int(ids[0])
        if color:
            GL.glNamedFramebufferTexture(self.fbo, GL.GL_COLOR_ATTACHMENT0, self.tex["c"], 0)
            GL.glNamedFramebufferDrawBuffers(self.fbo, 1, [GL.GL_COLOR_ATTACHMENT0])
        else:
            GL.glNamedFramebufferDrawBuffers(self.fbo, 1, [GL.GL_NONE])
        if depth:
            GL.glNamedFramebufferTexture(self.fbo, GF.gl_format(depth).attachment,
                                         self.tex["ds"], 0)
        self.status = GL.glCheckNamedFramebufferStatus(self.fbo, GL.GL_FRAMEBUFFER)
        self.src = GF.create_texture("rgba32f", W, H)
        self.ztex = GF.create_texture("r32f", W, H)
        uint = color is not None and F.get(color).is_integer
        t = "uvec4" if uint else "vec4"
        key = t
        if key not in Rig._programs:
            full = self.ctx.program(vertex_shader=_VS_FULL,
                                    fragment_shader=_FS_FULL.replace("{T}", t))
            quad = self.ctx.program(vertex_shader=_VS_QUAD,
                                    fragment_shader=_FS_QUAD.replace("{T}", t))
            Rig._programs[key] = (full, self.ctx.vertex_array(full, []), quad)
        self.full, self.full_vao, self.quad = Rig._programs[key]

    def release(self):
        for t in list(self.tex.values()) + [self.src, self.ztex]:
            GF.delete_texture(t)
        GL.glDeleteFramebuffers(1, np.array([self.fbo], np.uint32))

    # -- presets ---------------------------------------------------------------------------
    def preset(self, color=None, depth=None, stencil=None):
        if color is not None:
            GF.write_texture(self.tex["c"], self.color, color)
        if depth is not None or stencil is not None:
            if self.depth == "d24s8":
                d = np.zeros((H, W), np.uint32) if depth is None else depth
                GF.write_texture(self.tex["ds"], "d24s8", d, stencil)
            else:
                GF.write_texture(self.tex["ds"], self.depth, depth)

    def buffers(self):
        out = {}
        if self.color:
            out["c"] = GF.read_texture(self.tex["c"], self.color, W, H)
        if self.depth == "d24s8":
            out["ds"], out["ds.stencil"] = GF.split_depth_stencil(
                GF.read_texture(self.tex["ds"], "d24s8", W, H))
        elif self.depth:
            out["ds"] = GF.read_texture(self.tex["ds"], self.depth, W, H)
        return out

    # -- draws -----------------------------------------------------------------------------
    def _bind(self, state):
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.fbo)
        GL.glViewport(0, 0, W, H)
        writes = ["c"] if self.color else []
        GS.apply_state(state_from_dict(state, writes), writes,
                       depth_format=F.get(self.depth) if self.depth else None)

    def fullscreen(self, state, src, z=None, discard=False):
        """Every pixel gets ``src[y, x]`` (and ``gl_FragDepth = z[y, x]`` when given); with
        ``discard``, pixels whose source x is ``DISCARD`` get no fragment."""
        GF.write_texture(self.src, "rgba32f", np.asarray(src, np.float32))
        if z is not None:
            GF.write_texture(self.ztex, "r32f", np.asarray(z, np.float32))
        GL.glBindTextureUnit(0, self.src)
        GL.glBindTextureUnit(1, self.ztex)
        self.full["u_src"].value = 0
        self.full["u_z"].value = 1
        self.full["u_write_z"].value = z is not None
        self.full["u_discard"].value = bool(discard)
        self._bind(state)
        self.full_vao.render(moderngl.TRIANGLES, vertices=3)

    def quads(self, state, quads):
        """``quads``: (x0, y0, x1, y1, z_window, rgba, front) in pixels; one draw, in order."""
        verts = []
        for x0, y0, x1, y1, z, col, front in quads:
            nx0, nx1 = 2 * x0 / W - 1, 2 * x1 / W - 1
            ny0, ny1 = 2 * y0 / H - 1, 2 * y1 / H - 1
            zn = 2 * z - 1
            a, b, c, d = ([nx0, ny0, zn, *col], [nx1, ny0, zn, *col], [nx1, ny1, zn, *col],
                          [nx0, ny1, zn, *col])
            verts += [a, b, c, a, c, d] if front else [a, c, b, a, d, c]
        vbo = self.ctx.buffer(np.asarray(verts, np.float32).tobytes())
        vao = self.ctx.vertex_array(self.quad, [(vbo, "3f 4f", "a_pos", "a_col")])
        self._bind(state)
        vao.render(moderngl.TRIANGLES)
        vao.release()
        vbo.release()


def quad_coverage(x0, y0, x1, y1):
    ys, xs = np.mgrid[0:H, 0:W] + 0.5
    return (xs > x0) & (xs < x1) & (ys > y0) & (ys < y1)


def oracle_quads(buffers, state, quads, formats, depth_target):
    out = dict(buffers)
    for x0, y0, x1, y1, z, col, front in quads:
        z32 = np.float32(np.float32(2 * z - 1) * np.float32(0.5) + np.float32(0.5))
        out = FF.process_fragments(
            out, state, ["c"] if "c" in formats else [], formats,
            coverage=quad_coverage(x0, y0, x1, y1),
            outputs={"c": np.broadcast_to(np.asarray(col, np.float64), (H, W, 4))},
            depth=z32, front_facing=front, depth_target=depth_target)
    return out


def assert_codes(fmt, got, exp, passes=1, what=""):
    f = F.get(fmt)
    tol = f.tolerance(passes)
    if tol.units == "ulp":
        from pipegen.proof.compare import ulp_distance
        err = ulp_distance(np.asarray(got), np.asarray(exp).astype(got.dtype), tol.abs_floor)
    else:
        err = np.abs(np.asarray(got).astype(np.int64) - np.asarray(exp).astype(np.int64))
    limit = 0 if tol.units == "exact" else tol.limit
    assert err.max() <= limit, (f"{what} {fmt}: max error {err.max()} > {limit} {tol.units} "
                                f"at {np.argwhere(err > limit)[:4].tolist()}")
    return float(err.max())


@pytest.fixture(scope="module")
def rigs():
    made = {}

    def get(color="rgba8", depth=None):
        if (color, depth) not in made:
            made[(color, depth)] = Rig(color, depth)
        return made[(color, depth)]
    yield get
    for r in made.values():
        r.release()


def _rng(*key):
    """A generator seeded by ``key`` (stable across runs, unlike ``hash``)."""
    return np.random.default_rng(zlib.crc32(repr(key).encode()))


def _values(fmt, rng, shape=(H, W, 4)):
    """Random shader outputs for ``fmt`` with the hard cases mixed in (0, 1, unorm ties)."""
    f = F.get(fmt)
    if f.kind is F.Kind.FLOAT:
        v = rng.uniform(-0.5, 2.0, shape)
    else:
        v = rng.uniform(0.0, 1.0, shape)
        v[0, :4] = [0.0, 1.0, 0.5, 127.5 / 255]
        v[1, :4] = [(k + 0.5) / 255 for k in (0, 1, 2, 3)]
    return v


def _dst(fmt, rng):
    return FF.store(fmt, _values(fmt, rng))


# ---------------------------------------------------------------------------------------------
# blending
# ---------------------------------------------------------------------------------------------

BLEND_FORMATS = ["rgba8", "rgba16f", "rgba32f"]


def f_is_float(fmt):
    return F.get(fmt).kind is F.Kind.FLOAT


def _blend_case(rigs, fmt, eq_rgb, eq_alpha, constant, seed):
    rng = _rng(fmt, tuple(eq_rgb), tuple(eq_alpha), seed)
    rig = rigs(fmt)
    src = _values(fmt, rng)
    dst = _dst(fmt, rng)
    rig.preset(color=dst)
    state = {"blend": {"c": {"enabled": True, "rgb": list(eq_rgb), "alpha": list(eq_alpha)}},
             "blend_constant": list(constant)}
    rig.fullscreen(state, src)
    got = rig.buffers()["c"]
    exp = FF.write_color(src, dst, fmt, state["blend"]["c"], constant)
    err = assert_codes(fmt, got, exp, 1, f"{eq_rgb}/{eq_alpha}")
    if fmt == "rgba8" and LLVMPIPE:
        exact = FF.blend_unorm8(src, dst, eq_rgb, eq_alpha, constant)
        assert np.array_equal(got, exact), "llvmpipe's 8-bit blend model no longer bit-exact"
    if f_is_float(fmt) and LLVMPIPE:
        exact = FF.write_color(src, dst, fmt, state["blend"]["c"], constant, precision=np.float32)
        assert np.array_equal(got, exact, equal_nan=True), "float32 blend model not bit-exact"
    return err


@pytest.mark.parametrize("fmt", BLEND_FORMATS)
@pytest.mark.parametrize("factor", FACTORS)
def test_blend_src_factor(rigs, fmt, factor):
    const = [0.3, 0.6, 0.9, 0.45] if fmt == "rgba8" else [1.5, -0.25, 0.6, 0.3]
    _blend_case(rigs, fmt, ["add", factor, "zero"], ["add", factor, "zero"], const, 0)


@pytest.mark.parametrize("fmt", BLEND_FORMATS)
@pytest.mark.parametrize("factor", FACTORS)
def test_blend_dst_factor(rigs, fmt, factor):
    const = [0.8, 0.1, 0.25, 0.7] if fmt == "rgba8" else [0.8, 2.0, -0.5, 0.7]
    _blend_case(rigs, fmt, ["add", "one", factor], ["add", "zero", factor], const, 1)


@pytest.mark.parametrize("fmt", BLEND_FORMATS)
@pytest.mark.parametrize("op", OPS)
def test_blend_equation(rigs, fmt, op):
    # the same op with factor pairs that exercise both operands
    for k, (fs, fd) in enumerate([("src_alpha", "one_minus_src_alpha"), ("one", "one"),
                                  ("dst_color", "constant_alpha")]):
        _blend_case(rigs, fmt, [op, fs, fd], [op, fd, fs], [0.5, 0.25, 0.75, 0.4], k)


@pytest.mark.parametrize("fmt", ["rgba8", "rgba16f"])
def test_blend_separate_rgb_alpha(rigs, fmt):
    rng = np.random.default_rng(7)
    for _ in range(6):
        rgb = [str(rng.choice(OPS[:3])), str(rng.choice(FACTORS)), str(rng.choice(FACTORS))]
        alpha = [str(rng.choice(OPS)), str(rng.choice(FACTORS)), str(rng.choice(FACTORS))]
        _blend_case(rigs, fmt, rgb, alpha, list(rng.uniform(0, 1, 4)), 3)


@pytest.mark.parametrize("fmt", ["r8", "rg8", "rgba16", "rgb10a2", "r16f", "rg32f"])
def test_blend_other_formats(rigs, fmt):
    """Formats without alpha read destination alpha as 1; 16-/10-bit unorm blend in float."""
    for k, eq in enumerate([("add", "src_alpha", "one_minus_src_alpha"),
                            ("add", "dst_alpha", "one_minus_dst_alpha"),
                            ("revsub", "one", "constant_color"), ("max", "one", "one")]):
        rng = _rng(fmt, eq, k)
        rig = rigs(fmt)
        src = _values(fmt, rng)
        dst = _dst(fmt, rng)
        rig.preset(color=dst)
        b = {"enabled": True, "rgb": list(eq), "alpha": list(eq)}
        rig.fullscreen({"blend": {"c": b}, "blend_constant": [0.2, 0.4, 0.6, 0.8]}, src)
        exp = FF.write_color(src, dst, fmt, b, [0.2, 0.4, 0.6, 0.8])
        # rgb10a2: llvmpipe's float -> 10-bit conversion is off by one code for ~25 % of
        # values even without blending (measured): one more code than the blend alone.
        assert_codes(fmt, rig.buffers()["c"], exp, 2 if fmt == "rgb10a2" else 1, str(eq))


def test_blend_unclamped_float_vs_clamped_unorm(rigs):
    """Fixed-point targets clamp the constant and factors; float targets do not."""
    src = np.full((H, W, 4), 0.5)
    const = [2.0, -1.0, 0.5, 1.0]
    b = {"enabled": True, "rgb": ["add", "constant_color", "zero"],
         "alpha": ["add", "one", "zero"]}
    got = {}
    for fmt in ("rgba8", "rgba32f"):
        rig = rigs(fmt)
        rig.preset(color=FF.store(fmt, np.zeros((H, W, 4))))
        rig.fullscreen({"blend": {"c": b}, "blend_constant": const}, src)
        got[fmt] = rig.buffers()["c"][0, 0]
    assert got["rgba8"].tolist() == [128, 0, 64, 128]
    assert got["rgba32f"].tolist() == [1.0, -0.5, 0.25, 0.5]


def test_src_alpha_saturate(rigs):
    """f = min(As, 1 - Ad) for RGB, 1 for alpha: checked on hand-picked pairs, rgba8."""
    rig = rigs("rgba8")
    src = np.zeros((H, W, 4))
    dst = np.zeros((H, W, 4), np.uint8)
    src[..., :3] = 1.0
    src[..., 3] = np.linspace(0, 1, W)[None, :]
    dst[..., 3] = np.round(np.linspace(0, 255, H))[:, None]
    rig.preset(color=dst)
    b = {"enabled": True, "rgb": ["add", "src_alpha_saturate", "zero"],
         "alpha": ["add", "src_alpha_saturate", "zero"]}
    rig.fullscreen({"blend": {"c": b}}, src)
    got = rig.buffers()["c"].astype(int)
    f = np.minimum(FF.unorm_store(src[..., 3], 8), 255 - dst[..., 3].astype(int))
    assert np.abs(got[..., 0] - f).max() == 0
    assert np.array_equal(got[..., 3], FF.unorm_store(src[..., 3], 8))   # alpha factor is 1


def test_blend_constant_precision(rigs):
    """llvmpipe converts the blend constant to 8 bits for rgba8 targets (float32 product,
    round half to even: 0.3 * 255 = 76.5 in float32 -> 76, so 0.3 acts as 76/255 = 0.298) and
    multiplies codes; rgba32f uses the float constant.  Destination codes where
    ``rint(d * 0.3)`` and the 8-bit product disagree show which one the driver does."""
    dst = np.zeros((H, W, 4), np.uint8)
    d = np.arange(H * W).reshape(H, W) % 256
    dst[...] = d[..., None]
    b = {"enabled": True, "rgb": ["add", "zero", "constant_color"],
         "alpha": ["add", "zero", "constant_alpha"]}
    rig = rigs("rgba8")
    rig.preset(color=dst)
    rig.fullscreen({"blend": {"c": b}, "blend_constant": [0.3] * 4}, np.zeros((H, W, 4)))
    got = rig.buffers()["c"][..., 0].astype(int)
    assert FF.unorm_store(0.3, 8) == 76
    assert np.array_equal(got, FF.mul_unorm8(d, 76))
    spec = np.rint(d * 0.3)
    assert (got != spec).sum() > 10 and np.abs(got - spec).max() == 1
    rig = rigs("rgba32f")
    rig.preset(color=np.zeros((H, W, 4), np.float32))
    rig.fullscreen({"blend": {"c": {**b, "rgb": ["add", "constant_color", "zero"]}},
                    "blend_constant": [0.3] * 4}, np.ones((H, W, 4)))
    assert rig.buffers()["c"][0, 0, 0] == np.float32(0.3)


@pytest.mark.parametrize("mask", list(itertools.product([False, True], repeat=4)))
def test_color_mask(rigs, mask):
    rng = _rng("mask", mask)
    for fmt, blended in (("rgba8", False), ("rgba8", True), ("rgba16f", True)):
        rig = rigs(fmt)
        src, dst = _values(fmt, rng), _dst(fmt, rng)
        rig.preset(color=dst)
        b = {"enabled": blended, "rgb": ["add", "one", "one"], "alpha": ["add", "one", "one"],
             "write_mask": list(mask)}
        rig.fullscreen({"blend": {"c": b}}, src)
        got = rig.buffers()["c"]
        exp = FF.write_color(src, dst, fmt, b)
        assert_codes(fmt, got, exp, 1, f"mask {mask}")
        for ch in range(4):
            if not mask[ch]:
                assert np.array_equal(got[..., ch], dst[..., ch])


def test_blend_disabled_store_and_unorm_ties(rigs):
    """No blending: float -> unorm8 rounds half to even, with a float32 product."""
    rig = rigs("rgba8")
    src = np.zeros((H, W, 4))
    k = np.arange(H * W).reshape(H, W) % 255
    src[..., 0] = (k + 0.5) / 255.0
    src[..., 1] = np.linspace(-1, 2, H * W).reshape(H, W)
    src[..., 2] = np.nan
    src[..., 3] = (k + 0.49) / 255.0
    rig.preset(color=np.zeros((H, W, 4), np.uint8))
    rig.fullscreen({}, src)
    got = rig.buffers()["c"]
    assert np.array_equal(got, FF.store("rgba8", src))


@pytest.mark.parametrize("fmt", ["rgba8", "rgba16", "rgba16f", "rgba32f", "rg32f", "r16f"])
def test_store_special_values(rigs, fmt):
    """inf, -inf, NaN, huge and tiny values stored without blending match ``FF.store``
    (unorm: +inf -> max code, -inf and NaN -> 0; half: inf stays inf)."""
    rig = rigs(fmt)
    rng = np.random.default_rng(9)
    src = rng.uniform(-2, 2, (H, W, 4))
    special = np.array([np.inf, -np.inf, np.nan, 1e30, -1e30, 1e-30, 65520.0, -0.0])
    src[:2] = special[rng.integers(0, len(special), (2, W, 4))]
    rig.preset(color=FF.store(fmt, np.zeros((H, W, 4))))
    rig.fullscreen({}, src)
    got = rig.buffers()["c"]
    assert np.array_equal(got, FF.store(fmt, src), equal_nan=True)


def test_rgb10a2_store_is_not_round_to_nearest(rigs):
    """llvmpipe's float -> 10-bit conversion is off by one code for about a quarter of the
    values (2-bit alpha is exact): the tolerance's one code absorbs it."""
    rig = rigs("rgb10a2")
    src = np.random.default_rng(1).uniform(0, 1, (H, W, 4))
    rig.preset(color=np.zeros((H, W, 4), np.uint16))
    rig.fullscreen({}, src)
    got = rig.buffers()["c"].astype(int)
    exp = FF.store("rgb10a2", src).astype(int)
    assert np.abs(got - exp).max() == 1
    assert 0.1 < (got[..., :3] != exp[..., :3]).mean() < 0.4
    assert np.array_equal(got[..., 3], exp[..., 3])


def test_half_store_rounds_toward_zero(rigs):
    """llvmpipe stores rgba16f outputs rounding toward zero; overflow gives 65504, half
    denormals are kept."""
    rig = rigs("rgba16f")
    rng = np.random.default_rng(3)
    src = rng.uniform(-3, 3, (H, W, 4)) * 10.0 ** rng.integers(-6, 5, (H, W, 4))
    src[0, 0] = [70000.0, -70000.0, 65519.0, 65520.0]
    src[0, 1] = [1e-6, -1e-6, 6e-8, 1e-9]
    rig.preset(color=np.zeros((H, W, 4), np.float16))
    rig.fullscreen({}, src)
    got = rig.buffers()["c"]
    assert got[0, 0].tolist() == [65504.0, -65504.0, 65504.0, 65504.0]
    assert got[0, 1, 0] != 0                                          # denormal kept
    assert np.array_equal(got.view(np.uint16), FF.half_store(src).view(np.uint16))
    rne = FF.half_store(src, "rne")
    assert (rne != got).mean() > 0.2          # it really is not round-to-nearest


# ---------------------------------------------------------------------------------------------
# depth
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("dfmt", ["d24s8", "d32f"])
@pytest.mark.parametrize("func", FUNCS)
@pytest.mark.parametrize("write", [False, True])
def test_depth_func(rigs, dfmt, func, write):
    rng = _rng(dfmt, func, write)
    rig = rigs("rgba8", dfmt)
    f = F.get(dfmt)
    stored_z = rng.uniform(0, 1, (H, W)).astype(np.float32)
    stored = FF.depth_codes(dfmt, stored_z)
    z = rng.uniform(0, 1, (H, W)).astype(np.float32)
    # exact ties: fragments at the stored depth (decoded back from the code)
    tie = rng.uniform(size=(H, W)) < 0.3
    decoded = (stored / np.float64(16777215)).astype(np.float32) if dfmt == "d24s8" else stored
    z = np.where(tie, decoded, z)
    z[0, 0], z[0, 1] = 0.0, 1.0
    rig.preset(color=np.zeros((H, W, 4), np.uint8), depth=stored, stencil=None)
    state = {"depth": {"func": func, "write": write}}
    src = rng.uniform(0, 1, (H, W, 4))
    rig.fullscreen(state, src, z=z)
    got = rig.buffers()
    exp = FF.process_fragments({"c": np.zeros((H, W, 4), np.uint8), "ds": stored,
                                "ds.stencil": np.zeros((H, W), np.uint8)},
                               state, ["c"], {"c": "rgba8", "ds": dfmt},
                               coverage=np.ones((H, W), bool), outputs={"c": src}, depth=z,
                               depth_target="ds")
    assert np.array_equal(got["ds"], exp["ds"]), f"depth codes differ ({f.name})"
    assert np.array_equal(got["c"] != 0, exp["c"] != 0) and np.array_equal(got["c"], exp["c"])
    if func not in ("never", "always"):
        passed = FF.depth_test(func, z, stored, dfmt)
        assert 0 < passed.sum() < H * W


def test_depth_d24_quantisation_of_interpolated_z(rigs):
    """Window z is computed in float32 and converted with a float32 product, rounded to
    nearest: ``depth_codes`` reproduces llvmpipe exactly (a float64 product would not)."""
    rig = rigs(None, "d24s8")
    rng = np.random.default_rng(11)
    zs = rng.uniform(0.0, 1.0, W * H // 2)
    quads = []
    for i, z in enumerate(zs):
        x, y = (i % W), (i // W) * 2
        quads.append((x, y, x + 1, y + 2, float(z), (1, 1, 1, 1), True))
    rig.preset(depth=np.full((H, W), 0xFFFFFF, np.uint32))
    rig.quads({"depth": {"func": "always", "write": True}}, quads)
    got = rig.buffers()["ds"]
    exp = oracle_quads({"ds": np.full((H, W), 0xFFFFFF, np.uint32),
                        "ds.stencil": np.zeros((H, W), np.uint8)},
                       {"depth": {"func": "always", "write": True}}, quads, {"ds": "d24s8"}, "ds")
    assert np.array_equal(got, exp["ds"])


def test_depth_clamp(rigs):
    """GL_DEPTH_CLAMP keeps geometry beyond the far plane and stores depth 1.0."""
    rig = rigs("rgba8", "d32f")
    quads = [(0, 0, W, H, 1.25, (1, 0, 0, 1), True)]       # window z 1.25: clipped w/o clamp
    for clamp, expect_red in ((False, 0), (True, 255)):
        rig.preset(color=np.zeros((H, W, 4), np.uint8), depth=np.ones((H, W), np.float32))
        rig.quads({"depth": {"func": "lequal", "write": True, "clamp": clamp}}, quads)
        b = rig.buffers()
        assert (b["c"][..., 0] == expect_red).all()
        assert (b["ds"] == 1.0).all()


def test_polygon_offset(rigs):
    """``offset 0 -4`` pulls a coplanar quad in front (units of the d24 resolution)."""
    rig = rigs("rgba8", "d24s8")
    z = 0.5
    for offset, expect in ((None, 0), ([0.0, -4.0], 255)):
        rig.preset(color=np.zeros((H, W, 4), np.uint8),
                   depth=FF.depth_codes("d24s8", np.full((H, W), z)),
                   stencil=np.zeros((H, W), np.uint8))
        rig.quads({"depth": {"func": "less", "write": False}, "polygon_offset": offset},
                  [(0, 0, W, H, z, (1, 1, 1, 1), True)])
        assert (rig.buffers()["c"][..., 0] == expect).all()


# ---------------------------------------------------------------------------------------------
# stencil
# ---------------------------------------------------------------------------------------------


def _stencil_case(rigs, front, back, seed, depth_func="less"):
    rng = np.random.default_rng(seed)
    rig = rigs("rgba8", "d24s8")
    stencil = rng.integers(0, 256, (H, W)).astype(np.uint8)
    stencil[:, ::3] = rng.integers(0, 4, (H, (W + 2) // 3))      # many near 0 (decr, wrap)
    stencil[::5, :] = rng.integers(252, 256, ((H + 4) // 5, W))   # and near 255 (incr)
    depth = FF.depth_codes("d24s8", rng.uniform(0, 1, (H, W)))
    z = 0.5
    rig.preset(color=np.zeros((H, W, 4), np.uint8), depth=depth, stencil=stencil)
    state = {"depth": {"func": depth_func, "write": True},
             "stencil": {"front": front, "back": back}}
    quads = [(0, 0, W // 2, H, z, (1.0, 0.5, 0.25, 1.0), True),       # front-facing half
             (W // 2, 0, W, H, z, (0.25, 0.5, 1.0, 1.0), False)]      # back-facing half
    rig.quads(state, quads)
    got = rig.buffers()
    exp = oracle_quads({"c": np.zeros((H, W, 4), np.uint8), "ds": depth, "ds.stencil": stencil},
                       state, quads, {"c": "rgba8", "ds": "d24s8"}, "ds")
    assert np.array_equal(got["ds.stencil"], exp["ds.stencil"]), "stencil differs"
    assert np.array_equal(got["ds"], exp["ds"]), "depth differs"
    assert np.array_equal(got["c"], exp["c"]), "colour differs"
    return got, stencil


@pytest.mark.parametrize("func", FUNCS)
def test_stencil_func(rigs, func):
    rng = np.random.default_rng(FUNCS.index(func))
    for k in range(3):
        ref, rmask = int(rng.integers(0, 256)), [255, 0x0F, int(rng.integers(0, 256))][k]
        front = {"func": func, "ref": ref, "read_mask": rmask, "write_mask": 255,
                 "fail": "zero", "zfail": "invert", "zpass": "incr"}
        back = {"func": FUNCS[(FUNCS.index(func) + 3) % 8], "ref": 255 - ref,
                "read_mask": rmask ^ 0xFF, "write_mask": 255,
                "fail": "incr_wrap", "zfail": "replace", "zpass": "decr"}
        _stencil_case(rigs, front, back, 100 + k)


@pytest.mark.parametrize("op", SOPS)
def test_stencil_op(rigs, op):
    """Each op in each slot (fail / zfail / zpass), per face, with write masks."""
    i = SOPS.index(op)
    for slot in ("fail", "zfail", "zpass"):
        ops = {"fail": SOPS[(i + 3) % 8], "zfail": SOPS[(i + 5) % 8], "zpass": SOPS[(i + 6) % 8]}
        ops[slot] = op
        front = {"func": "less", "ref": 128, "read_mask": 255, "write_mask": 255, **ops}
        back = {"func": "gequal", "ref": 7, "read_mask": 0xF7, "write_mask": 0x3C,
                **{s: SOPS[(SOPS.index(o) + 1) % 8] for s, o in ops.items()}}
        back[slot] = op
        _stencil_case(rigs, front, back, 200 + i)


def test_stencil_faces_independent(rigs):
    """Front quads see only the front state, back quads only the back state."""
    front = {"func": "always", "ref": 10, "fail": "keep", "zfail": "keep", "zpass": "replace"}
    back = {"func": "always", "ref": 20, "fail": "keep", "zfail": "keep", "zpass": "replace"}
    got, _ = _stencil_case(rigs, front, back, 300, depth_func="always")
    assert (got["ds.stencil"][:, : W // 2] == 10).all()
    assert (got["ds.stencil"][:, W // 2:] == 20).all()


# ---------------------------------------------------------------------------------------------
# the targets and techniques the design relies on
# ---------------------------------------------------------------------------------------------


def test_d24s8_fbo_complete(rigs):
    rig = rigs("rgba8", "d24s8")
    assert rig.status == GL.GL_FRAMEBUFFER_COMPLETE
    for color in ("rgba16f", "r32ui", "rgb10a2"):
        assert rigs(color, "d24s8").status == GL.GL_FRAMEBUFFER_COMPLETE
    assert rigs(None, "d32f").status == GL.GL_FRAMEBUFFER_COMPLETE


def _bitplane_codes(index: np.ndarray) -> np.ndarray:
    """Trebilco bit shifting: the index's 2-bit chunk for channel ch in that channel's top
    two bits (codes, (..., 4))."""
    return np.stack([((index >> (2 * ch)) & 3) << 6 for ch in range(4)], axis=-1)


DISCARD = -1e30   # with discard=True, a source x of DISCARD makes the shader discard


def test_bitplane_packing_one_constant_color_bit_exact(rigs):
    """Up to four light indices per pixel written with blend ONE, CONSTANT_COLOR (0.25):
    every index decodes back bit-exactly (Trebilco 2007, "bit shifting")."""
    rig = rigs("rgba8")
    rng = np.random.default_rng(5)
    indices = rng.integers(1, 256, (4, H, W))
    count = rng.integers(0, 5, (H, W))          # 0..4 lights per pixel
    rig.preset(color=np.zeros((H, W, 4), np.uint8))
    b = {"enabled": True, "rgb": ["add", "one", "constant_color"],
         "alpha": ["add", "one", "constant_color"]}
    state = {"blend": {"c": b}, "blend_constant": [0.25] * 4}
    expect = np.zeros((H, W, 4), np.int64)
    oracle = np.zeros((H, W, 4), np.uint8)
    for k in range(4):
        live = k < count
        codes = _bitplane_codes(indices[k])
        src = np.where(live[..., None], codes / 255.0, DISCARD)
        rig.fullscreen(state, src, discard=True)
        expect = np.where(live[..., None], (expect >> 2) + codes, expect)
        oracle = FF.write_color(src, oracle, "rgba8", b, [0.25] * 4, mask=live)
    got = rig.buffers()["c"].astype(np.int64)
    assert np.array_equal(got, expect)
    assert np.array_equal(oracle, expect)
    for k in range(4):                           # the k-th most recent light decodes back
        dec = np.zeros((H, W), np.int64)
        for ch in range(4):
            dec |= ((got[..., ch] >> (6 - 2 * k)) & 3) << (2 * ch)
        have = count > k
        newest = np.take_along_axis(indices, np.clip(count - 1 - k, 0, 3)[None], 0)[0]
        assert np.array_equal(dec[have], newest[have])
        assert (dec[~have] == 0).all()


def test_max_blend_two_writes_stencil(rigs):
    """Trebilco's multi-pass MAX scheme: pass 1 (mask RG, stencil < 2 passes, incr) stores the
    first two lights as max(i) / max(1-i), pass 2 (mask BA, stencil == 0 passes, decr on
    fail) the others; up to four lights per pixel decode exactly."""
    rig = rigs("rgba8", "d24s8")
    rects = [(0, 0, 10, 10), (4, 2, 16, 12), (2, 6, 12, 16), (8, 0, 16, 8), (0, 12, 6, 16),
             (6, 4, 14, 14)]
    lights = [(r, 3 + 37 * k) for k, r in enumerate(rects)]   # distinct 8-bit indices
    zero_ds = np.zeros((H, W), np.uint32)
    rig.preset(color=np.zeros((H, W, 4), np.uint8), depth=zero_ds,
               stencil=np.zeros((H, W), np.uint8))
    face1 = {"func": "greater", "ref": 2, "fail": "keep", "zfail": "keep", "zpass": "incr"}
    face2 = {"func": "equal", "ref": 0, "fail": "decr", "zfail": "keep", "zpass": "keep"}
    passes = []
    for face, mask in ((face1, [True, True, False, False]), (face2, [False, False, True, True])):
        passes.append({"depth": {"func": "always", "write": False},
                       "stencil": {"front": face, "back": face},
                       "blend": {"c": {"enabled": True, "rgb": ["max"], "alpha": ["max"],
                                       "write_mask": mask}}})
    bufs = {"c": np.zeros((H, W, 4), np.uint8), "ds": zero_ds,
            "ds.stencil": np.zeros((H, W), np.uint8)}
    for state in passes:
        quads = [(*r, 0.5, (i / 255, 1 - i / 255, i / 255, 1 - i / 255), True)
                 for r, i in lights]
        rig.quads(state, quads)
        bufs = oracle_quads(bufs, state, quads, {"c": "rgba8", "ds": "d24s8"}, "ds")
    got = rig.buffers()
    assert np.array_equal(got["c"], bufs["c"])
    assert np.array_equal(got["ds.stencil"], bufs["ds.stencil"])
    c = got["c"].astype(int)
    for y in range(H):
        for x in range(W):
            cover = [i for r, i in lights if quad_coverage(*r)[y, x]]
            if len(cover) > 4:
                continue
            decoded = {c[y, x, 0], 255 - c[y, x, 1], c[y, x, 2], 255 - c[y, x, 3]} - {0, 255}
            # empty pixels: R = B = 0, G = A = 0 (max of nothing) -> decode {0, 255}
            assert decoded == set(cover), (y, x, cover, c[y, x])
