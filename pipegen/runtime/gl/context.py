"""The process-wide headless OpenGL context (moderngl on EGL) and the PyOpenGL bindings on it.

moderngl has no API for stencil state, the blend constant, per-target blend equations or
depth-stencil attachments, so the GL runtime drives those with PyOpenGL on the *same* context.
PyOpenGL picks its platform when it is first imported, so ``PYOPENGL_PLATFORM=egl`` must be set
before anything imports ``OpenGL``: this module sets it (unless the user chose one) and is the
only place the runtime imports ``OpenGL.GL`` from.

One context per process: EGL contexts are expensive to create on llvmpipe and PyOpenGL resolves
its function pointers against whatever context is current, so a second context would invite
mismatches.  ``get_context()`` creates it on first use; it stays current on the creating thread
(render from that thread).

``gl_limits()`` reports what the machine offers; ``describe()`` is a one-line summary (renderer,
version, sub-pixel bits) for reports.

Device choice (EGL, headless): ``$PIPEGEN_GL_DEVICE`` is an EGL device index (``0``, ``1``,
...), a substring of the renderer's name (``NVIDIA``, ``llvmpipe``), or ``auto`` (the default):
the first device whose renderer is not a software rasteriser (llvmpipe, softpipe,
SwiftShader), else device 0.  EGL lists a machine's GPUs and Mesa's software device side by
side; ``auto`` probes them in order with a context each (a few milliseconds apiece) and keeps
the one chosen.  ``device()`` says which was chosen and why.

Error checking.  PyOpenGL calls ``glGetError`` after every call by default, which doubles the
cost of the runtime's many small state calls; this module switches that off
(``OpenGL.ERROR_CHECKING = False``, which only takes effect before ``OpenGL.GL`` is first
imported, so import pipegen's runtime before PyOpenGL; ``PYOPENGL_ERROR_CHECKING`` in the
environment, PyOpenGL's own switch, wins).  The runtime instead checks once per frame and after
building resources (``check_error``), naming the pass only in debug mode: ``PIPEGEN_GL_DEBUG=1``
in the environment (or ``GLPipeline(..., debug=True)``) checks after every pass.
``ERROR_CHECKING`` tells whether PyOpenGL checks every call after all.
"""

from __future__ import annotations

import ctypes
import functools
import os
import re
import threading

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import sys  # noqa: E402

from pipegen.core.diagnostics import PipegenError  # noqa: E402

import moderngl  # noqa: E402
import OpenGL  # noqa: E402

if "OpenGL.GL" not in sys.modules and "PYOPENGL_ERROR_CHECKING" not in os.environ:
    OpenGL.ERROR_CHECKING = False     # one glGetError per frame instead (see the docstring)
from OpenGL import GL  # noqa: E402,F401  (re-exported: the runtime's single GL import point)

#: whether PyOpenGL checks glGetError after each call (False unless OpenGL.GL came first)
ERROR_CHECKING = bool(OpenGL.ERROR_CHECKING)


_WRAPPED_CTRL_C = re.compile(r"argument \d+: KeyboardInterrupt\b")


def ctrl_c_unwrapped(method):
    """``method`` with a Ctrl-C that PyOpenGL's argument conversion swallowed raised again.

    ctypes calls PyOpenGL's ``from_param`` (Python code) while it converts a call's arguments;
    a SIGINT whose handler runs there raises KeyboardInterrupt inside the conversion, which
    ctypes re-raises as ``ctypes.ArgumentError('argument 6: KeyboardInterrupt: ')``.  Without
    this, Ctrl-C during a read-back ends ``stress`` or ``check`` with a traceback instead of
    exit 130 and its resume command."""
    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        try:
            return method(*args, **kwargs)
        except ctypes.ArgumentError as e:
            if _WRAPPED_CTRL_C.match(str(e)):
                raise KeyboardInterrupt from e
            raise
    return wrapper


def debug_enabled() -> bool:
    """``PIPEGEN_GL_DEBUG`` set to anything but ``""``/``0``: check GL errors after every pass."""
    return os.environ.get("PIPEGEN_GL_DEBUG", "") not in ("", "0")


__all__ = ["GL", "get_context", "gl_limits", "describe", "device", "check_error",
           "clear_stale_errors", "debug_enabled", "ERROR_CHECKING", "ctrl_c_unwrapped"]

_lock = threading.Lock()
_ctx: moderngl.Context | None = None
_device: dict = {}                   # index, renderer, why: how the context's device was chosen
DEVICE_ENV = "PIPEGEN_GL_DEVICE"
SOFTWARE = ("llvmpipe", "softpipe", "swiftshader", "software rasterizer")
MAX_DEVICES = 16
_HINT = (f"{DEVICE_ENV} is an EGL device index, a part of a renderer's name, or auto (the "
         f"first hardware device); unset it for auto")


def is_software(renderer: str) -> bool:
    return any(s in renderer.lower() for s in SOFTWARE)


def _create(index: int) -> moderngl.Context:
    return moderngl.create_standalone_context(require=330, backend="egl", device_index=index)


