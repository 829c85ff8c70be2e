"""The numpy oracle of GL's fixed-function per-fragment rules (backend neutral).

Written from the OpenGL 4.5 core specification (§14.9 depth/stencil, §17.3 per-fragment
operations, §17.3.6 blending, §2.3.5 fixed-point conversion) and vectorised over pixels.
Both runtime test suites (GL/llvmpipe and the OpenCL reference) compare against it, so it knows
nothing of either backend.  State arguments take the PLAN spellings (``"less"``,
``["add", "one", "zero"]``, the pass ``state`` dict of internals.md) or the ``ir`` enums and
dataclasses.

Values and codes
----------------
*Codes* are what a target stores (``formats.Format.dtype``); *values* are the float64 numbers a
shader writes or reads.  ``load`` pads missing channels with GL's (0, 0, 0, 1).

Rounding model (spec plus the behaviours measured on Mesa 22.3 llvmpipe; see tests):

* float -> unorm: clamp to [0, 1], multiply by 2^b - 1 *in float32*, round half to even;
  NaN and -inf -> 0, +inf -> max.  (``formats.Format.quantize`` multiplies in float64, which
  rounds differently next to ties: (k + 0.5)/255 as float32 times 255 is exactly k + 0.5.)
* float -> half (``half_store``): llvmpipe rounds toward zero when it stores colour outputs into
  16-bit float targets (so overflow gives ±65504, never inf) and keeps half denormals; the
  default ``rounding="rtz"`` follows it, ``"rne"`` is IEEE round-to-nearest-even.
* window z -> d24: llvmpipe computes ``rint(float32(float32(z) * 16777215))`` (the product in
  float32): ``depth_codes``.  A float64 product (``formats.quantize``) differs by one code for
  about 1 % of random depths.
* Blending follows the spec in float64: for fixed-point targets the source, destination,
  constant and every factor are clamped to [0, 1] and so is the result; float targets clamp
  nothing.  Two models of what llvmpipe actually computes, both measured bit-exact over every
  op and factor (tests/test_gl_state.py): ``blend_unorm8`` (8-bit fixed point: source and
  constant converted to codes, llvmpipe's rounding of 8-bit products) differs from the float64
  formula by up to 2 codes per blend (``formats.Format.tolerance(1)``);
  ``blend(..., precision=np.float32)`` is float targets' float32 evaluation.
  ``blend(..., quantize_src=True)`` converts the source to the target's bits first.

Per-primitive fragment processing (``process_fragments``) follows the GL order: scissor and
coverage -> stencil test -> depth test -> stencil update (fail / zfail / zpass, write mask) ->
depth write -> blend -> colour write mask -> store.
"""

from __future__ import annotations

from typing import Any, Mapping, Optional, Sequence

import numpy as np

from pipegen.core import formats as F

__all__ = [
    "compare", "unorm_store", "half_store", "store", "load", "depth_codes", "depth_test",
    "depth_update", "stencil_test", "stencil_op", "stencil_update", "blend_factor", "blend",
    "mul_unorm8", "blend_unorm8", "color_mask", "write_color", "process_fragments",
]


def _v(x: Any) -> Any:
    return getattr(x, "value", x)


def _fmt(fmt) -> F.Format:
    return fmt if isinstance(fmt, F.Format) else F.get(fmt)


# ---------------------------------------------------------------------------------------------
# comparisons
# ---------------------------------------------------------------------------------------------


def compare(func, a, b) -> np.ndarray:
    """``a FUNC b`` elementwise (stencil: ``ref FUNC stored``; depth: ``incoming FUNC stored``)."""
    f = _v(func)
    a, b = np.asarray(a), np.asarray(b)
    if f == "never":
        return np.zeros(np.broadcast(a, b).shape, bool)
    if f == "always":
        return np.ones(np.broadcast(a, b).shape, bool)
    return {"less": np.less, "equal": np.equal, "lequal": np.less_equal,
            "greater": np.greater, "notequal": np.not_equal,
            "gequal": np.greater_equal}[f](a, b)


# ---------------------------------------------------------------------------------------------
# conversions
# ---------------------------------------------------------------------------------------------


