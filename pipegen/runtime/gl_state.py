"""Apply one pass's fixed-function state (the PLAN ``state`` dict) with PyOpenGL.

moderngl tracks none of this raw state (and has no API for most of it), so every pass sets
*all* of it explicitly: depth func/mask/clamp, per-face stencil func/ops/masks, per-target blend
enable/equations/factors, the blend constant, per-target colour masks, culling, polygon offset
and the scissor test, plus the rarely touched switches that would silently change results if
anything (moderngl, a user) left them on: dithering, sRGB writes, logic ops, alpha-to-coverage,
sample masks, sample shading, rasterizer discard, primitive restart, polygon mode.

The state dict is the one in internals.md ("Compiled plan"); enum values are the IR enums'
``.value`` strings, and ``ir`` enum members are accepted too.  The colour outputs are indexed by
the pass's ``writes`` list: ``state["blend"][name]`` applies to draw buffer ``writes.index(name)``.

Measured on Mesa 22.3 llvmpipe (LLVM 15; tests/test_gl_state.py pins each of these):

* unorm8 blending runs in 8-bit fixed point: the source colour and the blend constant are first
  converted to codes (float32 product, round half to even: a constant of 0.3 becomes 76, since
  0.3f * 255 is exactly 76.5 in float32), factors are codes (``1 - x`` is ``255 - x``), each
  product is ``(t + (t >> 8) + 128) >> 8`` with ``t = a*b`` (24 of the 65536 code pairs are
  not round-to-nearest), sums saturate.  ``fixed_function.blend_unorm8`` reproduces this
  bit-exactly over every op and factor; the spec's float formula (``fixed_function.blend``)
  differs from it by up to 2 codes in one blend, i.e. ``Format.tolerance(1)``.  Products with
  factor 0 or 255 are exact, so bit-plane packing with ``ONE, CONSTANT_COLOR`` 0.25 (code 64)
  on codes whose low bits are free is bit-exact.
* ``SRC_ALPHA_SATURATE`` is ``min(As, 1 - Ad)`` for RGB and 1 for alpha, per spec.
* Fixed-point targets clamp the constant (and factors, result) to [0, 1]; float targets use
  it unclamped (a constant of 2.0 doubles the source on rgba32f).
* Float targets blend in float32: every product and sum rounded, no FMA, and a factor shared
  by both terms (``add(src_color, src_color)``) applied once to ``s + d``;
  ``fixed_function.blend(..., precision=np.float32)`` reproduces it bit-exactly (rgba16f
  results then stored rounding toward zero).  rgba16 (unorm) blends are within 2 codes of the
  float formula.
* Colour stores into 16-bit float targets round toward zero (70000 -> 65504, 65520 -> 65504),
  keep half denormals and +-inf; NaN stays NaN.  Stores into unorm round half to even with a
  float32 product (16-bit too); +inf -> max code, -inf and NaN -> 0.  rgb10a2's 10-bit
  channels are off by one code from round-to-nearest for about a quarter of values.
* Window z -> d24 is ``rint(float32(z) * 16777215.0f)`` with a float32 product
  (``fixed_function.depth_codes``); depth tests compare the converted codes.
* +-inf in a *varying* becomes NaN by interpolation (inf - inf in the plane equation) even
  when all three vertices agree: only shader constants deliver inf to a store.
"""

from __future__ import annotations

from typing import Any, Mapping, Optional, Sequence

from .gl_context import GL

__all__ = ["COMPARE", "STENCIL_OP", "BLEND_OP", "BLEND_FACTOR", "CULL", "apply_state",
           "set_scissor", "reset_state", "default_state", "state_from_ir"]


def _v(x: Any) -> Any:
    """An IR enum member or its value string -> the value string."""
    return getattr(x, "value", x)


COMPARE = {
    "never": GL.GL_NEVER, "less": GL.GL_LESS, "equal": GL.GL_EQUAL, "lequal": GL.GL_LEQUAL,
    "greater": GL.GL_GREATER, "notequal": GL.GL_NOTEQUAL, "gequal": GL.GL_GEQUAL,
    "always": GL.GL_ALWAYS,
}

STENCIL_OP = {
    "keep": GL.GL_KEEP, "zero": GL.GL_ZERO, "replace": GL.GL_REPLACE, "incr": GL.GL_INCR,
    "decr": GL.GL_DECR, "incr_wrap": GL.GL_INCR_WRAP, "decr_wrap": GL.GL_DECR_WRAP,
    "invert": GL.GL_INVERT,
}

BLEND_OP = {
    "add": GL.GL_FUNC_ADD, "sub": GL.GL_FUNC_SUBTRACT, "revsub": GL.GL_FUNC_REVERSE_SUBTRACT,
    "min": GL.GL_MIN, "max": GL.GL_MAX,
}

