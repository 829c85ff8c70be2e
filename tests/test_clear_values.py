"""Clear values are normalised in one place, ``formats.Format.clear_*``: None -> zero, a scalar
-> every channel, short colours padded with zeros, long ones cut to the format's channels, then
quantised like a shader's output (uint formats: integer parts).  The GL runtime's clear words
(``gl_formats.clear_codes``) and the CL runtime's fill patterns (``TargetStore._fill``) are
built from them, so the two agree byte for byte."""

from __future__ import annotations

import math
import types

import numpy as np
import pytest

from pipegen.core import formats as F

NAN = float("nan")


def codes(name, color=None, depth=None):
    c = F.get(name).clear_codes(color, depth)
    assert c.dtype == F.get(name).dtype
    return c.tolist()


@pytest.mark.parametrize("name, color, channels", [
    ("rgba8", None, [0.0, 0.0, 0.0, 0.0]),
    ("rgba8", 0.25, [0.25, 0.25, 0.25, 0.25]),
    ("rgba8", (1, 0.5), [1.0, 0.5, 0.0, 0.0]),
    ("rgba8", (1, 2, 3, 4, 5), [1.0, 2.0, 3.0, 4.0]),
    ("rg16f", (0.1, 0.2, 0.3, 0.4), [0.1, 0.2]),
    ("r32ui", 7, [7.0]),
])
def test_clear_channels(name, color, channels):
    v = F.get(name).clear_channels(color)
    assert v.dtype == np.float64 and v.tolist() == channels


def test_clear_channels_keeps_nan_and_negative_zero():
    v = F.get("rgba32f").clear_channels((NAN, -0.0))
    assert math.isnan(v[0]) and math.copysign(1.0, v[1]) < 0 and v[2:].tolist() == [0, 0]


@pytest.mark.parametrize("name, color, expected", [
    ("rgba8", None, [0, 0, 0, 0]),
    ("rgba8", (1, 0.5), [255, 128, 0, 0]),          # 127.5 rounds half to even
    ("rgba8", 0.25, [64, 64, 64, 64]),
    ("rgba8", (-1, 2, NAN, 1), [0, 255, 0, 255]),   # clamped, NaN -> 0
    ("r8", (0.2, 0.9, 0.9, 0.9), [51]),             # cut to one channel
    ("rgb10a2", 1.0, [1023, 1023, 1023, 3]),
    ("rg8_snorm", (-2, NAN), [-128, -128]),         # 8-bit snorm saturates after rounding
    ("rg16_snorm", (-2, NAN), [-32767, -32767]),    # 16-bit snorm clamps first
    ("rgba8ui", (3, 200, 255.7), [3, 200, 255, 0]),
    ("r32ui", 4294967295.0, [4294967295]),
    ("rgba16f", (70000, -70000, 0.5), [65504, -65504, 0.5, 0]),   # toward zero
])
def test_clear_codes_colour(name, color, expected):
    assert codes(name, color) == expected


def test_clear_codes_depth_and_stencil():
    d24 = F.get("d24s8")
    assert codes("d24s8") == 0 and codes("d24s8", depth=1.0) == 16777215
    assert codes("d24s8", depth=0.5) == 8388608
    assert codes("d32f", depth=0.5) == 0.5 and codes("d32f", depth=2.0) == 1.0
    assert codes("d32f") == 0.0
    assert [d24.clear_stencil(s) for s in (None, 0, 255, 300)] == [0, 0, 255, 44]
    assert F.get("d24s8").clear_depth(None) == 0.0


def _cl_fill(fmt, color=None, depth=None, stencil=None, f64=False):
    """The byte patterns the CL runtime fills a target with (enqueue calls captured)."""
    cl = pytest.importorskip("pyopencl")
    from pipegen.runtime.cl import targets as CT
    log = []
    mp = pytest.MonkeyPatch()
    mp.setattr(cl, "enqueue_fill_buffer",
               lambda q, buf, pattern, offset, size: log.append((buf, np.asarray(pattern).tobytes())))
    mp.setattr(cl, "enqueue_copy",
               lambda q, buf, data: log.append((buf, np.asarray(data).tobytes())))
    try:
        store = object.__new__(CT.TargetStore)
        store.f64, store.queue, store._clear_patterns = f64, None, {}
        store._fill(types.SimpleNamespace(fmt=fmt), "buf", "sbuf", 1, color, depth, stencil,
                    True, True)
    finally:
        mp.undo()
    return dict(log)


@pytest.mark.parametrize("name", sorted(F.FORMATS))
def test_gl_and_cl_clear_the_same_bytes(name):
    from pipegen.runtime.gl import formats as GF
    fmt = F.get(name)
    if fmt.is_color:
        odd = 0.0 if fmt.is_integer else NAN     # (NaN has no integer part)
        for color in (None, 0.5, (0.2, 0.4), (1, -1, odd, 300), (3, 200, 255, 256)):
            assert _cl_fill(fmt, color)["buf"] == GF.clear_codes(name, color).tobytes()
            if not fmt.is_integer:     # the float64 evaluation: values, one per channel,
                f64 = np.frombuffer(_cl_fill(fmt, color, f64=True)["buf"], np.float64)
                assert len(f64) == fmt.channels
                # that read as the codes do (8-bit snorm: NaN is -1.0 here, code -128 there)
                assert np.array_equal(fmt.dequantize(fmt.quantize(f64)),
                                      fmt.dequantize(fmt.clear_codes(color)), equal_nan=True)
        return
    for depth, stencil in ((None, None), (1.0, 0), (0.5, 255), (1 / 3, 300)):
        cl = _cl_fill(fmt, depth=depth, stencil=stencil)
        gl = GF.clear_codes(name, depth=depth, stencil=stencil)
        if fmt.has_stencil:
            d, s = GF.split_depth_stencil(gl)
            assert cl["buf"] == d.tobytes() and cl["sbuf"] == s.tobytes()
        else:
            assert cl["buf"] == gl.tobytes()
