"""The guarded builtins (backends/cstyle.py: sqrt/pow of negatives through max(x, 0), the pow,
inversesqrt, log, log2 and normalize helpers, shift counts masked ``& 31``, ``uint(float)`` of
negatives and NaN) give the same bits on the wide path (opencl/wide/, 8 pixels per call) as on the
scalar path on hard inputs: NaN, +-inf, +-0, denormals, FLT_MIN, values around 2^31 and 2^32,
shift counts negative and >= 32.  A full-screen technique picks operand a from frag_coord.x and
b from frag_coord.y out of a table of such values (a ternary chain: per pixel, so nothing is
folded), applies each guarded form and is rendered with the scalar fragment function only and
with the wide one (forced: MIN_COST 0, WMIN 1).  NaNs compare equal whatever their sign or
payload (the compiler may commute a multiply, and x86 keeps the first operand's NaN: normalize
of a NaN vector gives 0xffc00000 on one path and 0x7fc00000 on the other).  GL (llvmpipe, the
reference) is compared where the CL arithmetic is defined to match it: shifts, int(float),
normalize, sqrt and inversesqrt, away from operands whose products are denormal (see TINY)."""

from __future__ import annotations

import numpy as np
import pytest

from pipegen.backends.opencl import wide as cl_wide
from pipegen.compiler.driver import compile_source
from pipegen.scene import default_scene

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

FLOATS = [
    "z / z", "-(z / z)", "1.0 / z", "-1.0 / z", "z", "-z",
    "1e-40", "-1e-40", "1.4e-45", "1.1754942e-38", "1.17549435e-38", "-1.17549435e-38",
    "1e-20", "1e-19", "1.0", "-1.0", "0.5", "-0.5", "2.0", "0.3", "100.0",
    "2147483520.0", "2147483648.0", "3e9", "4294967040.0", "4294967296.0", "5e9", "1e10",
    "3.4e38", "-3e9", "-2147483648.0", "-2147483904.0", "-0.75", "88.5",
]
INTS = ["0", "1", "-1", "2", "7", "31", "32", "33", "63", "64", "100", "-31", "-32", "-33",
        "-100", "2147483647", "(-2147483647 - 1)", "1431655765", "-1431655766", "65535"]


def chain(name, ty, vals):
    s = vals[-1]
    for k in range(len(vals) - 2, -1, -1):
        s = f"(i == {k} ? {vals[k]} : {s})"
    return f"{ty} {name}(int i, float z) {{\n  return {s};\n}}\n"


TECH = ("""
technique wide_guards "guarded builtins on hard inputs"
target f1 : rgba32f clear 0
target f2 : rgba32f clear 0
target f3 : rgba32f clear 0
target f4 : rgba32f clear 0
target f5 : rgba32f clear 0
target u1 : r32ui clear 0
target u2 : r32ui clear 0
target u3 : r32ui clear 0
target u4 : r32ui clear 0
target u5 : r32ui clear 0
target u6 : r32ui clear 0
target u7 : r32ui clear 0
target u8 : r32ui clear 0
target s1 : r32ui clear 0
target s2 : r32ui clear 0
target s3 : r32ui clear 0
target s4 : r32ui clear 0
target s5 : r32ui clear 0
target s6 : r32ui clear 0
target s7 : r32ui clear 0
target s8 : r32ui clear 0
output f1
""" + chain("hard_f", "float", FLOATS) + chain("hard_i", "int", INTS) + """
pass floats {
  draw fullscreen
  writes f1, f2, f3, f4, f5
  fragment {
    OPERANDS
FLOAT_AB
    f1 = vec4(sqrt(a), inversesqrt(a), log(a), log2(a));
    f2 = vec4(pow(a, b), pow(a, 2.2), pow(a, 0.5), pow(b, a));
    vec3 n = normalize(vec3(a, b, z));
    f3 = vec4(n, normalize(vec2(b, a)).x);
    vec2 p = pow(vec2(a, b), vec2(b, 2.0));
    f4 = vec4(p, log2(vec2(a, b)));
    vec2 q = inversesqrt(vec2(a, b));
    f5 = vec4(q, log(vec2(b, a)));
  }
}

pass convert {
  draw fullscreen
  writes u1, u2, u3, u4, u5, u6, u7, u8
  fragment {
    OPERANDS
FLOAT_AB
    u1 = uint(a);
    uvec2 v = uvec2(vec2(a, b));
    u2 = v.y;
    u3 = uint(int(a));
    ivec2 w = ivec2(vec2(b, a));
    u4 = uint(w.y);
    u5 = uint(a * 2.0);
    u6 = uint(-a);
    u7 = uint(a + b);
    u8 = uint(vec2(a, b).y * 0.5);
  }
}

pass shifts {
  draw fullscreen
  writes s1, s2, s3, s4, s5, s6, s7, s8
  fragment {
    OPERANDS
INT_AB
    uint ua = uint(a);
    uint ub = uint(b);
    s1 = uint(a << b);
    s2 = uint(a >> b);
    s3 = ua << ub;
    s4 = ua >> ub;
    s5 = ua >> b;
    s6 = uint(a << ub);
    s7 = 3u << ub;
    s8 = uint(-5 >> b) + (0x80000000u >> uint(a & 63));
  }
}
""".replace("OPERANDS", "float z = frag_coord.x * 0.0; int i = int(frag_coord.x); "
            "int j = int(frag_coord.y);")
    .replace("FLOAT_AB", "    float a = hard_f(i, z); float b = hard_f(j, z);")
    .replace("INT_AB", "    int a = hard_i(i, z); int b = hard_i(j, z);"))