def unorm_store(x, bits: int) -> np.ndarray:
    """Float -> b-bit unorm code: clamp to [0,1], scale, round half to even; NaN -> 0.

    The value and the product are float32, as in a shader (llvmpipe, measured bit-exact for
    8- and 16-bit channels; OpenCL's ``convert_uchar_sat_rte(x * 255.0f)`` is the same): near
    ties the float32 product rounds differently from a float64 one.
    """
    x = np.nan_to_num(np.asarray(x, dtype=np.float32), nan=0.0)
    y = np.rint(np.clip(x, np.float32(0.0), np.float32(1.0)) * np.float32((1 << bits) - 1))
    return y.astype(np.uint32 if bits > 16 else np.uint16 if bits > 8 else np.uint8)


def half_store(x, rounding: str = "rtz", flush: bool = False) -> np.ndarray:
    """Float -> float16 the way a colour store does.

    ``rounding="rtz"`` (llvmpipe, measured): round toward zero; |x| beyond the largest half
    becomes ±65504; ±inf stays ±inf; half denormals are kept.  ``"rne"``: IEEE round to nearest
    even with overflow to ±inf.  ``flush=True`` flushes half denormals to signed zero.
    """
    x = np.asarray(x, dtype=np.float64)
    x32 = x.astype(np.float32)             # the shader computes in float32
    with np.errstate(over="ignore", invalid="ignore"):
        h = x32.astype(np.float16)         # round to nearest even
        if rounding == "rtz":
            back = h.astype(np.float32)
            finite_in = np.isfinite(x32)
            # rounded away from zero (incl. overflow to inf): step one half towards zero
            away = finite_in & (np.abs(back) > np.abs(x32))
            h = np.where(away, np.nextafter(h, np.float16(0.0)), h)
        elif rounding != "rne":
            raise ValueError(f"rounding {rounding!r}")
    h = h.astype(np.float16)
    if flush:
        h = F.flush_denormals(h)
    return h


def store(fmt, x, half_rounding: str = "rtz") -> np.ndarray:
    """Shader output values -> stored codes of ``fmt`` (its channels only).

    ``x`` has a trailing channel axis with at least the format's channels (RGBA is fine);
    single-channel formats return arrays without it, like a render's result.
    """
    f = _fmt(fmt)
    x = np.asarray(x)
    if f.is_color:
        assert x.ndim and x.shape[-1] >= f.channels, "values need a trailing channel axis"
        x = x[..., 0] if f.channels == 1 else x[..., :f.channels]
    if f.kind is F.Kind.UNORM:
        if len(set(f.bits)) == 1:
            return unorm_store(x, f.bits[0]).astype(f.dtype)
        return np.stack([unorm_store(x[..., i], b) for i, b in enumerate(f.bits)],
                        axis=-1).astype(f.dtype)
    if f.kind is F.Kind.FLOAT and f.dtype == np.float16:
        return half_store(x, half_rounding)
    if f.kind is F.Kind.FLOAT:
        return np.asarray(x, dtype=np.float64).astype(np.float32)
    if f.kind is F.Kind.UINT:
        mask = (1 << max(f.bits)) - 1
        return (np.asarray(x).astype(np.int64) & mask).astype(f.dtype)
    return f.quantize(x)


def load(fmt, codes) -> np.ndarray:
    """Stored codes -> the float64 RGBA a blend (or shader) sees: missing channels (0, 0, 0, 1)."""
    f = _fmt(fmt)
    v = f.dequantize(codes)
    if f.channels == 1:
        v = v[..., None]
    pad = [0.0, 0.0, 0.0, 1.0][f.channels:]
    if pad:
        v = np.concatenate([v, np.broadcast_to(np.array(pad), v.shape[:-1] + (len(pad),))],
                           axis=-1)
    return v


def depth_codes(fmt, z) -> np.ndarray:
    """Window-space fragment depth -> the depth format's codes (see the module docstring)."""
    f = _fmt(fmt)
    z32 = np.clip(np.asarray(z, dtype=np.float32), np.float32(0.0), np.float32(1.0))
    if f.kind is F.Kind.DEPTH_STENCIL:
        return np.rint(z32 * np.float32(16777215.0)).astype(np.uint32)
    return F.flush_denormals(z32)


# ---------------------------------------------------------------------------------------------
# depth and stencil
# ---------------------------------------------------------------------------------------------