def _choose_device(choice: str) -> tuple[moderngl.Context, dict]:
    """A context on the device ``choice`` names (the module docstring), and how it was chosen."""
    if choice.isdigit():
        index = int(choice)
        try:
            ctx = _create(index)
        except Exception as e:         # glcontext: "requested device index 5, but found 1 devices"
            raise PipegenError(None, f"{DEVICE_ENV}={choice}: no such EGL device ({e})",
                               hint=_HINT) from None
        return ctx, dict(index=index, renderer=ctx.info["GL_RENDERER"],
                         why=f"{DEVICE_ENV}={choice}")
    seen = []
    for index in range(MAX_DEVICES):
        try:
            ctx = _create(index)
        except Exception:              # past the last device (or one EGL cannot open)
            break
        renderer = ctx.info["GL_RENDERER"]
        wanted = (not is_software(renderer)) if choice == "auto" else \
            choice.lower() in renderer.lower()
        if wanted:
            for other, _ in seen:
                other.release()
            why = (f"{DEVICE_ENV}={choice}" if choice != "auto" else
                   "the first hardware device EGL lists")
            return ctx, dict(index=index, renderer=renderer, why=why)
        seen.append((ctx, renderer))
    names = ", ".join(f"{i}: {r}" for i, (_, r) in enumerate(seen)) or "none"
    if choice != "auto" or not seen:
        for other, _ in seen:
            other.release()
        raise PipegenError(None, f"{DEVICE_ENV}={choice}: no EGL device's renderer matches "
                                 f"(devices: {names})", hint=_HINT)
    for other, _ in seen[1:]:
        other.release()
    return seen[0][0], dict(index=0, renderer=seen[0][1],
                            why=f"no hardware device: EGL lists {names}")


def device() -> dict:
    """How the context's EGL device was chosen: ``index``, ``renderer``, ``why``."""
    get_context()
    return dict(_device)


def get_context() -> moderngl.Context:
    """The shared standalone EGL context (created on first use, made current on each call)."""
    global _ctx
    with _lock:
        if _ctx is None:
            if os.environ.get("PYOPENGL_PLATFORM") != "egl":
                raise RuntimeError(
                    "pipegen's GL runtime needs PYOPENGL_PLATFORM=egl (set before OpenGL is "
                    f"imported); found {os.environ.get('PYOPENGL_PLATFORM')!r}")
            choice = os.environ.get(DEVICE_ENV, "").strip() or "auto"
            _ctx, chosen = _choose_device(choice)
            _device.update(chosen)
            # Byte-exact transfers for every width (r8 rows of odd length, ...).
            GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
            GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        return _ctx


def gl_limits() -> dict[str, int]:
    ctx = get_context()
    return {
        "max_draw_buffers": int(ctx.info["GL_MAX_DRAW_BUFFERS"]),
        "max_color_attachments": int(ctx.info["GL_MAX_COLOR_ATTACHMENTS"]),
        "max_samples": int(ctx.info["GL_MAX_SAMPLES"]),
        "max_texture_size": int(ctx.info["GL_MAX_TEXTURE_SIZE"]),
        "subpixel_bits": int(ctx.info["GL_SUBPIXEL_BITS"]),
        "max_texture_units": int(ctx.info["GL_MAX_TEXTURE_IMAGE_UNITS"]),
    }


def renderer_name(renderer: str) -> str:
    """A GL_RENDERER string without its details: "llvmpipe (LLVM 15.0.6, 256 bits)" ->
    "llvmpipe", "NVIDIA H200/PCIe/SSE2" -> "NVIDIA H200"."""
    return renderer.partition(" (")[0].partition("/")[0].strip() or renderer


def short_name() -> str:
    """The context's renderer, as ``renderer_name`` shortens it."""
    return renderer_name(get_context().info["GL_RENDERER"])


def describe() -> str:
    ctx = get_context()
    info = ctx.info
    return (f"{info['GL_RENDERER']} / {info['GL_VERSION']} "
            f"(subpixel bits {info['GL_SUBPIXEL_BITS']}; EGL device {_device.get('index')}: "
            f"{_device.get('why')})")


_NAMES = {0x0500: "GL_INVALID_ENUM", 0x0501: "GL_INVALID_VALUE", 0x0502: "GL_INVALID_OPERATION",
          0x0505: "GL_OUT_OF_MEMORY", 0x0506: "GL_INVALID_FRAMEBUFFER_OPERATION"}


def check_error(where: str = "", hint: bool = True) -> None:
    """Raise if GL recorded an error since the last check (by any call: PyOpenGL's or
    moderngl's); ``where`` names what ran since (a frame, a pass).  ``hint``: say how to
    find the pass (per-pass checks pass False)."""
    err = int(GL.glGetError())
    if err != GL.GL_NO_ERROR:
        hint = (" (PIPEGEN_GL_DEBUG=1 checks after every pass)"
                if hint and not debug_enabled() else "")
        raise RuntimeError(f"OpenGL error 0x{err:04x} {_NAMES.get(err, '')} {where}".rstrip()
                           + hint)


def clear_stale_errors() -> list[int]:
    """Consume GL errors left pending by other code on the shared context.

    moderngl never calls glGetError, so an error raised by a user's (or a test's) moderngl
    call stays pending until PyOpenGL, which checks after every call, reports it from the next
    unrelated call of ours.  The runtime clears them before it starts a frame so that its own
    error checks only ever report its own calls.
    """
    get_context()
    errors = []
    for _ in range(16):          # GL may queue one error per flag; it never exceeds a few
        e = GL.glGetError()
        if e == GL.GL_NO_ERROR:
            break
        errors.append(int(e))
    return errors
