"""Interleaved timing: the one loop that times candidates against each other on a noisy,
shared machine (``pipegen sweep``'s timing process, the benchmark scripts).

Timing each candidate's frames in a block lets a change in the machine's load (another job
starting, a CPU clocking down) land on one candidate only.  Interleaving them frame by frame,
in the given order on even frames and reversed on odd ones (A B B A ..., so that none always
runs first, after the other's caches), makes drift hit all alike; compare medians.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Hashable, Mapping, Optional, TypeVar

K = TypeVar("K", bound=Hashable)


@dataclass
class Samples:
    """One candidate's timed calls: wall time (s) each and, with a CPU clock, CPU time (s)."""
    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)


def interleave(fns: Mapping[K, Callable[[], object]], frames: int, *, alternate: bool = True,
               cpu: Optional[Callable[[], float]] = None, warmup: bool = True,
               after_call: Optional[Callable[[K], None]] = None,
               block: int = 1) -> dict[K, Samples]:
    """Call each of ``fns`` (key -> callable) once a frame for ``frames`` frames: in the
    mapping's order, reversed on odd frames if ``alternate``; first one untimed call of each
    if ``warmup`` (shader and kernel compilation, buffer creation are not frame time).

    ``block`` > 1: each callable's frames come in turns of ``block`` back to back (the turns
    ordered as the frames above), each turn opening with one untimed call (the first call
    after another callable's pays for its caches and its threads woken), the last turn cut to
    what is left: the steady state of back-to-back frames, where ``block`` 1 times every
    frame right after the others'.

    ``cpu``: a clock in seconds (``time.process_time``: all the process's threads) read around
    each call too, steadier than wall time where other work shares the CPUs.  ``after_call``:
    called with the key after each timed call, outside the timing (a progress bar).  Returns
    per key its ``Samples``, one entry per frame."""
    if warmup:
        for fn in fns.values():
            fn()
    out = {key: Samples() for key in fns}
    order = list(fns.items())
    turn = 0
    while any(len(s.wall) < frames for s in out.values()):
        for key, fn in (order[::-1] if alternate and turn % 2 else order):
            left = frames - len(out[key].wall)
            if block > 1 and left > 0:
                fn()                # the turn's untimed first call
            for _ in range(min(block, left)):
                c0 = cpu() if cpu is not None else 0.0
                t0 = time.perf_counter()
                fn()
                wall = time.perf_counter() - t0
                if cpu is not None:
                    out[key].cpu.append(cpu() - c0)
                out[key].wall.append(wall)
                if after_call is not None:
                    after_call(key)
        turn += 1
    return out
