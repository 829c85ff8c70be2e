"""The error budget of ``pipegen tune``: one or more ``METRIC OP NUMBER`` joined by ``,``, e.g.
``"p99<=2"`` or ``"p99<=2, max<=40, lights_dropped==0"``.  Every term must hold on every scene.

Metrics (all "lower is better"): ``p99``, ``max``, ``rmse`` of the output against the
reference in rgba8 codes; ``flip`` (mean ꟻLIP, 0..1); ``lights_dropped``: light-pixel pairs a
light-index packing cannot hold (``measure.lights_dropped``).  A budget bounds error from above,
so the comparisons are ``<=``, ``<`` and ``==`` (``==`` for counts: ``lights_dropped==0``).
A bad budget is a ``PipegenError`` with a caret under the offending text.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from pipegen.core.diagnostics import PipegenError, Span

# metric -> what it is, for messages and docs
METRICS = {
    "p99": "99th percentile of the per-pixel error (largest channel), rgba8 codes",
    "max": "largest channel error, rgba8 codes",
    "rmse": "RMSE over every RGB value, rgba8 codes",
    "flip": "mean ꟻLIP (LDR), 0..1",
    "lights_dropped": "light-pixel pairs beyond a light-index packing's capacity",
}
# metrics that need the technique rendered (the others are computed from the scene alone)
RENDERED = ("p99", "max", "rmse", "flip")
OPS = ("<=", "<", "==")
EXAMPLE = 'e.g. --budget "p99<=2" or --budget "p99<=2, lights_dropped==0"'
_TERM = re.compile(r"\s*([A-Za-z_][A-Za-z0-9_]*)?\s*(<=|>=|==|<|>|=)?\s*([^,]*?)\s*$")


@dataclass(frozen=True)
class Bound:
    """One term: ``metric op limit``."""

    metric: str
    op: str
    limit: float

    def holds(self, value: float) -> bool:
        if value is None or math.isnan(value):
            return False
        return {"<=": value <= self.limit, "<": value < self.limit,
                "==": value == self.limit}[self.op]

    def miss(self, value: float) -> float:
        """How far ``value`` is beyond the limit (0 when within it)."""
        if value is None or math.isnan(value):
            return math.inf
        return 0.0 if self.holds(value) else abs(value - self.limit)

    @property
    def text(self) -> str:
        return f"{self.metric}{self.op}{self.limit:g}"


@dataclass(frozen=True)
class Budget:
    terms: tuple[Bound, ...]
    source: str

    @property
    def text(self) -> str:
        return ", ".join(t.text for t in self.terms)

    @property
    def metrics(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(t.metric for t in self.terms))

    @property
    def needs_render(self) -> bool:
        return any(t.metric in RENDERED for t in self.terms)

    def holds(self, figures: dict) -> bool:
        return all(t.holds(figures.get(t.metric, math.nan)) for t in self.terms)

    def misses(self, figures: dict) -> list[tuple[Bound, float, float]]:
        """The terms that fail: (term, value, how far beyond its limit)."""
        return [(t, figures.get(t.metric, math.nan), t.miss(figures.get(t.metric, math.nan)))
                for t in self.terms if not t.holds(figures.get(t.metric, math.nan))]

    def shortfall(self, figures: dict) -> float:
        """One number to rank configurations that miss: the sum of each failing term's miss
        relative to its limit (a limit of 0 counts the miss itself)."""
        return sum(m / max(abs(t.limit), 1.0) for t, _, m in self.misses(figures))


def _error(text: str, column: int, width: int, message: str, hint: str) -> PipegenError:
    return PipegenError(Span("--budget", 1, column, 1, column + max(1, width), text), message,
                        hint=hint)


def parse_budget(text: str) -> Budget:
    """``"p99<=2, lights_dropped==0"`` -> ``Budget``; a ``PipegenError`` with a caret on bad
    text."""
    raw = str(text)
    if not raw.strip():
        raise _error(raw, 1, 1, "the budget is empty", f"give one or more METRIC<=NUMBER "
                                                       f"joined by commas, {EXAMPLE}")
    terms, column = [], 1
    for part in raw.split(","):
        lead = len(part) - len(part.lstrip())
        start = column + lead
        body = part.strip()
        m = _TERM.match(part)
        name, op, number = m.group(1), m.group(2), m.group(3)
        if not body:
            raise _error(raw, column, max(1, len(part)), "an empty term in the budget",
                         f"terms are joined by single commas, {EXAMPLE}")
        if not name or name not in METRICS:
            width = len(name) if name else len(body)
            raise _error(raw, start, width, f"unknown budget metric {name or body!r}",
                         "metrics: " + ", ".join(METRICS))
        at = start + part.lstrip().find(op) if op else start + len(name)
        if not op or op not in OPS:
            raise _error(raw, at, len(op or " "),
                         f"a budget bounds {name} from above: use <=, < or ==" +
                         (f", not {op}" if op else ""), EXAMPLE)
        num_at = column + part.rfind(number) if number else at + len(op)
        try:
            limit = float(number)
        except ValueError:
            limit = math.nan
        if not number or not math.isfinite(limit) or limit < 0:
            raise _error(raw, num_at, len(number or " "),
                         f"the limit of {name} must be a number >= 0"
                         + (f", not {number!r}" if number else ""), EXAMPLE)
        if any(t.metric == name for t in terms):
            raise _error(raw, start, len(body), f"{name} is bounded twice",
                         "give each metric once")
        terms.append(Bound(name, op, limit))
        column += len(part) + 1
    return Budget(tuple(terms), raw)
