"""The process-wide OpenCL context of the software reference (pyopencl on PoCL's CPU device).

PoCL reads ``POCL_CACHE_DIR`` once, when pyopencl first loads it, so ``configure_cache`` must run
before anything imports ``pyopencl``: this module imports pyopencl lazily, inside
``get_context()``, after choosing the cache folder.  The folder is (in order) the one passed to
``configure_cache``/``get_context``, ``$POCL_CACHE_DIR`` if the user set it, or
``<tempdir>/pipegen-cl-cache/<key>``.  pyopencl's own binary cache (in ``~/.cache``) is turned
off with ``PYOPENCL_NO_CACHE`` (PoCL's cache does the same job inside the build folder).

Programs are built with ``-cl-denorms-are-zero`` (DESIGN.md §7; note that PoCL treats it as a
permission, not a promise: the generated code flushes explicitly where results are stored) and
kept per process in a dict keyed by the source text, so a source is compiled at most once per
process (PoCL compiles take 0.3–3 s; its disk cache makes a rebuild in a later process ~30 ms).

``$PIPEGEN_CL_OPTIONS`` appends build options (experiments; results may then differ).

Device choice: ``$PIPEGEN_CL_DEVICE`` (substring of the device name) or the first CPU device of
the "Portable Computing Language" platform, else the first device found.  A CPU device's
worker threads are scheduled so that they do not preempt the host thread (``batch_schedule``).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import threading
import warnings
from typing import Optional

__all__ = ["configure_cache", "get_context", "build_program", "link_program", "describe",
           "BUILD_OPTIONS", "cache_dir", "FramePool", "batch_workers"]

# correctly rounded / and sqrt: llvmpipe's are (measured), OpenCL's default allows 2.5 ulp
BUILD_OPTIONS = ("-cl-denorms-are-zero", "-cl-std=CL1.2", "-cl-fp32-correctly-rounded-divide-sqrt")

_lock = threading.Lock()
_state: dict = {"ctx": None, "queue": None, "cache": None}
_programs: dict[str, object] = {}


def default_cache_dir(key: str = "default") -> str:
    safe = hashlib.sha1(key.encode()).hexdigest()[:12] if key != "default" else key
    return os.path.join(tempfile.gettempdir(), "pipegen-cl-cache", safe)


def configure_cache(path: Optional[str] = None, key: str = "default") -> str:
    """Choose PoCL's kernel cache folder (effective only before PoCL is loaded)."""
    with _lock:
        if _state["cache"] is not None:
            return _state["cache"]
        if path is None:
            path = os.environ.get("POCL_CACHE_DIR") or default_cache_dir(key)
        os.makedirs(path, exist_ok=True)
        os.environ["POCL_CACHE_DIR"] = path
        os.environ.setdefault("PYOPENCL_NO_CACHE", "1")
        os.environ.setdefault("PYOPENCL_COMPILER_OUTPUT", "0")
        _state["cache"] = path
        return path


def cache_dir() -> Optional[str]:
    return _state["cache"]


def get_context(cache: Optional[str] = None, key: str = "default"):
    """(context, queue) on the PoCL CPU device, created on first use."""
    configure_cache(cache, key)
    with _lock:
        if _state["ctx"] is None:
            import pyopencl as cl

            want = os.environ.get("PIPEGEN_CL_DEVICE", "")
            threads_before = _thread_ids()     # a CPU device starts its workers below
            candidates = []
            for plat in cl.get_platforms():
                for dev in plat.get_devices():
                    score = 0
                    if want and want.lower() in dev.name.lower():
                        score += 4
                    if "portable computing language" in plat.name.lower():
                        score += 2
                    if dev.type & cl.device_type.CPU:
                        score += 1
                    candidates.append((score, len(candidates), dev))
            if not candidates:
                raise RuntimeError("no OpenCL device found (is pocl-binary-distribution installed?)")
            dev = max(candidates, key=lambda c: (c[0], -c[1]))[2]
            ctx = cl.Context([dev])
            _state["ctx"] = ctx
            _state["queue"] = cl.CommandQueue(
                ctx, properties=cl.command_queue_properties.PROFILING_ENABLE)
            if dev.type & cl.device_type.CPU:
                _state["batch_workers"] = batch_schedule(_thread_ids() - threads_before)
        return _state["ctx"], _state["queue"]


