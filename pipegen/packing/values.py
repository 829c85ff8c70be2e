"""The value schemes: ``split16`` (a [0,1] value as 16 bits over two 8-bit channels,
``Split16``) and ``bitfield`` (fields packed into one uint, e.g. Kircher's 8-bit object id |
8-bit normal group, ``Bitfield``), with the exhaustive measurements behind their bounds:
``measure_split16_error``, ``exact_bits`` / ``measure_exact_bits``,
``bitfield_round_trip_failure`` (docs/encodings.md)."""

from __future__ import annotations

import re
from typing import Optional

from pipegen.core import formats
from pipegen.core.diagnostics import PipegenError
from pipegen.core.formats import Format, Kind
from pipegen.ir import nodes as ir
from pipegen.packing.base import (Scheme, as_uint32, cannot_fit, float_literal, unorm_code_expr,
                                  unorm_codes)
from pipegen.packing.error_tables import SPLIT16_ERROR


class Split16(Scheme):
    """x in [0,1] as a 16-bit code, high byte in the first channel and low byte in the second,
    each written as an 8-bit unorm value.  The round trip is exact for every 16-bit code."""

    OPTIONS = ("target",)

    def __init__(self, options, fmt, span):
        if fmt is not None:
            if not fmt.is_color or fmt.is_integer:
                raise cannot_fit(span, f"split16 needs a unorm or float colour target, "
                                 f"not {fmt.name}", "use rg8")
            if fmt.channels < 2:
                raise cannot_fit(span, f"split16 needs two channels, {fmt.name} has one",
                                 "use rg8; a 16-bit value fits a single r16 channel directly")
            if fmt.kind is Kind.UNORM and min(fmt.bits[:2]) < 8:
                raise cannot_fit(span, f"split16 needs 8-bit channels, {fmt.name} has fewer")
            if exact_bits(fmt) < 8:
                raise cannot_fit(span, f"split16 needs 8 exact bits per channel, {fmt.name} "
                                 f"holds {exact_bits(fmt)} for values in [0,1]",
                                 "use rg8, rg16 or rg16f")
        self.error = SPLIT16_ERROR     # measured: measure_split16_error()
        self.notes = [
            "split16: x in [0,1] rounded to 16 bits, high byte in the first channel, low "
            f"byte in the second (every code round-trips exactly); max error {self.error:.4g} "
            f"= {self.error * 65535:.4g} of a 16-bit step, measured at every code's rounding "
            "boundaries (float32 rounding of x*65535+0.5 adds to the ideal 0.5)",
        ]

    def functions(self, name):
        pack = (f"vec2 {name}_pack(float x) {{\n"
                f"    uint code = uint(floor(clamp(x, 0.0, 1.0) * 65535.0 + 0.5));\n"
                f"    return vec2(float(code >> 8u), float(code & 255u)) / 255.0;\n"
                f"}}")
        unpack = (f"float {name}_unpack(vec2 v) {{\n"
                  f"    uint hi = {unorm_code_expr('v.x', 255)};\n"
                  f"    uint lo = {unorm_code_expr('v.y', 255)};\n"
                  f"    return float((hi << 8u) | lo) / 65535.0;\n"
                  f"}}")
        return {"pack": pack, "unpack": unpack}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        def pack(x):
            x = np.clip(np.asarray(x, dtype=F32), F32(0), F32(1))
            code = np.floor(x * F32(65535) + F32(0.5)).astype(np.uint32)
            return np.stack([(code >> 8).astype(F32), (code & 255).astype(F32)], -1) / F32(255)

        def unpack(v):
            v = np.asarray(v, dtype=F32)
            hi, lo = unorm_codes(v[..., 0], 255), unorm_codes(v[..., 1], 255)
            return ((hi << 8) | lo).astype(F32) / F32(65535)

        return {"pack": pack, "unpack": unpack}


