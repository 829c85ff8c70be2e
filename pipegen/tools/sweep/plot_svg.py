"""The Pareto plot of a sweep as inline SVG for ``index.html``: one panel per backend, error
against frame time (or target memory without timings), every point a ``<circle class="pt"
data-row="N">`` the page's script makes clickable, its interquartile range a vertical bar, the
front a dashed step line, and front members whose times tie drawn as one shaded band labelled
"tie" (their order is noise).  Drawn here, not by matplotlib, so that each point is an element
of the page."""

from __future__ import annotations

import html
import math
from pathlib import Path

from pipegen.core.units import mebibytes
from pipegen.tools.sweep.pareto import front_ties, pareto_front

W, H = 470, 330                       # one panel
LEFT, RIGHT, TOP, BOTTOM = 58, 14, 30, 42
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf")


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _ticks(lo: float, hi: float, log: bool) -> list[float]:
    if log:
        out = []
        for k in range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1):
            out += [m * 10.0 ** k for m in (1, 2, 5) if lo <= m * 10.0 ** k <= hi]
        return out
    raw = (hi - lo) / 5 or 1.0
    step = 10 ** math.floor(math.log10(raw))
    step *= next(m for m in (1, 2, 2.5, 5, 10) if m * step >= raw)
    first = math.ceil(lo / step) * step
    return [first + k * step for k in range(int((hi - first) / step + 1e-9) + 1)]


def _tick_text(v: float) -> str:
    return f"{v:g}" if abs(v) >= 0.01 or v == 0 else f"{v:.1e}"


def colours(rows: list[dict]) -> dict:
    files = list(dict.fromkeys(r["file"] for r in rows))
    return {f: PALETTE[i % len(PALETTE)] for i, f in enumerate(files)}