def depth_test(func, z, stored, fmt) -> np.ndarray:
    """Does a fragment at window depth ``z`` pass against ``stored`` codes?  (``z FUNC stored``
    after converting ``z`` to the buffer's precision.)"""
    return compare(func, depth_codes(fmt, z), np.asarray(stored))


def depth_update(func, write: bool, z, stored, fmt, mask=True) -> tuple[np.ndarray, np.ndarray]:
    """(passed, new stored codes): the depth test plus the write where ``mask & passed``."""
    passed = depth_test(func, z, stored, fmt) & np.asarray(mask, bool)
    stored = np.asarray(stored)
    if write:
        stored = np.where(passed, depth_codes(fmt, z), stored).astype(stored.dtype)
    return passed, stored


def stencil_test(func, ref: int, read_mask: int, stencil) -> np.ndarray:
    """``(ref & read_mask) FUNC (stencil & read_mask)``; ``ref`` is clamped to [0, 255]."""
    m = int(read_mask) & 0xFF
    r = min(max(int(ref), 0), 255) & m
    return compare(func, np.uint32(r), np.asarray(stencil, dtype=np.uint32) & m)


def stencil_op(op, stencil, ref: int, bits: int = 8) -> np.ndarray:
    """The new stencil value of one op (before the write mask)."""
    o = _v(op)
    s = np.asarray(stencil, dtype=np.int64)
    top = (1 << bits) - 1
    if o == "keep":
        r = s
    elif o == "zero":
        r = np.zeros_like(s)
    elif o == "replace":
        r = np.full_like(s, min(max(int(ref), 0), top))
    elif o == "incr":
        r = np.minimum(s + 1, top)
    elif o == "decr":
        r = np.maximum(s - 1, 0)
    elif o == "incr_wrap":
        r = (s + 1) & top
    elif o == "decr_wrap":
        r = (s - 1) & top
    elif o == "invert":
        r = ~s & top
    else:
        raise ValueError(f"stencil op {o!r}")
    return r


def _face(face) -> dict:
    if isinstance(face, Mapping):
        d = {"func": "always", "ref": 0, "read_mask": 255, "write_mask": 255,
             "fail": "keep", "zfail": "keep", "zpass": "keep"}
        d.update(face)
        return {k: _v(v) for k, v in d.items()}
    return {k: _v(getattr(face, k)) for k in
            ("func", "ref", "read_mask", "write_mask", "fail", "zfail", "zpass")}


def _faces(state) -> tuple[dict, dict]:
    if isinstance(state, Mapping) and ("front" in state or "back" in state):
        return _face(state.get("front", {})), _face(state.get("back", {}))
    if hasattr(state, "front"):
        return _face(state.front), _face(state.back)
    f = _face(state)     # one face description for both
    return f, f


def stencil_update(stencil, state, depth_pass=True, front_facing=True, mask=True
                   ) -> tuple[np.ndarray, np.ndarray]:
    """One primitive's stencil stage: (new stencil, stencil-test passed).

    ``state``: ``{"front": face, "back": face}`` (PLAN), an ``ir.StencilState``, or a single
    face used for both.  ``depth_pass``: the depth test result (True where there is no depth
    test).  ``front_facing`` and ``mask`` (coverage) broadcast against ``stencil``.  Pixels
    outside ``mask`` keep their value.  The fragment survives where ``passed & depth_pass``.
    """
    s = np.asarray(stencil).astype(np.int64)
    shape = s.shape
    front, back = _faces(state)
    ff = np.broadcast_to(np.asarray(front_facing, bool), shape)
    dp = np.broadcast_to(np.asarray(depth_pass, bool), shape)
    cov = np.broadcast_to(np.asarray(mask, bool), shape)
    out = s.copy()
    passed = np.zeros(shape, bool)
    for face, sel in ((front, ff), (back, ~ff)):
        p = stencil_test(face["func"], face["ref"], face["read_mask"], s)
        new = np.where(~p, stencil_op(face["fail"], s, face["ref"]),
                       np.where(dp, stencil_op(face["zpass"], s, face["ref"]),
                                stencil_op(face["zfail"], s, face["ref"])))
        wm = int(face["write_mask"]) & 0xFF
        new = (s & ~wm) | (new & wm)
        here = sel & cov
        out = np.where(here, new, out)
        passed = np.where(here, p, passed)
    return out.astype(np.asarray(stencil).dtype), passed


