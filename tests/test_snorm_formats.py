"""Signed-normalised targets (rg8_snorm, rgba8_snorm, rg16_snorm: octahedral normals), added to
``formats.FORMATS`` as table rows only: both backends derive their storage and conversions.

llvmpipe's conversions (Mesa 22.3, measured; ``Format.quantize`` and the OpenCL backend
reproduce them):

- float -> 8-bit snorm: ``rint(x * 127)`` in float32 (half to even), *then* saturated to
  [-128, 127]: values below -1 reach -128, NaN gives -128 (``Encode.ROUND_SAT``);
- float -> 16-bit snorm: clamped to [-1, 1] first (NaN -> -1), then ``rint(x * 32767)``:
  never -32768 (``Encode.ROUND``);
- reads: ``max(code * (1/max), -1)`` with the float32 reciprocal (-128 and -127 both read
  -1.0); missing channels read (0, 1).

A small technique writes per-pixel values (code ties, ±1 ulp around them, ±1, out of range,
±inf, NaN) into each snorm target and reads them back with ``load`` and ``sample``; the codes
must equal ``Format.quantize`` of the same float32 values on both backends, and
``pipegen check`` must pass.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.core import formats as F
from pipegen.compiler.driver import compile_source

ROOT = Path(__file__).resolve().parents[1]
W, H = 160, 96

SNORM_PROBE = """
technique snorm_probe "signed-normalised stores and reads"
target n8 : rgba8_snorm size 160 x 96
target n2 : rg8_snorm size 160 x 96
target n16 : rg16_snorm size 160 x 96
target r8 : rgba32f size 160 x 96
target r2 : rgba32f size 160 x 96
target r16 : rgba32f size 160 x 96
target s8 : rgba32f size 160 x 96
target s16 : rgba32f size 160 x 96
output r8
pass store {
  draw fullscreen
  writes n8, n2, n16
  fragment {
    float i = floor(frag_coord.y) * 160.0 + floor(frag_coord.x);
    float h = mod(i, 640.0) - 320.0;
    float t8 = h / 254.0;                       // steps of half a code: every tie (k + .5) / 127
    float t16 = (i * 9.0 - 69001.0) / 65534.0;  // odd multiples of half a code: ties of 16 bits
    float zero = frag_coord.x - frag_coord.x;
    float k = mod(floor(i / 640.0), 8.0);
    float special = k < 1.0 ? 1.0 / zero : k < 2.0 ? -1.0 / zero : k < 3.0 ? zero / zero
                  : k < 4.0 ? 1.0 : k < 5.0 ? -1.0 : k < 6.0 ? -2.0 : k < 7.0 ? 1e30 : -1e30;
    n8 = vec4(t8, -t8 * 1.0000001, t8 * 0.9999999, special);
    n2 = vec4(t8 * 1.0000001, special, 0.0, 0.0);
    n16 = vec4(t16, special, 0.0, 0.0);
  }
}
pass read {
  draw fullscreen
  reads n8, n2, n16
  writes r8, r2, r16, s8, s16
  fragment {
    r8 = load(n8);
    r2 = load(n2);
    r16 = load(n16);
    vec2 uv = frag_coord.xy / vec2(160.0, 96.0) * 1.2 - 0.1
              + vec2(0.00123, 0.00071) * frag_coord.yx;
    s8 = sample(n8, uv);
    s16 = sample(n16, uv);
  }
}
"""

SNORM = ("rgba8_snorm", "rg8_snorm", "rg16_snorm")


def BOTH(test):
    """Renders on both backends (the test tiers' markers)."""
    return pytest.mark.gl(pytest.mark.cl(test))


def _values() -> dict[str, np.ndarray]:
    """The store pass's outputs in float32, computed like the shader (bottom row first)."""
    f32 = np.float32
    y, x = np.mgrid[0:H, 0:W].astype(f32)
    i = (y * f32(W) + x).astype(f32)
    h = (np.mod(i, f32(640)) - f32(320)).astype(f32)
    t8 = (h / f32(254)).astype(f32)
    t16 = ((i * f32(9) - f32(69001)) / f32(65534)).astype(f32)
    k = np.mod(np.floor(i / f32(640)), f32(8))
    with np.errstate(divide="ignore", invalid="ignore"):
        special = np.select([k < 1, k < 2, k < 3, k < 4, k < 5, k < 6, k < 7],
                            [f32(np.inf), f32(-np.inf), f32(np.nan), f32(1), f32(-1), f32(-2),
                             f32(1e30)], f32(-1e30)).astype(f32)
    return {"n8": np.stack([t8, (-t8 * f32(1.0000001)).astype(f32),
                            (t8 * f32(0.9999999)).astype(f32), special], -1),
            "n2": np.stack([(t8 * f32(1.0000001)).astype(f32), special], -1),
            "n16": np.stack([t16, special], -1)}


def test_snorm_formats_are_table_rows():
    for name in SNORM:
        f = F.get(name)
        assert f.kind is F.Kind.SNORM and f.is_signed and not f.blendable
        assert f.dtype == np.dtype(np.int8 if f.bits[0] == 8 else np.int16)
        assert f.tolerance().units == "code"


def test_snorm_quantize_follows_llvmpipe():
    """The measured conversions, on the cases where the candidates differ."""
    q8, q16 = F.get("rgba8_snorm").quantize, F.get("rg16_snorm").quantize
    # ties: float32(k.5 / 127) * 127 is exactly k.5 here, and rounds half to even
    x = np.array([-2.0, -1.004, -1.0, -0.5 / 127, 0.5 / 127, 1.5 / 127, 2.5 / 127, 1.0, 2.0,
                  np.inf, -np.inf, np.nan])
    assert q8(x).tolist() == [-128, -128, -127, 0, 0, 2, 2, 127, 127, 127, -128, -128]
    t = np.array([-2.0, -1.004, 0.5 / 32767, 1.5 / 32767, 2.5 / 32767, np.inf, -np.inf, np.nan])
    assert q16(t).tolist() == [-32767, -32767, 0, 2, 2, 32767, -32767, -32767]
    codes = np.array([-128, -127, -1, 0, 1, 127])
    assert F.get("rg8_snorm").dequantize(codes).tolist() == [-1.0, -1.0, -1 / 127, 0.0,
                                                              1 / 127, 1.0]


def test_snorm_opencl_layout():
    from pipegen.backends.opencl.formats import cl_format
    f = cl_format("rg16_snorm")
    assert f["cls"] == "snorm" and f["storage"] == "short2" and f["reg"] == "uint4"
    assert "convert_int4_rte" in f["encode"] and "-1.0f" in f["read"]
    assert "-128.0f" in cl_format("rgba8_snorm")["encode"]


def test_snorm_blending_is_refused():
    from pipegen.core.diagnostics import PipegenError
    src = """
technique t "x"
target n : rg8_snorm
output n
pass p { draw fullscreen writes n blend n add(one, one) fragment { n = vec4(0.5); } }
"""
    with pytest.raises(PipegenError, match="cannot be blended"):
        compile_source(src)


@pytest.fixture(scope="module")
def probe():
    pytest.importorskip("pyopencl")
    try:
        from pipegen.runtime.gl.context import get_context
        get_context()
    except Exception as exc:   # pragma: no cover - no EGL here
        pytest.skip(f"no OpenGL context: {exc}")
    from pipegen.scene import load_scene
    compiled = compile_source(SNORM_PROBE)
    scene = load_scene(ROOT / "examples/scenes/small.toml")
    gl = compiled.pipeline("gl").render(scene)
    cl = compiled.pipeline("cl").render(scene)
    return compiled, scene, gl, cl


@pytest.mark.parametrize("target,fmt", [("n8", "rgba8_snorm"), ("n2", "rg8_snorm"),
                                        ("n16", "rg16_snorm")])
@BOTH
def test_snorm_stores_are_quantize_on_both_backends(probe, target, fmt):
    _, _, gl, cl = probe
    want = F.get(fmt).quantize(_values()[target])
    assert gl[target].dtype == want.dtype and cl[target].dtype == want.dtype
    np.testing.assert_array_equal(gl[target], want)     # GL row order on both
    np.testing.assert_array_equal(cl[target], want)


@BOTH
def test_snorm_loads_bit_exact(probe):
    _, _, gl, cl = probe
    for name, src, fmt in (("r8", "n8", "rgba8_snorm"), ("r2", "n2", "rg8_snorm"),
                           ("r16", "n16", "rg16_snorm")):
        np.testing.assert_array_equal(gl[name], cl[name], err_msg=name)
        f32 = np.float32
        m = F.get(fmt).max_codes[0]
        want = np.maximum(gl[src].astype(f32) * (f32(1) / f32(m)), f32(-1))
        np.testing.assert_array_equal(gl[name][..., :want.shape[-1]], want, err_msg=name)
        if want.shape[-1] == 2:
            assert (gl[name][..., 2] == 0).all() and (gl[name][..., 3] == 1).all()


@BOTH
def test_snorm_samples_agree(probe):
    """Bilinear samples of snorm targets: llvmpipe filters the decoded texels like float ones
    (fused lerps, x then y), bit-exactly where the host has FMA (test_cl_exactness.py)."""
    compiled, _, gl, cl = probe
    from pipegen.proof.compare import compare_target
    exact = " fma " in Path("/proc/cpuinfo").read_text().replace("\n", " ") \
        if Path("/proc/cpuinfo").exists() else False
    for name in ("s8", "s16"):
        if exact:
            np.testing.assert_array_equal(gl[name], cl[name], err_msg=name)
        fmt = compiled.technique.target(name).format
        assert compare_target(name, fmt, gl[name], cl[name]).passed, name


@BOTH
def test_snorm_probe_passes_check(probe):
    from pipegen.proof.check import check
    compiled, scene, _, _ = probe
    result = check(compiled, scene)
    assert result.passed, [r.row() for r in result.rows if not r.passed]