def panel(rows: list[tuple[int, dict]], backend: str, title: str, xlabel: str,
          colour: dict) -> str:
    """One backend's panel; ``rows``: (1-based row number, row) of that backend."""
    timed = any(math.isfinite(r["frame_ms"]) for _, r in rows)
    ys = [r["frame_ms"] if timed else mebibytes(r["target_bytes"]) for _, r in rows]
    spans = [(r.get("frame_ms_q1", math.nan), r.get("frame_ms_q3", math.nan)) if timed
             else (y, y) for (_, r), y in zip(rows, ys)]
    spans = [s if all(map(math.isfinite, s)) else (y, y) for s, y in zip(spans, ys)]
    xs = [r["rmse_scene"] for _, r in rows]
    ok = [i for i in range(len(rows)) if math.isfinite(xs[i]) and math.isfinite(ys[i])]
    out = [f'<svg class="plot" viewBox="0 0 {W} {H}" width="{W}" height="{H}" '
           f'role="img" data-backend="{_e(backend)}"><title>{_e(title)}</title>',
           f'<text x="{W / 2}" y="16" class="ttl" text-anchor="middle">{_e(title)}</text>']
    if not ok:
        out.append(f'<text x="{W / 2}" y="{H / 2}" text-anchor="middle">no finite points'
                   f'</text></svg>')
        return "\n".join(out)
    x_lo, x_hi = min(xs[i] for i in ok), max(xs[i] for i in ok)
    pad = (x_hi - x_lo) * 0.08 or max(abs(x_hi) * 0.1, 0.05)
    x_lo, x_hi = max(0.0, x_lo - pad), x_hi + pad
    y_vals = [v for i in ok for v in (ys[i], *spans[i]) if math.isfinite(v)]
    y_lo, y_hi = min(y_vals), max(y_vals)
    log = y_lo > 0 and y_hi > 5 * y_lo
    if log:
        y_lo, y_hi = y_lo / 1.15, y_hi * 1.15
    else:
        pad = (y_hi - y_lo) * 0.1 or max(abs(y_hi) * 0.1, 0.05)
        y_lo, y_hi = max(0.0, y_lo - pad), y_hi + pad
    pw, ph = W - LEFT - RIGHT, H - TOP - BOTTOM

    def px(x: float) -> float:
        return LEFT + (x - x_lo) / (x_hi - x_lo) * pw

    def py(y: float) -> float:
        t = (math.log(y) - math.log(y_lo)) / (math.log(y_hi) - math.log(y_lo)) if log \
            else (y - y_lo) / (y_hi - y_lo)
        return TOP + (1 - t) * ph

    out.append(f'<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" class="frame"/>')
    for v in _ticks(x_lo, x_hi, False):
        out.append(f'<line x1="{px(v):.1f}" x2="{px(v):.1f}" y1="{TOP}" y2="{TOP + ph}" '
                   f'class="grid"/><text x="{px(v):.1f}" y="{TOP + ph + 14}" '
                   f'text-anchor="middle">{_tick_text(v)}</text>')
    for v in _ticks(y_lo, y_hi, log):
        out.append(f'<line x1="{LEFT}" x2="{LEFT + pw}" y1="{py(v):.1f}" y2="{py(v):.1f}" '
                   f'class="grid"/><text x="{LEFT - 4}" y="{py(v) + 4:.1f}" '
                   f'text-anchor="end">{_tick_text(v)}</text>')
    ylabel = "frame time (ms): median, bar q1-q3" if timed else "target memory (MiB)"
    out.append(f'<text x="{LEFT + pw / 2}" y="{H - 6}" text-anchor="middle">{_e(xlabel)}'
               f'</text><text transform="translate(14 {TOP + ph / 2}) rotate(-90)" '
               f'text-anchor="middle">{_e(ylabel)}</text>')
    front = pareto_front([(xs[i], ys[i]) if i in ok else (math.nan, math.nan)
                          for i in range(len(rows))], spans if timed else None)
    # the front's members whose time ranges overlap, consecutive in error: one band each
    for g in (g for g in front_ties(front, spans if timed else None) if len(g) > 1):
        x0, x1 = px(min(xs[i] for i in g)) - 8, px(max(xs[i] for i in g)) + 8
        y0, y1 = py(max(spans[i][1] for i in g)) - 4, py(min(spans[i][0] for i in g)) + 4
        nums = ", ".join(f"#{rows[i][0]}" for i in g)
        out.append(f'<g class="tie"><title>times tie (interquartile ranges overlap): {nums}'
                   f'</title><rect x="{x0:.1f}" y="{y0:.1f}" width="{x1 - x0:.1f}" '
                   f'height="{y1 - y0:.1f}" rx="4"/><text x="{x1:.1f}" y="{y0 - 3:.1f}" '
                   f'text-anchor="end">tie</text></g>')
    if front:
        pts = []
        for k, i in enumerate(front):
            if k:
                pts.append(f"{px(xs[i]):.1f},{py(ys[front[k - 1]]):.1f}")
            pts.append(f"{px(xs[i]):.1f},{py(ys[i]):.1f}")
        out.append(f'<polyline class="front" points="{" ".join(pts)}"><title>Pareto front'
                   f'</title></polyline>')
    for i in ok:
        n, r = rows[i]
        cx, cy = px(xs[i]), py(ys[i])
        if timed and spans[i][0] != spans[i][1]:
            out.append(f'<line class="iqr" x1="{cx:.1f}" x2="{cx:.1f}" '
                       f'y1="{py(spans[i][0]):.1f}" y2="{py(spans[i][1]):.1f}"/>')
        label = f"#{n} {r['technique']} {r['params']}".strip()
        cls = "pt front-pt" if i in front else "pt"
        # GL and CL disagree: a red ring (a style: it wins over the front's stroke)
        stroke = ' style="stroke:#d00;stroke-width:3"' if r["agree"] is False else ""
        out.append(f'<circle class="{cls}" data-row="{n}" cx="{cx:.1f}" cy="{cy:.1f}" r="6" '
                   f'fill="{colour[r["file"]]}"{stroke} tabindex="0"><title>{_e(label)}: '
                   f'rmse {xs[i]:.3g}, {ys[i]:.3g} {"ms" if timed else "MiB"}</title></circle>')
    legend = list(dict.fromkeys(r["file"] for _, r in rows))
    for k, f in enumerate(legend):
        y = TOP + 12 + 14 * k
        out.append(f'<circle cx="{LEFT + pw - 110}" cy="{y - 4}" r="4" fill="{colour[f]}"/>'
                   f'<text x="{LEFT + pw - 102}" y="{y}">{_e(Path(f).stem)}</text>')
    out.append("</svg>")
    return "\n".join(out)


def plot_svg(rows: list[dict], backends, scene: str, size: tuple[int, int],
             reference: str) -> str:
    """Every backend's panel side by side (``reference``: the label errors are against)."""
    from pipegen.tools.sweep.result import device_names
    colour = colours(rows)
    names = device_names(rows, backends)
    panels = []
    for b in backends:
        mine = [(n, r) for n, r in enumerate(rows, 1) if r["backend"] == b]
        title = (f"{names[b]}: {Path(scene).name} {size[0]}x{size[1]}, "
                 f"error vs {reference}")
        panels.append(panel(mine, b, title, f"RMSE vs {reference} reference (rgba8 codes)",
                            colour))
    return "\n".join(panels)
