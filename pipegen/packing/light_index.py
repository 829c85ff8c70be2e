"""The light-index schemes of Trebilco 2007 ("Light indexed deferred rendering"): which lights
reach a pixel, as 1-based light indices packed into a colour target (0 means no light).

* ``bitplanes``: bit shifting, blend ``ONE, CONSTANT_COLOR`` (``BitPlanes``);
* ``max_pairs``: MAX blend of ``(i, 1-i)`` with the stencil (``MaxPairs``);
* ``channel_slots``: CPU-sorted light sets, one channel each (``ChannelSlots``).

Next to each, the numpy model of how the target fills (``blend_bitplanes``,
``emulate_bitplanes``, ``emulate_max_pairs``, ``sort_lights_into_slots``).
"""

from __future__ import annotations

from typing import Optional

from pipegen.core import formats
from pipegen.core.diagnostics import PipegenError, Span
from pipegen.core.formats import Format, Kind
from pipegen.ir import nodes as ir
from pipegen.packing.base import (Scheme, as_uint32, cannot_fit, float_literal, int_option,
                                  need_target, unorm_code_expr, unorm_codes)
from pipegen.packing.capacity import capacity_row

_XYZW = "xyzw"


# =============================================================================================
# Light indices: bit planes (Trebilco's "bit shifting")
# =============================================================================================


