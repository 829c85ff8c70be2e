"""Packing schemes: generated pack/unpack functions, their capacity and quantisation error.

A ``pack NAME = SCHEME(key: value, …)`` declaration becomes a ``PackingSpec`` here.  Its
``functions_source`` is shader-language text (GLSL-flavoured, see docs/language.md) that the
front end parses like user code, so both backends emit it; every function is named
``NAME_fn`` and user code calls it as ``NAME.fn(…)``.

Every generated function has a numpy mirror (``numpy_impl``) that computes the same thing in
float32/uint32, so the schemes can be tested exhaustively without a GPU, and so the static
error of the normal encodings can be *measured* (``normal_error``) rather than guessed.

Schemes:

* light indices (Trebilco 2007, "Light indexed deferred rendering"): ``bitplanes`` (bit
  shifting with blend ``ONE, CONSTANT_COLOR``), ``max_pairs`` (MAX blend of ``(i, 1-i)`` with
  the stencil), ``channel_slots`` (CPU-sorted light sets, one channel each);
* values: ``split16`` (a [0,1] value as 16 bits over two 8-bit channels), ``bitfield`` (e.g.
  Kircher's 8-bit object id | 8-bit normal group);
* normals: ``kircher`` (Kircher & Lawrance 2009, eq. 1–3), ``spheremap``, ``octahedral``.

Light indices are 1-based (``light.index + 1u``): 0 means "no light" in every index scheme.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import field
from typing import Callable, Optional

from pipegen.core.records import record
from pipegen.core import formats
from pipegen.ir import nodes as ir
from pipegen.core.diagnostics import PipegenError, Span
from pipegen.core.formats import Format, Kind

# numpy is imported inside the mirrors and the measurements that use it: ``build`` (what
# compiling a technique calls) never needs it (tests/test_compile_imports.py).

SCHEMES = ("bitplanes", "max_pairs", "channel_slots", "split16", "bitfield",
           "kircher", "spheremap", "octahedral")

# Inputs closer than this (|n + (0,0,1)|^2, 8 n.z + 8) to a normal encoding's singular point
# take the guarded branch.  Written out in full so the literal needs no exponent syntax.
_TINY = "0.000000000001"   # 1e-12
_TINY_F = 1e-12


@record(frozen=True)
class PackingSpec:
    """What the front end needs from a packing scheme (see docs/internals.md)."""

    name: str
    scheme: str
    functions_source: str
    functions: tuple[str, ...]                          # short names: ("plane_value", "unpack")
    constants: dict[str, tuple[ir.Type, object]] = field(default_factory=dict)
    capacity: Optional[int] = None
    error: Optional[float] = None
    notes: tuple[str, ...] = ()


def build(name: str, scheme: str, options: dict, target_format: Optional[Format],
          span: Optional[Span]) -> PackingSpec:
    """Configure scheme ``scheme`` with ``options`` for ``pack name = scheme(…)``.

    ``target_format`` is the format of the target named by the ``target`` option (the front
    end resolves the name); a format name given directly as ``target`` is accepted too.
    Raises ``PipegenError(span, …)`` for bad options and for packings that cannot fit their
    target.
    """
    s = _configure(scheme, options, target_format, span)
    fns = s.functions(name)
    source = "\n\n".join(fns.values()) + "\n"
    return PackingSpec(name=name, scheme=scheme, functions_source=source,
                       functions=tuple(fns), constants=dict(s.constants),
                       capacity=s.capacity, error=s.error, notes=tuple(s.notes))


def numpy_impl(scheme: str, options: dict,
               target_format: Optional[Format] = None) -> dict[str, Callable]:
    """Vectorised numpy mirrors of the generated functions, by short name.

    Arguments and results are arrays with the vector components last (``unpack(v, k)`` takes
    ``v`` of shape (..., 4) and a Python int ``k``); arithmetic is float32/uint32 like the
    shaders'.
    """
    return _configure(scheme, options, target_format, None).mirror()


# =============================================================================================
# Option handling
# =============================================================================================


def _configure(scheme: str, options: dict, target_format: Optional[Format],
               span: Optional[Span]) -> "_Scheme":
    cls = _SCHEME_CLASSES.get(scheme)
    if cls is None:
        raise PipegenError(span, f"unknown packing scheme '{scheme}'",
                           "packing schemes: " + ", ".join(SCHEMES))
    options = dict(options or {})
    unknown = sorted(set(options) - set(cls.OPTIONS))
    if unknown:
        allowed = ", ".join(cls.OPTIONS) or "none"
        raise PipegenError(span, f"{scheme} has no option '{unknown[0]}'",
                           f"options of {scheme}: {allowed}")
    fmt = target_format
    if fmt is None and isinstance(options.get("target"), str):
        fmt = formats.FORMATS.get(options["target"])   # a format name instead of a target
    return cls(options, fmt, span)


def _int_option(scheme: str, options: dict, key: str, span: Optional[Span],
                default: Optional[int] = None) -> int:
    value = options.get(key, default)
    if value is None:
        raise PipegenError(span, f"{scheme} needs the option '{key}'",
                           f"write e.g. {scheme}({key}: 8, …)")
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            return int(value)
        raise PipegenError(span, f"{scheme} option '{key}' must be an integer, not {value!r}")
    return value


def _need_target(scheme: str, fmt: Optional[Format], span: Optional[Span]) -> Format:
    if fmt is None:
        raise PipegenError(span, f"{scheme} needs a target",
                           f"write e.g. {scheme}(target: lightidx, …) naming an rgba8 target")
    return fmt


def _cannot_fit(span: Optional[Span], what: str, hint: str = "") -> PipegenError:
    return PipegenError(span, f"packing cannot fit its target: {what}", hint)


# ---- tiny helpers shared by the source generators and the mirrors ----------------------------


def _fl(x: float) -> str:
    """A float literal of the shader language (always with a decimal point, no exponent)."""
    s = repr(float(x))
    assert "e" not in s and "inf" not in s and "nan" not in s, s
    return s


def _code_expr(v: str, scale: int) -> str:
    """The integer code of a unorm channel read as ``v``: round to nearest.

    ``floor(x*255+0.5)`` recovers the code from any value within ±0.5 code of it.  Trebilco's
    ``ceil(x*254.5)`` computes ``ceil(c + d - (c + d)/510)`` for code c read with error d, and
    gives c + 1 as soon as a value arrives slightly high (d = +0.01 breaks codes 1..5, d = +0.49
    every code below 250).  The clamp keeps out-of-range values (float targets) from the
    undefined negative float -> uint conversion.
    """
    return f"uint(clamp(floor({v} * {_fl(scale)} + 0.5), 0.0, {_fl(scale)}))"


def _codes(v: np.ndarray, scale: int) -> np.ndarray:
    import numpy as np
    F32 = np.float32
    v = np.asarray(v, dtype=F32)
    return np.clip(np.floor(v * F32(scale) + F32(0.5)), 0, scale).astype(np.uint32)


def _u32(x) -> np.ndarray:
    import numpy as np
    return np.asarray(x).astype(np.uint32)


_XYZW = "xyzw"


class _Scheme:
    OPTIONS: tuple[str, ...] = ()
    constants: dict = {}
    capacity: Optional[int] = None
    error: Optional[float] = None
    notes: list

    def functions(self, name: str) -> dict[str, str]:   # short name -> source text
        raise NotImplementedError

    def mirror(self) -> dict[str, Callable]:
        raise NotImplementedError


# =============================================================================================
# Light indices: bit planes (Trebilco's "bit shifting")
# =============================================================================================


class _BitPlanes(_Scheme):
    """An index of B bits is split into C chunks of b = B/C bits, chunk c in the top b bits of
    channel c.  The blend ``dst = src + dst * 2^-b`` shifts older lights down b bits per write,
    so each 8-bit channel holds 8/b lights, newest in the top bits.

    Chunk c holds index bits [c*b, (c+1)*b): red gets the low bits, as in the paper
    ("Red channel = (index & 0x3) << 6").
    """

    OPTIONS = ("index_bits", "target")

    def __init__(self, options: dict, fmt: Optional[Format], span: Optional[Span]):
        B = _int_option("bitplanes", options, "index_bits", span)
        fmt = _need_target("bitplanes", fmt, span)
        if not fmt.blendable:
            raise _cannot_fit(span, f"bit planes need a blendable 8-bit unorm colour target, "
                              f"not {fmt.name}", "use rgba8, rg8 or r8")
        if not fmt.blend_is_exact:
            raise PipegenError(
                span, f"bit planes into a target whose blending is not bit-exact ({fmt.name})",
                "the blend must shift codes exactly; only 8-bit unorm targets (r8, rg8, rgba8) "
                "blend bit-exactly")
        C = fmt.channels
        if B < 1 or B % C or 8 % (B // C):
            fits = [bits for bits in range(1, 8 * C + 1) if bits % C == 0 and 8 % (bits // C) == 0]
            raise _cannot_fit(
                span, f"{B}-bit indices do not split into whole bit planes over the {C} "
                f"channel(s) of {fmt.name}",
                f"index_bits must be a multiple of {C} that leaves 1, 2, 4 or 8 bits per "
                f"channel: one of {', '.join(map(str, fits))}")
        self.B, self.C, self.fmt = B, C, fmt
        self.b = B // C                              # bits per channel per light
        self.capacity = 8 // self.b
        self.blend_constant = 2.0 ** -self.b
        self.constants = {"capacity": (ir.INT, self.capacity),
                          "blend_constant": (ir.FLOAT, self.blend_constant)}
        row = _table_row(B, C)
        # Share of random indices whose chunks all have the top bit clear: only those leave
        # the retained lights intact when they are shifted out.
        clean = ((1 << (self.b - 1)) ** C - 1) / (2 ** B - 1)
        self.notes = [
            f"bit planes: {B}-bit light indices (1..{2 ** B - 1}, 0 = none) split into {C} x "
            f"{self.b}-bit chunks, one in the top bits of each channel of {fmt.name}",
            f"capacity {self.capacity} lights per fragment (Trebilco's table: "
            f"{row.lights_per_fragment} lights, {row.scene_lights} scene lights, "
            f"{row.surfaces}; {row.details})",
            f"blend the target add(one, constant_color) with blend constant "
            f"{self.blend_constant} in every channel, and clear it to 0",
            f"beyond capacity the oldest light is shifted out, not always cleanly: in a channel "
            f"where its chunk is {2 ** (self.b - 1)} or more the blend rounds up and adds 1 to "
            "what stays, corrupting the next-oldest index (and newer ones when the carry "
            "ripples through all-ones chunks; the channel saturates at 255 when every bit was "
            "set). With random indices, one light over capacity leaves the retained indices "
            f"intact in {clean:.1%} of pixels",
            "llvmpipe blends in 8-bit fixed point (blend_bitplanes mode 'unorm8', bit-exact); "
            "a float blend rounded once (mode 'exact') agrees with it up to capacity and "
            "differs beyond it, where the shifted-out bits make ties",
        ]

    def functions(self, name):
        b, C, mask = self.b, self.C, (1 << self.b) - 1
        comps = []
        for c in range(4):
            if c < C:
                comps.append(f"float(((index >> {c * b}u) & {mask}u) << {8 - b}u)")
            else:
                comps.append("0.0")
        plane = (
            f"// Index bits [c*{b}, (c+1)*{b}) go to the top bits of channel c; blending with\n"
            f"// add(one, constant_color), constant {self.blend_constant}, shifts older down.\n"
            f"vec4 {name}_plane_value(uint index) {{\n"
            f"    return vec4({', '.join(comps)}) / 255.0;\n"
            f"}}")
        lines = [
            f"// The k-th most recent index (k = 0: newest), 0 when empty or k >= {self.capacity}.",
            f"uint {name}_unpack(vec4 v, int k) {{",
            f"    if (k < 0 || k >= {self.capacity}) {{",
            "        return 0u;",
            "    }",
            f"    uint s = uint(8 - {b} * (k + 1));   // bit position of the k-th newest chunk",
            "    uint index = 0u;",
        ]
        for c in range(C):
            # Round to the nearest code: survives ±0.49 codes of error (ceil(x*254.5) does not).
            lines.append(f"    index = index | ((({_code_expr('v.' + _XYZW[c], 255)} >> s) "
                         f"& {mask}u) << {c * b}u);")
        lines += ["    return index;", "}"]
        return {"plane_value": plane, "unpack": "\n".join(lines)}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        b, C, mask, cap = self.b, self.C, (1 << self.b) - 1, self.capacity

        def plane_value(index):
            index = _u32(index)
            out = np.zeros(index.shape + (4,), dtype=F32)
            for c in range(C):
                out[..., c] = (((index >> (c * b)) & mask) << (8 - b)).astype(F32) / F32(255)
            return out

        def unpack(v, k):
            v = np.asarray(v, dtype=F32)
            if not 0 <= k < cap:
                return np.zeros(v.shape[:-1], dtype=np.uint32)
            s = 8 - b * (k + 1)
            index = np.zeros(v.shape[:-1], dtype=np.uint32)
            for c in range(C):     # uint32 throughout (numpy 1.x widens a numpy int k)
                index |= (((_codes(v[..., c], 255) >> s) & mask) << (c * b)).astype(np.uint32)
            return index

        return {"plane_value": plane_value, "unpack": unpack}


def blend_bitplanes(dst_codes, src_codes, bits_per_write: int, mode: str = "unorm8"):
    """One ``add(one, constant_color)`` blend of 8-bit unorm codes, constant 2^-bits_per_write.

    ``mode="unorm8"``: 8-bit fixed point as llvmpipe blends (bit-exact, tests): the constant is
    stored as a code, ``round(255 * 2^-b) = 2^(8-b)``, and the product ``dst * c / 255`` is
    rounded to nearest (llvmpipe's ``(t + (t >> 8) + 128) >> 8`` equals that for these
    constants).  ``mode="exact"``: the spec's float formula, rounded once when stored (ties to
    even): ``rint(src + dst * 2^-b)``.  Both saturate at 255, and both are exact while the
    bits shifted out are zero, i.e. up to capacity.
    """
    import numpy as np
    dst = np.asarray(dst_codes, dtype=np.float64)
    src = np.asarray(src_codes, dtype=np.float64)
    if mode == "exact":
        out = np.rint(src + dst * 2.0 ** -bits_per_write)
    elif mode == "unorm8":
        const = round(255 * 2.0 ** -bits_per_write)
        out = src + np.rint(dst * const / 255.0)
    else:
        raise ValueError(mode)
    return np.clip(out, 0, 255).astype(np.uint8)


def emulate_bitplanes(indices, index_bits: int, target: Format | str = "rgba8",
                      mode: str = "unorm8") -> np.ndarray:
    """The vec4 a pixel reads after lights ``indices`` (1-based, oldest first) were blended
    into a cleared bit-plane target.  ``indices`` may be (L,) or (L, P) for P pixels."""
    import numpy as np
    F32 = np.float32
    fmt = formats.get(target) if isinstance(target, str) else target
    impl = numpy_impl("bitplanes", {"index_bits": index_bits}, fmt)
    b = index_bits // fmt.channels
    idx = _u32(indices)
    codes = np.zeros(idx.shape[1:] + (4,), dtype=np.uint8)
    for light in idx:
        src = np.rint(impl["plane_value"](light).astype(np.float64) * 255)
        codes = blend_bitplanes(codes, src, b, mode)
    codes[..., fmt.channels:] = 0
    return codes.astype(F32) / F32(255)


# =============================================================================================
# Light indices: MAX-blended pairs with the stencil (Trebilco after Farrar)
# =============================================================================================


class _MaxPairs(_Scheme):
    """Two passes of the light volumes, each writing ``(i, 1-i)`` under MAX blending into one
    channel pair: a pair keeps the largest index and (as 1 - x) the smallest.  Pass 1 writes RG
    and lets the stencil pass twice per pixel; pass 2 writes BA for every later light.

    Unpacking follows from that: Index1 = R, Index2 = 1 - G (ignored if equal to Index1),
    Index3 = B, Index4 = 1 - A (ignored if equal to Index3).  The paper's printed list
    ("Index2 = 1 - Blue, Index3 = Green") pairs the wrong channels: G holds 1 - min of the
    *first* pair, so reading it as an index would be wrong.
    """

    OPTIONS = ("target",)

    def __init__(self, options, fmt, span):
        fmt = _need_target("max_pairs", fmt, span)
        if fmt.kind is not Kind.UNORM or fmt.channels != 4 or len(set(fmt.bits)) != 1:
            raise _cannot_fit(span, f"max_pairs needs a 4-channel unorm target, not {fmt.name}",
                              "use rgba8 (255 lights) or rgba16")
        self.fmt, self.scale = fmt, fmt.max_code
        self.capacity = 4
        self.constants = {"capacity": (ir.INT, 4)}
        self.notes = [
            f"max pairs: light indices 1..{self.scale} as (i, 1-i) in {fmt.name}, "
            "capacity 4 lights per fragment",
            "needs two passes of the light volumes and the stencil: blend max; pass 1 mask rg, "
            "stencil func greater ref 2 zpass incr; pass 2 mask ba, stencil func equal ref 0 "
            "fail decr; clear the target and the stencil to 0",
            "with more than 4 lights the first pair holds the max/min of the first two lights, "
            "the second pair the max/min of all later ones: the lights in between are dropped",
            "unpack: Index1 = R, Index2 = 1-G, Index3 = B, Index4 = 1-A (the paper's list "
            "pairs R with B and G with A, a typo); duplicates and empty pairs read as 0",
        ]

    def functions(self, name):
        sc = self.scale
        pair = (f"vec2 {name}_pair(uint index) {{\n"
                f"    float i = float(index) / {_fl(sc)};\n"
                f"    return vec2(i, 1.0 - i);\n"
                f"}}")
        value = (f"// The pair in both channel pairs; the pass's mask picks rg or ba.\n"
                 f"vec4 {name}_value(uint index) {{\n"
                 f"    vec2 p = {name}_pair(index);\n"
                 f"    return vec4(p, p);\n"
                 f"}}")
        unpack = (
            f"// k = 0, 1: largest and smallest index of the first pair (RG); 2, 3: of BA.\n"
            f"uint {name}_unpack(vec4 v, int k) {{\n"
            f"    uint hi = 0u;\n"
            f"    uint lo = 0u;\n"
            f"    if (k == 0 || k == 1) {{\n"
            f"        hi = {_code_expr('v.x', sc)};\n"
            f"        lo = {sc}u - {_code_expr('v.y', sc)};\n"
            f"    }} else if (k == 2 || k == 3) {{\n"
            f"        hi = {_code_expr('v.z', sc)};\n"
            f"        lo = {sc}u - {_code_expr('v.w', sc)};\n"
            f"    }}\n"
            f"    if (hi == 0u) {{\n"
            f"        return 0u;   // the pair was never written (it is cleared to 0)\n"
            f"    }}\n"
            f"    if (k == 0 || k == 2) {{\n"
            f"        return hi;\n"
            f"    }}\n"
            f"    return lo == hi ? 0u : lo;   // one light wrote the pair: no second index\n"
            f"}}")
        return {"pair": pair, "value": value, "unpack": unpack}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        sc = self.scale

        def pair(index):
            i = _u32(index).astype(F32) / F32(sc)
            return np.stack([i, F32(1) - i], axis=-1)

        def value(index):
            p = pair(index)
            return np.concatenate([p, p], axis=-1)

        def unpack(v, k):
            v = np.asarray(v, dtype=F32)
            if k not in (0, 1, 2, 3):
                return np.zeros(v.shape[:-1], dtype=np.uint32)
            c = 0 if k < 2 else 2
            hi = _codes(v[..., c], sc)
            lo = np.uint32(sc) - _codes(v[..., c + 1], sc)
            out = hi if k in (0, 2) else np.where(lo == hi, np.uint32(0), lo)
            return np.where(hi == 0, np.uint32(0), out).astype(np.uint32)

        return {"pair": pair, "value": value, "unpack": unpack}


def emulate_max_pairs(indices, scale: int = 255) -> np.ndarray:
    """The vec4 a pixel reads after the two max_pairs passes drew lights ``indices`` (1-based,
    in draw order) over it, with the stencil exactly as in the paper and pipelines/
    lidr_max_stencil.pipe: pass 1 ``func greater ref 2 zpass incr`` (ref > stencil passes),
    pass 2 ``func equal ref 0 fail decr``."""
    import numpy as np
    F32 = np.float32
    codes = np.zeros(4, dtype=np.int64)
    stencil = 0
    for i in indices:                      # pass 1: RG, first two lights
        if 2 > stencil:
            codes[0] = max(codes[0], i)
            codes[1] = max(codes[1], scale - i)
            stencil += 1
    for i in indices:                      # pass 2: BA, lights after the first `stencil`
        if stencil == 0:
            codes[2] = max(codes[2], i)
            codes[3] = max(codes[3], scale - i)
        else:
            stencil -= 1
    return codes.astype(F32) / F32(scale)


# =============================================================================================
# Light indices: CPU-sorted channel slots
# =============================================================================================


class _ChannelSlots(_Scheme):
    """Slot set k is drawn into channel k (``draw lights as sphere in NAME[k]`` with ``mask``
    on that channel).  The CPU puts every light into a set where its sphere overlaps no other,
    so a surface point is reached by at most one light per set and no blending is needed."""

    OPTIONS = ("target", "slots")

    def __init__(self, options, fmt, span):
        fmt = _need_target("channel_slots", fmt, span)
        if fmt.kind is not Kind.UNORM:
            raise _cannot_fit(span, f"channel_slots needs a unorm target, not {fmt.name}",
                              "use rgba8 (255 lights) or rgba16 (65535 lights)")
        n = _int_option("channel_slots", options, "slots", span, default=fmt.channels)
        if not 1 <= n <= fmt.channels:
            raise _cannot_fit(span, f"{n} slots in the {fmt.channels} channel(s) of {fmt.name}",
                              f"slots must be between 1 and {fmt.channels}")
        self.fmt, self.slots = fmt, n
        self.scale = (1 << min(fmt.bits[:n])) - 1
        self.capacity = n
        self.constants = {"capacity": (ir.INT, n)}
        self.notes = [
            f"channel slots: {n} CPU-sorted sets of non-overlapping light spheres, set k in "
            f"channel k of {fmt.name}; light indices 1..{self.scale}; capacity {n}",
            "lights that overlap a light in every set are dropped (sort_lights_into_slots "
            "reports them)",
        ]

    def functions(self, name):
        sc = self.scale
        value = (f"// The index in every channel; the pass's mask picks the slot's channel.\n"
                 f"vec4 {name}_value(uint index) {{\n"
                 f"    return vec4(float(index) / {_fl(sc)});\n"
                 f"}}")
        lines = ["// The index in slot k (0 = none).",
                 f"uint {name}_unpack(vec4 v, int k) {{"]
        for k in range(self.slots):
            lines += [f"    if (k == {k}) {{",
                      f"        return {_code_expr('v.' + _XYZW[k], sc)};",
                      "    }"]
        lines += ["    return 0u;", "}"]
        return {"value": value, "unpack": "\n".join(lines)}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        sc, n = self.scale, self.slots

        def value(index):
            i = _u32(index).astype(F32) / F32(sc)
            return np.repeat(i[..., None], 4, axis=-1)

        def unpack(v, k):
            v = np.asarray(v, dtype=F32)
            if not 0 <= k < n:
                return np.zeros(v.shape[:-1], dtype=np.uint32)
            return _codes(v[..., k], sc)

        return {"value": value, "unpack": unpack}


def sort_lights_into_slots(centers, radii, slots: int) -> tuple[list[list[int]], list[int]]:
    """Trebilco's CPU sort: each light (0-based, in table order, so earlier lights have
    priority) goes into the first of ``slots`` sets where its sphere intersects none already
    there; a light that fits nowhere is dropped.  Spheres that merely touch (distance equal to
    the sum of the radii) share a point and count as intersecting.

    Returns ``(sets, dropped)``: the light indices of each set, and the dropped ones.
    """
    import numpy as np
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    radii = np.asarray(radii, dtype=np.float64).reshape(-1)
    assert len(centers) == len(radii)
    sets: list[list[int]] = [[] for _ in range(slots)]
    dropped: list[int] = []
    for i in range(len(radii)):
        for members in sets:
            if members:
                d = np.linalg.norm(centers[members] - centers[i], axis=1)
                if np.any(d <= radii[members] + radii[i]):
                    continue
            members.append(i)
            break
        else:
            dropped.append(i)
    return sets, dropped


# =============================================================================================
# Values: split16 and bitfield
# =============================================================================================


class _Split16(_Scheme):
    """x in [0,1] as a 16-bit code, high byte in the first channel and low byte in the second,
    each written as an 8-bit unorm value.  The round trip is exact for every 16-bit code."""

    OPTIONS = ("target",)

    def __init__(self, options, fmt, span):
        if fmt is not None:
            if not fmt.is_color or fmt.is_integer:
                raise _cannot_fit(span, f"split16 needs a unorm or float colour target, "
                                  f"not {fmt.name}", "use rg8")
            if fmt.channels < 2:
                raise _cannot_fit(span, f"split16 needs two channels, {fmt.name} has one",
                                  "use rg8; a 16-bit value fits a single r16 channel directly")
            if fmt.kind is Kind.UNORM and min(fmt.bits[:2]) < 8:
                raise _cannot_fit(span, f"split16 needs 8-bit channels, {fmt.name} has fewer")
            if _exact_bits(fmt) < 8:
                raise _cannot_fit(span, f"split16 needs 8 exact bits per channel, {fmt.name} "
                                  f"holds {_exact_bits(fmt)} for values in [0,1]",
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
                  f"    uint hi = {_code_expr('v.x', 255)};\n"
                  f"    uint lo = {_code_expr('v.y', 255)};\n"
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
            hi, lo = _codes(v[..., 0], 255), _codes(v[..., 1], 255)
            return ((hi << 8) | lo).astype(F32) / F32(65535)

        return {"pack": pack, "unpack": unpack}


# max |unpack(store(pack(x))) - x| over x in [0,1]: measure_split16_error() (the same for every
# target split16 accepts, all of which store its 65536 codes exactly).  Generated with
# NORMAL_ERRORS by benchmarks/encoding_errors.py --write.
# BEGIN SPLIT16_ERROR
SPLIT16_ERROR = 7.68899917602539e-06
# END SPLIT16_ERROR


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
    f = numpy_impl("split16", {})
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
    "shininess", "alpha", "object_id", "normal_group", "layer",
}


def _exact_bits(fmt: Format) -> int:
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
    f = numpy_impl("bitfield", {"fields": [("v", bits)]})
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


class _Bitfield(_Scheme):
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
            raise _cannot_fit(span, f"bitfield of {total} bits is wider than a uint (32)")
        if fmt is not None:
            limit = _exact_bits(fmt) if fmt.is_color else 0
            if total > limit:
                raise _cannot_fit(
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
                           f"    return float(v) / {_fl(self.max)};\n"
                           f"}}")
        out["from_unorm"] = (f"uint {name}_from_unorm(float x) {{\n"
                             f"    float y = clamp(x, 0.0, 1.0) * {_fl(self.max)};\n"
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
                out = out | ((_u32(v) & np.uint32(m)) << np.uint32(s))
            return _u32(out)

        def field_of(s, m):
            return lambda v: (_u32(v) >> np.uint32(s)) & np.uint32(m)

        def to_unorm(v):
            return _u32(v).astype(F32) / F32(mx)

        def from_unorm(x):
            y = np.clip(np.asarray(x, dtype=F32), F32(0), F32(1)) * F32(mx)
            return np.floor(y + F32(0.5)).astype(np.uint32)

        impl = {"pack": pack}
        for f, _, s, m in shifts:
            impl[f"{f}_of"] = field_of(s, m)
        impl.update(to_unorm=to_unorm, from_unorm=from_unorm)
        return impl


# =============================================================================================
# Normals: Kircher hemisphere, spheremap, octahedral
# =============================================================================================
#
# All three encoders return values in [0,1] whatever the target, so one source serves unorm
# and float targets alike (a [-1,1] convention would be clamped away by rg8/rg16).


class _Normals(_Scheme):
    OPTIONS = ("target",)
    SCHEME = ""
    DOMAIN = "sphere"            # sample domain of the error measurement

    def __init__(self, options, fmt, span):
        if fmt is not None:
            if not fmt.is_color or fmt.is_integer:
                raise _cannot_fit(span, f"{self.SCHEME} stores two float values; "
                                  f"{fmt.name} cannot hold them", "use rg16, rg16f or rg8")
            if fmt.channels < 2:
                raise _cannot_fit(span, f"{self.SCHEME} needs two channels, "
                                  f"{fmt.name} has {fmt.channels}", "use rg16, rg16f or rg8")
        self.fmt = fmt
        self.notes = [self.NOTE, "encode returns values in [0,1] (x*0.5+0.5 style) for every "
                      "target; decode takes them back"]
        if fmt is None:
            self.notes.append("no target given: quantisation error not measured")
        else:
            self.error, mean = normal_error_figures(self.SCHEME, fmt.name)
            where = "hemisphere z >= 0" if self.DOMAIN == "hemisphere" else "whole sphere"
            self.notes.append(f"angular error through {fmt.name}: max {self.error:.4g}, mean "
                              f"{mean:.4g} degrees (encode, quantise, decode; {where}; "
                              "measured, docs/encodings.md)")
            if self.DOMAIN == "sphere":
                half, half_mean = normal_error_figures(self.SCHEME, fmt.name, hemisphere=True)
                self.notes.append(f"over the camera-facing hemisphere z >= 0 only: max "
                                  f"{half:.4g}, mean {half_mean:.4g} degrees")


class _Kircher(_Normals):
    SCHEME = "kircher"
    DOMAIN = "hemisphere"
    NOTE = ("kircher: n' = normalize(n + (0,0,1)), n'.xy stored (eq. 1); z = sqrt(1 - |n'.xy|^2), "
            "n = (2z n'x, 2z n'y, 2z^2 - 1) (eq. 2-3).  Domain: view-space normals facing the "
            "camera (z >= 0); precision falls off towards -z.  The singular input (0,0,-1) is "
            "encoded as a rim point and decodes to exactly (0,0,-1); no NaN.  Stored as "
            "n'.xy*0.5+0.5 this is the same map as spheremap (both are Lambert's azimuthal "
            "projection); only the intended domain differs")

    def functions(self, name):
        enc = (f"// Kircher & Lawrance eq. 1: the half vector of n and +z; its xy is stored.\n"
               f"vec2 {name}_encode(vec3 n) {{\n"
               f"    vec3 h = n + vec3(0.0, 0.0, 1.0);\n"
               f"    float d = dot(h, h);\n"
               f"    if (d <= {_TINY}) {{\n"
               f"        // n = (0,0,-1), where eq. 1 divides by 0: a rim point decodes to it.\n"
               f"        return vec2(1.0, 0.5);\n"
               f"    }}\n"
               f"    return (h * inversesqrt(d)).xy * 0.5 + 0.5;\n"
               f"}}")
        dec = (f"// Eq. 2-3; |e| can exceed 1 after quantisation, hence the clamp.\n"
               f"vec3 {name}_decode(vec2 e) {{\n"
               f"    vec2 h = e * 2.0 - 1.0;\n"
               f"    float z = sqrt(max(1.0 - dot(h, h), 0.0));\n"
               f"    return vec3(2.0 * z * h.x, 2.0 * z * h.y, 2.0 * z * z - 1.0);\n"
               f"}}")
        return {"encode": enc, "decode": dec}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        def encode(n):
            n = np.asarray(n, dtype=F32)
            h = n + np.array([0, 0, 1], dtype=F32)
            d = np.sum(h * h, axis=-1, dtype=F32)
            safe = d > F32(_TINY_F)
            inv = F32(1) / np.sqrt(np.where(safe, d, F32(1)))
            e = (h[..., :2] * inv[..., None]) * F32(0.5) + F32(0.5)
            return np.where(safe[..., None], e, np.array([1.0, 0.5], dtype=F32))

        def decode(e):
            h = np.asarray(e, dtype=F32) * F32(2) - F32(1)
            z = np.sqrt(np.maximum(F32(1) - np.sum(h * h, axis=-1, dtype=F32), F32(0)))
            return np.stack([F32(2) * z * h[..., 0], F32(2) * z * h[..., 1],
                             F32(2) * z * z - F32(1)], axis=-1)

        return {"encode": encode, "decode": decode}


class _Spheremap(_Normals):
    SCHEME = "spheremap"
    NOTE = ("spheremap (Lambert azimuthal): enc = n.xy / sqrt(8 n.z + 8) + 0.5 with 8 n.z + 8 "
            "computed as 4 |n + (0,0,1)|^2 (same for unit n, no cancellation near -z); whole "
            "sphere, -z on the rim of the disk, where precision is lowest; (0,0,-1) is encoded "
            "as a rim point and decodes exactly")

    def functions(self, name):
        enc = (f"vec2 {name}_encode(vec3 n) {{\n"
               f"    // 8 n.z + 8 for unit n, computed as 4 |n + (0,0,1)|^2: near -z, where the\n"
               f"    // rim needs every bit, 8 n.z + 8 loses them all to cancellation.\n"
               f"    vec3 h = n + vec3(0.0, 0.0, 1.0);\n"
               f"    float f = 4.0 * dot(h, h);\n"
               f"    if (f <= {_TINY}) {{\n"
               f"        return vec2(1.0, 0.5);   // n = (0,0,-1): a rim point decodes to it\n"
               f"    }}\n"
               f"    return n.xy * inversesqrt(f) + 0.5;\n"
               f"}}")
        dec = (f"vec3 {name}_decode(vec2 e) {{\n"
               f"    vec2 fe = e * 4.0 - 2.0;\n"
               f"    float f = min(dot(fe, fe), 4.0);   // outside the disk: the rim, -z\n"
               f"    float g = sqrt(1.0 - f * 0.25);\n"
               f"    return vec3(fe * g, 1.0 - f * 0.5);\n"
               f"}}")
        return {"encode": enc, "decode": dec}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        def encode(n):
            n = np.asarray(n, dtype=F32)
            h = n + np.array([0, 0, 1], dtype=F32)
            f = F32(4) * np.sum(h * h, axis=-1, dtype=F32)
            safe = f > F32(_TINY_F)
            inv = F32(1) / np.sqrt(np.where(safe, f, F32(1)))
            e = n[..., :2] * inv[..., None] + F32(0.5)
            return np.where(safe[..., None], e, np.array([1.0, 0.5], dtype=F32))

        def decode(e):
            fe = np.asarray(e, dtype=F32) * F32(4) - F32(2)
            f = np.minimum(np.sum(fe * fe, axis=-1, dtype=F32), F32(4))
            g = np.sqrt(F32(1) - f * F32(0.25))
            return np.concatenate([fe * g[..., None], (F32(1) - f * F32(0.5))[..., None]], -1)

        return {"encode": encode, "decode": decode}


class _Octahedral(_Normals):
    SCHEME = "octahedral"
    NOTE = ("octahedral: n / (|x|+|y|+|z|), the lower half folded over the diagonals with a "
            "sign that is never 0 (so -0.0 and +0.0 agree); whole sphere; the square's edges "
            "are mirror seams that decode identically from both sides")

    def functions(self, name):
        enc = (f"vec2 {name}_encode(vec3 n) {{\n"
               f"    vec2 p = n.xy / max(abs(n.x) + abs(n.y) + abs(n.z), {_TINY});\n"
               f"    if (n.z < 0.0) {{\n"
               f"        // Fold the lower half outwards; the sign must not be 0 on the axes.\n"
               f"        vec2 s = vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);\n"
               f"        p = (1.0 - abs(p.yx)) * s;\n"
               f"    }}\n"
               f"    return p * 0.5 + 0.5;\n"
               f"}}")
        dec = (f"vec3 {name}_decode(vec2 e) {{\n"
               f"    vec2 f = e * 2.0 - 1.0;\n"
               f"    vec3 n = vec3(f.x, f.y, 1.0 - abs(f.x) - abs(f.y));\n"
               f"    float t = max(-n.z, 0.0);   // > 0 only in the folded lower half\n"
               f"    n.x += n.x >= 0.0 ? -t : t;\n"
               f"    n.y += n.y >= 0.0 ? -t : t;\n"
               f"    return normalize(n);\n"
               f"}}")
        return {"encode": enc, "decode": dec}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        def encode(n):
            n = np.asarray(n, dtype=F32)
            l1 = np.abs(n[..., 0]) + np.abs(n[..., 1]) + np.abs(n[..., 2])
            p = n[..., :2] / np.maximum(l1, F32(_TINY_F))[..., None]
            s = np.where(p >= 0, F32(1), F32(-1))
            folded = (F32(1) - np.abs(p[..., ::-1])) * s
            p = np.where((n[..., 2] < 0)[..., None], folded, p)
            return p * F32(0.5) + F32(0.5)

        def decode(e):
            f = np.asarray(e, dtype=F32) * F32(2) - F32(1)
            z = F32(1) - np.abs(f[..., 0]) - np.abs(f[..., 1])
            t = np.maximum(-z, F32(0))[..., None]
            xy = f + np.where(f >= 0, -t, t)
            n = np.concatenate([xy, z[..., None]], -1)
            return n / np.sqrt(np.sum(n * n, axis=-1, dtype=F32))[..., None]

        return {"encode": encode, "decode": decode}


def _libm(fn: Callable[[float], float], x) -> np.ndarray:
    """``fn`` (a ``math`` function) applied to every element of ``x`` (float64 array).

    The measured tables must come out the same on every machine of a kind: numpy's own
    sin/cos/log are SIMD kernels chosen by CPU features and rewritten between numpy versions,
    so their last bits differ (tests/test_packing_exhaustive.py, docs/internals.md); Python's
    ``math`` calls the C library's, one per system image."""
    import numpy as np
    x = np.asarray(x, np.float64)
    return np.fromiter(map(fn, x.ravel().tolist()), np.float64, x.size).reshape(x.shape)


