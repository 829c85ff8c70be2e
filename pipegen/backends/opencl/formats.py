"""Target formats on the device, derived from ``core.formats`` (no format is named here): how a
format lives in an OpenCL buffer and in the raster kernel's registers (``cl_format``; the
float64 evaluation's ``cl_format64``), its loads, stores and decoding, and the prelude's
``pg_NAME_code4`` conversions of the narrow unorm formats (``scaled16_conversions``)."""

from __future__ import annotations

from typing import Optional

from pipegen.core import formats as F
from pipegen.core.float32 import f32
from pipegen.backends.opencl.dialect import OpenCLLanguage, dialect

_CL_SCALAR = {"uint8": "uchar", "int8": "char", "uint16": "ushort", "int16": "short",
              "uint32": "uint", "float16": "half", "float32": "float"}


def cl_format(name: str) -> dict:
    """How a target format lives in an OpenCL buffer and in the raster kernel's registers,
    derived from ``formats.Format`` (no format is named here).

    ``cls``: unorm8 | unorm | snorm | half | float | uint | d24 | d32f (depth bits).
    ``storage``: the buffer's element type (one per pixel).  ``reg``: the register type (uint4
    codes for unorm/uint, the int codes' bits for snorm, float4 values for float formats,
    uint / float for depth).  ``load``/``store``: expression / statement templates over ``b`` (buffer),
    ``i`` (pixel index) and ``r`` (register).  ``read``: the decoded float4 (uint4 for integer
    formats) a shader sees, over ``b``/``i``.  ``code``: the prelude function turning a float4
    into unorm codes; ``encode``: snorm's float4 ``r`` -> register expression.
    """
    fmt = F.get(name)
    n = fmt.channels
    np_name = fmt.element_dtype_name
    el = _CL_SCALAR[np_name]
    if fmt.kind is F.Kind.DEPTH_STENCIL:
        top = f"{fmt.max_codes[0]}.0f"
        return {"name": name, "cls": f"d{fmt.bits[0]}", "storage": el, "reg": el, "np": np_name,
                "load": "b[i]", "store": "b[i] = r;",
                "read": f"(float4)((float)b[i] / {top}, 0.0f, 0.0f, 1.0f)", "vec": "float4"}
    if fmt.kind is F.Kind.DEPTH:
        return {"name": name, "cls": f"d{fmt.bits[0]}f", "storage": el, "reg": el,
                "np": np_name, "load": "b[i]", "store": "b[i] = r;",
                "read": "(float4)(b[i], 0.0f, 0.0f, 1.0f)", "vec": "float4"}
    assert n in (1, 2, 4), f"{name}: OpenCL has no {n}-component storage of the same size"
    if fmt.kind is F.Kind.FLOAT:
        return _cl_float(fmt, el)
    storage = el if fmt.elements == 1 else f"{el}{n}"
    if fmt.packed:
        load, store = _packed_load_store(fmt)
    elif fmt.is_signed:
        load, store = _signed_load_store(fmt, el)
    else:
        load, store = _unsigned_load_store(fmt, el)
    out = {"name": name, "storage": storage, "reg": "uint4", "np": np_name, "load": load,
           "store": store, "read": None}
    if fmt.kind is F.Kind.UINT:
        return {**out, "cls": "uint", "vec": "uint4", "mask": f"{(1 << max(fmt.bits)) - 1}u"}
    rcpv = _rcp(pad_to_four(list(fmt.max_codes), n))
    out.update(vec="float4", rcpv=rcpv)
    if fmt.is_signed:
        ints = _signed_ints(fmt)
        return {**out, "cls": "snorm", "code": None, "encode": _snorm_encode(fmt),
                "read": f"fmax(convert_float4({ints}) * {rcpv}, -1.0f)"}
    if fmt.blend_is_exact:
        return {**out, "cls": "unorm8", "code": "pg_unorm8_code4"}
    assert fmt.encode is F.Encode.UNORM16, f"{name}: no OpenCL conversion for {fmt.encode}"
    narrow = any(b < 16 for b in fmt.bits)
    return {**out, "cls": "unorm", "code": f"pg_{name}_code4" if narrow else "pg_unorm16_code4"}


