"""The values the formats clamp, counted by the CL backend where it stores them.

A fragment output outside what its target's format holds (``backends/opencl/formats.
clamp_range``: a specular of 82.8 into rgba8, a negative value into unorm, beyond 65504 into a
half) is clamped by the store, silently on both backends.  The raster kernel counts, per
target it writes, the values (channels of fragments) outside, and keeps the largest and
smallest values (``cl_pass.cl.j2``, the prelude's ``pg_track``: a few vector integer operations
per fragment and target, an atomic per tile row only when some value was out); GL stores
through fixed-function hardware that never shows the values before it clamps them, so the CL
backend's counts stand for both (``pipegen check`` renders both).

``ClampCounters``: one device buffer, per pass 4 uints per target it writes (the count, the
highest and the lowest value as order keys, a spare), each pass's kernel given its own
sub-buffer; zeroed by one fill at a frame's start, read after a frame only when asked
(``CLPipeline.last_clamps``).  ``collect()`` gathers the clamps of every CL frame rendered
inside it (``pipegen run`` and ``check`` print them, ``proof/clamps.py`` words them).
"""

from __future__ import annotations

import contextlib
import contextvars
from dataclasses import dataclass
from typing import Iterator, Optional

import numpy as np

from pipegen.backends.opencl.formats import clamp_range
from pipegen.backends.plan import Plan

SLOTS = 4       # uints per (pass, target): count, highest key, lowest key, spare
# a frame's start: count 0, highest key 0 (below every float's), lowest key ~0 (above them)
_START = np.array([0, 0, 0xFFFFFFFF, 0], np.uint32)


@dataclass(frozen=True)
class Clamp:
    """Values one pass wrote to one target outside its format's range (``lo``, ``hi``):
    ``count`` of them in a frame (channels of fragments, the channels written), ``highest``
    the largest value above the range (None when none was above), ``lowest`` the smallest
    below it (a NaN written into a channel that also clamped may stand in for either)."""
    technique: str
    pass_name: str
    target: str
    format: str
    count: int
    highest: Optional[float]
    lowest: Optional[float]
    lo: float
    hi: float
    precision: str = "f32"      # the plan's: "f64" for the float64 evaluation


def _from_key(key: int) -> float:
    """The float whose ``pg_order_key`` is ``key``."""
    bits = key ^ 0x80000000 if key & 0x80000000 else ~key & 0xFFFFFFFF
    return float(np.array([bits], np.uint32).view(np.float32)[0])


class ClampCounters:
    """The clamp counters of a plan's passes on one device (module docstring)."""

    def __init__(self, ctx, queue, plan: Plan):
        import pyopencl as cl
        self.queue, self.plan = queue, plan
        align = max(4, ctx.devices[0].mem_base_addr_align // 8)
        most = max([len(p.writes) for p in plan.passes] + [1])
        self.stride = -(-most * SLOTS * 4 // align) * align        # bytes per pass
        self.buf = cl.Buffer(ctx, cl.mem_flags.READ_WRITE,
                             size=self.stride * max(1, len(plan.passes)))
        self.args = [self.buf.get_sub_region(k * self.stride, self.stride)
                     for k in range(len(plan.passes))]

    def start_frame(self) -> None:
        import pyopencl as cl
        cl.enqueue_fill_buffer(self.queue, self.buf, _START, 0, self.buf.size)

    def read(self) -> list[Clamp]:
        """The clamps of the frame the counters hold (call after it was queued)."""
        import pyopencl as cl
        words = np.empty(self.buf.size // 4, np.uint32)
        cl.enqueue_copy(self.queue, words, self.buf)
        out = []
        for k, p in enumerate(self.plan.passes):
            for j, name in enumerate(p.writes):
                n, top, bottom, _ = (int(x) for x in words[(k * self.stride) // 4 + SLOTS * j:][:SLOTS])
                if not n:
                    continue
                fmt = self.plan.target(name).format.name
                lo, hi, _ = clamp_range(fmt)
                high, low = _from_key(top), _from_key(bottom)
                out.append(Clamp(self.plan.technique, p.name, name, fmt, n,
                                 high if high > hi else None, low if low < lo else None,
                                 lo, hi, self.plan.precision))
        return out


# -- gathering the clamps of the frames rendered in a block -----------------------------------

_LOGS: contextvars.ContextVar[tuple] = contextvars.ContextVar("pipegen_clamp_logs", default=())


class ClampLog:
    """The clamps of the frames rendered inside ``collect()``: per (technique, pass, target)
    the frame with the most values clamped, its extremes widened by every frame's.

    ``clamps`` are the float32 frames' when the block rendered any: float64 frames beside
    them are evaluations around the technique (``check --precision f64`` renders it with its
    reads moved by their bounds, copies with its steps nudged, its reference: values that are
    not the technique's); a block of float64 frames alone (``run --precision f64``) gives
    theirs."""

    def __init__(self):
        self.by_key: dict[tuple, Clamp] = {}
        self.frames = 0          # CL frames seen (0: nothing was counted, e.g. only GL ran)
        self.precisions: set[str] = set()      # of the frames seen

    def add(self, clamps: list[Clamp]) -> None:
        self.frames += 1
        for c in clamps:
            key = (c.precision, c.technique, c.pass_name, c.target)
            old = self.by_key.get(key)
            if old is not None:
                c = Clamp(c.technique, c.pass_name, c.target, c.format, max(c.count, old.count),
                          _extreme(max, c.highest, old.highest),
                          _extreme(min, c.lowest, old.lowest), c.lo, c.hi, c.precision)
            self.by_key[key] = c

    def frame_seen(self, precision: str) -> None:
        self.precisions.add(precision)

    @property
    def clamps(self) -> list[Clamp]:
        pick = "f32" if "f32" in self.precisions else "f64"
        return [self.by_key[k] for k in sorted(self.by_key) if k[0] == pick]


def _extreme(pick, a: Optional[float], b: Optional[float]) -> Optional[float]:
    return b if a is None else a if b is None else pick(a, b)


@contextlib.contextmanager
def collect() -> Iterator[ClampLog]:
    """A ``ClampLog`` of every CL frame rendered inside the block (nested blocks each see
    them)."""
    log = ClampLog()
    token = _LOGS.set(_LOGS.get() + (log,))
    try:
        yield log
    finally:
        _LOGS.reset(token)


def collecting() -> bool:
    return bool(_LOGS.get())


def note(clamps: list[Clamp], precision: str = "f32") -> None:
    """A frame's clamps (a frame of a plan of ``precision``), to every ``collect()`` block
    around the render."""
    for log in _LOGS.get():
        log.frame_seen(precision)
        log.add(clamps)
