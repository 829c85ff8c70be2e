"""Render-target formats: the single source of truth.

Every consumer reads formats from here: the language front end (which names exist), the GL
runtime (``runtime/gl/formats.py`` derives GL's enums from a format's properties), the CL code
generator (storage, loads, stores and conversions, ``backends/opencl/formats.py``), the CL runtime
(``Format.pack``/``unpack``), the numpy oracle (quantize/dequantize) and the cross-backend
comparator (tolerances).  No other module names a format: adding one is a row in ``FORMATS``
(plus tests), as long as the backends already know its kind of storage and conversion
(``Encode``).

Arrays returned by a pipeline's ``render()`` hold *codes*: the integer values stored in the
target for fixed-point and integer formats, IEEE values for float formats.  ``dequantize``
turns codes into the floats a shader would read.
"""

from __future__ import annotations

import enum

from pipegen.core.records import record

# numpy is imported by the functions that compute with arrays, not here: compiling a technique
# reads formats but never needs numpy (tests/test_compile_imports.py).


class Kind(enum.Enum):
    UNORM = "unorm"
    SNORM = "snorm"
    FLOAT = "float"
    UINT = "uint"
    DEPTH = "depth"                  # depth-only (d32f)
    DEPTH_STENCIL = "depth_stencil"  # packed depth + 8-bit stencil (d24s8)


def stencil_mask(stencil_bits: int) -> int:
    """The bits of a stencil value an attachment of ``stencil_bits`` bits holds (GL masks
    stencil writes, references and clears to them)."""
    return (1 << stencil_bits) - 1


@record(frozen=True)
class Tolerance:
    """How far two backends may disagree on one channel of one pixel.

    ``units`` is "code" (integer code distance), "ulp" (distance in representable floats of the
    format) or "exact".  ``limit`` is the allowed distance in those units; ``abs_floor`` admits
    float values whose absolute difference is below it regardless of ulps (values near zero).
    """

    units: str
    limit: int
    abs_floor: float = 0.0


class Encode(enum.Enum):
    """How a shader's float output becomes a fixed-point code (llvmpipe, measured on Mesa 22.3;
    the CL backend and ``Format.quantize`` reproduce it).

    ``ROUND``: clamp to the format's range ([0, 1] or [-1, 1]; NaN -> the low end), multiply
    by the largest code in float32, round half to even.
    ``ROUND_SAT``: multiply by the largest code in float32, round half to even, saturate to
    the code range (NaN -> the lowest code): 8-bit snorm reaches -128 from values below -1
    (measured; 16-bit snorm clamps to -32767 instead, ``ROUND``).
    ``UNORM16``: llvmpipe's 16-bit blend type: the low 16 mantissa bits of
    ``clamp(x, 0, 1) * (65535/65536) + 128`` (two float32 roundings; the same codes as
    ``ROUND`` for 16-bit channels), then each narrower channel scaled down with Mesa's
    ``scale_bits`` (lp_state_fs.c; ``scale_bits16``).
    """

    ROUND = "round"
    ROUND_SAT = "round_sat"
    UNORM16 = "unorm16"


