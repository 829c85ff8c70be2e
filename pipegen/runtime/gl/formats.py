"""GL view of the target formats: GL's spelling of a ``formats.Format``, texture creation,
clears, readback.

``pipegen.core.formats`` is the single source of truth for what a format is (kind, bits, packing,
dtype, quantisation); GL's enums are *derived* from those properties here, with GL's naming
rules, so a format added to ``formats.FORMATS`` needs no edit in this file:

================  ==========================================  ================================
property          internal format (glTexStorage2D)            transfer type
================  ==========================================  ================================
unorm             ``GL_<CH><bits>``: GL_RGBA8, GL_R16         GL_UNSIGNED_BYTE / _SHORT
snorm             ``GL_<CH><bits>_SNORM``: GL_RG8_SNORM       GL_BYTE / GL_SHORT
float             ``GL_<CH><bits>F``: GL_RGBA16F              GL_HALF_FLOAT / GL_FLOAT
uint              ``GL_<CH><bits>UI``: GL_R32UI               GL_UNSIGNED_BYTE / _INT
packed word       runs of equal bits: GL_RGB10_A2             GL_UNSIGNED_INT_2_10_10_10_REV
depth + stencil   ``GL_DEPTH<d>_STENCIL<s>``                  GL_UNSIGNED_INT_<d>_<s>
depth (float)     ``GL_DEPTH_COMPONENT<d>F``                  GL_FLOAT
================  ==========================================  ================================

Readback returns *codes*, the same arrays ``formats.Format.quantize`` produces (packed words
are split with ``Format.unpack``; depth-stencil formats yield their packed words, see
``split_depth_stencil``).
Arrays are in GL memory order here (row 0 = window y 0, the *bottom* row); ``GLPipeline``
flips them into image order.  Single-channel formats give ``(H, W)``, others ``(H, W, C)``.

Clears go through ``glClearTexImage`` with the codes from ``Format.clear_codes``: they are exact,
identical to what the numpy oracle and the CL backend compute, and unaffected by scissor, masks
or the bound framebuffer (unlike ``glClear``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from pipegen.core import formats as F
from pipegen.core.diagnostics import PipegenError
from pipegen.runtime.gl.context import GL, get_context, gl_limits

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


_CHANNELS = "RGBA"
_SUFFIX = {F.Kind.UNORM: "", F.Kind.SNORM: "_SNORM", F.Kind.FLOAT: "F", F.Kind.UINT: "UI"}
_ELEMENT_TYPE = {"u1": "GL_UNSIGNED_BYTE", "i1": "GL_BYTE", "u2": "GL_UNSIGNED_SHORT",
                 "i2": "GL_SHORT", "u4": "GL_UNSIGNED_INT", "f2": "GL_HALF_FLOAT",
                 "f4": "GL_FLOAT"}


def _enum(name: str) -> int:
    value = getattr(GL, name, None)
    assert value is not None, f"GL has no {name}"
    return value


def _spell(fmt: F.Format) -> GLFormat:
    """GL's enums for a format, from its properties (the table in the module docstring)."""
    if fmt.kind is F.Kind.DEPTH_STENCIL:
        d, s = fmt.bits[0], fmt.stencil_bits
        return GLFormat(fmt.name, _enum(f"GL_DEPTH{d}_STENCIL{s}"), GL.GL_DEPTH_STENCIL,
                        _enum(f"GL_UNSIGNED_INT_{d}_{s}"), 1, np.uint32,
                        GL.GL_DEPTH_STENCIL_ATTACHMENT, "sampler2D")
    if fmt.kind is F.Kind.DEPTH:
        return GLFormat(fmt.name, _enum(f"GL_DEPTH_COMPONENT{fmt.bits[0]}F"),
                        GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, 1, np.float32,
                        GL.GL_DEPTH_ATTACHMENT, "sampler2D")
    channels = _CHANNELS[:fmt.channels]
    groups: list[list] = []          # runs of channels with the same bits: RGB10_A2
    for c, b in zip(channels, fmt.bits):
        if groups and groups[-1][1] == b:
            groups[-1][0] += c
        else:
            groups.append([c, b])
    internal = "_".join(f"{c}{b}" for c, b in groups) + _SUFFIX[fmt.kind]
    transfer = {1: "RED", 2: "RG", 3: "RGB", 4: "RGBA"}[fmt.channels]
    if fmt.is_integer:
        transfer += "_INTEGER"
    if fmt.packed:     # channel 0 in the low bits: GL's _REV packed type
        typ = f"GL_UNSIGNED_INT_{'_'.join(str(b) for b in reversed(fmt.bits))}_REV"
        assert fmt.word_bits == 32, fmt.name
        components = 1
    else:
        typ = _ELEMENT_TYPE[fmt.element_dtype.str[1:]]
        components = fmt.channels
    return GLFormat(fmt.name, _enum("GL_" + internal), _enum("GL_" + transfer), _enum(typ),
                    components, fmt.element_dtype.type, GL.GL_COLOR_ATTACHMENT0,
                    "usampler2D" if fmt.is_integer else "sampler2D")


@functools.cache
def gl_format(name: str) -> GLFormat:
    return _spell(F.get(name))


# every format has a GL spelling (an import error otherwise)
GL_FORMATS: dict[str, GLFormat] = {name: gl_format(name) for name in F.FORMATS}