# ---------------------------------------------------------------------------------------------
# blending
# ---------------------------------------------------------------------------------------------


def _eq(e) -> tuple[str, str, str]:
    if hasattr(e, "op"):
        return _v(e.op), _v(e.src), _v(e.dst)
    e = [_v(x) for x in e]
    if len(e) == 1:
        return e[0], "one", "one"
    return e[0], e[1], e[2]


def blend_factor(name, src, dst, constant, channels: str = "rgb", precision=np.float64
                 ) -> np.ndarray:
    """The factor ``name`` for RGB (``channels="rgb"``, shape (..., 3)) or alpha ((..., 1))."""
    n = _v(name)
    src, dst = np.asarray(src, precision), np.asarray(dst, precision)
    c = np.broadcast_to(np.asarray(constant, precision), src.shape)
    sl = slice(0, 3) if channels == "rgb" else slice(3, 4)
    one = np.ones(src[..., sl].shape, precision)
    if n == "zero":
        return 0.0 * one
    if n == "one":
        return one
    if n == "src_color":
        return src[..., sl]
    if n == "one_minus_src_color":
        return 1.0 - src[..., sl]
    if n == "dst_color":
        return dst[..., sl]
    if n == "one_minus_dst_color":
        return 1.0 - dst[..., sl]
    if n == "src_alpha":
        return src[..., 3:4] * one
    if n == "one_minus_src_alpha":
        return (1.0 - src[..., 3:4]) * one
    if n == "dst_alpha":
        return dst[..., 3:4] * one
    if n == "one_minus_dst_alpha":
        return (1.0 - dst[..., 3:4]) * one
    if n == "constant_color":
        return c[..., sl]
    if n == "one_minus_constant_color":
        return 1.0 - c[..., sl]
    if n == "constant_alpha":
        return c[..., 3:4] * one
    if n == "one_minus_constant_alpha":
        return (1.0 - c[..., 3:4]) * one
    if n == "src_alpha_saturate":
        if channels != "rgb":
            return one
        return np.minimum(src[..., 3:4], 1.0 - dst[..., 3:4]) * one
    raise ValueError(f"blend factor {n!r}")


def _apply(op, s, d, sf, df) -> np.ndarray:
    if op == "add":
        return s * sf + d * df
    if op == "sub":
        return s * sf - d * df
    if op == "revsub":
        return d * df - s * sf
    if op == "min":
        return np.minimum(s, d)
    if op == "max":
        return np.maximum(s, d)
    raise ValueError(f"blend op {op!r}")


def blend(src, dst, eq_rgb, eq_alpha, constant, fmt, quantize_src: bool = False,
          precision=np.float64) -> np.ndarray:
    """The blended RGBA value (float64, (..., 4)) for source ``src`` and destination ``dst``.

    ``src``: shader output values (..., 4); ``dst``: destination *values* (``load(fmt, codes)``);
    ``eq_rgb``/``eq_alpha``: ``(op, src_factor, dst_factor)``; ``constant``: the blend colour.
    Fixed-point formats clamp inputs, factors and the result to [0, 1]; float formats don't.
    Store the result with ``store(fmt, ...)``.  ``precision=np.float32`` evaluates every
    operation in float32 (each product and sum rounded, no fused multiply-add, and a factor
    shared by both terms applied once to their sum/difference): what llvmpipe does for float
    targets, bit-exactly (measured).
    """
    f = _fmt(fmt)
    s = np.asarray(src, np.float64).astype(precision)
    d = np.asarray(dst, np.float64).astype(precision)
    c = np.broadcast_to(np.asarray(constant, np.float64).astype(precision), s.shape)
    fixed = f.kind is F.Kind.UNORM
    if fixed:
        s = np.clip(np.nan_to_num(s, nan=0.0), 0.0, 1.0)
        d = np.clip(d, 0.0, 1.0)
        c = np.clip(c, 0.0, 1.0)
        if quantize_src:
            bits = (list(f.bits) + [8] * 4)[:4]
            s = np.stack([unorm_store(s[..., i], b) / float((1 << b) - 1)
                          for i, b in enumerate(bits)], axis=-1)
    out = np.empty(np.broadcast(s, d).shape, precision)
    for sl, eq, ch in ((slice(0, 3), eq_rgb, "rgb"), (slice(3, 4), eq_alpha, "alpha")):
        op, fs, fd = _eq(eq)
        sf = blend_factor(fs, s, d, c, ch, precision)
        df = blend_factor(fd, s, d, c, ch, precision)
        if fixed:
            sf, df = np.clip(sf, 0.0, 1.0), np.clip(df, 0.0, 1.0)
        with np.errstate(over="ignore", invalid="ignore"):
            if precision is np.float32 and fs == fd and op in ("add", "sub", "revsub"):
                # llvmpipe factors a shared factor out: (s +- d) * f, one rounding less
                sum_ = _apply(op, s[..., sl], d[..., sl], 1.0, 1.0)
                out[..., sl] = sum_ * sf
            else:
                out[..., sl] = _apply(op, s[..., sl], d[..., sl], sf, df)
    if fixed:
        out = np.clip(out, 0.0, 1.0)
    return out.astype(np.float64)


