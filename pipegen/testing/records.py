"""Every comparison ``pipegen.testing`` makes, as a record the pytest plugin's HTML report
reads (``--pipegen-report=DIR``).

A test's comparisons are appended to ``RECORDED`` as they are made (passing or not); the plugin
takes them after each test (``take()``) and files them under the test's id.  Pictures are kept
only when ``settings.keep_images`` is set (a report was asked for): small renders, but a whole
suite's worth of them need not stay in memory otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

KINDS = ("backends", "f64", "golden", "expect")


@dataclass
class Comparison:
    """One target compared with another rendering of it.

    ``kind``: "backends" (GL against CL), "f64" (a float32 backend against the float64
    evaluation), "golden" (a render against its stored golden), "expect" (an expectation of a
    ``.pipe`` file).  ``numbers``: label -> text for the report's table (max error, bound,
    pixels over, discontinuities, ꟻLIP, ...).  ``images``: name -> uint8 RGB array (H, W, 3),
    top row first, among "expected", "actual", "difference", "flip"; empty unless
    ``settings.keep_images``.  ``command``: a shell command that reproduces the comparison.
    ``message``: the failure message (empty when it passed)."""

    kind: str
    technique: str
    target: str
    passed: bool
    summary: str
    numbers: dict[str, str] = field(default_factory=dict)
    images: dict[str, Any] = field(default_factory=dict)
    command: str = ""
    message: str = ""
    test: str = ""
    artifacts: dict[str, str] = field(default_factory=dict)   # name -> path of a file written


RECORDED: list[Comparison] = []


def record(c: Comparison) -> Comparison:
    from pipegen.testing import settings
    c.test = c.test or settings.current_test
    RECORDED.append(c)
    return c


def take() -> list[Comparison]:
    """The comparisons recorded since the last ``take`` (and forget them)."""
    out = list(RECORDED)
    RECORDED.clear()
    return out