# ---------------------------------------------------------------------------------------------
# textures
# ---------------------------------------------------------------------------------------------


def create_texture(name: str, width: int, height: int, samples: int = 1) -> int:
    """An immutable texture of format ``name`` (multisampled when ``samples > 1``)."""
    ctx = get_context()
    g = gl_format(name)
    from pipegen.runtime.gl import names
    if samples > gl_limits()["max_samples"]:
        # the language allows 8 (SAMPLE_COUNTS); llvmpipe stops at 4, and GL would only say
        # "framebuffer incomplete" at the first pass drawing there
        raise PipegenError(None, f"{samples} samples per pixel: GL ({ctx.info['GL_RENDERER']}) "
                                 f"renders at most {gl_limits()['max_samples']} (GL_MAX_SAMPLES)",
                           "render on CL alone (`--backend cl`, `pipeline('cl')`), or ask for "
                           "fewer samples")
    if samples > 1:
        tex = names.create_texture_name(GL.GL_TEXTURE_2D_MULTISAMPLE)
        GL.glTextureStorage2DMultisample(tex, samples, g.internal, width, height, True)
        got_buf = np.zeros(1, np.int32)
        GL.glGetTextureLevelParameteriv(tex, 0, GL.GL_TEXTURE_SAMPLES, got_buf)
        got = int(got_buf[0])
        if got != samples:
            # GL may round a count up (llvmpipe renders 2 as 4): the CL backend, and the
            # image's error, would then be for a count nobody asked for
            names.delete_textures(tex)
            raise PipegenError(None, f"{samples} samples per pixel: GL "
                                     f"({ctx.info['GL_RENDERER']}) renders them as {got}",
                               "render on CL alone (`--backend cl`, `pipeline('cl')`), or ask "
                               f"for {got} samples")
    else:
        tex = names.create_texture_name(GL.GL_TEXTURE_2D)
        GL.glTextureStorage2D(tex, 1, g.internal, width, height)
        # Texture parameters are overridden by the runtime's sampler objects; these defaults
        # make a texture complete and sane for anyone binding it without one.
        GL.glTextureParameteri(tex, GL.GL_TEXTURE_MIN_FILTER, GL.GL_NEAREST)
        GL.glTextureParameteri(tex, GL.GL_TEXTURE_MAG_FILTER, GL.GL_NEAREST)
        GL.glTextureParameteri(tex, GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE)
        GL.glTextureParameteri(tex, GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)
        if g.fmt.has_stencil:
            GL.glTextureParameteri(tex, GL.GL_DEPTH_STENCIL_TEXTURE_MODE, GL.GL_DEPTH_COMPONENT)
        if not g.fmt.is_color:
            GL.glTextureParameteri(tex, GL.GL_TEXTURE_COMPARE_MODE, GL.GL_NONE)
    return tex


def delete_texture(tex: int) -> None:
    from pipegen.runtime.gl import names
    names.delete_textures(tex)


def _pack_transfer(name: str, codes: np.ndarray) -> np.ndarray:
    """Codes (formats' dtype, (..., C) or (...)) -> GL transfer memory."""
    g = gl_format(name)
    fmt = g.fmt
    c = np.asarray(codes)
    if fmt.kind is F.Kind.DEPTH_STENCIL:
        raise AssertionError("depth-stencil transfers go through pack_depth_stencil")
    if fmt.packed:
        c = c.reshape(c.shape[:-1] + (fmt.channels,))
    return np.ascontiguousarray(fmt.pack(c).astype(g.np_type))


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
    """The GL transfer word(s) of one pixel cleared to the given value(s) (None -> zero; the
    values are normalised and quantised by ``Format.clear_codes``/``clear_stencil``)."""
    fmt = gl_format(name).fmt
    codes = fmt.clear_codes(color, depth)
    if fmt.kind is F.Kind.DEPTH_STENCIL:
        return pack_depth_stencil(np.array([codes]), np.array([fmt.clear_stencil(stencil)]))
    if fmt.kind is F.Kind.DEPTH:
        return np.array([codes], np.float32)
    return np.atleast_1d(_pack_transfer(name, codes))


def clear_texture(tex: int, name: str, color=None, depth=None, stencil=None) -> None:
    """Clear every texel (every sample) to the value(s); exact codes via ``Format.quantize``."""
    g = gl_format(name)
    data = clear_codes(name, color, depth, stencil)
    GL.glClearTexImage(tex, 0, g.format, g.type, data)


def read_texture(tex: int, name: str, width: int, height: int) -> np.ndarray:
    """Read a single-sample texture back as codes (GL row order: bottom row first).

    Depth-stencil formats yield the packed words; use ``split_depth_stencil``.
    """
    g = gl_format(name)
    fmt = g.fmt
    shape = (height, width) if g.components == 1 else (height, width, g.components)
    out = np.zeros(shape, dtype=g.np_type)
    GL.glGetTextureImage(tex, 0, g.format, g.type, out.nbytes, out)
    return fmt.unpack(out) if fmt.packed else out


def write_texture(tex: int, name: str, codes: np.ndarray, stencil: np.ndarray = None) -> None:
    """Upload codes (GL row order) into a single-sample texture: tests preset targets this way.

    For depth-stencil formats ``codes`` are the depth codes and ``stencil`` the stencil values.
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
