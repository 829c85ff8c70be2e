"""numpy models of the language's bit casts and half packing, as llvmpipe computes them
(measured on Mesa 22.3 llvmpipe; tests/test_bitcasts.py checks GL, CL and these agree bit for
bit; docs/language.md, "Bit casts and half packing").

- ``floatBitsToUint`` / ``uintBitsToFloat`` (and the int forms) reinterpret the 32 bits;
  nothing is flushed or canonicalised (denormals and NaN payloads pass through).
- ``packHalf2x16(v)``: each component rounded to half with round-to-nearest-even; |x| >= 65520
  (and inf) becomes +-inf, values below 2^-14 become half denormals (2^-25 and below: +-0,
  a tie rounds to even), a NaN becomes ``sign | 0x7fff`` whatever its payload; ``v.x`` in the
  low 16 bits.
- ``unpackHalf2x16(u)``: exact (half denormals become normal float32 values), except that a half
  NaN becomes the float32 ``sign | 0x7fffffff``; the low 16 bits are ``.x``.
"""

from __future__ import annotations

import numpy as np


def float_bits(x) -> np.ndarray:
    """floatBitsToUint: the float32 bits of ``x`` (float32; float64 values are rounded)."""
    return np.ascontiguousarray(np.asarray(x, np.float32)).view(np.uint32)


def bits_float(u) -> np.ndarray:
    """uintBitsToFloat: float32 values with bits ``u``."""
    return np.ascontiguousarray(np.asarray(u, np.uint32)).view(np.float32)


def half_bits(x) -> np.ndarray:
    """The 16-bit code (as uint32) packHalf2x16 gives one float32 component."""
    f = np.asarray(x, np.float32)
    with np.errstate(all="ignore"):
        h = f.astype(np.float16).view(np.uint16).astype(np.uint32)   # round to nearest even
    nan = np.isnan(f)
    sign = (float_bits(f) >> 16) & 0x8000
    return np.where(nan, sign | 0x7FFF, h).astype(np.uint32)


def pack_half2x16(x, y) -> np.ndarray:
    """packHalf2x16(vec2(x, y)): x in the low half."""
    return half_bits(x) | (half_bits(y) << 16)


def half_value(h) -> np.ndarray:
    """float32 values of 16-bit codes as unpackHalf2x16 gives them (NaN -> sign | 0x7fffffff)."""
    h = np.asarray(h, np.uint32) & 0xFFFF
    f = float_bits(h.astype(np.uint16).view(np.float16).astype(np.float32)).copy()
    nan = ((h & 0x7C00) == 0x7C00) & ((h & 0x3FF) != 0)
    f[nan] = ((h[nan] & 0x8000) << 16) | 0x7FFFFFFF
    return bits_float(f)


def unpack_half2x16(u) -> np.ndarray:
    """unpackHalf2x16(u): (..., 2) float32, ``[..., 0]`` from the low 16 bits."""
    u = np.asarray(u, np.uint32)
    return np.stack([half_value(u & 0xFFFF), half_value(u >> 16)], axis=-1)
