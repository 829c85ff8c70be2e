"""Bit-exactness of the OpenCL reference with llvmpipe (Mesa 22.3) where it mirrors llvmpipe's
arithmetic operation for operation:

- varyings: llvmpipe's plane setup (lp_state_setup.c: perspective attributes premultiplied by
  1/w, a0 at the window origin) and per-pixel evaluation (lp_bld_interp.c: two fused
  multiply-adds, then ``* (1 / w)``), ``cl_setup.attribute_planes``;
- bilinear filtering of float, half and 16-bit unorm textures (lp_bld_sample_soa.c,
  clamp-to-edge texel coordinates, float weights, ``fma(w, v1 - v0, v0)`` x then y);
- stores to 16-bit unorm (``x * (65535/65536) + 128``, the low mantissa bits) and rgb10a2
  (that 16-bit code shifted down: rgb ``>> 6``, alpha rescaled);
- the per-pixel blend counts the raster kernel keeps for ``pipegen check`` (no GL needed).

llvmpipe fuses its ``fmuladd``s only on FMA hardware; the reference always fuses, so the exact
assertions hold where the host has FMA, the tolerances of ``pipegen check`` elsewhere.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyopencl")

pytestmark = [pytest.mark.gl, pytest.mark.cl]

from cl_util import TriScene, make_pass, make_plan, quad, target  # noqa: E402
from pipegen.proof.compare import compare_target, ulp_distance  # noqa: E402
from pipegen.compiler.driver import compile_file, compile_source  # noqa: E402
from pipegen.runtime.cl import setup as CS  # noqa: E402
from pipegen.runtime.cl.pipeline import CLPipeline  # noqa: E402
from pipegen.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _host_has_fma() -> bool:
    try:
        return " fma " in f" {Path('/proc/cpuinfo').read_text()} ".replace("\n", " ")
    except OSError:  # pragma: no cover
        return False


EXACT = _host_has_fma()


@pytest.fixture(scope="module")
def gl_available():
    try:
        from pipegen.runtime.gl.context import get_context
        get_context()
    except Exception as exc:   # no EGL / llvmpipe here: the CL-only tests still run
        pytest.skip(f"no OpenGL context: {exc}")


def _render_both(compiled, scene):
    return compiled.pipeline("gl").render(scene), compiled.pipeline("cl").render(scene)


def _assert_agree(compiled, g, c, names):
    for name in names:
        a, b = g[name], c[name]
        if EXACT:
            same = (a == b) | ((a != a) & (b != b)) if a.dtype.kind == "f" else a == b
            assert same.all(), (name, int((~same).sum()))
        else:   # pragma: no cover - hosts without FMA
            fmt = compiled.technique.target(name).format
            assert compare_target(name, fmt, a, b).passed, name


# ---- varyings -------------------------------------------------------------------------------

def test_attribute_planes_are_the_depth_plane_for_z():
    """The general plane setup gives llvmpipe's depth plane (checked code for code against
    llvmpipe in test_cl_depth.py) when the attribute is window z."""
    rng = np.random.default_rng(3)
    n = 200
    xw = rng.uniform(0, 300, (n, 3)).astype(np.float32)
    yw = rng.uniform(0, 200, (n, 3)).astype(np.float32)
    zw = rng.uniform(0, 1, (n, 3)).astype(np.float32)
    X, Y = np.rint(xw * 256.0).astype(np.int64), np.rint(yw * 256.0).astype(np.int64)
    area = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0])
    pz, _ = CS.depth_plane(xw, yw, zw, area)
    planes = CS.attribute_planes(xw, yw, area, zw[:, :, None])
    assert planes.dtype == np.float32 and planes.shape == (n, 3, 1)
    assert np.array_equal(planes[:, :, 0].view(np.int32), pz.view(np.int32))


def test_perspective_planes_reproduce_the_vertex_values():
    """a/w planes evaluated at a vertex and divided by the 1/w plane give the vertex's value
    (to float32 rounding): the planes are llvmpipe's perspective-correct interpolation."""
    xw = np.array([[10.25, 70.5, 20.0]], np.float32)
    yw = np.array([[5.0, 12.75, 60.5]], np.float32)
    iw = np.array([[1.0, 0.25, 0.5]], np.float32)
    attr = np.array([[[1.0, -2.0], [3.0, 0.5], [-4.0, 8.0]]], np.float32)
    area = np.array([1])
    w = CS.attribute_planes(xw, yw, area, iw[:, :, None], center=0.0)[0, :, 0]
    a = CS.attribute_planes(xw, yw, area, attr * iw[:, :, None], center=0.0)[0]
    for k in range(3):
        x, y = xw[0, k], yw[0, k]
        val = (a[0] + a[1] * x + a[2] * y) / (w[0] + w[1] * x + w[2] * y)
        assert np.allclose(val, attr[0, k], rtol=1e-5, atol=1e-5)