def cl_format64(name: str) -> dict:
    """``cl_format`` for the float64 evaluation: every non-integer target holds its values as
    doubles (one ``double``/``double2``/``double4`` per pixel, ``cls`` "f64"; depth ``cls``
    "d64", the window depth), unquantised; integer formats keep their codes (``cl_format``).
    ``src_clamp``: the function applied to a shader output (and the blend constant) before
    blending and storing, ``store_clamp`` to the stored result: the format's value range
    ([0, 1] unorm, [-1, 1] snorm, +-65504 for finite half values; none for float32)."""
    fmt = F.get(name)
    if fmt.kind is F.Kind.UINT:
        return cl_format(name)
    if fmt.kind in (F.Kind.DEPTH, F.Kind.DEPTH_STENCIL):
        return {"name": name, "cls": "d64", "storage": "double", "reg": "double",
                "np": "float64", "load": "b[i]", "store": "b[i] = r;",
                "read": "(double4)(b[i], 0.0, 0.0, 1.0)", "vec": "double4"}
    n = fmt.channels
    assert n in (1, 2, 4), name
    if n == 1:
        load, store = "(double4)(b[i], 0.0, 0.0, 1.0)", "b[i] = r.x;"
    elif n == 2:
        load, store = "(double4)(b[i], 0.0, 1.0)", "b[i] = r.xy;"
    else:
        load, store = "b[i]", "b[i] = r;"
    if fmt.kind is F.Kind.UNORM:
        src = store_clamp = "pg_dclamp01"
    elif fmt.kind is F.Kind.SNORM:
        src = store_clamp = "pg_dclamp11"
    elif max(fmt.bits) == 16:
        src, store_clamp = "", "pg_dclamp_half"
    else:
        src = store_clamp = ""
    return {"name": name, "cls": "f64", "storage": "double" if n == 1 else f"double{n}",
            "reg": "double4", "np": "float64", "load": load, "store": store, "read": load,
            "vec": "double4", "src_clamp": src, "store_clamp": store_clamp}


def clamp_range(name: str) -> Optional[tuple[float, float, bool]]:
    """The range a colour format clamps the values written to it into, as ``(lo, hi,
    finite)``, or None for formats that hold every value (float32, depth, stencil): unorm
    [0, 1], snorm [-1, 1], float16 +-65504 (``finite``: infinities are kept, not clamped),
    unsigned integers narrower than 32 bits [0, the largest code] (llvmpipe saturates them).  NaN is in no range's
    outside: its conversion (to the low end) is no clamp.  The raster kernel counts the
    fragments whose outputs lie outside (``clamp_test``; ``runtime/cl/clamps.py``)."""
    fmt = F.get(name)
    if fmt.kind is F.Kind.UNORM:
        return 0.0, 1.0, False
    if fmt.kind is F.Kind.SNORM:
        return -1.0, 1.0, False
    if fmt.kind is F.Kind.FLOAT and max(fmt.bits) == 16:
        return -65504.0, 65504.0, True
    if fmt.kind is F.Kind.UINT and max(fmt.bits) < 32:
        return 0.0, float((1 << max(fmt.bits)) - 1), False
    return None


def clamp_test(name: str, precision: str = "f32") -> Optional[dict]:
    """The raster kernel's count of the values a fragment writes outside ``clamp_range``
    (the prelude's ``pg_outside``/``pg_outside_half``, ``pg_track``, ``pg_add_clamps``), or
    None when the format clamps nothing: ``fn`` and its ``lo``/``hi`` literals in the
    output's type, ``mask`` (the format's channels, bits), ``types``: the row's counters
    (counts, largest, smallest: vectors of the output's width) and the largest's ``start``."""
    got = clamp_range(name)
    if got is None:
        return None
    lo, hi, finite = got
    fmt = F.get(name)
    mask = (1 << fmt.channels) - 1
    if fmt.kind is F.Kind.UINT:
        return {"fn": "pg_outside", "lo": f"{int(lo)}u", "hi": f"{int(hi)}u", "mask": mask,
                "types": ("int4", "uint4", "uint4"), "start": ("(uint4)(0u)",)}
    lang = dialect(precision)()
    fn = "pg_outside_half" if finite else "pg_outside"
    types, start = ("int4", "int4", "uint4"), "(int4)(INT_MIN)"
    if precision == "f64":
        types, start = ("long4", "long4", "ulong4"), "(long4)(LONG_MIN)"
    return {"fn": fn, "lo": lang.render_float(lo), "hi": lang.render_float(hi), "mask": mask,
            "types": types, "start": (start,)}