BLEND_FACTOR = {
    "zero": GL.GL_ZERO, "one": GL.GL_ONE,
    "src_color": GL.GL_SRC_COLOR, "one_minus_src_color": GL.GL_ONE_MINUS_SRC_COLOR,
    "dst_color": GL.GL_DST_COLOR, "one_minus_dst_color": GL.GL_ONE_MINUS_DST_COLOR,
    "src_alpha": GL.GL_SRC_ALPHA, "one_minus_src_alpha": GL.GL_ONE_MINUS_SRC_ALPHA,
    "dst_alpha": GL.GL_DST_ALPHA, "one_minus_dst_alpha": GL.GL_ONE_MINUS_DST_ALPHA,
    "constant_color": GL.GL_CONSTANT_COLOR,
    "one_minus_constant_color": GL.GL_ONE_MINUS_CONSTANT_COLOR,
    "constant_alpha": GL.GL_CONSTANT_ALPHA,
    "one_minus_constant_alpha": GL.GL_ONE_MINUS_CONSTANT_ALPHA,
    "src_alpha_saturate": GL.GL_SRC_ALPHA_SATURATE,
}

CULL = {"back": GL.GL_BACK, "front": GL.GL_FRONT}

MAX_DRAW_BUFFERS = 8   # GL_MAX_DRAW_BUFFERS on llvmpipe; masks are reset on all of them

_DEFAULT_FACE = {"func": "always", "ref": 0, "read_mask": 255, "write_mask": 255,
                 "fail": "keep", "zfail": "keep", "zpass": "keep"}


def default_state() -> dict:
    """The state of a pass that declares nothing (depth off, no stencil, no blending)."""
    return {
        "depth": {"func": "always", "write": False, "clamp": False},
        "stencil": {"front": dict(_DEFAULT_FACE), "back": dict(_DEFAULT_FACE)},
        "blend": {},
        "blend_constant": [0.0, 0.0, 0.0, 0.0],
        "cull": "none",
        "polygon_offset": None,
    }


def _equation(e) -> list[str]:
    """``[op, src, dst]`` (``[op]`` alone for min/max, whose factors GL ignores) or an
    ``ir.BlendEquation`` -> three value strings."""
    if hasattr(e, "op"):
        return [_v(e.op), _v(e.src), _v(e.dst)]
    e = [_v(x) for x in e]
    return e + ["one", "one"][: 3 - len(e)] if len(e) < 3 else e[:3]


def _enable(cap: int, on: bool) -> None:
    (GL.glEnable if on else GL.glDisable)(cap)


def reset_state() -> None:
    """Switch off everything pipegen never uses (set again by every ``apply_state``)."""
    for cap in (GL.GL_DITHER, GL.GL_FRAMEBUFFER_SRGB, GL.GL_COLOR_LOGIC_OP,
                GL.GL_SAMPLE_ALPHA_TO_COVERAGE, GL.GL_SAMPLE_ALPHA_TO_ONE, GL.GL_SAMPLE_COVERAGE,
                GL.GL_SAMPLE_MASK, GL.GL_SAMPLE_SHADING, GL.GL_RASTERIZER_DISCARD,
                GL.GL_PRIMITIVE_RESTART, GL.GL_PRIMITIVE_RESTART_FIXED_INDEX,
                GL.GL_POLYGON_OFFSET_LINE, GL.GL_POLYGON_OFFSET_POINT):
        GL.glDisable(cap)
    for i in range(8):
        GL.glDisable(GL.GL_CLIP_DISTANCE0 + i)
    GL.glEnable(GL.GL_MULTISAMPLE)            # only matters for MSAA attachments
    GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
    GL.glFrontFace(GL.GL_CCW)
    GL.glDepthRange(0.0, 1.0)


