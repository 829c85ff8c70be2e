"""``intensity_planes``: a [0,1] value per light slot, bit-packed like the ``bitplanes`` light
indices, so that slot k of the values belongs to slot k of the indices.

Trebilco 2007, "Light indexed deferred rendering", Shadows, Shadow Maps, Pre-pass: "If soft
shadows are desired, a 'shadow intensity' value can be output in a separate render target.
These 'shadow intensity' values will need to be bit-packed/unpacked in a way similar to the
light index values, and accessed in the forward pass to attenuate the lighting."
(pipelines/lidr_shadow_prepass.pipe writes one per light beside its index.)

The value is rounded to an N-bit code and the code is laid out as a bit-plane index of b bits
per channel: bits [c*b, (c+1)*b) in the top b bits of channel c.  Blended with the index
target's ``add(one, constant_color)`` and constant 2^-b in the same draws, each write shifts
the older codes down by b bits in every channel exactly as it shifts the indices, so both
targets hold the same lights in the same slots.  b comes from the index packing's capacity
(``lights: slots.capacity``: b = 8 / capacity), which makes the blend constants equal.

``measure_intensity_error`` is the exhaustive measurement behind ``INTENSITY_ERRORS``
(tests/test_lidr_shadow_prepass.py repeats it; docs/encodings.md).
"""

from __future__ import annotations

from typing import Optional

from pipegen.core import formats
from pipegen.core.diagnostics import PipegenError
from pipegen.core.formats import Format
from pipegen.ir import nodes as ir
from pipegen.packing.base import (Scheme, cannot_fit, float_literal, int_option,
                                  need_target, unorm_code_expr)
from pipegen.packing.light_index import code_in_slot, planes_of

_XYZW = "xyzw"
MAX_BITS = 16         # as split16; a PCF fraction needs far fewer (16 taps: 8 bits err < 1/510)

# max |unpack(store(plane_value(x))) - x| over the float32 x in [0, 1], per intensity_bits,
# found where it lies, at the codes' rounding boundaries: measure_intensity_error(bits), 4
# significant digits.  The ideal is 0.5 / (2^N - 1); float32
# rounding of x * (2^N - 1) + 0.5 near a boundary adds up to a few ulps of the product.
# tests/test_lidr_shadow_prepass.py checks that a fresh measurement reproduces every entry.
INTENSITY_ERRORS: dict[int, float] = {
    1: 0.5, 2: 0.1667, 3: 0.07143, 4: 0.03333, 5: 0.01613, 6: 0.007937, 7: 0.003937,
    8: 0.001961, 9: 0.0009785, 10: 0.0004888, 11: 0.0002443, 12: 0.0001221, 13: 6.109e-05,
    14: 3.058e-05, 15: 1.532e-05, 16: 7.689e-06,
}