def test_gbuffer_varyings_bit_exact_with_llvmpipe(gl_available):
    """World positions (rgba32f) and normals (rgba16f) of a perspective G-buffer pass are the
    values llvmpipe interpolates, bit for bit (they differed by ~1e-6 relative with
    barycentric interpolation: thousands of ulps near zero, different halves after a store)."""
    compiled = compile_file(ROOT / "pipelines/deferred.pipe")
    scene = load_scene(ROOT / "examples/scenes/mixed_lights.toml").with_size(160, 90)
    g, c = _render_both(compiled, scene)
    _assert_agree(compiled, g, c, ["gpos", "gnormal", "galbedo", "ds"])


MSAA_PROBE = """
technique msaa "varyings and frag_coord.w with 4 samples, and with one"
target gpos : rgba32f samples 4 clear 0
target gn : rgba16f samples 4 clear 0
target ds : d24s8 samples 4 clear depth 1.0 stencil 0
target gpos1 : rgba32f clear 0
target ds1 : d24s8 clear depth 1.0 stencil 0
output gpos
pass ms {
  draw scene.opaque
  writes gpos, gn
  depth ds less write
  cull back
  fragment { gpos = vec4(world_pos, frag_coord.w); gn = vec4(normalize(normal), 1.0); }
}
pass single {
  draw scene.opaque
  writes gpos1
  depth ds1 less write
  cull back
  fragment { gpos1 = vec4(view_pos.xy, frag_coord.zw); }
}
"""


def test_multisampled_varyings_bit_exact_with_llvmpipe(gl_available):
    """With multisampling llvmpipe folds no pixel centre into a0 and evaluates the planes at
    the pixel centre; frag_coord.w is the interpolated 1/w plane (resolved averages of the
    samples compared, edges included)."""
    compiled = compile_source(MSAA_PROBE)
    scene = load_scene(ROOT / "examples/scenes/mixed_lights.toml").with_size(160, 90)
    g, c = _render_both(compiled, scene)
    _assert_agree(compiled, g, c, ["gpos", "gn", "ds", "gpos1", "ds1"])



MSAA_DEPTH_PROBE = """
technique msaaz "frag_coord.z with 4 samples: the plane at the pixel centre, unclamped"
target gz : r32f samples 4 clear 1.0
target beyond : r32f samples 4 clear 0
target ds : d24s8 samples 4 clear depth 1.0 stencil 0
output gz
pass ms {
  draw scene.opaque
  writes gz, beyond
  depth ds less write
  cull back
  fragment { gz = frag_coord.z; beyond = frag_coord.z > 1.0 ? 1.0 : 0.0; }
}
"""


def test_multisampled_frag_coord_z_is_the_unclamped_centre_plane(gl_available):
    """With multisampling frag_coord.z is the depth plane at the pixel centre, evaluated as
    the per-sample depths are and not clamped: a triangle covering samples but not the
    centre extrapolates it past 1 (one such pixel in many_lights at 320x180, where clamping
    it put zcopy of lidr_msaa_texture 5629 ulp from llvmpipe's)."""
    compiled = compile_source(MSAA_DEPTH_PROBE)
    scene = load_scene(ROOT / "examples/scenes/many_lights.toml").with_size(320, 180)
    g, c = _render_both(compiled, scene)
    assert (g["beyond"] > 0).any() and (c["beyond"] > 0).any()   # the case is exercised
    _assert_agree(compiled, g, c, ["gz", "beyond", "ds"])

