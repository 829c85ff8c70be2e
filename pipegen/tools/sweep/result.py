"""A sweep's result: one row per variant and backend (:data:`COLUMNS`, then
:data:`EXTRA_COLUMNS`), where and how it was measured, the error maps, and the printed table."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

from pipegen.core.units import format_bytes

# at least these columns, in this order, then the extras
COLUMNS = ["technique", "params", "backend", "frame_ms", "target_bytes", "rmse_scene",
           "p99_scene", "max_scene", "flip_scene", "rmse_f64", "p99_f64", "max_f64", "agree"]
# (frame_ms is the median of the timed frames, frame_ms_q1..frame_ms_q3 their interquartile
# range; ties: the numbers of the rows on the same backend whose ranges overlap; pareto: on its
# backend's front; target_bytes: the sum of all targets, peak_bytes: the most live at once,
# allocated_bytes: what the row's backend allocates sharing storage between targets of
# disjoint lifetimes (ir/lifetimes.py: CL true aliasing, GL slot reuse), bandwidth_bytes: the
# frame's estimated memory traffic on the sweep's scene (ir/traffic.py's rule, each pass
# counted as often as the scene's lights run it); reference: what the *_scene errors are
# measured against; clamped: values
# the formats clamped in a CL frame, the output's highlights aside (empty on GL rows: GL never
# shows them); target_errors: each intermediate attribute's p99 in its own units; device: the
# backend and the device its worker rendered on, "GL (NVIDIA H200)", as plots name it)
EXTRA_COLUMNS = ["cpu_ms", "rmse_interior", "max_interior", "file", "width", "height", "notes",
                 "frame_ms_q1", "frame_ms_q3", "ties", "pareto", "reference", "clamped",
                 "target_errors", "peak_bytes", "allocated_bytes", "bandwidth_bytes", "device"]
# results.json only, per row: where its error map and image are, its worst pixels
# ([x, y, [got r, g, b], [reference r, g, b]], y from the top, rgba8 codes), the command that
# reproduces it, its intermediate targets' errors (``jobs.intermediate_errors``) and, on CL
# rows, the clamps (``runtime.cl.clamps.Clamp`` fields and ``warned``)
JSON_ONLY = ["error_map", "image", "worst", "command", "targets", "clamps"]
# the columns that hold numbers (an empty one is NaN in memory, null in results.json)
NUMERIC = {"frame_ms", "cpu_ms", "rmse_scene", "p99_scene", "max_scene", "flip_scene", "rmse_f64",
           "p99_f64", "max_f64", "rmse_interior", "max_interior", "frame_ms_q1", "frame_ms_q3",
           "clamped"}


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
    images: dict = field(default_factory=dict)  # {file name under images/: PNG bytes}
    references: dict = field(default_factory=dict)  # {technique: {label, text, why}}
    command: str = ""                      # the command line that reproduces the sweep
    warnings: list[str] = field(default_factory=list)   # values the formats clamped

    def targets_table(self) -> str:
        return format_targets(self.rows)

    def table(self) -> str:
        return format_table(self.rows, self.references)

    def summary(self) -> str:
        head = (f"sweep on {self.scene} at {self.width}x{self.height} ({self.lights} lights), "
                f"{len({r['file'] + r['params'] for r in self.rows})} variants x "
                f"{len(self.backends)} backends")
        lines = [head, self.table()]
        targets = self.targets_table()
        lines += [targets] if targets else []
        lines += [f"renders and error maps: {self.where}", self.timing]
        lines += [f"note: {n}" for n in self.notes] + self.warnings
        return "\n".join(lines) + "\n"


def _fmt(value, digits: int) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.{digits}f}"


def _ties(numbers) -> str:
    numbers = list(numbers or ())
    if not numbers:
        return ""
    shown = ",".join(map(str, numbers[:3]))
    return "=" + shown + (f"+{len(numbers) - 3}" if len(numbers) > 3 else "")


def _spread(r: dict) -> str:
    q1, q3 = r.get("frame_ms_q1", math.nan), r.get("frame_ms_q3", math.nan)
    if not (isinstance(q1, float) and math.isfinite(q1) and math.isfinite(q3)):
        return "-"
    return f"{q1:.1f}-{q3:.1f}"


def reference_line(rows: list[dict], references: dict) -> str:
    """What the errors are measured against (``references``: {technique: {label, text, why}}):
    one reference, or one per technique."""
    techniques = list(dict.fromkeys(r["technique"] for r in rows))
    known = [references[t] for t in techniques if t in references]
    if not known:                       # an older results.json: the label alone
        labels = sorted({r.get("reference") or "scene" for r in rows})
        return "reference: " + ", ".join(labels)
    said = {(k["text"], k.get("why", "")) for k in known}
    if len(said) == 1:
        text, why = next(iter(said))
        return f"reference: {text}" + (f" (the default: {why})" if why else "")
    return "references: " + "; ".join(
        f"{t}: {references[t]['text']}" + (" (its default)" if references[t].get("why") else "")
        for t in techniques if t in references)


def reference_label(rows: list[dict]) -> str:
    """The reference as plot titles and table headings name it."""
    labels = list(dict.fromkeys(r.get("reference") or "scene" for r in rows))
    return labels[0] if len(labels) == 1 else "each technique's reference (" + \
        ", ".join(labels) + ")"


def format_table(rows: list[dict], references: Optional[dict] = None) -> str:
    header = ("#", "technique", "params", "backend", "frame ms", "q1-q3", "tie", "targets MiB",
              "rmse", "p99", "max", "ꟻLIP", "rmse f64", "p99 f64", "max f64", "agree", "front")
    body = [(str(n), r["technique"], r["params"] or "-", r["backend"], _fmt(r["frame_ms"], 1),
             _spread(r), _ties(r.get("ties")),
             format_bytes(r["target_bytes"], "MiB", suffix=False), _fmt(r["rmse_scene"], 2),
             _fmt(r["p99_scene"], 0), _fmt(r["max_scene"], 0), _fmt(r["flip_scene"], 4),
             _fmt(r["rmse_f64"], 3), _fmt(r["p99_f64"], 0), _fmt(r["max_f64"], 0),
             {True: "yes", False: "NO", None: "-"}[r["agree"]],
             "*" if r.get("pareto") else "") for n, r in enumerate(rows, 1)]
    table = [header, *body]
    widths = [max(len(x[i]) for x in table) for i in range(len(header))]
    right = {0, *range(4, 6), *range(7, 15)}
    lines = ["  ".join((c.rjust(w) if i in right else c.ljust(w))
                       for i, (c, w) in enumerate(zip(x, widths))).rstrip() for x in table]
    against = reference_label(rows)
    against = f"the {against} reference" if "(" not in against else against
    lines.insert(1, f"errors in rgba8 codes vs {against} (rmse, p99, max: whole image) and vs "
                    f"the f64 evaluation; ꟻLIP: mean, vs {against}")
    lines.append("frame ms: median of the timed frames, q1-q3 their interquartile range; tie: "
                 "the rows (# on the same backend) whose ranges overlap, not ranked by time; "
                 "front *: on the Pareto front of its backend (error against frame time, ties "
                 "not ranked)")
    lines.append(reference_line(rows, references or {}))
    return "\n".join(lines)


UNIT_SHORT = {"degrees": "deg", "scene units": "world", "field steps": "steps",
              "codes": "codes", "value units": "value"}


def format_targets(rows: list[dict]) -> str:
    """The intermediate targets' errors: a line per row, a column per attribute (``p99/max``
    in the attribute's own units: degrees for a decoded normal, scene units for a depth's
    world position, field steps, codes or stored units), and what they are against; below,
    what each column holds and how it was decoded."""
    columns: dict[str, dict] = {}                   # column -> {units, how}
    for r in rows:
        for e in r.get("targets") or []:
            c = columns.setdefault(e.get("column", e["attribute"]),
                                   {"units": e["units"], "how": set()})
            c["how"].add(e["attribute"])
    if not columns:
        return ""
    header = ("#", "backend", *(f"{c} ({UNIT_SHORT.get(v['units'], v['units'])})"
                                for c, v in columns.items()), "vs")
    body = []
    for n, r in enumerate(rows, 1):
        got = {e.get("column", e["attribute"]): f"{e['p99']:.2g}/{e['max']:.2g}"
               for e in r.get("targets") or []}
        vs = ",".join(sorted({e["against"] for e in r.get("targets") or []})) or "-"
        body.append((str(n), r["backend"], *(got.get(c, "-") for c in columns), vs))
    table = [header, *body]
    widths = [max(len(x[i]) for x in table) for i in range(len(header))]
    left = {1, len(header) - 1}
    out = ["  ".join(c.ljust(w) if i in left else c.rjust(w)
                     for i, (c, w) in enumerate(zip(x, widths))).rstrip() for x in table]
    out.insert(0, "intermediate targets: p99/max of each attribute against the reference's "
                  "same target (vs f64: the variant's own float64 evaluation, its precision "
                  "error alone: the scene reference has no targets)")
    out += [f"  {c}: {', '.join(sorted(v['how']))}" for c, v in columns.items()
            if v["how"] != {c}]
    return "\n".join(out)


def backend_title(backend: str) -> str:
    """A row's ``device`` where its worker did not say (a journal of an older sweep): the
    backend's title."""
    from pipegen.backends import registry
    return registry.get(backend).title


def device_names(rows: list[dict], backends) -> dict[str, str]:
    """{backend: what plots call it}: the device its rows were rendered on ("GL (NVIDIA
    H200)"), all of them where workers differed ("GL (llvmpipe) | GL (NVIDIA H200)")."""
    return {b: " | ".join(dict.fromkeys(r.get("device") or backend_title(b)
                                        for r in rows if r["backend"] == b))
            or backend_title(b) for b in backends}