def apply_state(state: Mapping, writes: Sequence[str] = (), *,
                depth_format: Optional[str] = None, scissor=None) -> None:
    """Set every piece of fixed-function state for one pass.

    ``state``: the PLAN pass ``state`` dict (missing keys take ``default_state()`` values).
    ``writes``: the pass's colour targets in attachment order.  ``depth_format``: the format
    name of the depth attachment, or None when the pass has none (then depth and stencil tests
    are disabled).  ``scissor``: ``(x, y, w, h)`` in window pixels, or None for no scissor.
    """
    d = default_state()
    depth = {**d["depth"], **(state.get("depth") or {})}
    stencil = state.get("stencil") or d["stencil"]
    blend = state.get("blend") or {}
    constant = state.get("blend_constant")
    constant = d["blend_constant"] if constant is None else constant
    cull = _v(state.get("cull") or "none")
    offset = state.get("polygon_offset")

    reset_state()

    # -- depth ---------------------------------------------------------------------------------
    has_depth = depth_format is not None
    has_stencil = depth_format == "d24s8"
    # With an attachment the test stays enabled even for ALWAYS: GL only writes depth while the
    # test is enabled, and ALWAYS/no-write is the same as disabled.
    _enable(GL.GL_DEPTH_TEST, has_depth)
    GL.glDepthFunc(COMPARE[_v(depth["func"])])
    GL.glDepthMask(GL.GL_TRUE if (has_depth and depth["write"]) else GL.GL_FALSE)
    _enable(GL.GL_DEPTH_CLAMP, bool(depth.get("clamp")))

    # -- stencil -------------------------------------------------------------------------------
    _enable(GL.GL_STENCIL_TEST, has_stencil)
    for face_name, face in (("front", GL.GL_FRONT), ("back", GL.GL_BACK)):
        s = {**_DEFAULT_FACE, **(stencil.get(face_name) or {})}
        GL.glStencilFuncSeparate(face, COMPARE[_v(s["func"])], int(s["ref"]),
                                 int(s["read_mask"]) & 0xFF)
        GL.glStencilOpSeparate(face, STENCIL_OP[_v(s["fail"])], STENCIL_OP[_v(s["zfail"])],
                               STENCIL_OP[_v(s["zpass"])])
        GL.glStencilMaskSeparate(face, int(s["write_mask"]) & 0xFF)

    # -- blend + colour masks per draw buffer --------------------------------------------------
    for i in range(MAX_DRAW_BUFFERS):
        b = blend.get(writes[i]) if i < len(writes) else None
        if b is None:
            GL.glDisablei(GL.GL_BLEND, i)
            GL.glBlendEquationSeparatei(i, GL.GL_FUNC_ADD, GL.GL_FUNC_ADD)
            GL.glBlendFuncSeparatei(i, GL.GL_ONE, GL.GL_ZERO, GL.GL_ONE, GL.GL_ZERO)
            GL.glColorMaski(i, True, True, True, True)
            continue
        rgb = _equation(b.get("rgb", ["add", "one", "zero"]))
        alpha = _equation(b.get("alpha", ["add", "one", "zero"]))
        (GL.glEnablei if b.get("enabled") else GL.glDisablei)(GL.GL_BLEND, i)
        GL.glBlendEquationSeparatei(i, BLEND_OP[rgb[0]], BLEND_OP[alpha[0]])
        GL.glBlendFuncSeparatei(i, BLEND_FACTOR[rgb[1]], BLEND_FACTOR[rgb[2]],
                                BLEND_FACTOR[alpha[1]], BLEND_FACTOR[alpha[2]])
        m = [bool(x) for x in b.get("write_mask", [True] * 4)]
        GL.glColorMaski(i, *m)
    GL.glBlendColor(*[float(c) for c in constant])

    # -- rasterisation -------------------------------------------------------------------------
    if cull == "none":
        GL.glDisable(GL.GL_CULL_FACE)
    else:
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(CULL[cull])
    if offset:
        GL.glEnable(GL.GL_POLYGON_OFFSET_FILL)
        GL.glPolygonOffset(float(offset[0]), float(offset[1]))
    else:
        GL.glDisable(GL.GL_POLYGON_OFFSET_FILL)
        GL.glPolygonOffset(0.0, 0.0)
    set_scissor(scissor)


def set_scissor(rect) -> None:
    """``(x, y, w, h)`` enables the scissor test on that window rectangle; None disables it."""
    if rect is None:
        GL.glDisable(GL.GL_SCISSOR_TEST)
    else:
        x, y, w, h = (int(v) for v in rect)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        GL.glScissor(x, y, max(w, 0), max(h, 0))


def state_from_ir(state) -> dict:
    """An ``ir.PassState`` -> the PLAN state dict (for tests and tools that start from the IR)."""
    def face(f):
        return {"func": f.func.value, "ref": f.ref, "read_mask": f.read_mask,
                "write_mask": f.write_mask, "fail": f.fail.value, "zfail": f.zfail.value,
                "zpass": f.zpass.value}
    depth = {"func": state.depth.func.value, "write": state.depth.write,
             "clamp": state.depth.clamp}
    if getattr(state.depth, "inside", None) is not None:
        depth["inside"] = state.depth.inside.value
    return {
        "depth": depth,
        "stencil": {"front": face(state.stencil.front), "back": face(state.stencil.back)},
        "blend": {name: {"enabled": b.enabled,
                         "rgb": [b.rgb.op.value, b.rgb.src.value, b.rgb.dst.value],
                         "alpha": [b.alpha.op.value, b.alpha.src.value, b.alpha.dst.value],
                         "write_mask": list(b.write_mask)} for name, b in state.blend},
        "blend_constant": list(state.blend_constant),
        "cull": state.cull.value,
        "polygon_offset": (None if state.polygon_offset is None
                           else [state.polygon_offset.factor, state.polygon_offset.units]),
    }