def measure_split16_error(target: Format | str = "rg8") -> tuple[float, float]:
    """(max error, the x where it occurs) of split16's round trip through ``target``.

    The round trip is exact for every 16-bit code, so the error of an x is |c/65535 - x| for
    the code c it rounds to: within one code's interval it is largest at the interval's ends.
    Evaluated exhaustively at those ends: for every code, the float32 values within 4 ulps of
    both rounding boundaries (c ± 0.5)/65535 (the float32 products x*65535 + 0.5 decide a
    boundary to within 2 ulps), and the codes themselves."""
    import numpy as np
    F32 = np.float32
    fmt = formats.get(target) if isinstance(target, str) else target
    f = Split16({}, None, None).mirror()
    c = np.arange(65536, dtype=np.float64)
    base = np.concatenate([(c - 0.5) / 65535, (c + 0.5) / 65535, c / 65535]).astype(F32)
    xs, up, down = [base], base, base
    for _ in range(4):
        up, down = np.nextafter(up, F32(2)), np.nextafter(down, F32(-1))
        xs += [up, down]
    x = np.clip(np.concatenate(xs), F32(0), F32(1))
    pad = np.zeros((len(x), fmt.channels), F32)
    pad[:, :2] = f["pack"](x)
    stored = fmt.dequantize(fmt.quantize(pad))[:, :2].astype(F32)
    err = np.abs(f["unpack"](stored).astype(np.float64) - x.astype(np.float64))
    i = int(np.argmax(err))
    return float(err[i]), float(x[i])


# Names a bitfield field may not take: its functions use them as parameter names.
_RESERVED = {
    "if", "else", "for", "while", "do", "break", "continue", "return", "discard", "true",
    "false", "in", "out", "inout", "const", "uniform", "struct", "void", "float", "int", "uint",
    "bool", "vec2", "vec3", "vec4", "ivec2", "ivec3", "ivec4", "uvec2", "uvec3", "uvec4",
    "bvec2", "bvec3", "bvec4", "mat3", "mat4", "dot", "cross", "normalize", "length",
    "distance", "clamp", "mix", "step", "smoothstep", "pow", "exp", "exp2", "log", "log2",
    "sqrt", "inversesqrt", "min", "max", "abs", "sign", "floor", "ceil", "round", "fract",
    "mod", "sin", "cos", "tan", "atan", "load", "sample", "size", "frag_coord", "camera_pos",
    "view", "proj", "inv_view", "inv_proj", "output_size", "num_lights", "ambient",
    "lights", "light", "world_pos", "view_pos", "normal", "view_normal", "albedo", "specular",
    "shininess", "alpha", "object_id", "normal_group", "layer", "sample_id", "sample_mask", "load_sample",
}


def exact_bits(fmt: Format) -> int:
    """Bits of an integer that survive ``to_unorm`` → a channel of ``fmt`` → ``from_unorm``."""
    b = fmt.bits[0]
    if fmt.kind in (Kind.UNORM, Kind.UINT):
        return b
    if fmt.kind is Kind.SNORM:
        return b - 1
    if fmt.kind is Kind.FLOAT:
        # v / (2^n - 1) and back: half has 11 significant bits, but llvmpipe's half store
        # rounds toward zero (up to 1 ulp off), which leaves 10 exact; float32 23 (at 24 bits
        # the product x * (2^24 - 1) rounds to whole numbers and misses).
        return 10 if b == 16 else 23
    return 0


def bitfield_round_trip_failure(fmt: Format | str, bits: int,
                                 chunk: int = 1 << 20) -> Optional[int]:
    """The first ``bits``-bit value that does not survive bitfield's ``to_unorm`` → a channel
    of ``fmt`` → ``from_unorm``, or None: every value 0 .. 2^bits - 1 is tried (in chunks,
    stopping at the first failure)."""
    import numpy as np
    F32 = np.float32
    fmt = formats.get(fmt) if isinstance(fmt, str) else fmt
    f = Bitfield({"fields": [("v", bits)]}, None, None).mirror()
    for lo in range(0, 1 << bits, chunk):
        v = np.arange(lo, min(lo + chunk, 1 << bits), dtype=np.uint32)
        pad = np.zeros((len(v), fmt.channels), F32)
        pad[:, 0] = f["to_unorm"](v)
        stored = fmt.dequantize(fmt.quantize(pad))[:, 0].astype(F32)
        bad = np.nonzero(f["from_unorm"](stored) != v)[0]
        if len(bad):
            return int(v[bad[0]])
    return None


def measure_exact_bits(fmt: Format | str, limit: int = 24) -> tuple[int, Optional[int]]:
    """(the widest bitfield every value of which round-trips through a channel of ``fmt``,
    the first value of one bit more that does not): exhaustive over every width up to the
    answer + 1 (at most ``limit``)."""
    fmt = formats.get(fmt) if isinstance(fmt, str) else fmt
    for bits in range(1, limit + 1):
        bad = bitfield_round_trip_failure(fmt, bits)
        if bad is not None:
            return bits - 1, bad
    return limit, None


