"""Render-target formats: the single source of truth.

Every consumer reads formats from here: the language front end (which names exist), the GL
backend (its own table maps a format *name* to GL enums), the CL code generator (store/convert
code), the numpy oracle (quantize/dequantize) and the cross-backend comparator (tolerances).

Arrays returned by a pipeline's ``render()`` hold *codes*: the integer values stored in the
target for fixed-point and integer formats, IEEE values for float formats.  ``dequantize``
turns codes into the floats a shader would read.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np


class Kind(enum.Enum):
    UNORM = "unorm"
    SNORM = "snorm"
    FLOAT = "float"
    UINT = "uint"
    DEPTH = "depth"                  # depth-only (d32f)
    DEPTH_STENCIL = "depth_stencil"  # packed depth + 8-bit stencil (d24s8)


@dataclass(frozen=True)
class Tolerance:
    """How far two backends may disagree on one channel of one pixel.

    ``units`` is "code" (integer code distance), "ulp" (distance in representable floats of the
    format) or "exact".  ``limit`` is the allowed distance in those units; ``abs_floor`` admits
    float values whose absolute difference is below it regardless of ulps (values near zero).
    """

    units: str
    limit: int
    abs_floor: float = 0.0


@dataclass(frozen=True)
class Format:
    name: str
    kind: Kind
    bits: tuple[int, ...]           # bits per colour channel (depth formats: (depth_bits,))
    stencil_bits: int = 0

    # -- shape -----------------------------------------------------------------------------
    @property
    def channels(self) -> int:
        return len(self.bits)

    @property
    def bytes_per_pixel(self) -> int:
        return (sum(self.bits) + self.stencil_bits + 7) // 8

    @property
    def is_color(self) -> bool:
        return self.kind not in (Kind.DEPTH, Kind.DEPTH_STENCIL)

    @property
    def has_depth(self) -> bool:
        return not self.is_color

    @property
    def has_stencil(self) -> bool:
        return self.stencil_bits > 0

    @property
    def is_integer(self) -> bool:
        """Integer formats are written with uint values and never blended."""
        return self.kind is Kind.UINT

    @property
    def blendable(self) -> bool:
        return self.kind in (Kind.UNORM, Kind.SNORM, Kind.FLOAT)

    @property
    def blend_is_exact(self) -> bool:
        """Whether blending into this format can be bit-exact (bit-plane packing needs it).

        Only 8-bit unorm is: 16-bit unorm blending goes through float on llvmpipe, and float
        formats round products of arbitrary constants.
        """
        return self.kind is Kind.UNORM and all(b == 8 for b in self.bits)

    @property
    def max_code(self) -> int:
        assert self.kind in (Kind.UNORM, Kind.UINT, Kind.DEPTH_STENCIL)
        return (1 << max(self.bits)) - 1

    # -- numpy storage ---------------------------------------------------------------------
    @property
    def dtype(self) -> np.dtype:
        """dtype of the arrays that hold this target's codes after readback."""
        b = max(self.bits)
        if self.kind is Kind.FLOAT:
            return np.dtype(np.float16 if b == 16 else np.float32)
        if self.kind is Kind.DEPTH:
            return np.dtype(np.float32)
        if self.kind is Kind.SNORM:
            return np.dtype({8: np.int8, 16: np.int16}[b])
        if self.kind is Kind.DEPTH_STENCIL:
            return np.dtype(np.uint32)
        return np.dtype({8: np.uint8, 10: np.uint16, 16: np.uint16, 32: np.uint32}[b])

    def array_shape(self, width: int, height: int) -> tuple[int, ...]:
        return (height, width) if self.channels == 1 else (height, width, self.channels)

    # -- conversions (the numpy oracle's view of the format) ------------------------------
    def quantize(self, x: np.ndarray) -> np.ndarray:
        """Shader output value(s) -> stored codes, following the conversions measured on
        llvmpipe (which the CL backend reproduces):

        - unorm: clamp to [0,1], multiply by 2^b-1 in float32, round half to even; NaN -> 0;
        - float16: finite values clamp to ±65504 and round toward zero (70000 -> 65504);
          ±inf and NaN are kept, half denormals too;
        - float32 / d32f: stored as float32 with denormals flushed (CL builds with
          -cl-denorms-are-zero; llvmpipe flushes);
        - d24: ``rint(float32(z) * 16777215.0f)`` in float32.
        """
        x = np.asarray(x, dtype=np.float64)
        if self.kind in (Kind.UNORM, Kind.DEPTH_STENCIL):
            scale = np.array([(1 << b) - 1 for b in self.bits], dtype=np.float32)
            if self.kind is Kind.DEPTH_STENCIL or self.channels == 1:
                scale = scale[0]
            clamped = np.clip(np.nan_to_num(x, nan=0.0), 0.0, 1.0).astype(np.float32)
            return np.rint(clamped * scale).astype(self.dtype)
        if self.kind is Kind.SNORM:
            scale = np.float32((1 << (max(self.bits) - 1)) - 1)
            clamped = np.clip(np.nan_to_num(x, nan=0.0), -1.0, 1.0).astype(np.float32)
            return np.rint(clamped * scale).astype(self.dtype)
        if self.kind is Kind.FLOAT and self.dtype == np.float16:
            return half_toward_zero(x)
        if self.kind in (Kind.FLOAT, Kind.DEPTH):
            y = x.astype(np.float32)
            if self.kind is Kind.DEPTH:
                y = np.clip(y, 0.0, 1.0)
            return flush_denormals(y)
        if self.kind is Kind.UINT:
            return np.asarray(x).astype(np.uint64).astype(self.dtype)
        raise AssertionError(self.kind)

    def dequantize(self, codes: np.ndarray) -> np.ndarray:
        """Stored codes -> the float value a shader reads (float64)."""
        c = np.asarray(codes)
        if self.kind in (Kind.UNORM, Kind.DEPTH_STENCIL):
            scale = np.array([(1 << b) - 1 for b in self.bits], dtype=np.float64)
            if self.kind is Kind.DEPTH_STENCIL or self.channels == 1:
                scale = scale[0]
            return c.astype(np.float64) / scale
        if self.kind is Kind.SNORM:
            scale = float((1 << (max(self.bits) - 1)) - 1)
            return np.maximum(c.astype(np.float64) / scale, -1.0)
        return c.astype(np.float64)

    def tolerance(self, blended_passes: int = 0) -> Tolerance:
        """Cross-backend tolerance for this format (DESIGN.md §7).

        ``blended_passes`` is the number of passes that blend into the target: each blend step
        may round differently on the two backends.
        """
        p = blended_passes
        if self.kind in (Kind.UNORM, Kind.SNORM):
            return Tolerance("code", 1 + p)
        if self.kind is Kind.FLOAT and max(self.bits) == 16:
            return Tolerance("ulp", 1 + p, abs_floor=2.0 ** -14)
        if self.kind is Kind.FLOAT:
            return Tolerance("ulp", 8 + 4 * p, abs_floor=1e-6)
        if self.kind is Kind.DEPTH_STENCIL:
            return Tolerance("code", 2)
        if self.kind is Kind.DEPTH:
            return Tolerance("ulp", 4)
        return Tolerance("exact", 0)