def fibonacci_sphere(count: int, hemisphere: bool = False) -> np.ndarray:
    """``count`` nearly evenly spread unit vectors (float64), on z >= 0 if ``hemisphere``
    (the same bits on every machine: correctly rounded arithmetic and libm's cos/sin)."""
    import numpy as np
    i = np.arange(count, dtype=np.float64) + 0.5
    z = 1.0 - i / count if hemisphere else 1.0 - 2.0 * i / count
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = i * (math.pi * (3.0 - math.sqrt(5.0)))
    return np.stack([r * _libm(math.cos, phi), r * _libm(math.sin, phi), z], axis=-1)


def _unit_rows(p: np.ndarray) -> np.ndarray:
    """Rows of ``p`` (..., 3) scaled to unit length, in correctly rounded operations only (a
    fixed order, no reduction kernel): the same bits on every machine."""
    import numpy as np
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    return p / np.sqrt(x * x + y * y + z * z)[..., None]


def _special_normals(hemisphere: bool) -> np.ndarray:
    """The hard spots of the normal encodings, added to the Fibonacci grid.

    Both domains: the axes, the equator's diagonals, (1,1,1)-style octant centres.  Whole
    sphere: (0,0,-1) (the singular point of Kircher and spheremap) and the normals around it
    down to 1e-5 degrees, on rings (the error of spheremap peaks at a distance from -z that
    depends on the format's step, too close to the pole for an even grid to find), and both
    sides of the octahedral seams (x = 0 or y = 0 below the equator, which map to the edges of
    the square) at offsets 1e-7 .. 1e-2."""
    import numpy as np
    pts = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (1, 1, 0), (-1, 1, 0),
           (1, -1, 0), (-1, -1, 0), (1, 1, 1), (-1, -1, 1), (1e-7, 0, 1), (1, 1e-7, 1e-7)]
    if not hemisphere:
        pts += [(0, 0, -1), (1, 1, -1), (-1, 1, -1), (1e-6, 0, -1), (0, -1e-6, -1),
                (0, 1, -1), (0, -1, -1), (1, 0, -1), (-1, 0, -1), (-1e-7, 1, -1), (1e-7, 1, -1)]
    p = _unit_rows(np.array(pts, dtype=np.float64))
    if hemisphere:
        return p
    golden = math.pi * (3.0 - math.sqrt(5.0))
    lo, hi = math.log(1e-5), math.log(30.0)                  # 2000 radii, 1e-5 .. 30 degrees
    t = _libm(math.radians, _libm(math.exp, lo + np.arange(2000) * ((hi - lo) / 1999)))
    t = t[:, None]
    a = (np.arange(256)[None, :] * (2 * math.pi / 256) + np.arange(2000)[:, None] * golden)
    sin_t, cos_a, sin_a = _libm(math.sin, t), _libm(math.cos, a), _libm(math.sin, a)
    ring = np.stack([sin_t * cos_a, sin_t * sin_a,
                     np.broadcast_to(-_libm(math.cos, t), a.shape)], -1).reshape(-1, 3)
    # Octahedral seams: the great half-circles x = 0 and y = 0 below the equator, nudged off
    # them to both sides.
    u = np.linspace(-math.pi / 2, math.pi / 2, 1001)[:, None]          # along the seam
    off = np.array([0.0, 1e-7, -1e-7, 1e-5, -1e-5, 1e-3, -1e-3, 1e-2, -1e-2])[None, :]
    s, c = np.broadcast_arrays(_libm(math.sin, u), -_libm(math.cos, u))  # z = -cos(u) <= 0
    along = np.broadcast_to(s, (1001, off.shape[1]))
    down = np.broadcast_to(c, (1001, off.shape[1]))
    side = np.broadcast_to(off, (1001, off.shape[1]))
    seams = np.concatenate([np.stack([side, along, down], -1).reshape(-1, 3),
                            np.stack([along, side, down], -1).reshape(-1, 3)])
    return np.concatenate([p, ring, _unit_rows(seams)])


