"""Bit casts and half packing (``floatBitsToUint``, ``uintBitsToFloat``, ``floatBitsToInt``,
``intBitsToFloat``, ``packHalf2x16``, ``unpackHalf2x16``): GL (llvmpipe), CL (PoCL) and the
numpy model (``pipegen.reference.bitcasts``) agree bit for bit.

One full-screen pass over 256x256 pixels, pixel index i = 256 y + x, writes r32ui targets:

- ``p0..p3``: packHalf2x16 of float32 bit patterns whose top 16 bits are i (every sign,
  exponent and top-7 mantissa bits) and whose low 16 bits sit on, just below and just above the
  rounding ties of normal halves, or are hashed; plus two fully hashed patterns;
- ``u0``, ``u1``: unpackHalf2x16 of every 16-bit code (low half i, high half i with the sign
  flipped), through floatBitsToUint;
- ``r0``, ``r1``: uintBitsToFloat / floatBitsToUint and the int forms round trip every bit
  pattern (NaN payloads and denormals included), vector forms included.

The float64 evaluation (``precision="f64"``) gives the same bits: a bit cast's float argument
is rounded to float32 first, its float result widened (exactly).
"""

from __future__ import annotations

import numpy as np
import pytest

from pipegen.compiler.driver import compile_source
from pipegen.reference import bitcasts as B
from pipegen.scene import default_scene

SRC = """
technique bitcasts "bit casts and half packing on every backend"
target p0 : r32ui clear 0
target p1 : r32ui clear 0
target p2 : r32ui clear 0
target p3 : r32ui clear 0
target u0 : r32ui clear 0
target u1 : r32ui clear 0
target r0 : r32ui clear 0
target r1 : r32ui clear 0
output p0
pass p {
  draw fullscreen
  writes p0, p1, p2, p3, u0, u1, r0, r1
  fragment {
    uint i = uint(frag_coord.y) * 256u + uint(frag_coord.x);
    uint h = i * 2654435761u;
    h = h ^ (h >> 15u);
    uint hi = i << 16u;
    p0 = packHalf2x16(vec2(uintBitsToFloat(hi | 0x1000u), uintBitsToFloat(hi | 0x0FFFu)));
    p1 = packHalf2x16(vec2(uintBitsToFloat(hi | 0x3000u), uintBitsToFloat(hi | (h & 0xFFFFu))));
    p2 = packHalf2x16(uintBitsToFloat(uvec2(hi | 0x1001u, hi)));
    p3 = packHalf2x16(uintBitsToFloat(uvec2(h, i)));
    vec2 u = unpackHalf2x16(i | ((i ^ 0x8000u) << 16u));
    u0 = floatBitsToUint(u.x);
    u1 = floatBitsToUint(u).y;
    vec3 v = uintBitsToFloat(uvec3(h, i, hi));
    r0 = floatBitsToUint(v).x ^ floatBitsToUint(v.y);
    r1 = uvec2(floatBitsToInt(intBitsToFloat(ivec2(int(h), 3)))).x;
  }
}
"""


def expected() -> dict:
    """The targets as the numpy model computes them (row = window y)."""
    i = np.arange(65536, dtype=np.uint32)
    h = i * np.uint32(2654435761)
    h ^= h >> 15
    hi = i << 16
    f = B.bits_float
    v = {
        "p0": B.pack_half2x16(f(hi | 0x1000), f(hi | 0x0FFF)),
        "p1": B.pack_half2x16(f(hi | 0x3000), f(hi | (h & 0xFFFF))),
        "p2": B.pack_half2x16(f(hi | 0x1001), f(hi)),
        "p3": B.pack_half2x16(f(h), f(i)),
        "u0": B.float_bits(B.unpack_half2x16(i | ((i ^ 0x8000) << 16))[:, 0]),
        "u1": B.float_bits(B.unpack_half2x16(i | ((i ^ 0x8000) << 16))[:, 1]),
        "r0": B.float_bits(f(h)) ^ i,
        "r1": h,
    }
    return {k: a.reshape(256, 256) for k, a in v.items()}


def test_model_on_known_values():
    """The model's rules, on hand-picked values (docs/language.md states them)."""
    x = np.array([1.0, -2.0, 65504.0, 65519.996, 65520.0, np.inf, 2.0 ** -14, 2.0 ** -24,
                  2.0 ** -25, 1.5 * 2.0 ** -25, 1.0 + 2.0 ** -11, 1.0 + 3 * 2.0 ** -11],
                 np.float32)
    want = [0x3C00, 0xC000, 0x7BFF, 0x7BFF, 0x7C00, 0x7C00, 0x0400, 0x0001, 0x0000, 0x0001,
            0x3C00, 0x3C02]
    assert [int(c) for c in B.half_bits(x)] == want
    nan = B.bits_float(np.array([0x7FC00000, 0xFF800001, 0x7FBFFFFF], np.uint32))
    assert [int(c) for c in B.half_bits(nan)] == [0x7FFF, 0xFFFF, 0x7FFF]
    assert B.pack_half2x16(np.float32(1.0), np.float32(-2.0)) == 0xC0003C00
    u = B.float_bits(B.unpack_half2x16(np.array([0x7C00FC00, 0x7E00FC01, 0x00010400], np.uint32)))
    assert [[int(a) for a in r] for r in u] == [[0xFF800000, 0x7F800000],
                                                [0xFFFFFFFF, 0x7FFFFFFF],
                                                [0x38800000, 0x33800000]]