class Bitfield(Scheme):
    """Fields packed into one uint, the first field in the high bits (Kircher's DSF id:
    ``fields: (object: 8, group: 8)`` → object id in bits 8..15, normal group in 0..7)."""

    OPTIONS = ("fields", "target")

    def __init__(self, options, fmt, span):
        raw = options.get("fields")
        if isinstance(raw, dict):
            raw = list(raw.items())
        if not raw:
            raise PipegenError(span, "bitfield needs fields",
                               "write e.g. bitfield(fields: (object: 8, group: 8))")
        fields = []
        for item in raw:
            if not (isinstance(item, (tuple, list)) and len(item) == 2):
                raise PipegenError(span, f"bitfield field {item!r} is not (name: bits)")
            fname, bits = item
            if not (isinstance(fname, str) and re.fullmatch(r"[A-Za-z_]\w*", fname)):
                raise PipegenError(span, f"bitfield field name {fname!r} is not an identifier")
            if fname in _RESERVED or fname.startswith("gl_"):
                raise PipegenError(span, f"bitfield field name '{fname}' is reserved",
                                   "choose another name, e.g. object_id -> obj")
            if any(fname == f for f, _ in fields):
                raise PipegenError(span, f"bitfield field '{fname}' appears twice")
            if isinstance(bits, bool) or not isinstance(bits, int) or bits < 1:
                raise PipegenError(span, f"bitfield field '{fname}' needs a positive bit count")
            fields.append((fname, bits))
        total = sum(b for _, b in fields)
        if total > 32:
            raise cannot_fit(span, f"bitfield of {total} bits is wider than a uint (32)")
        if fmt is not None:
            limit = exact_bits(fmt) if fmt.is_color else 0
            if total > limit:
                raise cannot_fit(
                    span, f"a {total}-bit bitfield is wider than one channel of {fmt.name} "
                    f"({limit} exact bits)",
                    "use a wider target (r16/rg16 hold 16 bits, r32ui 32) or fewer bits")
        self.fields, self.total = fields, total
        self.max = (1 << total) - 1
        self.error = 0.0
        self.constants = {"bits": (ir.INT, total)}
        layout, shift = [], total
        for f, b in fields:
            shift -= b
            layout.append(f"{f} bits {shift}..{shift + b - 1}")
        self.notes = [f"bitfield: {total} bits, " + ", ".join(layout) +
                      "; values are masked to their width"]
        if total > 23:
            self.notes.append(f"to_unorm/from_unorm are not exact for {total} bits "
                              "(float32 arithmetic keeps 23); store the uint in r32ui")

    def _shifts(self):
        shift = self.total
        for f, b in self.fields:
            shift -= b
            yield f, b, shift, (1 << b) - 1

    def functions(self, name):
        params = ", ".join(f"uint {f}" for f, _ in self.fields)
        parts = [f"(({f} & {m}u) << {s}u)" for f, _, s, m in self._shifts()]
        out = {"pack": (f"// The first field in the high bits; every field masked to its width.\n"
                        f"uint {name}_pack({params}) {{\n"
                        f"    return {' | '.join(parts)};\n"
                        f"}}")}
        for f, _, s, m in self._shifts():
            out[f"{f}_of"] = (f"uint {name}_{f}_of(uint v) {{\n"
                              f"    return (v >> {s}u) & {m}u;\n"
                              f"}}")
        out["to_unorm"] = (f"float {name}_to_unorm(uint v) {{\n"
                           f"    return float(v) / {float_literal(self.max)};\n"
                           f"}}")
        out["from_unorm"] = (f"uint {name}_from_unorm(float x) {{\n"
                             f"    float y = clamp(x, 0.0, 1.0) * {float_literal(self.max)};\n"
                             f"    return uint(floor(y + 0.5));\n"
                             f"}}")
        return out

    def mirror(self):
        import numpy as np
        F32 = np.float32
        shifts = list(self._shifts())
        mx = self.max

        def pack(*values):
            assert len(values) == len(shifts)
            out = np.uint32(0)
            for v, (_, _, s, m) in zip(values, shifts):
                out = out | ((as_uint32(v) & np.uint32(m)) << np.uint32(s))
            return as_uint32(out)

        def field_of(s, m):
            return lambda v: (as_uint32(v) >> np.uint32(s)) & np.uint32(m)

        def to_unorm(v):
            return as_uint32(v).astype(F32) / F32(mx)

        def from_unorm(x):
            y = np.clip(np.asarray(x, dtype=F32), F32(0), F32(1)) * F32(mx)
            return np.floor(y + F32(0.5)).astype(np.uint32)

        impl = {"pack": pack}
        for f, _, s, m in shifts:
            impl[f"{f}_of"] = field_of(s, m)
        impl.update(to_unorm=to_unorm, from_unorm=from_unorm)
        return impl