def half_toward_zero(x: np.ndarray) -> np.ndarray:
    """float -> float16 rounding toward zero, finite values clamped to ±65504 (llvmpipe's
    rgba16f store)."""
    f = np.asarray(x, dtype=np.float32)
    finite = np.isfinite(f)
    f = np.where(finite, np.clip(f, -65504.0, 65504.0), f)
    with np.errstate(over="ignore", invalid="ignore"):
        h = f.astype(np.float16)
        overshoot = finite & (np.abs(h.astype(np.float32)) > np.abs(f))
    toward_zero = np.nextafter(h, np.zeros_like(h))
    return np.where(overshoot, toward_zero, h)


def flush_denormals(x: np.ndarray) -> np.ndarray:
    """Flush subnormal floats to (signed) zero, as llvmpipe does and CL does under
    ``-cl-denorms-are-zero``."""
    x = np.asarray(x)
    if x.dtype.kind != "f":
        return x
    tiny = np.finfo(x.dtype).tiny
    with np.errstate(invalid="ignore"):
        sub = (x != 0) & (np.abs(x) < tiny)
    return np.where(sub, np.copysign(np.zeros_like(x), x), x)


def _f(name: str, kind: Kind, bits: tuple[int, ...], stencil: int = 0) -> Format:
    return Format(name, kind, bits, stencil)


FORMATS: dict[str, Format] = {
    f.name: f
    for f in [
        _f("r8", Kind.UNORM, (8,)),
        _f("rg8", Kind.UNORM, (8, 8)),
        _f("rgba8", Kind.UNORM, (8, 8, 8, 8)),
        _f("r16", Kind.UNORM, (16,)),
        _f("rg16", Kind.UNORM, (16, 16)),
        _f("rgba16", Kind.UNORM, (16, 16, 16, 16)),
        _f("r16f", Kind.FLOAT, (16,)),
        _f("rg16f", Kind.FLOAT, (16, 16)),
        _f("rgba16f", Kind.FLOAT, (16, 16, 16, 16)),
        _f("r32f", Kind.FLOAT, (32,)),
        _f("rg32f", Kind.FLOAT, (32, 32)),
        _f("rgba32f", Kind.FLOAT, (32, 32, 32, 32)),
        _f("r32ui", Kind.UINT, (32,)),
        _f("rgba8ui", Kind.UINT, (8, 8, 8, 8)),
        _f("rgb10a2", Kind.UNORM, (10, 10, 10, 2)),
        _f("d24s8", Kind.DEPTH_STENCIL, (24,), stencil=8),
        _f("d32f", Kind.DEPTH, (32,)),
    ]
}


def get(name: str) -> Format:
    return FORMATS[name]
