"""The values the formats clamped, in words and figures (counted by the CL backend,
``runtime/cl/clamps.py``).

``warning_lines(clamps, output)``: one warning per (pass, target) whose stored values are not
the values written, for ``pipegen run`` and ``check``.  Values above the range of the
technique's ``output`` (its final image) are the display's highlights saturating, which the
picture shows (every shipped technique writes HDR light into its rgba8 output): they are
counted, not warned about; a value below it, and any clamp of an intermediate target, is
invisible in the picture and warned about.

``Clamped``: the testing API's figure (``Targets.clamped``): target -> values clamped in the
frame (channels of fragments), all passes together, ``passes(target)`` per pass.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Iterator, Optional

from pipegen.runtime.cl.clamps import Clamp


def _number(x: float) -> str:
    return f"{x:.4g}"


class ClampWarning(UserWarning):
    """A value a format clamped, as ``pipegen.testing.render`` warns about it (once per pass
    and target, by Python's default warning filter)."""


def record(c: Clamp, output: Optional[str]) -> dict:
    """A clamp as plain data (a sweep's job result, results.json), ``warned`` added."""
    return dict(vars(c), warned=warned(c, output))


def from_record(data: dict) -> Clamp:
    """:func:`record` read back."""
    return Clamp(**{k: v for k, v in data.items() if k != "warned"})


def warned(c: Clamp, output: Optional[str]) -> bool:
    """Whether a clamp is warned about (the module docstring): not the output's highlights."""
    return not (c.target == output and c.lowest is None)


def describe(c: Clamp) -> str:
    """``pass gbuffer wrote 108 values outside what galbedo holds (rgba8: 0 to 1), as high
    as 82.8; ...``: the values (channels of fragments), the format's range, the extremes."""
    extremes = [f"as high as {_number(c.highest)}" if c.highest is not None else "",
                f"as low as {_number(c.lowest)}" if c.lowest is not None else ""]
    extremes = " and ".join(e for e in extremes if e)
    noun = "value" if c.count == 1 else "values"
    return (f"pass {c.pass_name} wrote {c.count} {noun} outside what {c.target} holds "
            f"({c.format}: {_number(c.lo)} to {_number(c.hi)})"
            f"{', ' + extremes if extremes else ''}; the format clamped them")


def warning_lines(clamps: list[Clamp], output: Optional[str]) -> list[str]:
    """The warnings of a command's frames (``ClampLog.clamps``), one per pass and target."""
    out = []
    for c in clamps:
        if warned(c, output):
            out.append(f"warning: {describe(c)} (counted on the CL backend, per frame)")
    if out:
        out.append("  hint: what the target stores is not what the pass computed: scale the "
                   "value into the range, or give the target a format that holds it")
    return out


class Clamped(Mapping):
    """A frame's clamped values: ``clamped["galbedo"]`` (all passes; only targets with
    some are keys: ``clamped.get(name, 0)``), ``passes("galbedo")`` -> {pass: count},
    ``clamps``: the records (extremes, range), ``warnings()``: what ``pipegen run`` says."""

    def __init__(self, clamps: list[Clamp], output: Optional[str] = None):
        self.clamps = list(clamps)
        self.output = output
        self._totals: dict[str, int] = {}
        for c in self.clamps:
            self._totals[c.target] = self._totals.get(c.target, 0) + c.count

    def __getitem__(self, target: str) -> int:
        return self._totals[target]

    def __iter__(self) -> Iterator[str]:
        return iter(self._totals)

    def __len__(self) -> int:
        return len(self._totals)

    def passes(self, target: str) -> dict[str, int]:
        return {c.pass_name: c.count for c in self.clamps if c.target == target}

    def warnings(self) -> list[str]:
        return warning_lines(self.clamps, self.output)

    def __repr__(self) -> str:
        return f"Clamped({self._totals!r})"


def clamped_values(pipeline, output: Optional[str] = None) -> Optional[Clamped]:
    """The last frame's ``Clamped`` of a pipeline that counts them (the CL backend's), else
    None: GL clamps in fixed-function stores that never show the values written."""
    got = getattr(pipeline, "last_clamps", None)
    return None if got is None else Clamped(got, output)