def angular_error_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between vectors (need not be unit), in degrees; exact near 0 (atan2 form)."""
    import numpy as np
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1),
                                 np.sum(a * b, axis=-1)))


def _chord_sq(n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """|n - d/|d||^2 for unit ``n`` (float64): the squared chord between ``n`` and the
    direction of ``d``, increasing with their angle.  Correctly rounded operations in a fixed
    order only, so every machine gets the same bits: the measurement's search decides on it."""
    import numpy as np
    d = np.asarray(d, np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    inv = 1.0 / np.sqrt(x * x + y * y + z * z)
    dx, dy, dz = n[..., 0] - x * inv, n[..., 1] - y * inv, n[..., 2] - z * inv
    return dx * dx + dy * dy + dz * dz


def _chord_to_deg(c2: np.ndarray) -> np.ndarray:
    """The angle (degrees) of a squared chord: 2 asin(|chord| / 2), as accurate near 0 and
    exact to float64 rounding up to 180 degrees."""
    import numpy as np
    return np.degrees(2.0 * np.arcsin(np.minimum(np.sqrt(c2) * 0.5, 1.0)))


# ---- measured error of the normal encodings --------------------------------------------------

NORMAL_GRID = 1 << 20            # Fibonacci normals per domain (whole sphere or hemisphere)
_REFINE_WORST, _REFINE_ROUNDS, _REFINE_CANDIDATES = 48, 14, 192
NORMAL_SEED = 20140417           # the local search's random steps (the table's measurement)
NORMAL_FORMATS = ("rg8", "rgb10a2", "rg16", "rg8_snorm", "rg16_snorm", "rg16f", "rg32f")


def normal_storage(fmt: Format | str) -> str:
    """The format in ``NORMAL_FORMATS`` that stores a normal's two [0,1] values exactly as
    ``fmt`` does (same kind, bits and conversion in its first two channels): rgba8 -> rg8,
    rgba16f -> rg16f, …"""
    fmt = formats.get(fmt) if isinstance(fmt, str) else fmt
    for name in NORMAL_FORMATS:
        g = formats.get(name)
        if (g.kind, g.bits[:2], g.encode) == (fmt.kind, fmt.bits[:2], fmt.encode):
            return name
    raise KeyError(fmt.name)


@record(frozen=True)
class NormalError:
    """Angular error (degrees) of encode → store in ``storage`` → decode over one domain."""
    scheme: str
    storage: str
    domain: str                  # "sphere" or "hemisphere" (z >= 0)
    max: float                   # over the grid, the hard spots and the local search
    mean: float                  # over the (equal-area) Fibonacci grid only
    worst: tuple[float, float, float]   # the normal where the maximum was found
    points: int                  # normals evaluated (grid + hard spots + search)


@functools.lru_cache(maxsize=4)
def _normal_grid(hemisphere: bool, samples: int) -> np.ndarray:
    import numpy as np
    return np.concatenate([fibonacci_sphere(samples, hemisphere), _special_normals(hemisphere)])


def _store_normals(e: np.ndarray, fmt: Format) -> np.ndarray:
    """What a shader reads back after writing encoded normals ``e`` (..., 2) into ``fmt``."""
    import numpy as np
    F32 = np.float32
    pad = np.zeros(e.shape[:-1] + (fmt.channels,), np.float32)
    pad[..., :2] = e
    return fmt.dequantize(fmt.quantize(pad))[..., :2].astype(F32)


@functools.lru_cache(maxsize=None)
def measure_normal_error(scheme: str, storage: str, hemisphere: bool,
                         samples: int = NORMAL_GRID, seed: int = NORMAL_SEED) -> NormalError:
    """Measure the angular error of encode → quantise to ``storage`` → decode (the float32
    arithmetic of the mirrors, the stores of ``formats``), in degrees.

    The normals: ``samples`` Fibonacci points on the domain, the hard spots of
    ``_special_normals`` and a deterministic local search: from each of the 48 worst
    normals (on the whole sphere, one of them replaced by the hemisphere's worst), 14 rounds
    of 192 random steps with a radius that starts at twice the grid spacing and shrinks by 0.6
    per round, keeping the worst.  The maximum is a lower bound of the supremum; the search
    adds up to ~3 % to the grid's maximum (it finishes the climb into the worst quantisation
    cell).  Where it ends depends on its path: six other seeds find maxima within 0.6 % of
    the table's for every storage but rg32f, whose errors (~3e-5 degrees) are float32 rounding
    noise with many near-equal peaks (-9 % .. +5 %; ``python benchmarks/encoding_errors.py
    --path-spread 6``); fresh random normals stay below it
    (tests/test_packing_exhaustive.py).  The mean is over the Fibonacci points alone (they
    are equal-area, so it is the mean over the domain).

    Reproducible by construction: everything that decides which normals are measured and
    which one is the worst (the grid, the mirrors, the squared chords compared, the ranking
    with ties broken by position, the random steps) is correctly rounded arithmetic, libm or
    numpy's seeded bit stream, never a numpy transcendental kernel (those differ by CPU and
    numpy version); only the conversion of chords to degrees uses one, after the search, and
    changes the figures in their last bits at most."""
    import numpy as np
    F32 = np.float32
    fmt = formats.get(storage)
    impl = numpy_impl(scheme, {})

    def chords(n):
        return _chord_sq(n, impl["decode"](_store_normals(impl["encode"](n.astype(F32)), fmt)))

    n = _normal_grid(hemisphere, samples)
    err = chords(n)
    mean = float(np.mean(_chord_to_deg(err[:samples])))
    k = _REFINE_WORST
    idx = np.lexsort((np.arange(len(err)), -err))[:k]     # the k worst, ties by position
    best, best_err = n[idx].copy(), err[idx].copy()
    if not hemisphere:
        # The hemisphere is part of the sphere: start one search where its measurement found
        # its maximum, so that the sphere's figure is never below the hemisphere's.
        half = measure_normal_error(scheme, storage, True, samples, seed)
        j = int(np.argmin(best_err))
        best[j] = half.worst
        best_err[j] = chords(np.array([half.worst]))[0]
    rng = np.random.default_rng(seed)
    radius = 2.0 * math.sqrt((2 if hemisphere else 4) * math.pi / samples)
    for _ in range(_REFINE_ROUNDS):
        cand = _unit_rows(best[:, None, :] + rng.normal(size=(k, _REFINE_CANDIDATES, 3)) * radius)
        if hemisphere:
            cand[..., 2] = np.abs(cand[..., 2])
        e = chords(cand.reshape(-1, 3)).reshape(k, _REFINE_CANDIDATES)
        j = np.argmax(e, axis=1)
        top = e[np.arange(k), j]
        better = top > best_err
        best[better] = cand[np.arange(k), j][better]
        best_err[better] = top[better]
        radius *= 0.6
    i = int(np.argmax(best_err))
    worst = float(best_err[i])
    if err.max() > worst:                     # cannot happen (the search keeps the start)
        i, worst, best = int(np.argmax(err)), float(err.max()), n
    return NormalError(scheme, storage, "hemisphere" if hemisphere else "sphere",
                       math.degrees(2.0 * math.asin(min(math.sqrt(worst) * 0.5, 1.0))), mean,
                       tuple(float(x) for x in best[i]),
                       len(n) + _REFINE_ROUNDS * k * _REFINE_CANDIDATES)


def _sig(x: float, digits: int = 4) -> float:
    """``x`` rounded to ``digits`` significant digits (how the table stores it)."""
    return float(f"{x:.{digits}g}")


# The measured figures: (scheme, storage, domain) -> (max, mean) in degrees, 4 significant
# digits.  Generated by `python benchmarks/encoding_errors.py --write` (which also writes
# docs/encodings.md) from measure_normal_error; tests/test_packing_exhaustive.py checks that a
# fresh measurement reproduces every entry.  Do not edit by hand.
# BEGIN NORMAL_ERRORS
NORMAL_ERRORS: dict[tuple[str, str, str], tuple[float, float]] = {
    ('kircher', 'rg8', 'hemisphere'): (0.8993, 0.3525),
    ('kircher', 'rgb10a2', 'hemisphere'): (0.334, 0.1038),
    ('kircher', 'rg16', 'hemisphere'): (0.003466, 0.001371),
    ('kircher', 'rg8_snorm', 'hemisphere'): (1.807, 0.7074),
    ('kircher', 'rg16_snorm', 'hemisphere'): (0.006971, 0.002743),
    ('kircher', 'rg16f', 'hemisphere'): (0.2231, 0.06515),
    ('kircher', 'rg32f', 'hemisphere'): (3.766e-05, 5.521e-06),
    ('spheremap', 'rg8', 'sphere'): (11.61, 0.4922),
    ('spheremap', 'rg8', 'hemisphere'): (0.8993, 0.3525),
    ('spheremap', 'rgb10a2', 'sphere'): (7.777, 0.1986),
    ('spheremap', 'rgb10a2', 'hemisphere'): (0.334, 0.1038),
    ('spheremap', 'rg16', 'sphere'): (0.746, 0.001946),
    ('spheremap', 'rg16', 'hemisphere'): (0.003466, 0.001371),
    ('spheremap', 'rg8_snorm', 'sphere'): (16.77, 0.9804),
    ('spheremap', 'rg8_snorm', 'hemisphere'): (1.807, 0.7074),
    ('spheremap', 'rg16_snorm', 'sphere'): (1.056, 0.003898),
    ('spheremap', 'rg16_snorm', 'hemisphere'): (0.006943, 0.002743),
    ('spheremap', 'rg16f', 'sphere'): (6.003, 0.08555),
    ('spheremap', 'rg16f', 'hemisphere'): (0.2231, 0.06515),
    ('spheremap', 'rg32f', 'sphere'): (0.0755, 9.371e-06),
    ('spheremap', 'rg32f', 'hemisphere'): (3.308e-05, 5.208e-06),
    ('octahedral', 'rg8', 'sphere'): (0.9532, 0.3356),
    ('octahedral', 'rg8', 'hemisphere'): (0.953, 0.3355),
    ('octahedral', 'rgb10a2', 'sphere'): (0.3951, 0.1205),
    ('octahedral', 'rgb10a2', 'hemisphere'): (0.3178, 0.1005),
    ('octahedral', 'rg16', 'sphere'): (0.00372, 0.001306),
    ('octahedral', 'rg16', 'hemisphere'): (0.003702, 0.001306),
    ('octahedral', 'rg8_snorm', 'sphere'): (1.914, 0.6736),
    ('octahedral', 'rg8_snorm', 'hemisphere'): (1.913, 0.6735),
    ('octahedral', 'rg16_snorm', 'sphere'): (0.007417, 0.00261),
    ('octahedral', 'rg16_snorm', 'hemisphere'): (0.007417, 0.002613),
    ('octahedral', 'rg16f', 'sphere'): (0.2373, 0.06054),
    ('octahedral', 'rg16f', 'hemisphere'): (0.2373, 0.06338),
    ('octahedral', 'rg32f', 'sphere'): (2.585e-05, 4.767e-06),
    ('octahedral', 'rg32f', 'hemisphere'): (2.533e-05, 4.688e-06),
}
# END NORMAL_ERRORS


def normal_error_figures(scheme: str, format_name: str,
                         hemisphere: Optional[bool] = None) -> tuple[float, float]:
    """(max, mean) angular error in degrees of ``scheme`` through ``format_name``: the
    tabulated measurement (``NORMAL_ERRORS``), measured now if the table lacks it.  The
    domain is the whole sphere, except for ``kircher`` (and when ``hemisphere`` is true): the
    hemisphere z >= 0 of camera-facing view-space normals, all Kircher's mapping is meant
    for."""
    if hemisphere is None:
        hemisphere = scheme == "kircher"
    key = (scheme, normal_storage(format_name), "hemisphere" if hemisphere else "sphere")
    if key not in NORMAL_ERRORS:
        m = measure_normal_error(key[0], key[1], hemisphere)
        return _sig(m.max), _sig(m.mean)
    return NORMAL_ERRORS[key]


def normal_error(scheme: str, format_name: str, samples: Optional[int] = None,
                 hemisphere: Optional[bool] = None) -> float:
    """Max angular error (degrees) of encode → quantise to ``format_name`` → decode: the
    tabulated figure (``normal_error_figures``), or with ``samples`` a fresh measurement on a
    grid of that many normals."""
    if samples is None:
        return normal_error_figures(scheme, format_name, hemisphere)[0]
    if hemisphere is None:
        hemisphere = scheme == "kircher"
    return measure_normal_error(scheme, normal_storage(format_name), bool(hemisphere),
                                samples).max


# =============================================================================================
# Trebilco's capacity table
# =============================================================================================


@record(frozen=True)
class CapacityRow:
    lights_per_fragment: int
    scene_lights: int            # 2^index_bits - 1 (index 0 = no light)
    index_bits: int
    channels: int                # 8-bit channels in all, over every surface
    surfaces: str
    bits_per_channel: float      # bits of one light in one channel (< 1: light split over targets)
    passes: int                  # passes of the light volumes
    stencil: bool
    details: str
    bitplanes: bool              # what build("bitplanes") can generate (one target, 1 pass)


def _surfaces(c: int) -> str:
    if c == 1:
        return "1 x 8bit channel"
    if c < 4 or c % 4:
        return f"{c} x 8bit channels"
    if c == 4:
        return "1 x RGBA8 surface"
    return f"{c // 4} x RGBA8 surfaces ({c // 4} render targets)"


def _table_row(index_bits: int, channels: int) -> CapacityRow:
    B, C = index_bits, channels
    lights = 8 * C // B                       # total bits / bits per light
    bpc = B / C
    if bpc >= 1:
        b = int(bpc)
        passes, stencil = 1, False
        details = (f"light index written directly out ({B} bits)" if C == 1
                   else f"light index split into {C}x{b}bit values")
    else:
        # Fewer than one bit per channel: each light goes 1 bit per channel into B channels
        # (B/4 targets); the stencil moves writes to the next targets once those are full.
        passes, stencil = C // B, True
        at_once = B // 4
        details = (f"light index split into {B}x1bit values; output to {at_once} render "
                   f"target{'s' if at_once > 1 else ''} at a time and use the stencil as in the "
                   f"max blend method when 8 overlaps are reached "
                   f"({passes} passes of the light volumes)")
    return CapacityRow(lights, 2 ** B - 1, B, C, _surfaces(C), bpc, passes, stencil, details,
                       bitplanes=(C <= 4 and bpc >= 1 and bpc.is_integer() and 8 % int(bpc) == 0))


def capacity_table(index_bits_options=(4, 8, 16), targets=(1, 2, 4, 8, 16)) -> list[CapacityRow]:
    """Trebilco's bit-packing table: lights per fragment for each light index size and each
    amount of 8-bit channels (``targets``: 1 = r8, 2 = rg8, 4 = one rgba8, 8 and 16 = two and
    four rgba8 render targets).  Combinations that do not hold one index (fewer bits than the
    index) or that need less than half a bit per channel (not in the paper) are left out; with
    the defaults the rows are exactly the paper's 13."""
    rows = []
    for B in index_bits_options:
        for C in targets:
            if 8 * C >= B and 2 * B >= C:
                rows.append(_table_row(B, C))
    return rows


def format_capacity_table(rows: list[CapacityRow]) -> str:
    """The table as Markdown (for reports and docs)."""
    out = ["| lights per fragment | scene lights | surfaces | details |",
           "|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r.lights_per_fragment} | {r.scene_lights} | {r.surfaces} | "
                   f"{r.details} |")
    return "\n".join(out)


_SCHEME_CLASSES: dict[str, type[_Scheme]] = {
    "bitplanes": _BitPlanes, "max_pairs": _MaxPairs, "channel_slots": _ChannelSlots,
    "split16": _Split16, "bitfield": _Bitfield, "kircher": _Kircher,
    "spheremap": _Spheremap, "octahedral": _Octahedral,
}