def mul_unorm8(a, b) -> np.ndarray:
    """llvmpipe's 8-bit normalised product ``a*b/255`` of codes: ``(t + (t >> 8) + 128) >> 8``
    with ``t = a*b``.  It differs from round-to-nearest for 24 of the 65536 code pairs, all
    just above a half (229 * 152 / 255 = 136.502 -> 136)."""
    t = np.asarray(a, np.int64) * np.asarray(b, np.int64)
    return (t + (t >> 8) + 0x80) >> 8


def blend_unorm8(src, dst_codes, eq_rgb, eq_alpha, constant) -> np.ndarray:
    """Blending into an 8-bit unorm target in 8-bit fixed point, the way llvmpipe does it.

    Source and constant are converted to codes first (``unorm_store``), factors are codes
    (``1 - x`` is ``255 - x``), each product is ``mul_unorm8``, sums saturate.  Measured
    bit-exact against Mesa 22.3 llvmpipe over every equation and factor (tests); the spec's
    float formula (``blend``) differs from it by up to 2 codes.  A backend that wants to match
    llvmpipe exactly on rgba8 blends (packing schemes) can implement this.  Returns codes
    (..., 4); the caller keeps the channels its format has (missing dst alpha: pass 255).
    """
    s = unorm_store(np.asarray(src, np.float64), 8).astype(np.int64)
    d = np.asarray(dst_codes, np.int64)
    c = np.broadcast_to(unorm_store(np.asarray(constant, np.float64), 8).astype(np.int64),
                        s.shape)
    out = np.zeros(np.broadcast(s, d).shape, np.int64)
    for sl, eq, ch in ((slice(0, 3), eq_rgb, "rgb"), (slice(3, 4), eq_alpha, "alpha")):
        op, fs, fd = _eq(eq)
        a, b = s[..., sl], d[..., sl]
        if op in ("min", "max"):
            r = np.minimum(a, b) if op == "min" else np.maximum(a, b)
        else:
            sf = np.rint(blend_factor(fs, s / 255.0, d / 255.0, c / 255.0, ch) * 255.0)
            df = np.rint(blend_factor(fd, s / 255.0, d / 255.0, c / 255.0, ch) * 255.0)
            x, y = mul_unorm8(a, sf), mul_unorm8(b, df)
            r = x + y if op == "add" else x - y if op == "sub" else y - x
        out[..., sl] = np.clip(r, 0, 255)
    return out.astype(np.uint8)


def color_mask(new, old, write_mask, fmt) -> np.ndarray:
    """Keep ``old`` codes in channels whose write mask is off."""
    f = _fmt(fmt)
    new, old = np.asarray(new), np.asarray(old)
    m = [bool(x) for x in write_mask]
    if f.channels == 1:          # arrays without a channel axis: only the red mask applies
        return new if m[0] else old
    keep = np.array(m[:f.channels])
    return np.where(keep, new, old).astype(old.dtype)