def test_builtins_type_like_glsl():
    """Vector forms keep the size; packHalf2x16 takes a vec2; no implicit conversions."""
    from pipegen.ir import nodes as ir
    from pipegen.ir.builtins import resolve_builtin
    assert resolve_builtin("floatBitsToUint", [ir.VEC3]) == ir.Type(ir.Scalar.UINT, 3)
    assert resolve_builtin("floatBitsToInt", [ir.FLOAT]) == ir.INT
    assert resolve_builtin("uintBitsToFloat", [ir.UVEC4]) == ir.VEC4
    assert resolve_builtin("intBitsToFloat", [ir.Type(ir.Scalar.INT, 2)]) == ir.VEC2
    assert resolve_builtin("packHalf2x16", [ir.VEC2]) == ir.UINT
    assert resolve_builtin("unpackHalf2x16", [ir.UINT]) == ir.VEC2
    assert resolve_builtin("uintBitsToFloat", [ir.FLOAT]) is None
    assert resolve_builtin("packHalf2x16", [ir.VEC3]) is None
    assert resolve_builtin("unpackHalf2x16", [ir.INT]) is None


def test_emitted_text():
    """GLSL calls the builtins (the packing ones under GL_ARB_shading_language_packing, only in
    shaders that use them); OpenCL C reinterprets with as_* and packs with the program's own
    integer helpers; the float64 dialect rounds to float32 first."""
    c = compile_source(SRC)
    frag = c.plan("gl").passes[0].code.fragment
    assert "#extension GL_ARB_shading_language_packing : require" in frag.splitlines()[1]
    assert "packHalf2x16(" in frag and "floatBitsToInt(" in frag
    cl = c.plan("cl").passes[0].code.fragment
    assert "pg_pack_half2x16(" in cl and "as_uint3(" in cl and "as_float3(" in cl
    from pipegen.backends.opencl.emit import emit_cl
    f64 = emit_cl(c.technique, "f64").passes[0].code.fragment
    assert "convert_float2(" in f64 and "convert_double2(pg_unpack_half2x16(" in f64
    plain = compile_source("""
technique plain "bit casts without packing"
target a : r32ui clear 0
output a
pass p {
  draw fullscreen
  writes a
  fragment { a = floatBitsToUint(uintBitsToFloat(uint(frag_coord.x))); }
}
""")
    assert "#extension" not in plain.plan("gl").passes[0].code.fragment
    assert "pg_pack_half2x16" not in plain.plan("cl").passes[0].code.fragment


@pytest.fixture(scope="module")
def rendered():
    compiled = compile_source(SRC)
    scene = default_scene().with_size(256, 256)
    return compiled, scene


@pytest.mark.gl
@pytest.mark.cl
def test_gl_cl_and_numpy_agree_exactly(rendered):
    compiled, scene = rendered
    want = expected()
    for backend in ("gl", "cl"):
        got = compiled.pipeline(backend).render(scene)
        for name, w in want.items():
            g = np.asarray(got[name]).astype(np.uint32)
            bad = np.nonzero(g != w)
            assert not bad[0].size, (backend, name, [(hex(int(w[p])), hex(int(g[p])))
                                                     for p in zip(*bad)][:5])


@pytest.mark.cl
def test_float64_evaluation_gives_the_float32_bits(rendered):
    """precision="f64": bit casts see the float32 value (here every float is one), so the
    bits are the float32 evaluation's."""
    compiled, scene = rendered
    want = expected()
    got = compiled.pipeline("cl", precision="f64").render(scene)
    for name, w in want.items():
        assert np.array_equal(np.asarray(got[name]).astype(np.uint32), w), name


F64_ROUNDING = """
technique bitcasts64 "a double value is rounded to float32 before its bits are taken"
target a : r32ui clear 0
target b : r32ui clear 0
output a
pass p {
  draw fullscreen
  writes a, b
  fragment {
    float z = frag_coord.x * 0.0;
    a = floatBitsToUint(0.1 + z);
    b = packHalf2x16(vec2(1.0 + z + 0.00048828125 + 0.00000001, 65519.99 + z));
  }
}
"""


@pytest.mark.cl
def test_float64_rounds_to_float32_first():
    """In double, 1 + 2^-11 + 1e-8 is above the half tie, but its float32 is the tie itself
    (1 + 2^-11 exactly): rounded to float32 first, it packs to even (1.0), as float32 would."""
    compiled = compile_source(F64_ROUNDING)
    scene = default_scene().with_size(4, 2)
    got = compiled.pipeline("cl", precision="f64").render(scene)
    assert np.all(np.asarray(got["a"]).astype(np.uint32) == 0x3DCCCCCD)   # float32(0.1)
    x = np.float32(np.float64(1.0) + 0.00048828125 + 0.00000001)
    assert B.half_bits(x) == 0x3C00    # the tie, to even (double directly: 0x3C01)
    want = B.pack_half2x16(x, np.float32(65519.99))
    assert np.all(np.asarray(got["b"]).astype(np.uint32) == want)