# ---- texture filtering and unorm stores ------------------------------------------------------

FILTER_PROBE = """
technique probe "float bilinear filtering and unorm16 / rgb10a2 stores"
target lut16 : rgba16f size 37 x 11
target lut32 : r32f size 37 x 11
target lutu : rgba16 size 37 x 11
target o16 : rgba32f size 160 x 96
target o32 : r32f size 160 x 96
target ou : rgba32f size 160 x 96
target s10 : rgb10a2 size 160 x 96
target s16 : rgba16 size 160 x 96
output o16
pass tabulate {
  draw fullscreen
  writes lut16, lut32, lutu
  fragment {
    uint h = (uint(frag_coord.x) * 2654435761u) ^ (uint(frag_coord.y) * 40503u + 12345u);
    h = h ^ (h >> 13);
    float v = float(h & 65535u) / 65536.0;
    vec4 q = vec4(v * 7.0 - 3.0, v * v * 100.0, 1.0 - v, v * 0.001);
    lut16 = q;
    lut32 = q;
    lutu = vec4(v, v * v, 1.0 - v, fract(v * 3.5));
  }
}
pass probe {
  draw fullscreen
  reads lut16, lut32, lutu
  writes o16, o32, ou, s10, s16
  fragment {
    vec2 uv = frag_coord.xy / vec2(160.0, 96.0) * 1.4 - 0.2
              + vec2(0.00123, 0.00071) * frag_coord.yx;
    o16 = sample(lut16, uv);
    o32 = sample(lut32, uv);
    ou = sample(lutu, uv);
    float x = (floor(frag_coord.y) * 160.0 + floor(frag_coord.x)) / 15359.0;
    vec4 s = vec4(x, x * 0.999 + 0.0003, 1.0 - x, x * x);
    s10 = s;
    s16 = s;
  }
}
"""


@pytest.fixture(scope="module")
def filter_probe(gl_available):
    compiled = compile_source(FILTER_PROBE)
    scene = load_scene(ROOT / "examples/scenes/small.toml")
    return compiled, _render_both(compiled, scene)


def test_float_bilinear_filtering_bit_exact(filter_probe):
    """Bilinear samples of half, float and 16-bit unorm textures, including coordinates
    outside [0, 1] (clamp to edge): llvmpipe's values bit for bit (with the textbook
    ``mix(mix(t00, t10, wx), mix(t01, t11, wx), wy)`` a quarter of them differed, by up to
    thousands of ulps near zero)."""
    compiled, (g, c) = filter_probe
    _assert_agree(compiled, g, c, ["lut16", "lut32", "lutu"])     # the tables themselves
    _assert_agree(compiled, g, c, ["o16", "o32", "ou"])


def test_unorm16_and_rgb10a2_stores_bit_exact(filter_probe):
    """rgba16 and rgb10a2 stores are llvmpipe's codes (rgb10a2 truncates its 16-bit code:
    0.6710101 is stored as 687, not rint(0.6710101 * 1023) = 686)."""
    compiled, (g, c) = filter_probe
    assert np.array_equal(g["s10"], c["s10"])
    assert np.array_equal(g["s16"], c["s16"])
    x = np.float32(0.6710101)
    code16 = int((np.float32(x * np.float32(65535 / 65536)) + np.float32(128)).view(np.uint32)
                 & 0xFFFF)
    assert code16 >> 6 == 687


# ---- per-pixel blend counts ------------------------------------------------------------------

ADD = {"enabled": True, "rgb": ["add", "one", "one"], "alpha": ["add", "one", "one"],
       "write_mask": [True] * 4}
DISCARD_RIGHT = ("static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n"
                 "    if (in->pix.x >= 12) return false;\n"
                 "    out->o_color = (float4)(0.1f);\n"
                 "    return true;\n}\n")


