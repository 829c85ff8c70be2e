"""GL view of the target formats: format *name* -> GL enums, texture creation, clears, readback.

``pipegen.formats`` is the single source of truth for what a format is (kind, bits, dtype,
quantisation); this table only says how GL spells it.  Readback returns *codes*, the same arrays
``formats.Format.quantize`` produces:

=========  =====================================  ================================================
kind       GL transfer                            codes returned
=========  =====================================  ================================================
unorm      GL_UNSIGNED_BYTE / _SHORT              uint8 / uint16 codes
rgb10a2    GL_UNSIGNED_INT_2_10_10_10_REV         uint16 codes (R, G, B 10-bit; A 2-bit)
float16    GL_HALF_FLOAT                          float16
float32    GL_FLOAT                               float32
uint       GL_*_INTEGER                           uint8 (rgba8ui) / uint32 (r32ui)
d24s8      GL_DEPTH_STENCIL / GL_UNSIGNED_INT_24_8  uint32 24-bit depth codes + uint8 stencil
d32f       GL_DEPTH_COMPONENT / GL_FLOAT          float32
=========  =====================================  ================================================

Arrays are in GL memory order here (row 0 = window y 0, the *bottom* row); ``GLPipeline``
flips them into image order.  Single-channel formats give ``(H, W)``, others ``(H, W, C)``.

Clears go through ``glClearTexImage`` with the codes from ``Format.quantize``: they are exact,
identical to what the numpy oracle and the CL backend compute, and unaffected by scissor, masks
or the bound framebuffer (unlike ``glClear``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from .. import formats as F
from .gl_context import GL, get_context

__all__ = ["GLFormat", "GL_FORMATS", "gl_format", "create_texture", "delete_texture",
           "clear_texture", "read_texture", "write_texture", "split_depth_stencil",
           "pack_depth_stencil", "clear_codes"]


@dataclass(frozen=True)
class GLFormat:
    name: str
    internal: int          # sized internal format (glTexStorage2D)
    format: int            # pixel transfer format
    type: int              # pixel transfer type
    components: int        # components per pixel in transfer memory (packed types: 1)
    np_type: type          # numpy dtype of transfer memory
    attachment: int        # GL_COLOR_ATTACHMENT0 (offset by index) or the depth(/stencil) point
    sampler: str           # GLSL sampler type that reads it

    @property
    def fmt(self) -> F.Format:
        return F.get(self.name)


def _c(name, internal, fmt, typ, comps, np_type, sampler="sampler2D"):
    return GLFormat(name, internal, fmt, typ, comps, np_type, GL.GL_COLOR_ATTACHMENT0, sampler)


GL_FORMATS: dict[str, GLFormat] = {
    g.name: g for g in [
        _c("r8", GL.GL_R8, GL.GL_RED, GL.GL_UNSIGNED_BYTE, 1, np.uint8),
        _c("rg8", GL.GL_RG8, GL.GL_RG, GL.GL_UNSIGNED_BYTE, 2, np.uint8),
        _c("rgba8", GL.GL_RGBA8, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, 4, np.uint8),
        _c("r16", GL.GL_R16, GL.GL_RED, GL.GL_UNSIGNED_SHORT, 1, np.uint16),
        _c("rg16", GL.GL_RG16, GL.GL_RG, GL.GL_UNSIGNED_SHORT, 2, np.uint16),
        _c("rgba16", GL.GL_RGBA16, GL.GL_RGBA, GL.GL_UNSIGNED_SHORT, 4, np.uint16),
        _c("r16f", GL.GL_R16F, GL.GL_RED, GL.GL_HALF_FLOAT, 1, np.float16),
        _c("rg16f", GL.GL_RG16F, GL.GL_RG, GL.GL_HALF_FLOAT, 2, np.float16),
        _c("rgba16f", GL.GL_RGBA16F, GL.GL_RGBA, GL.GL_HALF_FLOAT, 4, np.float16),
        _c("r32f", GL.GL_R32F, GL.GL_RED, GL.GL_FLOAT, 1, np.float32),
        _c("rg32f", GL.GL_RG32F, GL.GL_RG, GL.GL_FLOAT, 2, np.float32),
        _c("rgba32f", GL.GL_RGBA32F, GL.GL_RGBA, GL.GL_FLOAT, 4, np.float32),
        _c("r32ui", GL.GL_R32UI, GL.GL_RED_INTEGER, GL.GL_UNSIGNED_INT, 1, np.uint32,
           "usampler2D"),
        _c("rgba8ui", GL.GL_RGBA8UI, GL.GL_RGBA_INTEGER, GL.GL_UNSIGNED_BYTE, 4, np.uint8,
           "usampler2D"),
        _c("rgb10a2", GL.GL_RGB10_A2, GL.GL_RGBA, GL.GL_UNSIGNED_INT_2_10_10_10_REV, 1,
           np.uint32),
        GLFormat("d24s8", GL.GL_DEPTH24_STENCIL8, GL.GL_DEPTH_STENCIL, GL.GL_UNSIGNED_INT_24_8,
                 1, np.uint32, GL.GL_DEPTH_STENCIL_ATTACHMENT, "sampler2D"),
        GLFormat("d32f", GL.GL_DEPTH_COMPONENT32F, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, 1,
                 np.float32, GL.GL_DEPTH_ATTACHMENT, "sampler2D"),
    ]
}

assert set(GL_FORMATS) == set(F.FORMATS), "gl_formats.py and formats.py disagree on names"


def gl_format(name: str) -> GLFormat:
    return GL_FORMATS[name]


# ---------------------------------------------------------------------------------------------
# textures
# ---------------------------------------------------------------------------------------------


def create_texture(name: str, width: int, height: int, samples: int = 1) -> int:
    """An immutable texture of format ``name`` (multisampled when ``samples > 1``)."""
    get_context()
    g = gl_format(name)
    ids = np.zeros(1, np.uint32)
    if samples > 1:
        GL.glCreateTextures(GL.GL_TEXTURE_2D_MULTISAMPLE, 1, ids)
        GL.glTextureStorage2DMultisample(int(ids[0]), samples, g.internal, width, height, True)
    else:
        GL.glCreateTextures(GL.GL_TEXTURE_2D, 1, ids)
        tex = int(ids[0])
        GL.glTextureStorage2D(tex, 1, g.internal, width, height)
        # Texture parameters are overridden by the runtime's sampler objects; these defaults
        # make a texture complete and sane for anyone binding it without one.
        GL.glTextureParameteri(tex, GL.GL_TEXTURE_MIN_FILTER, GL.GL_NEAREST)
        GL.glTextureParameteri(tex, GL.GL_TEXTURE_MAG_FILTER, GL.GL_NEAREST)
        GL.glTextureParameteri(tex, GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE)
        GL.glTextureParameteri(tex, GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)
        if g.name == "d24s8":
            GL.glTextureParameteri(tex, GL.GL_DEPTH_STENCIL_TEXTURE_MODE, GL.GL_DEPTH_COMPONENT)
        if not g.fmt.is_color:
            GL.glTextureParameteri(tex, GL.GL_TEXTURE_COMPARE_MODE, GL.GL_NONE)
    return int(ids[0])


def delete_texture(tex: int) -> None:
    GL.glDeleteTextures(np.array([tex], np.uint32))


def _pack_transfer(name: str, codes: np.ndarray) -> np.ndarray:
    """Codes (formats' dtype, (..., C) or (...)) -> GL transfer memory."""
    g = gl_format(name)
    fmt = g.fmt
    c = np.asarray(codes)
    if name == "rgb10a2":
        c = c.astype(np.uint32).reshape(c.shape[:-1] + (4,))
        return (c[..., 0] & 1023) | ((c[..., 1] & 1023) << 10) | ((c[..., 2] & 1023) << 20) \
            | ((c[..., 3] & 3) << 30)
    if fmt.kind is F.Kind.DEPTH_STENCIL:
        raise AssertionError("d24s8 transfers go through pack_depth_stencil")
    return np.ascontiguousarray(c.astype(g.np_type))


def pack_depth_stencil(depth_codes, stencil) -> np.ndarray:
    d = np.asarray(depth_codes, dtype=np.uint32) & 0xFFFFFF
    s = np.asarray(stencil, dtype=np.uint32) & 0xFF
    return (d << 8) | s


def split_depth_stencil(packed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GL_UNSIGNED_INT_24_8 words -> (uint32 24-bit depth codes, uint8 stencil)."""
    p = np.asarray(packed, dtype=np.uint32)
    return p >> 8, (p & 0xFF).astype(np.uint8)


def clear_codes(name: str, color: Optional[Sequence[float]] = None,
                depth: Optional[float] = None, stencil: Optional[int] = None) -> np.ndarray:
    """The GL transfer word(s) of one pixel cleared to the given value(s) (None -> zero)."""
    g = gl_format(name)
    fmt = g.fmt
    if fmt.kind is F.Kind.DEPTH_STENCIL:
        d = fmt.quantize(np.float64(depth if depth is not None else 0.0))
        return pack_depth_stencil(np.array([d]), np.array([stencil or 0]))
    if fmt.kind is F.Kind.DEPTH:
        return np.array([fmt.quantize(np.float64(depth if depth is not None else 0.0))],
                        np.float32)
    col = np.zeros(4) if color is None else np.asarray(color, dtype=np.float64)
    if col.ndim == 0:
        col = np.full(4, float(col))
    col = np.concatenate([col, np.zeros(4 - len(col))])[:4] if len(col) < 4 else col[:4]
    if fmt.kind is F.Kind.UINT:
        codes = np.asarray(col[: fmt.channels]).astype(np.uint64).astype(fmt.dtype)
    else:
        codes = fmt.quantize(col[: fmt.channels])
    return np.atleast_1d(_pack_transfer(name, codes))


def clear_texture(tex: int, name: str, color=None, depth=None, stencil=None) -> None:
    """Clear every texel (every sample) to the value(s); exact codes via ``Format.quantize``."""
    g = gl_format(name)
    data = clear_codes(name, color, depth, stencil)
    GL.glClearTexImage(tex, 0, g.format, g.type, data)


def read_texture(tex: int, name: str, width: int, height: int) -> np.ndarray:
    """Read a single-sample texture back as codes (GL row order: bottom row first).

    d24s8 yields the packed words; use ``split_depth_stencil``.
    """
    g = gl_format(name)
    fmt = g.fmt
    shape = (height, width) if g.components == 1 else (height, width, g.components)
    out = np.zeros(shape, dtype=g.np_type)
    GL.glGetTextureImage(tex, 0, g.format, g.type, out.nbytes, out)
    if name == "rgb10a2":
        w = out.astype(np.uint32)
        return np.stack([w & 1023, (w >> 10) & 1023, (w >> 20) & 1023, w >> 30],
                        axis=-1).astype(fmt.dtype)
    return out


def write_texture(tex: int, name: str, codes: np.ndarray, stencil: np.ndarray = None) -> None:
    """Upload codes (GL row order) into a single-sample texture: tests preset targets this way.

    For d24s8 ``codes`` are the 24-bit depth codes and ``stencil`` the stencil values.
    """
    g = gl_format(name)
    c = np.asarray(codes)
    h, w = c.shape[:2]
    if g.fmt.kind is F.Kind.DEPTH_STENCIL:
        data = pack_depth_stencil(c, np.zeros_like(c) if stencil is None else stencil)
    else:
        data = _pack_transfer(name, c)
    data = np.ascontiguousarray(data)
    GL.glTextureSubImage2D(tex, 0, 0, 0, w, h, g.format, g.type, data)
