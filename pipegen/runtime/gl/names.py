"""Creating and deleting GL object names (textures, framebuffers, samplers) through the raw
ctypes entry points.

PyOpenGL's array-handling wrappers keep a little memory on each call that passes a numpy array
as the names' storage (about 0.15-0.3 KiB per call, measured with ``benchmarks/soak.py``'s
method: create and delete in a loop, ``malloc_trim``, resident size); a process that builds
pipelines for hours (a sweep, a test suite) paid it on every target, pass and sampler.  The
unwrapped functions take a ctypes array and keep nothing.
"""

from __future__ import annotations

import ctypes
from typing import Iterable

from pipegen.runtime.gl.context import GL


def _raw(fn):
    return getattr(fn, "wrappedOperation", fn)


_CREATE_TEXTURES = _raw(GL.glCreateTextures)
_CREATE_FRAMEBUFFERS = _raw(GL.glCreateFramebuffers)
_CREATE_SAMPLERS = _raw(GL.glCreateSamplers)
_DELETE_TEXTURES = _raw(GL.glDeleteTextures)
_DELETE_FRAMEBUFFERS = _raw(GL.glDeleteFramebuffers)
_DELETE_SAMPLERS = _raw(GL.glDeleteSamplers)


def _ids(names: Iterable[int]):
    names = [int(n) for n in names]
    return len(names), (ctypes.c_uint * max(len(names), 1))(*names)


def create_texture_name(target: int) -> int:
    ids = (ctypes.c_uint * 1)()
    _CREATE_TEXTURES(target, 1, ids)
    return int(ids[0])


def create_framebuffer() -> int:
    ids = (ctypes.c_uint * 1)()
    _CREATE_FRAMEBUFFERS(1, ids)
    return int(ids[0])


def create_sampler() -> int:
    ids = (ctypes.c_uint * 1)()
    _CREATE_SAMPLERS(1, ids)
    return int(ids[0])


def delete_textures(*names: int) -> None:
    n, ids = _ids(names)
    if n:
        _DELETE_TEXTURES(n, ids)


def delete_framebuffers(*names: int) -> None:
    n, ids = _ids(names)
    if n:
        _DELETE_FRAMEBUFFERS(n, ids)


def delete_samplers(*names: int) -> None:
    n, ids = _ids(names)
    if n:
        _DELETE_SAMPLERS(n, ids)