def test_blend_counts_count_blended_fragments_per_pixel():
    """``last_blend_counts`` holds, per pixel, the fragments blended into a target during the
    frame: overlapping triangles of one pass each count, fragments that are discarded or fail
    the depth test do not, and passes without blending add nothing."""
    W, H = 16, 8
    left = quad(-1, -1, 0, 1, 0.5)       # columns 0..7, depth 0.75
    all_ = quad(-1, -1, 1, 1, 0.0)       # every pixel, depth 0.5
    back = quad(-1, -1, 1, 1, 0.8)       # every pixel, behind: fails "less" after all_
    plan = make_plan(
        [target("color", "rgba16f", clear_color=[0, 0, 0, 0]),
         target("plain", "rgba8", clear_color=[0, 0, 0, 0]),
         target("ds", "d24s8", clear_depth=1.0, clear_stencil=0)],
        [make_pass("blend", writes=("color",), fragment=DISCARD_RIGHT, inputs=(), discard=True,
                   depth_target="ds",
                   state={"blend": {"color": ADD},
                          "depth": {"func": "less", "write": True, "clamp": False}}),
         make_pass("opaque", writes=("plain",), fragment=DISCARD_RIGHT.replace("color", "plain"),
                   inputs=(), discard=True)])
    pipe = CLPipeline(plan)
    # in order: all_ passes and writes depth 0.5; left (0.75), back (0.9) and all_ again (0.5,
    # not less) fail: every pixel not discarded counts once
    scene = TriScene(W, H, all_ + left + back + all_)
    pipe.render(scene)
    counts = pipe.last_blend_counts
    assert set(counts) == {"color"}
    n = counts["color"]
    assert n.shape == (H, W) and n.dtype == np.uint32
    assert (n[:, :12] == 1).all() and (n[:, 12:] == 0).all()
    # without depth test every covering triangle counts
    plan["passes"][0]["state"]["depth"] = {"func": "always", "write": False, "clamp": False}
    pipe = CLPipeline(plan)
    pipe.render(scene)
    n = pipe.last_blend_counts["color"]
    assert (n[:, :8] == 4).all() and (n[:, 8:12] == 3).all() and (n[:, 12:] == 0).all()
    # captures carry the counts so far
    _, caps = pipe.render(scene, capture_passes=True)
    assert np.array_equal(caps[0]["blend_counts"]["color"], n)


def test_check_uses_per_pixel_blend_counts(gl_available):
    """``pipegen check`` holds each pixel of a light accumulation target to 1 + P(x, y)
    with P from the CL backend's blend counts."""
    from pipegen.proof.check import check
    compiled = compile_file(ROOT / "pipelines/deferred.pipe")
    scene = load_scene(ROOT / "examples/scenes/mixed_lights.toml").with_size(160, 90)
    result = check(compiled, scene)
    row = next(r for r in result.rows if r.name == "accum")
    assert row.limit_map is not None and row.limit_map.shape == (90, 160)
    assert row.limit_map.min() == 1 and row.limit_map.max() > 1
    assert result.passed


RESOLVE_PROBE = """
technique resolves "multisampled targets of every format the device resolve takes"
target c8 : rgba8 samples 4 clear 0
target c10 : rgb10a2 samples 4 clear 0
target c16 : rgba16 samples 4 clear 0
target h16 : rgba16f samples 4 clear 0
target r16 : r16f samples 4 clear 0
target f32 : rgba32f samples 4 clear 0
target ds : d24s8 samples 4 clear depth 1.0 stencil 0
output c8
pass ms {
  draw scene.opaque
  writes c8, c10, c16, h16, r16, f32
  depth ds less write
  stencil { func always ref 7 pass replace }
  cull back
  fragment {
    vec3 n = normalize(normal);
    c8 = vec4(n * 0.5 + 0.5, frag_coord.z);
    c10 = vec4(fract(world_pos * 3.7), 0.4);
    c16 = vec4(fract(world_pos * 0.37), fract(frag_coord.z * 9.0));
    h16 = vec4(world_pos, frag_coord.w);
    r16 = vec4(world_pos.x * 31.0, 0.0, 0.0, 1.0);
    f32 = vec4(n, frag_coord.z);
  }
}
"""


