"""The Pareto front of a sweep: which variants no other beats on both error and cost, and
``pareto.png`` drawing it per backend (matplotlib, imported only when drawing)."""

from __future__ import annotations

import math
from pathlib import Path

from pipegen.core.units import mebibytes
from pipegen.tools.sweep.result import SweepResult


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats on both x and y (lower is better), sorted
    by x."""
    idx = [i for i, (x, y) in enumerate(points) if math.isfinite(x) and math.isfinite(y)]
    idx.sort(key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in idx:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def pareto_png(result: SweepResult, path, title: str = "") -> None:
    """Frame time (or, without timings, target memory) against RMSE vs the scene reference,
    one panel per backend, the Pareto front drawn, every point labelled."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    timed = any(math.isfinite(r["frame_ms"]) for r in result.rows)
    ylabel = "frame time (ms)" if timed else "target memory (MiB; no timings)"
    backends = list(result.backends)
    fig, axes = plt.subplots(1, len(backends), figsize=(6.4 * len(backends), 5.2),
                             squeeze=False)
    files = sorted({r["file"] for r in result.rows}, key=[r["file"] for r in result.rows].index)
    colours = {f: plt.get_cmap("tab10")(i % 10) for i, f in enumerate(files)}
    names = {"gl": "GL (llvmpipe)", "cl": "CL (PoCL)"}
    for ax, b in zip(axes[0], backends):
        rows = [r for r in result.rows if r["backend"] == b]
        pts = [(r["rmse_scene"], r["frame_ms"] if timed else mebibytes(r["target_bytes"]))
               for r in rows]
        order = sorted(range(len(rows)), key=lambda i: pts[i][1])
        for rank, i in enumerate(order):
            r, (x, y) = rows[i], pts[i]
            ax.scatter([x], [y], color=colours[r["file"]], s=36, zorder=3,
                       edgecolors="black" if r["agree"] is False else "none")
            label = r["params"] or r["technique"]
            if len(files) > 1 and r["params"]:
                label = f"{r['technique']} {r['params']}"
            # neighbours in y alternate above and below their points: fewer overlaps
            ax.annotate(label, (x, y), textcoords="offset points",
                        xytext=(5, 3 if rank % 2 == 0 else -9), ha="left", fontsize=7)
        ys = [y for _, y in pts if math.isfinite(y) and y > 0]
        if ys and max(ys) > 5 * min(ys):
            ax.set_yscale("log")
        xs = [x for x, _ in pts if math.isfinite(x)]
        if xs:
            lo, hi = min(xs), max(xs)
            span = (hi - lo) or max(hi, 1e-3)
            ax.set_xlim(lo - 0.08 * span, hi + 0.45 * span)      # room for the labels
        front = pareto_front(pts)
        if front:
            fx = [pts[i][0] for i in front]
            fy = [pts[i][1] for i in front]
            ax.step(fx, fy, where="post", color="0.4", linestyle="--", linewidth=1, zorder=2,
                    label="Pareto front")
        for f in files:
            ax.scatter([], [], color=colours[f], label=Path(f).stem)
        ax.set_xlabel("RMSE vs float64 scene reference (rgba8 codes)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{names.get(b, b)}: {Path(result.scene).name} "
                     f"{result.width}x{result.height}", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
