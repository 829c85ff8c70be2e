"""Target memory as a frame graph plans it: each target's lifetime over the frame's passes,
and which targets can share storage because their lifetimes are disjoint.

A technique's passes run in declaration order (a repeat group as a loop over the lights, a
shadow-map pass once per shadow-casting light, both inside their own pass indices).  Every
target starts a frame holding its clear value: both runtimes clear all targets at the start
of a frame, so no target carries contents from one frame into the next (the previous frame's
camera reaches shaders as matrices, never as a target), and there is nothing to keep alive
across frames.  A target's **lifetime** runs from the first pass that touches it (writes it,
attaches it as depth, reads it or clears it) to the last; a repeat group extends the lifetime
of every target it touches over the whole group (the next light's passes read what the last
light's wrote); the output, and a target no pass touches, live to the end of the frame
(``END``); a target given contents before the frame (``pinned``: a test's preset) lives from
its start (``START``).

Two targets may share storage when one's lifetime ends before the other's begins: the later
one is cleared to its own clear value where it starts, so a runtime that shares storage clears
lazily (before the first pass execution at or after the target's first pass) instead of at the
start of the frame.  ``memory_plan`` gives the sharing, by one of two rules:

- ``BYTES``: true aliasing (the CL runtime: one device buffer per slot, a view per target), any
  formats and sizes; a slot holds the largest of its targets;
- ``DESCRIPTOR``: slot reuse (the GL runtime: textures cannot alias memory, so only a texture of
  the same format, size and sample count can be handed on from one target to the next).

Slots are filled greedily in lifetime order, each target taking the free slot that grows least.
The three figures (``MemoryPlan``): the sum of all targets, the peak live at once (the most any
sharing could reach) and the bytes allocated; every count is ``memory.target_bytes``.
"""

from __future__ import annotations

from enum import Enum
from typing import Iterable, Mapping, Optional, Sequence

from pipegen.core.records import record
from pipegen.ir.memory import target_bytes

START = -1     # a lifetime that begins before the first pass (a preset target)


class Sharing(Enum):
    NONE = "none"               # every target its own storage
    BYTES = "bytes"             # true aliasing of untyped storage (CL buffers)
    DESCRIPTOR = "descriptor"   # slot reuse of same-format, same-size, same-samples textures


@record(frozen=True)
class Lifetime:
    first: int      # index of the first pass touching the target (START: before the frame)
    last: int       # index of the last one (len(passes): the end of the frame)

    def overlaps(self, other: "Lifetime") -> bool:
        return self.first <= other.last and other.first <= self.last


@record(frozen=True)
class Slot:
    targets: tuple[str, ...]    # in lifetime order: each starts after the one before ends
    bytes: int                  # the largest of its targets


@record(frozen=True)
class MemoryPlan:
    lifetimes: Mapping[str, Lifetime]
    slots: tuple[Slot, ...]
    sharing: Sharing
    total_bytes: int            # every target in storage of its own
    peak_bytes: int             # the most bytes live at any one pass
    peak_pass: int              # where (a pass index, or len(passes) for the frame's end)

    @property
    def allocated_bytes(self) -> int:
        return sum(s.bytes for s in self.slots)

    @property
    def aliased(self) -> frozenset:
        """Targets whose storage a later target of the frame takes over: their contents are
        not kept to the end of the frame."""
        return frozenset(n for s in self.slots for n in s.targets[:-1])

    def slot_of(self, name: str) -> Slot:
        for s in self.slots:
            if name in s.targets:
                return s
        raise KeyError(name)

    def shared(self) -> list[tuple[str, ...]]:
        """The slots held by more than one target, as their target names."""
        return [s.targets for s in self.slots if len(s.targets) > 1]


def touched(p) -> list[str]:
    """The targets pass ``p`` touches (an ``ir.Pass`` or a plan's ``PassPlan``)."""
    names = list(p.writes) + list(p.reads) + [name for name, _ in p.clears]
    if p.depth_target:
        names.append(p.depth_target)
    return names