def test_device_resolve_matches_the_numpy_resolve():
    """The multisample resolve on the device (cl_targets.TargetStore.resolve, cl_resolve.cl.j2)
    gives the numpy resolve's codes bit for bit: unorm8, packed 10-10-10-2, unorm16, half
    (4 and 1 channels), d24s8 with its stencil, and float32 (which stays on the host)."""
    compiled = compile_source(RESOLVE_PROBE)
    scene = load_scene(ROOT / "examples/scenes/mixed_lights.toml").with_size(160, 90)
    device = compiled.pipeline("cl").render(scene)
    host_pipe = compiled.pipeline("cl")
    host_pipe.store.device_resolve = False
    host = host_pipe.render(scene)
    assert device.keys() == host.keys()
    for name in device:
        assert np.array_equal(device[name], host[name]), name
    assert (device["ds.stencil"] == 7).any() and len(np.unique(device["c8"])) > 50


def test_unorm8_and_d24_codes_round_like_convert_sat_rte():
    """``pg_unorm8_code4`` rounds by adding 2^23 and ``pg_d24_code`` through ``rint`` (both
    faster on PoCL than ``convert_*_sat_rte``): the same codes as ``convert_uint*_sat_rte`` of the
    clamped, scaled value on 64 floats either side of every unorm8 code's rounding edge and
    of 20,000 d24 edges, on specials (NaN, infinities, signed zeros, denormals) and on 10^6
    random floats; and the codes round half to even (numpy's float32 arithmetic)."""
    import pyopencl as cl
    from pipegen.backends.opencl.programs import prelude_source
    from pipegen.runtime.cl import context as cl_context

    rng = np.random.default_rng(7)
    f32 = np.float32

    def around(edges, n):
        base = np.asarray(edges, f32).view(np.int32)[:, None] + np.arange(-n, n + 1)
        return base.reshape(-1).view(f32)

    specials = np.array([np.nan, -np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-45, -1e-45, 1e-38,
                         1.0, -1.0, 2.0, 1e30, -1e30], f32)
    u8 = np.concatenate([around((np.arange(256) + 0.5) / 255, 64), around(np.arange(256) / 255, 8),
                         specials, rng.uniform(-0.5, 1.5, 10 ** 6).astype(f32)])
    d24 = np.concatenate([around((rng.integers(0, 1 << 24, 20000) + 0.5) / 16777215, 4),
                          specials, rng.uniform(-0.5, 1.5, 10 ** 6).astype(f32)])
    n = max(len(u8), len(d24))
    x = np.zeros((2, n), f32)
    x[0, :len(u8)], x[1, :len(d24)] = u8, d24
    src = prelude_source() + """
__kernel void k(__global const float *x, const int n, __global uint *got, __global uint *ref) {
    const int i = get_global_id(0);
    const float4 u = (float4)(x[i], 0.0f, 0.0f, 0.0f);
    got[i] = pg_unorm8_code4(u).x;
    ref[i] = convert_uint4_sat_rte(fmin(fmax(u, 0.0f), 1.0f) * 255.0f).x;
    got[n + i] = pg_d24_code(x[n + i]);
    ref[n + i] = convert_uint_sat_rte(fmin(fmax(x[n + i], 0.0f), 1.0f) * 16777215.0f);
}
"""
    ctx, queue = cl_context.get_context()
    prog = cl_context.build_program(src)
    mf = cl.mem_flags
    xb = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=x)
    outs = [np.zeros(2 * n, np.uint32) for _ in range(2)]
    bufs = [cl.Buffer(ctx, mf.WRITE_ONLY, o.nbytes) for o in outs]
    prog.k(queue, (n,), None, xb, np.int32(n), *bufs)
    for o, b in zip(outs, bufs):
        cl.enqueue_copy(queue, o, b)
    queue.finish()
    assert np.array_equal(outs[0], outs[1])
    for lo, scale in ((0, 255.0), (n, 16777215.0)):
        v = np.nan_to_num(x[lo // n], nan=0.0)
        expect = np.rint(np.clip(v, 0, 1).astype(f32) * f32(scale)).astype(np.uint32)
        assert np.array_equal(outs[0][lo:lo + n], expect)
