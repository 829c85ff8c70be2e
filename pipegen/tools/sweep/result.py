"""A sweep's result: one row per variant and backend (:data:`COLUMNS`, then
:data:`EXTRA_COLUMNS`), where and how it was measured, the error maps, and the printed table."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pipegen.core.units import format_bytes

# at least these columns, in this order, then the extras
COLUMNS = ["technique", "params", "backend", "frame_ms", "target_bytes", "rmse_scene",
           "p99_scene", "max_scene", "flip_scene", "rmse_f64", "p99_f64", "max_f64", "agree"]
EXTRA_COLUMNS = ["cpu_ms", "rmse_interior", "max_interior", "file", "width", "height", "notes"]
# the columns that hold numbers (an empty one is NaN in memory, null in results.json)
NUMERIC = {"frame_ms", "cpu_ms", "rmse_scene", "p99_scene", "max_scene", "flip_scene", "rmse_f64",
           "p99_f64", "max_f64", "rmse_interior", "max_interior"}


@dataclass
class SweepResult:
    rows: list[dict]                       # one per (variant, backend): COLUMNS + EXTRA_COLUMNS
    scene: str
    width: int
    height: int
    lights: int
    backends: tuple
    where: str                             # where the renders ran
    timing: str                            # how frame times were taken (or why not)
    notes: list[str] = field(default_factory=list)
    maps: dict = field(default_factory=dict)   # {file name under errors/: PNG bytes}

    def table(self) -> str:
        return format_table(self.rows)

    def summary(self) -> str:
        head = (f"sweep on {self.scene} at {self.width}x{self.height} ({self.lights} lights), "
                f"{len({r['file'] + r['params'] for r in self.rows})} variants x "
                f"{len(self.backends)} backends")
        lines = [head, self.table(), f"renders and error maps: {self.where}", self.timing]
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines) + "\n"


def _fmt(value, digits: int) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.{digits}f}"


def format_table(rows: list[dict]) -> str:
    header = ("technique", "params", "backend", "frame ms", "targets MiB", "rmse", "p99",
              "max", "ꟻLIP", "rmse f64", "p99 f64", "max f64", "agree")
    body = [(r["technique"], r["params"] or "-", r["backend"], _fmt(r["frame_ms"], 1),
             format_bytes(r["target_bytes"], "MiB", suffix=False), _fmt(r["rmse_scene"], 2),
             _fmt(r["p99_scene"], 0), _fmt(r["max_scene"], 0), _fmt(r["flip_scene"], 4),
             _fmt(r["rmse_f64"], 3), _fmt(r["p99_f64"], 0), _fmt(r["max_f64"], 0),
             {True: "yes", False: "NO", None: "-"}[r["agree"]]) for r in rows]
    table = [header, *body]
    widths = [max(len(x[i]) for x in table) for i in range(len(header))]
    right = set(range(3, 12))
    lines = ["  ".join((c.rjust(w) if i in right else c.ljust(w))
                       for i, (c, w) in enumerate(zip(x, widths))).rstrip() for x in table]
    lines.insert(1, "errors in rgba8 codes vs the scene reference (rmse, p99, max: whole "
                    "image) and vs the f64 evaluation; ꟻLIP: mean, vs the scene reference")
    return "\n".join(lines)