def _blend_state(b) -> dict:
    if b is None:
        return {"enabled": False, "rgb": ["add", "one", "zero"], "alpha": ["add", "one", "zero"],
                "write_mask": [True] * 4}
    if isinstance(b, Mapping):
        d = {"enabled": False, "rgb": ["add", "one", "zero"], "alpha": ["add", "one", "zero"],
             "write_mask": [True] * 4}
        d.update(b)
        return d
    return {"enabled": b.enabled, "rgb": _eq(b.rgb), "alpha": _eq(b.alpha),
            "write_mask": list(b.write_mask)}


def write_color(src, dst_codes, fmt, blend_state=None, constant=(0, 0, 0, 0), mask=True,
                half_rounding: str = "rtz", quantize_src: bool = False,
                precision=np.float64) -> np.ndarray:
    """One colour attachment's update: blend (if enabled and the format blends), colour
    mask, store, and keep ``dst_codes`` where ``mask`` (fragments that survived) is False.
    ``precision``: see ``blend``."""
    f = _fmt(fmt)
    b = _blend_state(blend_state)
    dst_codes = np.asarray(dst_codes)
    src = np.asarray(src, np.float64)
    if src.shape[-1] < 4:
        src = np.concatenate([src, np.broadcast_to(np.array([0.0, 0.0, 0.0, 1.0][src.shape[-1]:]),
                                                   src.shape[:-1] + (4 - src.shape[-1],))], -1)
    if b["enabled"] and f.blendable:
        value = blend(src, load(f, dst_codes), b["rgb"], b["alpha"], constant, f, quantize_src,
                      precision)
    else:
        value = src
    new = store(f, value, half_rounding)
    new = color_mask(new, dst_codes, b["write_mask"], f)
    m = np.asarray(mask, bool)
    if f.channels > 1 and m.ndim:
        m = m[..., None]
    return np.where(m, new, dst_codes).astype(dst_codes.dtype)


# ---------------------------------------------------------------------------------------------
# one primitive through the per-fragment operations
# ---------------------------------------------------------------------------------------------


def process_fragments(buffers: dict, state: Mapping, writes: Sequence[str],
                      formats: Mapping[str, Any], *, coverage, outputs: Mapping[str, Any] = None,
                      depth=None, front_facing=True, depth_target: Optional[str] = None,
                      half_rounding: str = "rtz", quantize_src: bool = False,
                      precision=np.float64) -> dict:
    """Run one primitive's fragments through stencil, depth, blend and masks; new buffers.

    ``buffers``: ``{target: codes}`` like a render's result (GL row order), with a d24s8
    target's stencil under ``"NAME.stencil"``.  ``state``: the PLAN pass state dict.
    ``writes``: colour targets; ``formats``: ``{target: format name or Format}``.
    ``coverage``: bool (H, W), the pixels the primitive covers (after scissor).  ``outputs``:
    ``{target: (H, W, 4) values}`` the fragment shader writes (omit for depth/stencil only).
    ``depth``: window z of the fragments (scalar or (H, W)); ``front_facing``: bool or (H, W).
    """
    out = dict(buffers)
    cov = np.asarray(coverage, bool)
    shape = cov.shape
    surv = cov.copy()
    depth_pass = np.ones(shape, bool)
    dstate = {"func": "always", "write": False, **(state.get("depth") or {})}
    if depth_target is not None:
        dfmt = _fmt(formats[depth_target])
        z = np.broadcast_to(np.asarray(depth if depth is not None else 0.0, np.float64), shape)
        depth_pass = depth_test(dstate["func"], z, out[depth_target], dfmt)
        if dfmt.has_stencil and state.get("stencil"):
            skey = depth_target + ".stencil"
            new_s, s_pass = stencil_update(out[skey], state["stencil"], depth_pass, front_facing,
                                           cov)
            out[skey] = new_s
            surv &= s_pass
        surv &= depth_pass
        if dstate.get("write"):
            codes = depth_codes(dfmt, z)
            out[depth_target] = np.where(surv, codes, out[depth_target]).astype(
                out[depth_target].dtype)
    blend_states = state.get("blend") or {}
    constant = state.get("blend_constant")
    constant = (0.0, 0.0, 0.0, 0.0) if constant is None else constant
    for name in writes:
        if outputs is None or name not in outputs:
            continue
        out[name] = write_color(outputs[name], out[name], formats[name], blend_states.get(name),
                                constant, surv, half_rounding, quantize_src, precision)
    return out