def repeat_spans(passes: Sequence) -> list[tuple[int, int]]:
    """(first, last) pass index of each repeat group: consecutive passes with one
    ``repeat_group`` (as ``runtime.draws.schedule`` runs them)."""
    spans, k = [], 0
    while k < len(passes):
        group, end = passes[k].repeat_group, k + 1
        if group is not None:
            while end < len(passes) and passes[end].repeat_group == group:
                end += 1
            spans.append((k, end - 1))
        k = end
    return spans


def lifetimes(passes: Sequence, targets: Iterable, output: str,
              pinned: Iterable[str] = ()) -> dict[str, Lifetime]:
    """{target name: ``Lifetime``} over ``passes`` (see the module docstring)."""
    end = len(passes)
    first: dict[str, int] = {}
    last: dict[str, int] = {}
    for k, p in enumerate(passes):
        for name in touched(p):
            first.setdefault(name, k)
            last[name] = k
    for lo, hi in repeat_spans(passes):
        for name in {n for p in passes[lo:hi + 1] for n in touched(p)}:
            first[name] = min(first[name], lo)
            last[name] = max(last[name], hi)
    pinned = set(pinned)
    out = {}
    for t in targets:
        lo, hi = first.get(t.name, end), last.get(t.name, end)
        if t.name == output:
            hi = end
        if t.name in pinned:
            lo = START
        out[t.name] = Lifetime(lo, hi)
    return out


def descriptor(t, width: int, height: int) -> tuple:
    """What a texture is created with: format, size in pixels, samples."""
    return (t.format.name, t.size.resolve(width, height), t.samples)


def memory_plan(passes: Sequence, targets: Sequence, output: str, width: int, height: int,
                sharing: Sharing = Sharing.BYTES, pinned: Iterable[str] = ()) -> MemoryPlan:
    """Lifetimes and shared storage of ``targets`` at output size ``width`` x ``height``
    (``passes``/``targets``: a technique's or a plan's)."""
    life = lifetimes(passes, targets, output, pinned)
    size = {t.name: target_bytes(t, width, height) for t in targets}
    kind = {t.name: descriptor(t, width, height) for t in targets}
    order = sorted(range(len(targets)),
                   key=lambda i: (life[targets[i].name].first, -size[targets[i].name], i))
    slots: list[list[str]] = []
    slot_bytes: list[int] = []
    for i in order:
        name = targets[i].name
        best: Optional[tuple] = None
        if sharing is not Sharing.NONE:
            for s, members in enumerate(slots):
                if life[members[-1]].last >= life[name].first:
                    continue
                if sharing is Sharing.DESCRIPTOR and kind[members[-1]] != kind[name]:
                    continue
                grow = max(0, size[name] - slot_bytes[s])
                key = (grow, abs(slot_bytes[s] - size[name]), s)
                if best is None or key < best:
                    best = key
        if best is None:
            slots.append([name])
            slot_bytes.append(size[name])
        else:
            s = best[2]
            slots[s].append(name)
            slot_bytes[s] = max(slot_bytes[s], size[name])
    peak, peak_at = 0, START
    for k in range(START, len(passes) + 1):
        live = sum(size[n] for n, lt in life.items() if lt.first <= k <= lt.last)
        if live > peak:
            peak, peak_at = live, k
    return MemoryPlan(life, tuple(Slot(tuple(m), b) for m, b in zip(slots, slot_bytes)),
                      sharing, sum(size.values()), peak, peak_at)


def technique_memory(tech, width: int, height: int,
                     sharing: Sharing = Sharing.BYTES) -> MemoryPlan:
    """``memory_plan`` of an ``ir.Technique`` (or a ``Plan``: the same fields)."""
    return memory_plan(tech.passes, tech.targets, tech.output, width, height, sharing)