def pad_to_four(values: list, n: int) -> list:
    """Per-channel values of an n-channel format, padded to 4 (missing channels repeat the
    last value, whose lanes are never used)."""
    return values + values[-1:] * (4 - n)


def _unsigned_load_store(fmt: F.Format, el: str) -> tuple[str, str]:
    n = fmt.channels
    one = fmt.max_codes[-1] if fmt.is_normalized else 1      # GL reads missing alpha as 1
    if n == 1:
        return f"(uint4)(b[i], 0u, 0u, {one}u)", f"b[i] = ({el})r.x;"
    if n == 2:
        return f"(uint4)(convert_uint2(b[i]), 0u, {one}u)", f"b[i] = convert_{el}2(r.xy);"
    if el == "uint":
        return "b[i]", "b[i] = r;"
    return "convert_uint4(b[i])", f"b[i] = convert_{el}4(r);"


def _signed_ints(fmt: F.Format) -> str:
    """int4 codes of an snorm pixel (``b[i]``); GL reads missing channels as (0, 1)."""
    n, one = fmt.channels, fmt.max_codes[-1]
    if n == 1:
        return f"(int4)(b[i], 0, 0, {one})"
    if n == 2:
        return f"(int4)(convert_int2(b[i]), 0, {one})"
    return "convert_int4(b[i])"


def _signed_load_store(fmt: F.Format, el: str) -> tuple[str, str]:
    """snorm: registers hold the int codes' bits (uint4, so masks and moves are shared)."""
    n = fmt.channels
    if n == 1:
        store = f"b[i] = ({el})as_int(r.x);"
    elif n == 2:
        store = f"b[i] = convert_{el}2(as_int2(r.xy));"
    else:
        store = f"b[i] = convert_{el}4(as_int4(r));"
    return f"as_uint4({_signed_ints(fmt)})", store


def _packed_load_store(fmt: F.Format) -> tuple[str, str]:
    """Channels packed into one word, channel 0 in the low bits."""
    loads, stores = [], []
    for k, (bits, shift) in enumerate(zip(fmt.bits, fmt.shifts)):
        mask = f" & {(1 << bits) - 1}u" if shift + bits < fmt.word_bits else ""
        word = f"(b[i] >> {shift})" if shift and mask else f"b[i] >> {shift}" if shift else "b[i]"
        loads.append(word + mask)
        value = f"r.{'xyzw'[k]}"
        value = f"({value}{mask})" if mask else value
        stores.append(f"({value} << {shift})" if shift else value)
    loads += ["0u", "0u", "0u", f"{fmt.max_codes[-1]}u"][len(loads):]
    return f"(uint4)({', '.join(loads)})", f"b[i] = {' | '.join(stores)};"


def _snorm_encode(fmt: F.Format) -> str:
    """float4 ``r`` -> snorm register (the codes' bits), as ``Format.quantize`` (``Encode``)."""
    m = rcp_literal(fmt.max_codes[0])
    if fmt.encode is F.Encode.ROUND_SAT:     # round x * max, saturate to [-max - 1, max]
        lo = rcp_literal(-fmt.max_codes[0] - 1)
        return f"as_uint4(convert_int4_rte(fmin(fmax(r * {m}, {lo}), {m})))"
    assert fmt.encode is F.Encode.ROUND, fmt.encode
    return f"as_uint4(convert_int4_rte(fmin(fmax(r, -1.0f), 1.0f) * {m}))"


