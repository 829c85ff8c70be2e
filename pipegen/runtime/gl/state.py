"""Apply one pass's fixed-function state (``PassPlan.state``, an ``ir.PassState``) with PyOpenGL.

moderngl tracks none of this raw state (and has no API for most of it), so ``apply_state`` sets
*all* of it explicitly: depth func/mask/clamp, per-face stencil func/ops/masks, per-target blend
enable/equations/factors, the blend constant, per-target colour masks, culling, polygon offset
and the scissor test, plus the rarely touched switches that would silently change results if
anything (moderngl, a user) left them on: dithering, sRGB writes, logic ops, alpha-to-coverage,
sample masks, sample shading, rasterizer discard, primitive restart, polygon mode.

``apply_state`` is the reference: tests pin GL's behaviour through it, and
``GLPipeline(..., transitions=False)`` calls it before every pass.  A pipeline normally sets
state through ``gl_transitions`` instead (each pass's state lowered once to the slots it
depends on, only the differences from the previous pass set); it renders bit-identically
(tests/test_gl_transitions.py).  Both read the GL tables of ``gl_enums``; ``apply_state`` and
``set_scissor`` tell the process-wide ``gl_transitions.TRACKER`` that the state changed.

The GL tables are keyed by the IR enums' ``.value`` strings.  The colour outputs are
indexed by the pass's ``writes``: ``state.blend_for(name)`` applies to draw buffer
``writes.index(name)``.

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

from typing import Optional, Sequence

from pipegen.core import formats as F
from pipegen.ir import nodes as ir
from pipegen.runtime.gl.context import GL
from pipegen.runtime.gl.enums import BLEND_FACTOR, BLEND_OP, COMPARE, CULL, STENCIL_OP

__all__ = ["COMPARE", "STENCIL_OP", "BLEND_OP", "BLEND_FACTOR", "CULL", "apply_state",
           "set_scissor", "reset_state"]

MAX_DRAW_BUFFERS = 8   # GL_MAX_DRAW_BUFFERS on llvmpipe; masks are reset on all of them

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
    from pipegen.runtime.gl.transitions import TRACKER
    TRACKER.invalidate()
    for i in range(8):
        GL.glDisable(GL.GL_CLIP_DISTANCE0 + i)
    GL.glEnable(GL.GL_MULTISAMPLE)            # only matters for MSAA attachments
    GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
    GL.glFrontFace(GL.GL_CCW)
    GL.glDepthRange(0.0, 1.0)


def apply_state(state: ir.PassState, writes: Sequence[str] = (), *,
                depth_format: Optional[F.Format] = None, scissor=None) -> None:
    """Set every piece of fixed-function state for one pass.

    ``state``: the pass's ``ir.PassState``.  ``writes``: the pass's colour targets in
    attachment order.  ``depth_format``: the format of the depth attachment, or None when the
    pass has none (then depth and stencil tests are disabled).  ``scissor``: ``(x, y, w, h)``
    in window pixels, or None for no scissor.
    """
    depth = state.depth
    reset_state()

    # -- depth ---------------------------------------------------------------------------------
    has_depth = depth_format is not None
    has_stencil = has_depth and depth_format.has_stencil
    # With an attachment the test stays enabled even for ALWAYS: GL only writes depth while the
    # test is enabled, and ALWAYS/no-write is the same as disabled.
    _enable(GL.GL_DEPTH_TEST, has_depth)
    GL.glDepthFunc(COMPARE[depth.func.value])
    GL.glDepthMask(GL.GL_TRUE if (has_depth and depth.write) else GL.GL_FALSE)
    _enable(GL.GL_DEPTH_CLAMP, depth.clamp)

    # -- stencil -------------------------------------------------------------------------------
    _enable(GL.GL_STENCIL_TEST, has_stencil)
    for s, face in ((state.stencil.front, GL.GL_FRONT), (state.stencil.back, GL.GL_BACK)):
        GL.glStencilFuncSeparate(face, COMPARE[s.func.value], int(s.ref), int(s.read_mask) & 0xFF)
        GL.glStencilOpSeparate(face, STENCIL_OP[s.fail.value], STENCIL_OP[s.zfail.value],
                               STENCIL_OP[s.zpass.value])
        GL.glStencilMaskSeparate(face, int(s.write_mask) & 0xFF)

    # -- blend + colour masks per draw buffer --------------------------------------------------
    for i in range(MAX_DRAW_BUFFERS):
        b = state.blend_for(writes[i]) if i < len(writes) else ir.TargetBlend()
        rgb, alpha = b.rgb, b.alpha
        (GL.glEnablei if b.enabled else GL.glDisablei)(GL.GL_BLEND, i)
        GL.glBlendEquationSeparatei(i, BLEND_OP[rgb.op.value], BLEND_OP[alpha.op.value])
        GL.glBlendFuncSeparatei(i, BLEND_FACTOR[rgb.src.value], BLEND_FACTOR[rgb.dst.value],
                                BLEND_FACTOR[alpha.src.value], BLEND_FACTOR[alpha.dst.value])
        GL.glColorMaski(i, *(bool(m) for m in b.write_mask))
    GL.glBlendColor(*[float(c) for c in state.blend_constant])

    # -- rasterisation -------------------------------------------------------------------------
    if state.cull in (ir.CullMode.NONE, ir.CullMode.AUTO):   # auto: the runtime picks per light
        GL.glDisable(GL.GL_CULL_FACE)
    else:
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(CULL[state.cull.value])
    offset = state.polygon_offset
    if offset is not None:
        GL.glEnable(GL.GL_POLYGON_OFFSET_FILL)
        GL.glPolygonOffset(float(offset.factor), float(offset.units))
    else:
        GL.glDisable(GL.GL_POLYGON_OFFSET_FILL)
        GL.glPolygonOffset(0.0, 0.0)
    set_scissor(scissor)
    from pipegen.runtime.gl.transitions import TRACKER
    TRACKER.invalidate()        # state set behind the tracker's back: it knows nothing now


def set_scissor(rect) -> None:
    """``(x, y, w, h)`` enables the scissor test on that window rectangle; None disables it."""
    from pipegen.runtime.gl.transitions import TRACKER
    if rect is None:
        GL.glDisable(GL.GL_SCISSOR_TEST)
    else:
        x, y, w, h = (int(v) for v in rect)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        GL.glScissor(x, y, max(w, 0), max(h, 0))
        rect = (x, y, max(w, 0), max(h, 0))
    TRACKER.scissor_rect = rect
