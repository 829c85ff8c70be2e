"""``formats.Format`` describes its storage (bits, kind, packing, conversions, dtype) and the
backends derive everything from that: GL's enums (``runtime/gl/formats.py``), OpenCL's buffer
layout and conversions (``backends/opencl/formats.cl_format``), the CL runtime's packing."""

from __future__ import annotations

import numpy as np
import pytest

from pipegen.core import formats as F

RNG = np.random.default_rng(7)


def _codes(f: F.Format, n: int = 1000) -> np.ndarray:
    lo = -(1 << (max(f.bits) - 1)) if f.is_signed else 0
    hi = (1 << (max(f.bits) - 1)) - 1 if f.is_signed else (1 << max(f.bits)) - 1
    c = np.stack([RNG.integers(lo >> (max(f.bits) - b), (hi >> (max(f.bits) - b)) + 1, n)
                  for b in f.bits], -1).astype(f.dtype)
    return c[..., 0] if f.channels == 1 else c


@pytest.mark.parametrize("name", [n for n, f in F.FORMATS.items() if f.is_color])
def test_pack_unpack_round_trip(name):
    f = F.get(name)
    if f.kind is F.Kind.FLOAT:
        return
    c = _codes(f)
    words = f.pack(c)
    assert words.dtype == f.element_dtype
    assert words.shape == (c.shape if not f.packed else c.shape[:-1])
    np.testing.assert_array_equal(f.unpack(words), c)


def test_packed_layout_is_gl_rev_order():
    """rgb10a2: R in bits 0-9, G 10-19, B 20-29, A 30-31 (GL_UNSIGNED_INT_2_10_10_10_REV)."""
    f = F.get("rgb10a2")
    assert f.packed and f.shifts == (0, 10, 20, 30) and f.element_dtype == np.uint32
    assert int(f.pack(np.array([1, 2, 3, 1]))) == 1 | 2 << 10 | 3 << 20 | 1 << 30
    assert f.dtype == np.uint16 and f.bytes_per_pixel == 4


def test_rgb10a2_quantize_is_llvmpipes_16_bit_path():
    """The 16-bit code, then Mesa's scale_bits (measured, tests/test_cl_raster.py)."""
    f32 = np.float32
    x = RNG.uniform(-0.2, 1.2, (4000, 4))
    c = np.clip(np.nan_to_num(x.astype(f32), nan=0.0), 0, 1).astype(f32)
    c16 = ((c * f32(65535 / 65536)).astype(f32) + f32(128)).astype(f32).view(np.uint32) & 0xFFFF
    want = c16 >> 6
    want[..., 3] = ((c16[..., 3] >> 2) * 3 + 8192) >> 14
    np.testing.assert_array_equal(F.get("rgb10a2").quantize(x), want)
    assert F.get("rgb10a2").quantize(np.array([0.6710101] * 4))[0] == 687   # rint gives 686


def test_unorm16_path_equals_round_half_even_for_16_bits():
    """The two float32 roundings of llvmpipe's 16-bit conversion give rint(x * 65535)."""
    k = np.arange(65535)
    ties = ((k + 0.5) / 65535).astype(np.float32)
    x = np.concatenate([ties, np.nextafter(ties, np.float32(2)), np.nextafter(ties, np.float32(-1)),
                        RNG.uniform(-0.1, 1.1, 100000).astype(np.float32)])
    want = np.rint(np.clip(x, 0, 1).astype(np.float32) * np.float32(65535))
    np.testing.assert_array_equal(F.get("r16").quantize(x), want)


def test_scale_bits16():
    c = np.arange(65536)
    assert (F.scale_bits16(c, 16) == c).all()
    assert (F.scale_bits16(c, 10) == c >> 6).all()
    assert (F.scale_bits16(c, 2) == ((c >> 2) * 3 + 8192) >> 14).all()