def rcp_literal(x: float) -> str:
    """A float32 literal as the programs spell it (the name: most are reciprocals)."""
    return OpenCLLanguage().render_float(float(x))


def _cl_float(fmt: F.Format, el: str) -> dict:
    n, name = fmt.channels, fmt.name
    if el == "half":
        suffix = "" if n == 1 else str(n)
        if n == 1:
            load = "(float4)(vload_half(i, b), 0.0f, 0.0f, 1.0f)"
            store = "vstore_half_rtz(r.x, i, b);"
        elif n == 2:
            load = "(float4)(vload_half2(i, b), 0.0f, 1.0f)"
            store = "vstore_half2_rtz(r.xy, i, b);"
        else:
            load = "vload_half4(i, b)"
            store = "vstore_half4_rtz(r, i, b);"
        return {"name": name, "cls": "half", "storage": "half", "reg": "float4",
                "np": "float16", "load": load, "store": store, "read": load, "vec": "float4",
                "suffix": suffix}
    storage = "float" if n == 1 else f"float{n}"
    if n == 1:
        load, store = "(float4)(b[i], 0.0f, 0.0f, 1.0f)", "b[i] = r.x;"
    elif n == 2:
        load, store = "(float4)(b[i], 0.0f, 1.0f)", "b[i] = r.xy;"
    else:
        load, store = "b[i]", "b[i] = r;"
    return {"name": name, "cls": "float", "storage": storage, "reg": "float4",
            "np": "float32", "load": load, "store": store, "read": load, "vec": "float4"}


def scaled16_conversions() -> list[dict]:
    """The prelude's ``pg_NAME_code4`` of the unorm formats narrower than 16 bits that llvmpipe
    stores through its 16-bit blend type (``formats.Encode.UNORM16``): ``expr`` narrows the
    16-bit codes ``c`` with Mesa's ``scale_bits`` (``formats.scale_bits16``), ``doc`` says so."""
    out = []
    for fmt in F.FORMATS.values():
        if fmt.kind is not F.Kind.UNORM or fmt.encode is not F.Encode.UNORM16 \
                or all(b >= 16 for b in fmt.bits):
            continue
        assert fmt.channels == 4, fmt.name
        exprs, docs = [], []
        k = 0
        while k < 4:           # runs of channels with the same bits: one swizzle each
            j = k
            while j < 4 and fmt.bits[j] == fmt.bits[k]:
                j += 1
            b, d, sw = fmt.bits[k], 16 - fmt.bits[k], "xyzw"[k:j]
            who = "alpha" if sw == "w" else "rgba"[k:j]
            if d <= b:
                exprs.append(f"c.{sw} >> {d}")
                docs.append(f'{who} c16 >> {d} (truncating, "wrong rounding" in Mesa\'s words)')
            else:
                exprs.append(f"((c.{sw} >> {b}) * {(1 << b) - 1}u + {1 << (d - 1)}u) >> {d}")
                docs.append(f"{who} ((c16 >> {b}) * {(1 << b) - 1} + 2^{d - 1}) >> {d}")
            k = j
        out.append({"name": fmt.name, "expr": ", ".join(exprs), "doc": ", ".join(docs)})
    return out


def _rcp(maxima) -> str:
    """float4 literal of the float32 reciprocals 1/max: llvmpipe turns unorm codes into floats
    as ``code * (1/max)`` (measured; 196 * (1/255) is one ulp above 196 / 255)."""
    lang = OpenCLLanguage()
    vals = [lang.render_float(f32(1.0 / f32(m))) for m in maxima]
    return f"(float4)({', '.join(vals)})"


def read_expr(f: dict) -> str:
    """Decoded value a shader reads (float4 / uint4) over buffer ``b`` and index ``i``."""
    if f["read"] is not None:
        return f["read"]
    if f["cls"] == "uint":
        return f["load"]
    return f"convert_float4({f['load']}) * {f['rcpv']}"