@record(frozen=True)
class Format:
    """One render-target format: everything a backend, the oracle or the comparator needs.

    ``bits``: bits per colour channel (depth formats: ``(depth_bits,)``); ``kind``: how the
    codes are read; ``encode``: how a float becomes a code (fixed-point kinds); ``word_bits``:
    0 when each channel is an element of its own, else the width of the one word the channels
    are packed into, channel 0 in the low bits (GL's ``*_REV`` packed types, e.g. rgb10a2's
    10/10/10/2 bits in a 32-bit word).  Everything else is derived from these.
    """

    name: str
    kind: Kind
    bits: tuple[int, ...]           # bits per colour channel (depth formats: (depth_bits,))
    stencil_bits: int = 0
    encode: Encode = Encode.ROUND   # float -> code (UNORM / SNORM)
    word_bits: int = 0              # channels packed into one word of this width (0: not packed)

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
    def is_normalized(self) -> bool:
        """Fixed-point colour formats: codes stand for values in [0, 1] (unorm) or [-1, 1]."""
        return self.kind in (Kind.UNORM, Kind.SNORM)

    @property
    def is_signed(self) -> bool:
        return self.kind is Kind.SNORM

    @property
    def blendable(self) -> bool:
        """Whether pipegen lets a pass blend into this format.  snorm is not blendable: what
        llvmpipe computes for it is not modelled (measured on Mesa 22.3: up to 123 codes from
        the spec's float formula with SRC_ALPHA factors), so it could not be cross-checked."""
        return self.kind in (Kind.UNORM, Kind.FLOAT)

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

    @property
    def max_codes(self) -> tuple[int, ...]:
        """The code of 1.0 per channel (unorm, snorm, the depth of d24s8): 2^b - 1, snorm
        2^(b-1) - 1 (its codes run from -max - 1, which also reads as -1.0, to max)."""
        assert self.is_normalized or self.kind is Kind.DEPTH_STENCIL, self.name
        if self.kind is Kind.SNORM:
            return tuple((1 << (b - 1)) - 1 for b in self.bits)
        return tuple((1 << b) - 1 for b in self.bits)

    # -- storage -----------------------------------------------------------------------------
    @property
    def packed(self) -> bool:
        return self.word_bits > 0

    @property
    def shifts(self) -> tuple[int, ...]:
        """Bit offset of each channel in the packed word (channel 0 in the low bits)."""
        return tuple(sum(self.bits[:k]) for k in range(self.channels))

    @property
    def element_dtype(self) -> np.dtype:
        """dtype of one stored element: the packed word, or one channel's code."""
        import numpy as np
        return np.dtype(self.element_dtype_name)

    @property
    def element_dtype_name(self) -> str:
        """numpy's name of ``element_dtype`` (``uint32``), known without importing numpy."""
        if self.packed:
            return f"uint{self.word_bits}"
        return self.dtype_name

    @property
    def elements(self) -> int:
        """Stored elements per pixel (1 for packed formats)."""
        return 1 if self.packed else self.channels

    def pack(self, codes: np.ndarray) -> np.ndarray:
        """Codes ``(..., C)`` (single channel: ``(...)``) -> stored elements: one word per
        pixel for packed formats, else the codes themselves in ``dtype``."""
        import numpy as np
        c = np.asarray(codes)
        if not self.packed:
            return np.ascontiguousarray(c.astype(self.dtype))
        w = self.element_dtype
        c = c.astype(np.uint64)
        word = np.zeros(c.shape[:-1], np.uint64)
        for k, (b, s) in enumerate(zip(self.bits, self.shifts)):
            word |= (c[..., k] & np.uint64((1 << b) - 1)) << np.uint64(s)
        return word.astype(w)

    def unpack(self, words: np.ndarray) -> np.ndarray:
        """Stored elements -> codes (inverse of ``pack``)."""
        import numpy as np
        w = np.asarray(words)
        if not self.packed:
            return w
        # in the word's own unsigned type (a field never reaches past the word), each
        # channel written straight into the result
        w = w.astype(np.dtype(w.dtype.str.replace("i", "u")), copy=False)
        out = np.empty(w.shape + (len(self.bits),), self.dtype)
        for k, (b, s) in enumerate(zip(self.bits, self.shifts)):
            out[..., k] = (w >> w.dtype.type(s)) & w.dtype.type((1 << b) - 1)
        return out

    # -- numpy storage ---------------------------------------------------------------------
    @property
    def dtype(self) -> np.dtype:
        """dtype of the arrays that hold this target's codes after readback."""
        import numpy as np
        return np.dtype(self.dtype_name)

    @property
    def dtype_name(self) -> str:
        """numpy's name of ``dtype`` (``uint8``, ``float16``), known without importing numpy."""
        b = max(self.bits)
        if self.kind is Kind.FLOAT:
            return "float16" if b == 16 else "float32"
        if self.kind is Kind.DEPTH:
            return "float32"
        if self.kind is Kind.DEPTH_STENCIL:
            return "uint32"
        size = 8 if b <= 8 else 16 if b <= 16 else 32
        return f"{'int' if self.kind is Kind.SNORM else 'uint'}{size}"

    def array_shape(self, width: int, height: int) -> tuple[int, ...]:
        return (height, width) if self.channels == 1 else (height, width, self.channels)

    # -- conversions (the numpy oracle's view of the format) ------------------------------
    def _per_channel(self, values: tuple[int, ...]):
        """A per-channel constant, shaped for arrays with (or, single channel, without) a
        trailing channel axis."""
        import numpy as np
        return values[0] if self.channels == 1 or len(set(values)) == 1 else np.array(values)

    def quantize(self, x: np.ndarray) -> np.ndarray:
        """Shader output value(s) -> stored codes, following the conversions measured on
        llvmpipe (which the CL backend reproduces):

        - unorm and snorm: as ``encode`` says (``Encode``): clamp to [0, 1] / [-1, 1] (NaN ->
          the low end), multiply by the largest code in float32, round half to even; 8-bit
          snorm saturates after rounding instead (-128 below -1); rgb10a2 through llvmpipe's
          16-bit path;
        - float16: finite values clamp to ±65504 and round toward zero (70000 -> 65504);
          ±inf and NaN are kept, half denormals too;
        - float32 / d32f: stored as float32 with denormals flushed (CL builds with
          -cl-denorms-are-zero; llvmpipe flushes);
        - d24: ``rint(float32(z) * 16777215.0f)`` in float32.
        """
        import numpy as np
        x = np.asarray(x, dtype=np.float64)
        if self.is_normalized or self.kind is Kind.DEPTH_STENCIL:
            lo = -1.0 if self.is_signed else 0.0
            if self.encode is Encode.ROUND_SAT:
                top = np.asarray(self._per_channel(self.max_codes), dtype=np.float32)
                with np.errstate(over="ignore", invalid="ignore"):
                    y = np.rint(x.astype(np.float32) * top)
                low = -top - 1 if self.is_signed else np.zeros_like(top)
                y = np.where(np.isnan(y), low, np.clip(y, low, top))
                return y.astype(self.dtype)
            clamped = np.clip(np.nan_to_num(x, nan=lo), lo, 1.0).astype(np.float32)
            if self.encode is Encode.UNORM16:
                c16 = unorm16_codes(clamped)
                return scale_bits16(c16, self._per_channel(self.bits)).astype(self.dtype)
            scale = np.asarray(self._per_channel(self.max_codes), dtype=np.float32)
            return np.rint(clamped * scale).astype(self.dtype)
        if self.kind is Kind.FLOAT and self.dtype == np.float16:
            return half_toward_zero(x)
        if self.kind in (Kind.FLOAT, Kind.DEPTH):
            y = x.astype(np.float32)
            if self.kind is Kind.DEPTH:      # float32 bounds: numpy 1.x widens 0-d arrays
                y = np.clip(y, np.float32(0.0), np.float32(1.0))
            return flush_denormals(y)
        if self.kind is Kind.UINT:
            return np.asarray(x).astype(np.uint64).astype(self.dtype)
        raise AssertionError(self.kind)

    def dequantize(self, codes: np.ndarray) -> np.ndarray:
        """Stored codes -> the float value a shader reads (float64)."""
        import numpy as np
        c = np.asarray(codes)
        if self.is_normalized or self.kind is Kind.DEPTH_STENCIL:
            scale = np.asarray(self._per_channel(self.max_codes), dtype=np.float64)
            v = c.astype(np.float64) / scale
            return np.maximum(v, -1.0) if self.is_signed else v
        return c.astype(np.float64)

    # -- clears (both runtimes normalise a clear value here) ------------------------------
    def clear_channels(self, color=None) -> np.ndarray:
        """A clear colour -> float64 values of this format's channels: None -> zeros, a scalar
        -> every channel, a shorter sequence padded with zeros, a longer one cut."""
        import numpy as np
        col = np.zeros(4) if color is None else np.asarray(color, np.float64)
        if col.ndim == 0:
            col = np.full(4, float(col))
        return np.concatenate([col, np.zeros(4)])[:4][:self.channels]

    @staticmethod
    def clear_depth(depth=None) -> np.float64:
        """A clear depth -> the float64 depth value (None -> 0.0), not yet quantised."""
        import numpy as np
        return np.float64(depth if depth is not None else 0.0)

    def clear_stencil(self, stencil=None) -> int:
        """A clear stencil -> the stencil code (None -> 0, cut to ``stencil_bits``)."""
        return int(stencil or 0) & stencil_mask(self.stencil_bits)

    def clear_codes(self, color=None, depth=None) -> np.ndarray:
        """The codes of one pixel cleared to ``color`` (colour formats: ``(channels,)`` in
        ``dtype``; uint formats take the values' integer parts) or ``depth`` (depth formats: a
        0-d array, d24s8's depth code alone: ``clear_stencil`` gives the stencil)."""
        if self.has_depth:
            return self.quantize(self.clear_depth(depth))
        return self.quantize(self.clear_channels(color))

    @staticmethod
    def clear_key(color=None, depth=None, stencil=None) -> tuple:
        """A clear value as a dict key (colour: None, a scalar or a sequence): both runtimes
        keep the words they clear with per format and value, cleared again every frame."""
        import numpy as np
        return (None if color is None else tuple(np.ravel(color).tolist()), depth, stencil)

    def tolerance(self, blended_passes: int = 0) -> Tolerance:
        """The limit two float32 renderings of this format may differ by (docs/tolerances.md).

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


def unorm16_codes(x: np.ndarray) -> np.ndarray:
    """llvmpipe's float -> 16-bit unorm conversion (lp_bld_conv.c,
    lp_build_clamped_float_to_unsigned_norm): the low 16 mantissa bits of
    ``x * (65535/65536) + 128`` in float32, ``x`` already clamped to [0, 1] (uint32 codes)."""
    import numpy as np
    f32 = np.float32
    y = (np.asarray(x, f32) * f32(65535 / 65536)).astype(f32) + f32(128.0)
    return np.ascontiguousarray(y.astype(f32)).view(np.uint32) & np.uint32(0xFFFF)


def scale_bits16(c16: np.ndarray, bits) -> np.ndarray:
    """16-bit codes -> ``bits``-bit codes as Mesa's ``scale_bits`` (lp_state_fs.c) narrows
    them: ``c >> (16 - b)`` when ``16 - b <= b`` (truncating: "wrong rounding" in Mesa's
    words), else ``((c >> b) * (2^b - 1) + 2^(15 - b)) >> (16 - b)``.  ``bits`` is an int or
    an array broadcast against ``c16``'s last axis."""
    import numpy as np
    c = np.asarray(c16).astype(np.int64)
    b = np.asarray(bits, np.int64)
    d = 16 - b
    shifted = c >> d
    rounded = ((c >> b) * ((1 << b) - 1) + (1 << np.maximum(d - 1, 0))) >> d
    return np.where(d <= b, shifted, rounded)