class BitPlanes(Scheme):
    """An index of B bits is split into C chunks of b = B/C bits, chunk c in the top b bits of
    channel c.  The blend ``dst = src + dst * 2^-b`` shifts older lights down b bits per write,
    so each 8-bit channel holds 8/b lights, newest in the top bits.

    Chunk c holds index bits [c*b, (c+1)*b): red gets the low bits, as in the paper
    ("Red channel = (index & 0x3) << 6").
    """

    OPTIONS = ("index_bits", "target")

    def __init__(self, options: dict, fmt: Optional[Format], span: Optional[Span]):
        B = int_option("bitplanes", options, "index_bits", span)
        fmt = need_target("bitplanes", fmt, span)
        if not fmt.blendable:
            raise cannot_fit(span, f"bit planes need a blendable 8-bit unorm colour target, "
                             f"not {fmt.name}", "use rgba8, rg8 or r8")
        if not fmt.blend_is_exact:
            raise PipegenError(
                span, f"bit planes into a target whose blending is not bit-exact ({fmt.name})",
                "the blend must shift codes exactly; only 8-bit unorm targets (r8, rg8, rgba8) "
                "blend bit-exactly")
        C = fmt.channels
        if B < 1 or B % C or 8 % (B // C):
            fits = [bits for bits in range(1, 8 * C + 1) if bits % C == 0 and 8 % (bits // C) == 0]
            raise cannot_fit(
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
        row = capacity_row(B, C)
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
            lines.append(f"    index = index | ((({unorm_code_expr('v.' + _XYZW[c], 255)} >> s) "
                         f"& {mask}u) << {c * b}u);")
        lines += ["    return index;", "}"]
        return {"plane_value": plane, "unpack": "\n".join(lines)}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        b, C, cap = self.b, self.C, self.capacity

        def plane_value(index):
            return planes_of(as_uint32(index), b, C)

        def unpack(v, k):
            v = np.asarray(v, dtype=F32)
            if not 0 <= k < cap:
                return np.zeros(v.shape[:-1], dtype=np.uint32)
            return code_in_slot(v, k, b, C)

        return {"plane_value": plane_value, "unpack": unpack}


def planes_of(code, b: int, channels: int):
    """The rgba value (float32, /255) that writes uint32 ``code`` as bit planes: chunk c (``b``
    bits) of the code in the top bits of channel c, for ``channels`` channels.  Shared by the
    float64 mirrors of ``bitplanes`` and ``intensity_planes``."""
    import numpy as np
    out = np.zeros(np.shape(code) + (4,), dtype=np.float32)
    mask = (1 << b) - 1
    for c in range(channels):
        out[..., c] = (((code >> (c * b)) & mask) << (8 - b)).astype(np.float32) / np.float32(255)
    return out


def code_in_slot(v, k: int, b: int, channels: int):
    """The uint32 code in slot ``k`` of bit-plane value ``v`` (float32 rgba, 8-bit unorm
    channels): chunk c taken from bits ``8 - b (k + 1)`` up of channel c."""
    import numpy as np
    s, mask = 8 - b * (k + 1), (1 << b) - 1
    code = np.zeros(v.shape[:-1], dtype=np.uint32)
    for c in range(channels):     # uint32 throughout (numpy 1.x widens a numpy int k)
        code |= (((unorm_codes(v[..., c], 255) >> s) & mask) << (c * b)).astype(np.uint32)
    return code


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
    impl = BitPlanes({"index_bits": index_bits}, fmt, None).mirror()
    b = index_bits // fmt.channels
    idx = as_uint32(indices)
    codes = np.zeros(idx.shape[1:] + (4,), dtype=np.uint8)
    for light in idx:
        src = np.rint(impl["plane_value"](light).astype(np.float64) * 255)
        codes = blend_bitplanes(codes, src, b, mode)
    codes[..., fmt.channels:] = 0
    return codes.astype(F32) / F32(255)


# =============================================================================================
# Light indices: MAX-blended pairs with the stencil (Trebilco after Farrar)
# =============================================================================================


class MaxPairs(Scheme):
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
        fmt = need_target("max_pairs", fmt, span)
        if fmt.kind is not Kind.UNORM or fmt.channels != 4 or len(set(fmt.bits)) != 1:
            raise cannot_fit(span, f"max_pairs needs a 4-channel unorm target, not {fmt.name}",
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
                f"    float i = float(index) / {float_literal(sc)};\n"
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
            f"        hi = {unorm_code_expr('v.x', sc)};\n"
            f"        lo = {sc}u - {unorm_code_expr('v.y', sc)};\n"
            f"    }} else if (k == 2 || k == 3) {{\n"
            f"        hi = {unorm_code_expr('v.z', sc)};\n"
            f"        lo = {sc}u - {unorm_code_expr('v.w', sc)};\n"
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
            i = as_uint32(index).astype(F32) / F32(sc)
            return np.stack([i, F32(1) - i], axis=-1)

        def value(index):
            p = pair(index)
            return np.concatenate([p, p], axis=-1)

        def unpack(v, k):
            v = np.asarray(v, dtype=F32)
            if k not in (0, 1, 2, 3):
                return np.zeros(v.shape[:-1], dtype=np.uint32)
            c = 0 if k < 2 else 2
            hi = unorm_codes(v[..., c], sc)
            lo = np.uint32(sc) - unorm_codes(v[..., c + 1], sc)
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


class ChannelSlots(Scheme):
    """Slot set k is drawn into channel k (``draw lights as sphere in NAME[k]`` with ``mask``
    on that channel).  The CPU puts every light into a set where its sphere overlaps no other,
    so a surface point is reached by at most one light per set and no blending is needed."""

    OPTIONS = ("target", "slots")

    def __init__(self, options, fmt, span):
        fmt = need_target("channel_slots", fmt, span)
        if fmt.kind is not Kind.UNORM:
            raise cannot_fit(span, f"channel_slots needs a unorm target, not {fmt.name}",
                             "use rgba8 (255 lights) or rgba16 (65535 lights)")
        n = int_option("channel_slots", options, "slots", span, default=fmt.channels)
        if not 1 <= n <= fmt.channels:
            raise cannot_fit(span, f"{n} slots in the {fmt.channels} channel(s) of {fmt.name}",
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
                 f"    return vec4(float(index) / {float_literal(sc)});\n"
                 f"}}")
        lines = ["// The index in slot k (0 = none).",
                 f"uint {name}_unpack(vec4 v, int k) {{"]
        for k in range(self.slots):
            lines += [f"    if (k == {k}) {{",
                      f"        return {unorm_code_expr('v.' + _XYZW[k], sc)};",
                      "    }"]
        lines += ["    return 0u;", "}"]
        return {"value": value, "unpack": "\n".join(lines)}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        sc, n = self.scale, self.slots

        def value(index):
            i = as_uint32(index).astype(F32) / F32(sc)
            return np.repeat(i[..., None], 4, axis=-1)

        def unpack(v, k):
            v = np.asarray(v, dtype=F32)
            if not 0 <= k < n:
                return np.zeros(v.shape[:-1], dtype=np.uint32)
            return unorm_codes(v[..., k], sc)

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