@pytest.fixture(scope="module")
def renders():
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(cl_wide, "MIN_COST", 0)
        mp.setattr(cl_wide, "GATHER_COST", 0)
        mp.setattr(cl_wide, "WMIN", 1)
        mp.setattr(cl_wide, "ENABLED", False)
        scalar = compile_source(TECH).pipeline("cl")
        mp.setattr(cl_wide, "ENABLED", True)
        wide = compile_source(TECH).pipeline("cl")
    finally:
        mp.undo()
    passes = [p.name for p in wide.plan.passes
              if p.code.fragment and cl_wide.MARK in p.code.fragment]
    assert passes == ["floats", "convert", "shifts"]
    scene = default_scene().with_size(len(FLOATS), len(FLOATS))
    return scalar.render(scene), wide.render(scene), scene


def _differ(x, y) -> np.ndarray:
    x, y = np.ascontiguousarray(x), np.ascontiguousarray(y)
    d = x.view(np.uint32) != y.view(np.uint32)
    if x.dtype == np.float32:
        d &= ~(np.isnan(x) & np.isnan(y))
    return d


def _b_at_least_2_32() -> np.ndarray:
    """Rows (operand b) whose float is >= 2^32: uint(b) is out of range (see below)."""
    big = {"1.0 / z", "4294967296.0", "5e9", "1e10", "3.4e38"}
    return np.array([f in big for f in FLOATS])


def test_wide_guards_are_bit_identical_to_scalar(renders):
    scalar, wide, _ = renders
    assert scalar.keys() == wide.keys()
    for k in scalar:
        d = _differ(scalar[k], wide[k])
        assert not d.any(), (k, np.argwhere(d)[:5])


def test_uvec_from_huge_floats_saturates(renders):
    """uint(float >= 2^32) is out of range (GLSL: undefined).  The CL backend converts
    saturating, as llvmpipe's GL does: 0xffffffff on the scalar and the wide path alike.  With
    the plain cast (LLVM's fptoui, poison there) the scalar path's convert_uint2 gave
    0x80000000 and the wide path's convert_uint8 the low 32 bits, or not, depending on how
    PoCL built the kernel (with one PoCL thread, as in a pytest-xdist worker, they agreed; with
    two they did not)."""
    scalar, wide, _ = renders
    assert not _differ(scalar["u2"], wide["u2"]).any()
    big = _b_at_least_2_32()
    assert big.any() and (scalar["u2"][big] == 0xFFFFFFFF).all()


# Operands whose products are float32 denormals: whether llvmpipe flushes a denormal depends on
# what GL work the process did before (measured: in a fresh process it flushes, as PoCL does;
# after another technique's GL pipeline has rendered, it keeps them), so GL is compared only
# away from them.
TINY = {"1e-40", "-1e-40", "1.4e-45", "1.1754942e-38", "1.17549435e-38", "-1.17549435e-38",
        "1e-20", "1e-19"}


@pytest.mark.gl
def test_gl_agrees_where_defined(renders):
    scalar, _, scene = renders
    gl = compile_source(TECH).pipeline("gl").render(scene)
    for k in ("s1", "s2", "s3", "s4", "s5", "s6", "s7", "s8", "u1", "u2", "u3", "u4", "u5",
              "u6", "u7", "u8"):
        assert not _differ(scalar[k], gl[k]).any(), k
    tiny = np.array([f in TINY for f in FLOATS])
    away = ~(tiny[:, None] | tiny[None, :])              # rows: operand b, columns: a
    assert not _differ(scalar["f3"], gl["f3"])[away].any()
    assert not _differ(scalar["f1"], gl["f1"])[..., :2][away].any()   # sqrt, inversesqrt