def half_toward_zero(x: np.ndarray) -> np.ndarray:
    """float -> float16 rounding toward zero, finite values clamped to ±65504 (llvmpipe's
    rgba16f store)."""
    import numpy as np
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
    import numpy as np
    x = np.asarray(x)
    if x.dtype.kind != "f":
        return x
    tiny = np.finfo(x.dtype).tiny
    with np.errstate(invalid="ignore"):
        sub = (x != 0) & (np.abs(x) < tiny)
    return np.where(sub, np.copysign(np.zeros_like(x), x), x)


U, S, FL, UI = Kind.UNORM, Kind.SNORM, Kind.FLOAT, Kind.UINT

# THE table.  A new format is one row here (plus tests); the backends derive the rest
# (runtime/gl/formats.py GL's spelling, backends/opencl/formats.py the OpenCL storage and
# conversions).
FORMATS: dict[str, Format] = {
    f.name: f
    for f in [
        Format("r8", U, (8,)),
        Format("rg8", U, (8, 8)),
        Format("rgba8", U, (8, 8, 8, 8)),
        Format("r16", U, (16,), encode=Encode.UNORM16),
        Format("rg16", U, (16, 16), encode=Encode.UNORM16),
        Format("rgba16", U, (16, 16, 16, 16), encode=Encode.UNORM16),
        Format("r16f", FL, (16,)),
        Format("rg16f", FL, (16, 16)),
        Format("rgba16f", FL, (16, 16, 16, 16)),
        Format("r32f", FL, (32,)),
        Format("rg32f", FL, (32, 32)),
        Format("rgba32f", FL, (32, 32, 32, 32)),
        Format("r32ui", UI, (32,)),
        Format("rgba8ui", UI, (8, 8, 8, 8)),
        Format("rgb10a2", U, (10, 10, 10, 2), encode=Encode.UNORM16, word_bits=32),
        Format("rg8_snorm", S, (8, 8), encode=Encode.ROUND_SAT),
        Format("rgba8_snorm", S, (8, 8, 8, 8), encode=Encode.ROUND_SAT),
        Format("rg16_snorm", S, (16, 16)),
        Format("d24s8", Kind.DEPTH_STENCIL, (24,), stencil_bits=8),
        Format("d32f", Kind.DEPTH, (32,)),
    ]
}
del U, S, FL, UI


def get(name: str) -> Format:
    return FORMATS[name]