def _thread_ids() -> set[int]:
    try:
        return {int(t) for t in os.listdir("/proc/self/task")}
    except OSError:          # not Linux: no thread list, nothing is rescheduled
        return set()


def batch_schedule(threads: set[int]) -> list[int]:
    """Put a CPU device's worker threads (``threads``: those that appeared while the device
    was opened) under Linux's ``SCHED_BATCH``; returns those moved.

    Why: the host thread's work for the next pass (set-up read-backs, bins, launches) and the
    device's kernels share the same cores.  Woken by a launch, PoCL's workers (one per core)
    preempt the host thread, which then waits for a core until the kernel ends, so host and
    device work add up instead of overlapping (a frame's timeline: each launch returned only
    when its kernel had finished).  A ``SCHED_BATCH`` thread keeps its fair share of the CPU
    (same weight as ``SCHED_OTHER``, also against other processes) but does not preempt the
    running thread when woken, so the host thread keeps its core until it blocks.
    ``benchmarks/cl_workers_ab.py``, CL frames back to back: 0.86-0.92x at 160x90 (forward,
    whose frame is mostly one raster kernel, 1.00x), 0.86-0.92x at 320x180, 0.96-0.98x at
    640x360.  Any user may switch its own threads to this policy.
    ``$PIPEGEN_CL_BATCH_WORKERS=0`` leaves them as they are.  A device that starts its workers
    only later (none appear while it is opened; PoCL 3.0 starts them then) is left as it is."""
    if os.environ.get("PIPEGEN_CL_BATCH_WORKERS", "1") == "0" or \
            not hasattr(os, "SCHED_BATCH"):
        return []
    moved = []
    for tid in sorted(threads):
        try:
            if os.sched_getscheduler(tid) == os.SCHED_OTHER:
                os.sched_setscheduler(tid, os.SCHED_BATCH, os.sched_param(0))
                moved.append(tid)
        except OSError:      # gone already, or a policy this process may not change
            continue
    return moved


def batch_workers() -> list[int]:
    """The device threads ``batch_schedule`` moved when the context was made (empty: none,
    e.g. not Linux, not a CPU device, or pyopencl had opened the device before)."""
    return list(_state.get("batch_workers", ()))


def _options(extra: tuple[str, ...] = ()) -> tuple[str, ...]:
    return tuple(BUILD_OPTIONS) + tuple(extra) + tuple(
        os.environ.get("PIPEGEN_CL_OPTIONS", "").split())


def _failed(what: str, exc: Exception, source: str) -> RuntimeError:
    """The error of a failed build, with the numbered source next to the log."""
    numbered = "\n".join(f"{i + 1:5d}  {line}" for i, line in enumerate(source.split("\n")))
    return RuntimeError(f"OpenCL {what} failed: {exc}\n--- source ---\n{numbered}")


def _cached(sources: tuple[str, ...], opts: tuple[str, ...], make):
    """The program for ``sources`` built with ``opts``, made by ``make`` once per process."""
    key = hashlib.sha256(("\0\0".join(sources) + "\0" + " ".join(opts)).encode()).hexdigest()
    prog = _programs.get(key)
    if prog is None:
        prog = _programs[key] = make()
    return prog


def build_program(source: str, options: tuple[str, ...] = ()):
    """Build (once per process) and return the ``pyopencl.Program`` for ``source``."""
    import pyopencl as cl

    ctx, _ = get_context()
    opts = _options(options)

    def make():
        try:
            return cl.Program(ctx, source).build(options=list(opts))
        except cl.RuntimeError as exc:
            raise _failed("build", exc, source) from None
    return _cached((source,), opts, make)


def link_program(sources: tuple[str, ...]):
    """Compile each of ``sources`` on its own and link them into one ``pyopencl.Program``
    (once per process; a repeat group's fused kernel and its passes' units, whose
    program-scope names are static, ``backends/opencl/group.py``)."""
    import pyopencl as cl

    ctx, _ = get_context()
    opts = _options()

    def make():
        units = []
        for source in sources:
            try:
                with warnings.catch_warnings():     # "defeats compiler caching": pyopencl's
                    warnings.simplefilter("ignore")  # own cache is off (PoCL's is used)
                    units.append(cl.Program(ctx, source).compile(options=list(opts)))
            except cl.RuntimeError as exc:
                raise _failed("compile", exc, source) from None
        try:
            return cl.link_program(ctx, units)
        except cl.RuntimeError as exc:      # an unresolved or clashing name: the kernel's unit
            raise _failed("link", exc, sources[-1]) from None
    return _cached(tuple(sources), opts, make)


