"""The Pareto front of a sweep: which variants no other beats on both error and cost, and
``pareto.png`` drawing it per backend (matplotlib, imported only when drawing)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

from pipegen.core.units import mebibytes
from pipegen.tools.sweep.result import SweepResult, reference_label


def pareto_front(points: list[tuple[float, float]],
                 spans: Optional[list[tuple[float, float]]] = None) -> list[int]:
    """Indices of the front (lower is better on both x and y), sorted by x.

    ``spans``: per point, the range ``(lo, hi)`` its y was measured in (frame times: the
    interquartile range); y values whose ranges overlap are ties, neither better.  Walking from
    the most accurate point (smallest x), a point joins the front only when its range lies
    entirely below the range of every more accurate point already on it, or, equally accurate,
    when no such point's range lies entirely below its own.  So a variant faster than a more
    accurate one only within the noise is off the front, two equally accurate variants whose
    times tie both stay, and a variant clearly faster than every more accurate one on the
    front stays even where a tie links it to them.  Without ``spans`` each y is exact: the
    usual front."""
    idx = [i for i, (x, y) in enumerate(points) if math.isfinite(x) and math.isfinite(y)]
    lo_hi = [(y, y) for _, y in points] if spans is None else \
        [(min(s[0], p[1]), max(s[1], p[1])) if all(map(math.isfinite, s)) else (p[1], p[1])
         for s, p in zip(spans, points)]
    idx.sort(key=lambda i: (points[i][0], lo_hi[i][0], points[i][1]))
    front: list[int] = []
    for b in idx:
        if all(lo_hi[b][1] < lo_hi[a][0] if points[a][0] < points[b][0]
               else not lo_hi[a][1] < lo_hi[b][0] for a in front):
            front.append(b)
    return sorted(front, key=lambda i: (points[i][0], points[i][1]))


def tie_groups(spans: list[tuple[float, float]]) -> list[list[int]]:
    """For each range, the indices of the other ranges overlapping it (ties), by index."""
    ok = [all(map(math.isfinite, s)) for s in spans]
    return [[j for j, t in enumerate(spans) if j != i and ok[i] and ok[j]
             and t[0] <= s[1] and s[0] <= t[1]] for i, s in enumerate(spans)]


def mark_front_and_ties(rows: list[dict]) -> None:
    """Set every row's ``pareto`` (on its backend's front: RMSE against frame time, or target
    memory without timings) and ``ties`` (the 1-based numbers of the rows on its backend whose
    frame time ranges overlap its own)."""
    for b in dict.fromkeys(r["backend"] for r in rows):
        mine = [i for i, r in enumerate(rows) if r["backend"] == b]
        sel = [rows[i] for i in mine]
        spans = [(r.get("frame_ms_q1", math.nan), r.get("frame_ms_q3", math.nan)) for r in sel]
        timed = any(math.isfinite(r["frame_ms"]) for r in sel)
        pts = [(r["rmse_scene"], r["frame_ms"] if timed else float(r["target_bytes"]))
               for r in sel]
        front = set(pareto_front(pts, spans if timed else None))
        for k, (r, ties) in enumerate(zip(sel, tie_groups(spans))):
            r["pareto"] = k in front
            r["ties"] = [mine[j] + 1 for j in ties]


def front_ties(front: list[int], spans: Optional[list[tuple[float, float]]]) -> list[list[int]]:
    """The front (indices sorted by error) cut into runs whose time ranges overlap a member of
    the run: each run of two or more is drawn as one band, "tie"."""
    groups: list[list[int]] = []
    for i in front:
        if groups and spans is not None and any(
                spans[j][0] <= spans[i][1] and spans[i][0] <= spans[j][1] for j in groups[-1]):
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


def pareto_png(result: SweepResult, path, title: str = "") -> None:
    """Frame time (or, without timings, target memory) against RMSE vs the reference, one
    panel per backend: each point's interquartile range as an error bar, the Pareto front
    drawn, front members whose times tie shaded as one band, every point labelled."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    timed = any(math.isfinite(r["frame_ms"]) for r in result.rows)
    ylabel = "frame time (ms): median, bar q1-q3" if timed else \
        "target memory (MiB; no timings)"
    ref = reference_label(result.rows)
    backends = list(result.backends)
    fig, axes = plt.subplots(1, len(backends), figsize=(6.4 * len(backends), 5.2),
                             squeeze=False)
    files = sorted({r["file"] for r in result.rows}, key=[r["file"] for r in result.rows].index)
    colours = {f: plt.get_cmap("tab10")(i % 10) for i, f in enumerate(files)}
    from pipegen.tools.sweep.result import device_names
    names = device_names(result.rows, backends)
    labels = point_labels(result.rows, several_files=len(files) > 1)
    for ax, b in zip(axes[0], backends):
        rows = [r for r in result.rows if r["backend"] == b]
        pts = [(r["rmse_scene"], r["frame_ms"] if timed else mebibytes(r["target_bytes"]))
               for r in rows]
        spans = [_span(r, y) for r, (_, y) in zip(rows, pts)] if timed else None
        order = sorted(range(len(rows)), key=lambda i: pts[i][1])
        for rank, i in enumerate(order):
            r, (x, y) = rows[i], pts[i]
            ax.scatter([x], [y], color=colours[r["file"]], s=36, zorder=3,
                       edgecolors="black" if r["agree"] is False else "none")
            if spans is not None and spans[i][0] != spans[i][1]:
                ax.plot([x, x], spans[i], color="0.25", linewidth=1, zorder=2)
            label = labels[id(r)]
            # neighbours in y alternate above and below their points: fewer overlaps
            ax.annotate(label, (x, y), textcoords="offset points",
                        xytext=(5, 3 if rank % 2 == 0 else -9), ha="left", fontsize=7)
        ys = [y for _, y in pts if math.isfinite(y) and y > 0]
        if ys and max(ys) > 5 * min(ys):
            ax.set_yscale("log")
        xs = [x for x, _ in pts if math.isfinite(x)]
        span = 1e-3
        if xs:
            lo, hi = min(xs), max(xs)
            span = (hi - lo) or max(hi, 1e-3)
            ax.set_xlim(lo - 0.08 * span, hi + 0.45 * span)      # room for the labels
        front = pareto_front(pts, spans)
        if front:
            fx = [pts[i][0] for i in front]
            fy = [pts[i][1] for i in front]
            ax.step(fx, fy, where="post", color="0.4", linestyle="--", linewidth=1, zorder=2,
                    label="Pareto front")
        for k, g in enumerate(t for t in front_ties(front, spans) if len(t) > 1):
            x0, x1 = min(pts[i][0] for i in g), max(pts[i][0] for i in g)
            y0, y1 = min(spans[i][0] for i in g), max(spans[i][1] for i in g)
            pad = 0.03 * span
            ax.add_patch(Rectangle((x0 - pad, y0), x1 - x0 + 2 * pad, y1 - y0, zorder=1,
                                   facecolor="#ffdd33", alpha=0.35, edgecolor="#cc9900",
                                   label="times tie (q1-q3 overlap)" if k == 0 else None))
            ax.annotate("tie", (x1 + pad, y1), fontsize=7, color="#996600", ha="left",
                        va="bottom")
        for f in files:
            ax.scatter([], [], color=colours[f], label=Path(f).stem)
        ax.set_xlabel(f"RMSE vs {ref} reference (rgba8 codes)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{names.get(b, b)}: {Path(result.scene).name} "
                     f"{result.width}x{result.height}, error vs {ref}", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def point_labels(rows: list[dict], several_files: bool, width: int = 38) -> dict[int, str]:
    """Each row's label (by ``id(row)``): the parameters that tell it from the other rows,
    wrapped; a parameter set to one value in every row that has it (``-p shadow_size=768`` on
    every technique) says nothing and is left out (the table lists it).  With several files
    the technique's name leads (its colour is in the legend too)."""
    import textwrap
    parsed = {id(r): dict(kv.split("=", 1) for kv in r["params"].split() if "=" in kv)
              for r in rows}
    values: dict[str, set] = {}
    for d in parsed.values():
        for k, v in d.items():
            values.setdefault(k, set()).add(v)
    out = {}
    for r in rows:
        varying = " ".join(f"{k}={v}" for k, v in parsed[id(r)].items() if len(values[k]) > 1)
        label = f"{r['technique']} {varying}".strip() if several_files or not varying \
            else varying
        out[id(r)] = textwrap.fill(label, width)
    return out


def _span(row: dict, y: float) -> tuple[float, float]:
    lo, hi = row.get("frame_ms_q1", math.nan), row.get("frame_ms_q3", math.nan)
    return (lo, hi) if math.isfinite(lo) and math.isfinite(hi) else (y, y)
