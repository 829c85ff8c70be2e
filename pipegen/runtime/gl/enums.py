"""The IR's fixed-function enums as GL enums, keyed by the IR enums' ``.value`` strings: one
table each for compare functions, stencil ops, blend equations, blend factors and culled faces.
``gl_state.apply_state`` (the reference) and ``gl_transitions`` (what a pipeline sets) both read
them, and nothing else in them depends on either."""

from __future__ import annotations

from pipegen.runtime.gl.context import GL

__all__ = ["COMPARE", "STENCIL_OP", "BLEND_OP", "BLEND_FACTOR", "CULL"]


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