def set_args(kernel, *args) -> None:
    """``kernel.set_args(*args)``, with the kernel's scalar argument types declared from its
    first call's arguments (numpy scalars; buffers and None: pointers).  pyopencl then packs
    the scalars with a generated invoker: ~1.5 us for 16 arguments, against ~90 us when it
    probes the type of every argument of an undeclared kernel (a light pre-pass frame sets
    ~70 scalars: ~0.7 ms of host time before its first raster kernel).  Vector scalars
    (``cltypes.make_int2``: 0-d arrays) are declared too: undeclared, each cost ~20 us a call
    (deferred's light pass reads five targets: 48 us against 5 us a launch, 81 a frame)."""
    if not getattr(kernel, "_pg_typed", False):
        import numpy as np
        dtypes = []
        for a in args:
            if isinstance(a, (bool, int, float)):
                raise TypeError("kernel scalars are numpy scalars (their type is the "
                                f"kernel's argument type), not {type(a).__name__}")
            scalar = isinstance(a, np.generic) or (isinstance(a, np.ndarray) and a.ndim == 0)
            dtypes.append(a.dtype if scalar else None)
        kernel.set_scalar_arg_dtypes(dtypes)
        kernel._pg_typed = True
    kernel.set_args(*args)


_INVOKER_SOURCES = "<generated: 'pyopencl invoker for "


def forget_invoker_sources() -> int:
    """Drop the source text pyopencl (through pytools) files in ``linecache`` for each
    kernel's generated argument setter: one entry per ``cl.Kernel`` made, never removed, so a
    process building pipelines for hours grew by about 140 KiB a pipeline (issue 29's soak).
    The text only serves tracebacks inside those setters.  Returns how many were dropped."""
    import linecache
    stale = [k for k in linecache.cache if isinstance(k, str) and k.startswith(_INVOKER_SOURCES)]
    for k in stale:
        linecache.cache.pop(k, None)
    return len(stale)


def short_name() -> str:
    """"PoCL" on PoCL's platform (the reference this backend is built on), else the device's
    name."""
    ctx, _ = get_context()
    dev = ctx.devices[0]
    return "PoCL" if "portable computing language" in dev.platform.name.lower() else dev.name


def describe() -> str:
    ctx, _ = get_context()
    dev = ctx.devices[0]
    return f"{dev.platform.name} {dev.platform.version} / {dev.name} ({dev.max_compute_units} CUs)"


class FramePool:
    """Device buffers a frame's geometry uses (vertex outputs, set-up fields, cut varyings),
    handed out again by later frames: ``recycle()`` at a frame's start, once the frame before
    has finished, makes every buffer handed out since the last recycle available again (same
    flags and size: a scene's draws ask for the same sizes frame after frame).  PoCL gives a
    new buffer fresh pages, and the kernels that first write them pay the page faults (light
    pre-pass at 640x360: 12 varying copies of 0.1-0.5 ms each, the same copies into reused
    buffers ~0.02 ms).  ``enabled = False`` (``buffer`` then creates every buffer anew): for
    geometry kept across frames, which must never be recycled."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.enabled = True
        self._free: dict = {}
        self._used: list = []

    def buffer(self, nbytes: int, flags=None):
        """A buffer of at least 16 bytes, ``nbytes`` if more, READ_WRITE unless ``flags``."""
        import pyopencl as cl
        flags = cl.mem_flags.READ_WRITE if flags is None else flags
        key = (int(flags), max(16, int(nbytes)))
        if not self.enabled:
            return cl.Buffer(self.ctx, flags, size=key[1])
        free = self._free.get(key)
        buf = free.pop() if free else cl.Buffer(self.ctx, flags, size=key[1])
        self._used.append((key, buf))
        return buf

    def recycle(self) -> None:
        """Every buffer handed out since the last call is free again (the caller's frame that
        used them has finished on the device, and nothing reads them any more)."""
        for key, buf in self._used:
            self._free.setdefault(key, []).append(buf)
        self._used = []