def test_opencl_layouts_are_derived():
    from pipegen.backends.opencl.formats import cl_format
    for name, f in F.FORMATS.items():
        d = cl_format(name)
        assert d["storage"] and d["load"] and d["store"] and d["name"] == name
        assert d["np"] == f.element_dtype.name
    d = cl_format("rgb10a2")
    assert d["load"] == ("(uint4)(b[i] & 1023u, (b[i] >> 10) & 1023u, (b[i] >> 20) & 1023u, "
                         "b[i] >> 30)")
    assert d["store"] == ("b[i] = (r.x & 1023u) | ((r.y & 1023u) << 10) | ((r.z & 1023u) << 20) "
                          "| (r.w << 30);")
    assert d["code"] == "pg_rgb10a2_code4"


def test_opencl_prelude_conversions_follow_the_table():
    from pipegen.backends.opencl.formats import scaled16_conversions
    (conv,) = scaled16_conversions()
    assert conv["name"] == "rgb10a2"
    assert conv["expr"] == "c.xyz >> 6, ((c.w >> 2) * 3u + 8192u) >> 14"


GL_SPELLING = {   # format -> (internal format, transfer format, transfer type)
    "r8": ("GL_R8", "GL_RED", "GL_UNSIGNED_BYTE"),
    "rg8": ("GL_RG8", "GL_RG", "GL_UNSIGNED_BYTE"),
    "rgba8": ("GL_RGBA8", "GL_RGBA", "GL_UNSIGNED_BYTE"),
    "r16": ("GL_R16", "GL_RED", "GL_UNSIGNED_SHORT"),
    "rg16": ("GL_RG16", "GL_RG", "GL_UNSIGNED_SHORT"),
    "rgba16": ("GL_RGBA16", "GL_RGBA", "GL_UNSIGNED_SHORT"),
    "r16f": ("GL_R16F", "GL_RED", "GL_HALF_FLOAT"),
    "rg16f": ("GL_RG16F", "GL_RG", "GL_HALF_FLOAT"),
    "rgba16f": ("GL_RGBA16F", "GL_RGBA", "GL_HALF_FLOAT"),
    "r32f": ("GL_R32F", "GL_RED", "GL_FLOAT"),
    "rg32f": ("GL_RG32F", "GL_RG", "GL_FLOAT"),
    "rgba32f": ("GL_RGBA32F", "GL_RGBA", "GL_FLOAT"),
    "r32ui": ("GL_R32UI", "GL_RED_INTEGER", "GL_UNSIGNED_INT"),
    "rgba8ui": ("GL_RGBA8UI", "GL_RGBA_INTEGER", "GL_UNSIGNED_BYTE"),
    "rgb10a2": ("GL_RGB10_A2", "GL_RGBA", "GL_UNSIGNED_INT_2_10_10_10_REV"),
    "rg8_snorm": ("GL_RG8_SNORM", "GL_RG", "GL_BYTE"),
    "rgba8_snorm": ("GL_RGBA8_SNORM", "GL_RGBA", "GL_BYTE"),
    "rg16_snorm": ("GL_RG16_SNORM", "GL_RG", "GL_SHORT"),
    "d24s8": ("GL_DEPTH24_STENCIL8", "GL_DEPTH_STENCIL", "GL_UNSIGNED_INT_24_8"),
    "d32f": ("GL_DEPTH_COMPONENT32F", "GL_DEPTH_COMPONENT", "GL_FLOAT"),
}


def test_gl_spelling_is_derived_from_properties():
    pytest.importorskip("OpenGL")
    try:
        from pipegen.runtime.gl import formats as GF
        from pipegen.runtime.gl.context import GL
    except Exception as exc:   # pragma: no cover - no EGL platform
        pytest.skip(f"PyOpenGL unavailable: {exc}")
    assert set(GL_SPELLING) == set(F.FORMATS)
    for name, (internal, fmt, typ) in GL_SPELLING.items():
        g = GF.gl_format(name)
        assert (g.internal, g.format, g.type) == (getattr(GL, internal), getattr(GL, fmt),
                                                 getattr(GL, typ)), name
        assert g.sampler == ("usampler2D" if F.get(name).is_integer else "sampler2D")