class IntensityPlanes(Scheme):
    """x in [0,1] as an N-bit code (``intensity_bits``, default 8) in bit planes of b = 8 /
    ``lights`` bits per channel: ceil(N / b) channels carry it, the others stay 0."""

    OPTIONS = ("lights", "intensity_bits", "target", "format")

    def __init__(self, options: dict, fmt: Optional[Format], span):
        # ``format: rgba8`` instead of ``target: T`` when the target is conditional (absent
        # where the technique needs no intensities, while the functions stay declared)
        if fmt is None and isinstance(options.get("format"), str):
            if options["format"] not in formats.FORMATS:
                raise PipegenError(span, f"unknown format '{options['format']}'",
                                   "write e.g. format: rgba8")
            fmt = formats.get(options["format"])
        fmt = need_target("intensity_planes", fmt, span)
        if not fmt.blendable or not fmt.blend_is_exact:
            raise cannot_fit(span, f"intensity planes need an 8-bit unorm colour target that "
                             f"blends bit-exactly, not {fmt.name}", "use rgba8, rg8 or r8")
        cap = int_option("intensity_planes", options, "lights", span)
        if cap not in (1, 2, 4, 8):
            raise PipegenError(span, f"intensity_planes holds 1, 2, 4 or 8 lights per pixel "
                               f"(8 / lights bits per channel), not {cap}",
                               "pass the index packing's capacity: lights: slots.capacity")
        N = int_option("intensity_bits", options, "intensity_bits", span, default=8)
        b, C = 8 // cap, fmt.channels
        if not 1 <= N <= min(MAX_BITS, C * b):
            raise cannot_fit(span, f"{N}-bit intensities in {C} channel(s) of {b} bits per "
                             f"light ({fmt.name}, {cap} lights)",
                             f"intensity_bits must be 1..{min(MAX_BITS, C * b)}")
        self.N, self.b, self.fmt = N, b, fmt
        self.used = -(-N // b)                       # channels the code occupies
        self.levels = (1 << N) - 1
        self.capacity = cap
        self.blend_constant = 2.0 ** -b
        self.error = INTENSITY_ERRORS[N]
        self.constants = {"capacity": (ir.INT, cap),
                          "blend_constant": (ir.FLOAT, self.blend_constant)}
        self.notes = [
            f"intensity planes: a [0,1] value per light as a {N}-bit code ({self.levels} "
            f"steps) in {self.used} channel(s) of {fmt.name}, {b} bits per channel per light, "
            f"capacity {cap} lights (the slots of a bit-plane index packing of the same "
            f"capacity, written in the same draws)",
            f"blend the target add(one, constant_color) with blend constant "
            f"{self.blend_constant} (the index packing's) and clear it to 0",
            f"max error {self.error:.4g} (half a step: {0.5 / self.levels:.4g}), measured over "
            f"the float32 values in [0,1] at every code's rounding boundaries; exact up to "
            f"capacity in the blend (beyond it the oldest slot is shifted out as the index's "
            f"is, and may add 1 to the next code's low chunk)",
        ]

    def functions(self, name):
        b, mask, L = self.b, (1 << self.b) - 1, float_literal(self.levels)
        comps = [f"float(((code >> {c * b}u) & {mask}u) << {8 - b}u)" if c < self.used
                 else "0.0" for c in range(4)]
        plane = (
            f"// x rounded to {self.N} bits; code bits [c*{b}, (c+1)*{b}) in the top bits of\n"
            f"// channel c, shifted down by the blend like a bit-plane light index.\n"
            f"vec4 {name}_plane_value(float x) {{\n"
            f"    uint code = uint(floor(clamp(x, 0.0, 1.0) * {L} + 0.5));\n"
            f"    return vec4({', '.join(comps)}) / 255.0;\n"
            f"}}")
        lines = [
            f"// The value in the k-th most recent slot (k = 0: newest); 0 when empty or "
            f"k >= {self.capacity}.",
            f"float {name}_unpack(vec4 v, int k) {{",
            f"    if (k < 0 || k >= {self.capacity}) {{",
            "        return 0.0;",
            "    }",
            f"    uint s = uint(8 - {b} * (k + 1));   // bit position of the k-th newest chunk",
            "    uint code = 0u;",
        ]
        for c in range(self.used):
            lines.append(f"    code = code | ((({unorm_code_expr('v.' + _XYZW[c], 255)} >> s) "
                         f"& {mask}u) << {c * b}u);")
        lines += [f"    return float(code) / {L};", "}"]
        return {"plane_value": plane, "unpack": "\n".join(lines)}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        b, cap, used = self.b, self.capacity, self.used
        L = F32(self.levels)

        def codes(x):
            x = np.clip(np.asarray(x, dtype=F32), F32(0), F32(1))
            return np.floor(x * L + F32(0.5)).astype(np.uint32)

        def plane_value(x):
            return planes_of(codes(x), b, used)

        def unpack(v, k):
            v = np.asarray(v, dtype=F32)
            if not 0 <= k < cap:
                return np.zeros(v.shape[:-1], dtype=F32)
            return code_in_slot(v, k, b, used).astype(F32) / L

        return {"plane_value": plane_value, "unpack": unpack, "codes": codes}


def measure_intensity_error(bits: int) -> tuple[float, float]:
    """(max error, the x where it occurs) of an ``bits``-bit intensity's round trip
    (``plane_value`` → rgba8 → ``unpack``, one light).  Every code round-trips exactly
    (tested), so the error of x is |c/L - x| for the code c it rounds to, largest at the ends
    of c's interval: evaluated at every code's rounding boundaries (c ± 0.5)/L and within 4
    float32 ulps of them, and at the codes themselves (as ``measure_split16_error``)."""
    import numpy as np
    F32 = np.float32
    L = (1 << bits) - 1
    lights = 4 if bits <= 8 else 2                   # 2 or 4 bits per channel of rgba8
    f = IntensityPlanes({"lights": lights, "intensity_bits": bits}, _rgba8(), None).mirror()
    c = np.arange(L + 1, dtype=np.float64)
    base = np.concatenate([(c - 0.5) / L, (c + 0.5) / L, c / L]).astype(F32)
    xs, up, down = [base], base, base
    for _ in range(4):
        up, down = np.nextafter(up, F32(2)), np.nextafter(down, F32(-1))
        xs += [up, down]
    x = np.clip(np.concatenate(xs), F32(0), F32(1))
    stored = _rgba8().dequantize(_rgba8().quantize(f["plane_value"](x))).astype(F32)
    err = np.abs(f["unpack"](stored, 0).astype(np.float64) - x.astype(np.float64))
    i = int(np.argmax(err))
    return float(err[i]), float(x[i])


def _rgba8() -> Format:
    return formats.get("rgba8")


def emulate_intensity_planes(values, lights: int, bits: int = 8,
                             mode: str = "unorm8") -> "np.ndarray":
    """The vec4 a pixel of a cleared rgba8 intensity target reads after ``values`` (L, P) (the
    lights' intensities, oldest first) were written and blended like bit-plane indices
    (``light_index.blend_bitplanes``: ``mode`` "unorm8" is llvmpipe's 8-bit fixed point,
    "exact" the float blend rounded once)."""
    import numpy as np
    from pipegen.packing.light_index import blend_bitplanes
    F32 = np.float32
    impl = IntensityPlanes({"lights": lights, "intensity_bits": bits}, _rgba8(), None).mirror()
    values = np.asarray(values, F32)
    out = np.zeros(values.shape[1:] + (4,), dtype=np.uint8)
    for v in values:
        src = np.rint(impl["plane_value"](v).astype(np.float64) * 255)
        out = blend_bitplanes(out, src, 8 // lights, mode)
    return out.astype(F32) / F32(255)
