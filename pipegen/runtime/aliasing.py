"""When a runtime that shares target storage (``ir.lifetimes``) clears each target, and which
targets its storage holds at a given moment: the same bookkeeping for both runtimes.

Without sharing every target is cleared at the start of a frame, as always.  With sharing,
the first target of each slot is too (nothing used its storage before it); a later one is
cleared when its lifetime begins: before the first pass execution at or after its first pass
(``before_pass``), or at the end of the frame when no such execution ran (``finish``: a repeat
group with no light of its types, say).  Clearing then instead of at the start of the frame
gives the same contents, since nothing touches a target before its first pass.

``holding()`` names, per slot, the target whose contents the storage holds now: the latest one
cleared.  After ``finish`` that is the last of each slot, so a frame's result (``render``)
holds every target except ``MemoryPlan.aliased``, whose storage a later target took over.
"""

from __future__ import annotations

from pipegen.ir.lifetimes import MemoryPlan, Sharing


class FrameClears:
    def __init__(self, memory: MemoryPlan):
        self.memory = memory
        self._pending: list[str] = []
        self._holding: list[str] = []

    def start(self) -> list[str]:
        """The targets to clear at the start of a frame (in plan order of their slots)."""
        slots = self.memory.slots
        life = self.memory.lifetimes
        if self.memory.sharing is Sharing.NONE:
            self._pending = []
        else:
            self._pending = sorted((n for s in slots for n in s.targets[1:]),
                                   key=lambda n: life[n].first)
        self._holding = [s.targets[0] for s in slots]
        return list(self._holding)

    def before_pass(self, k: int) -> list[str]:
        """The targets to clear before an execution of pass ``k``, in lifetime order."""
        due = []
        life = self.memory.lifetimes
        while self._pending and life[self._pending[0]].first <= k:
            due.append(self._pending.pop(0))
        self._hold(due)
        return due

    def finish(self) -> list[str]:
        """The targets still to clear at the end of a frame (no pass execution reached them)."""
        due, self._pending = self._pending, []
        self._hold(due)
        return due

    def holding(self) -> list[str]:
        return list(self._holding)

    def _hold(self, names: list[str]) -> None:
        for name in names:
            s = self.memory.slots.index(self.memory.slot_of(name))
            self._holding[s] = name
