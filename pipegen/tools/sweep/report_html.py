"""``index.html`` of a sweep's folder: a page to explore the result, in the spirit of Herbie's
reports.

- a summary per backend: the most accurate row, the fastest (with the rows whose times tie with
  it), the Pareto front;
- the Pareto plot as inline SVG (``plot_svg.py``): hovering over a point shows its row (image,
  error map, parameters, figures, worst pixels, command) in the panel beside the plot, a click
  pins it there;
- the table of every row (a plain table, readable without JavaScript; a click on a column's
  heading sorts by it, a click on a row shows it);
- one card per row: its image and error map, its figures, its worst pixels, the command that
  reproduces it.

Self-contained: inline CSS and script, no network; the pictures are the folder's own
``images/`` and ``errors/`` PNGs, by relative path.
"""

from __future__ import annotations

import html
import math

from pipegen.core.units import format_bytes
from pipegen.tools.sweep.plot_svg import plot_svg
from pipegen.tools.sweep.result import SweepResult, reference_label, reference_line

SHOWN_WIDTH = 320      # small renders are scaled up by a whole factor to at most this width
MAX_SCALE = 8


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _num(v, digits: int) -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) \
        else f"{v:.{digits}f}"


def _label(n: int, r: dict) -> str:
    return f"#{n} {r['technique']} {r['params']} ({r['backend']})".replace("  ", " ")


def _shown_size(w: int, h: int) -> tuple[int, int]:
    scale = max(1, min(MAX_SCALE, SHOWN_WIDTH // max(1, w)))
    if w * scale > SHOWN_WIDTH:
        return SHOWN_WIDTH, max(1, round(h * SHOWN_WIDTH / w))
    return w * scale, h * scale


# -- the summary ------------------------------------------------------------------------------


def _summary(result: SweepResult) -> str:
    items = []
    numbered = list(enumerate(result.rows, 1))
    for b in result.backends:
        mine = [(n, r) for n, r in numbered if r["backend"] == b]
        finite = [(n, r) for n, r in mine if math.isfinite(r["rmse_scene"])]
        parts = []
        if finite:
            n, r = min(finite, key=lambda t: t[1]["rmse_scene"])
            same = [f'<a href="#row-{k}">#{k}</a>' for k, o in finite
                    if k != n and o["rmse_scene"] == r["rmse_scene"]]
            also = f" (the same error: {', '.join(same)})" if same else ""
            parts.append(f'<li>most accurate: <a href="#row-{n}">{_e(_label(n, r))}</a>, '
                         f'rmse {_num(r["rmse_scene"], 3)}, p99 {_num(r["p99_scene"], 0)}, '
                         f'max {_num(r["max_scene"], 0)} codes{also}</li>')
        timed = [(n, r) for n, r in mine if math.isfinite(r["frame_ms"])]
        if timed:
            n, r = min(timed, key=lambda t: t[1]["frame_ms"])
            ties = r.get("ties") or []
            links = ", ".join(f'<a href="#row-{t}">#{t}</a>' for t in ties)
            tie = (f" &mdash; ties with {links} (interquartile ranges overlap: not "
                   f"ranked)") if ties else ""
            parts.append(f'<li>fastest: <a href="#row-{n}">{_e(_label(n, r))}</a>, '
                         f'{_num(r["frame_ms"], 2)} ms (q1-q3 {_num(r["frame_ms_q1"], 2)}-'
                         f'{_num(r["frame_ms_q3"], 2)}){tie}</li>')
        else:
            n, r = min(mine, key=lambda t: t[1]["target_bytes"])
            parts.append(f'<li>not timed; smallest targets: <a href="#row-{n}">'
                         f'{_e(_label(n, r))}</a>, {format_bytes(r["target_bytes"], "MiB")}'
                         f'</li>')
        front = sorted((t for t in mine if t[1].get("pareto")),
                       key=lambda t: t[1]["rmse_scene"])
        links = ", ".join(f'<a href="#row-{n}">#{n}</a>' for n, _ in front)
        parts.append(f"<li>Pareto front (error against {'frame time' if timed else 'memory'}"
                     f", ties not ranked): {links or 'none'}</li>")
        items.append(f"<h3>{_e(b.upper())}</h3><ul>{''.join(parts)}</ul>")
    return "\n".join(items)


# -- the table --------------------------------------------------------------------------------

# (heading, key or function, digits or None for text)
TABLE = (("#", None, None), ("technique", "technique", None), ("params", "params", None),
         ("backend", "backend", None), ("frame ms", "frame_ms", 2), ("q1", "frame_ms_q1", 2),
         ("q3", "frame_ms_q3", 2), ("tie", "ties", None), ("targets MiB", "target_bytes", None),
         ("rmse", "rmse_scene", 3), ("p99", "p99_scene", 0), ("max", "max_scene", 0),
         ("ꟻLIP", "flip_scene", 4), ("rmse f64", "rmse_f64", 3), ("p99 f64", "p99_f64", 0),
         ("max f64", "max_f64", 0), ("agree", "agree", None), ("front", "pareto", None),
         ("reference", "reference", None))


def _cell(n: int, r: dict, key, digits) -> tuple[str, str]:
    """(shown text, sort value) of one cell."""
    if key is None:
        return str(n), str(n)
    v = r.get(key)
    if key == "target_bytes":
        return format_bytes(v, "MiB", suffix=False), str(v)
    if key == "ties":
        return " ".join(f"#{t}" for t in v or ()), str(len(v or ()))
    if key in ("agree", "pareto"):
        text = {True: "yes", False: "NO" if key == "agree" else "",
                None: "-"}[v]
        return text, {True: "1", False: "0", None: ""}[v]
    if digits is not None:
        finite = isinstance(v, (int, float)) and math.isfinite(v)
        return _num(v, digits), repr(float(v)) if finite else ""
    return str(v or ""), str(v or "")


def _table(result: SweepResult) -> str:
    head = "".join(f'<th data-num="{int(d is not None or k in ("target_bytes", None))}">'
                   f'<button type="button">{_e(h)}</button></th>' for h, k, d in TABLE)
    body = []
    for n, r in enumerate(result.rows, 1):
        cells = []
        for h, k, d in TABLE:
            text, sort = _cell(n, r, k, d)
            if k is None:
                text = f'<a href="#row-{n}">{n}</a>'
            else:
                text = _e(text)
            cells.append(f'<td data-v="{_e(sort)}">{text}</td>')
        cls = ' class="front-row"' if r.get("pareto") else ""
        body.append(f'<tr data-row="{n}"{cls}>{"".join(cells)}</tr>')
    return (f'<div class="scroll"><table id="table"><thead><tr>{head}</tr></thead><tbody>\n'
            + "\n".join(body) + "\n</tbody></table></div>")


# -- the cards --------------------------------------------------------------------------------


def _swatch(rgb) -> str:
    r, g, b = (int(c) for c in rgb)
    return (f'<span class="sw" style="background:rgb({r},{g},{b})"></span>'
            f"{r}, {g}, {b}")


def _card(n: int, r: dict, result: SweepResult) -> str:
    w, h = _shown_size(result.width, result.height)
    figures = [("frame ms", f'{_num(r["frame_ms"], 2)} (q1-q3 {_num(r.get("frame_ms_q1"), 2)}'
                            f'-{_num(r.get("frame_ms_q3"), 2)})'),
               ("targets", format_bytes(r["target_bytes"], "MiB")),
               (f"vs {r.get('reference') or 'scene'}",
                f'rmse {_num(r["rmse_scene"], 3)}, p99 {_num(r["p99_scene"], 0)}, '
                f'max {_num(r["max_scene"], 0)}; interior rmse {_num(r["rmse_interior"], 3)}, '
                f'max {_num(r["max_interior"], 0)}; ꟻLIP {_num(r["flip_scene"], 4)}'),
               ("vs f64", f'rmse {_num(r["rmse_f64"], 3)}, p99 {_num(r["p99_f64"], 0)}, '
                          f'max {_num(r["max_f64"], 0)}'),
               ("GL = CL", {True: "yes", False: "NO", None: "-"}[r["agree"]])]
    if r.get("ties"):
        figures.append(("ties with", " ".join(f"#{t}" for t in r["ties"]) +
                        " (frame times not ranked)"))
    if r.get("notes"):
        figures.append(("notes", r["notes"]))
    dl = "".join(f"<dt>{_e(k)}</dt><dd>{_e(v)}</dd>" for k, v in figures)
    worst = r.get("worst") or []
    if worst:
        lines = "".join(f"<tr><td>{x}</td><td>{y}</td><td>{_swatch(got)}</td>"
                        f"<td>{_swatch(want)}</td><td>"
                        f"{max(abs(int(a) - int(b)) for a, b in zip(got, want))}</td></tr>"
                        for x, y, got, want in worst)
        worst_html = ('<table class="worst"><caption>worst pixels (x, y from the top left; '
                      'rgba8 codes)</caption><tr><th>x</th><th>y</th><th>got</th>'
                      f'<th>reference</th><th>error</th></tr>{lines}</table>')
    else:
        worst_html = '<p class="worst">worst pixels: none recorded</p>'
    worst_html += _targets_html(r) + _clamps_html(r)
    pics = "".join(
        f'<figure><img src="{_e(r[key])}" width="{w}" height="{h}" alt="{_e(cap)} of row {n}">'
        f'<figcaption>{_e(cap)}</figcaption></figure>'
        for key, cap in (("image", "image"), ("error_map", "error map")) if r.get(key))
    front = ' <span class="badge">front</span>' if r.get("pareto") else ""
    return (f'<section class="card" id="row-{n}" data-row="{n}"><h3>{_e(_label(n, r))}'
            f'{front}</h3><div class="pics">{pics}</div><dl>{dl}</dl>{worst_html}'
            f'<p class="cmd">reproduce:</p><pre>{_e(r.get("command") or "")}</pre></section>')


def _targets_html(r: dict) -> str:
    """The row's intermediate targets, each attribute in its own units, with its worst
    pixel."""
    errors = r.get("targets") or []
    if not errors:
        return ""
    lines = "".join(
        f"<tr><td>{_e(e['attribute'])}</td><td>{_sig(e['rmse'])}</td>"
        f"<td>{_sig(e['p99'])}</td><td>{_sig(e['max'])}</td><td>{_e(e['units'])}</td>"
        f"<td>{_e(_where(e))}</td><td>{_e(e['against'])}</td></tr>" for e in errors)
    return ('<table class="worst targets"><caption>intermediate targets, against the '
            "reference's same target (f64: this variant's own float64 evaluation)</caption>"
            '<tr><th>attribute</th><th>rmse</th><th>p99</th><th>max</th><th>units</th>'
            f'<th>worst pixel (x, y: got / reference)</th><th>vs</th></tr>{lines}</table>')


def _sig(v) -> str:
    """Three significant figures: attribute errors span 1e-5 (a depth in scene units) to
    degrees."""
    return "-" if v is None or v != v else f"{v:.3g}"


def _where(e: dict) -> str:
    if not e.get("worst"):
        return "-"
    x, y, got, want = e["worst"][0]
    show = lambda v: "(" + ", ".join("-" if a is None else f"{a:.4g}" for a in v) + ")"
    return f"{x}, {y}: {show(got)} / {show(want)}"


def _clamps_html(r: dict) -> str:
    """What the formats clamped in the row's CL frame."""
    from pipegen.proof.clamps import describe, from_record
    shown = [c for c in r.get("clamps") or [] if c.get("warned")]
    if not shown:
        return ""
    items = "".join(f"<li>{_e(describe(from_record(c)))}</li>" for c in shown)
    return ('<div class="clamps"><p>values the formats clamped (CL frame):</p>'
            f'<ul>{items}</ul></div>')


# -- the page ---------------------------------------------------------------------------------


def report_page(result: SweepResult) -> str:
    """The whole page, as text."""
    ref = reference_label(result.rows)
    title = (f"pipegen sweep: {', '.join(dict.fromkeys(r['technique'] for r in result.rows))}"
             f" on {result.scene}")
    plot = plot_svg(result.rows, result.backends, result.scene,
                    (result.width, result.height), ref)
    notes = "".join(f"<li>{_e(n)}</li>" for n in result.notes + result.warnings)
    cmd = f"<pre>{_e(result.command)}</pre>" if result.command else ""
    cards = "\n".join(_card(n, r, result) for n, r in enumerate(result.rows, 1))
    return _PAGE.format(
        title=_e(title), css=_CSS, script=_SCRIPT, cmd=cmd,
        head=_e(f"{result.width}x{result.height}, {result.lights} lights, "
                f"{len(result.rows)} rows ({len(result.backends)} backends)"),
        reference=_e(reference_line(result.rows, result.references)),
        where=_e(result.where), timing=_e(result.timing),
        notes=f"<ul>{notes}</ul>" if notes else "", summary=_summary(result), plot=plot,
        table=_table(result), cards=cards)


_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:1.2em;color:#222}
h1{font-size:1.3em;margin:0 0 .3em} h2{font-size:1.1em;margin:1.2em 0 .4em}
h3{font-size:1em;margin:.6em 0 .3em} .meta{color:#555} pre{background:#f4f4f4;padding:.4em;
white-space:pre-wrap;word-break:break-all;margin:.2em 0}
.explore{display:flex;flex-wrap:wrap;gap:1em;align-items:flex-start}
.plots{display:flex;flex-wrap:wrap;gap:.5em}
svg.plot{font-size:10px;background:#fff;border:1px solid #ddd}
svg .ttl{font-size:11px;font-weight:600} svg .frame{fill:none;stroke:#999}
svg .grid{stroke:#eee} svg .front{fill:none;stroke:#666;stroke-dasharray:5 3}
svg .iqr{stroke:#444;stroke-width:1.5} svg .tie rect{fill:#fd3;fill-opacity:.35;stroke:#c90}
svg .tie text{fill:#960;font-weight:600} svg .pt{cursor:pointer}
svg .pt.sel{stroke:#000;stroke-width:3} svg .front-pt{stroke:#333;stroke-width:1}
#detail{flex:1 1 300px;min-width:300px;max-width:680px;border:1px solid #ccc;padding:.5em;
background:#fafafa}
table{border-collapse:collapse} #table td,#table th{border:1px solid #ddd;padding:2px 6px}
#table td{text-align:right} #table td:nth-child(2),#table td:nth-child(3),
#table td:nth-child(4),#table td:last-child{text-align:left}
#table th button{font:inherit;font-weight:600;border:0;background:none;cursor:pointer}
#table tr.front-row{background:#f1f8ff} #table tr.sel{outline:2px solid #000}
#table tbody tr{cursor:pointer} #table td{white-space:nowrap} .scroll{overflow-x:auto}
.card{border:1px solid #ddd;padding:.5em;margin:.6em 0;max-width:900px}
.pics{display:flex;flex-wrap:wrap;gap:1em} figure{margin:0} figcaption{color:#555;font-size:.9em}
img{image-rendering:pixelated;border:1px solid #ccc}
dl{display:grid;grid-template-columns:max-content auto;gap:0 1em;margin:.4em 0}
dt{color:#555} dd{margin:0} .worst td,.worst th{padding:1px 6px;text-align:left}
.worst caption{text-align:left;color:#555} .badge{background:#def;padding:0 4px;
border-radius:3px;font-size:.85em}
.sw{display:inline-block;width:10px;height:10px;border:1px solid #888;margin-right:4px}
"""

# shows a row in #detail (its card's content), sorts the table by a column
_SCRIPT = """
(function () {
  var detail = document.getElementById('detail');
  var pinned = null;
  function show(n) {
    var card = document.getElementById('row-' + n);
    if (!card) return;
    detail.innerHTML = card.innerHTML;
    detail.setAttribute('data-row', n);
    document.querySelectorAll('.pt').forEach(function (p) {
      p.classList.toggle('sel', p.getAttribute('data-row') === String(n)); });
    document.querySelectorAll('#table tbody tr').forEach(function (t) {
      t.classList.toggle('sel', t.getAttribute('data-row') === String(n)); });
  }
  document.querySelectorAll('.pt').forEach(function (p) {
    var n = p.getAttribute('data-row');
    p.addEventListener('click', function () { pinned = n; show(n); });
    p.addEventListener('keydown', function (e) {
      if (e.key === 'Enter') { pinned = n; show(n); } });
    p.addEventListener('mouseenter', function () { show(n); });
    p.addEventListener('mouseleave', function () { if (pinned) show(pinned); });
  });
  var body = document.querySelector('#table tbody');
  body.addEventListener('click', function (e) {
    var tr = e.target.closest('tr');
    if (tr && e.target.tagName !== 'A') { pinned = tr.getAttribute('data-row'); show(pinned); }
  });
  document.querySelectorAll('#table th').forEach(function (th, col) {
    var up = true;
    th.querySelector('button').addEventListener('click', function () {
      var num = th.getAttribute('data-num') === '1';
      var rows = Array.prototype.slice.call(body.rows);
      rows.sort(function (a, b) {
        var x = a.cells[col].getAttribute('data-v'), y = b.cells[col].getAttribute('data-v');
        if (x === y) return 0;
        if (x === '') return 1;
        if (y === '') return -1;
        var d = num ? parseFloat(x) - parseFloat(y) : (x < y ? -1 : 1);
        return up ? d : -d;
      });
      rows.forEach(function (r) { body.appendChild(r); });
      document.querySelectorAll('#table th').forEach(function (h) {
        h.removeAttribute('aria-sort'); });
      th.setAttribute('aria-sort', up ? 'ascending' : 'descending');
      up = !up;
    });
  });
})();
"""

_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>{css}</style></head>
<body>
<h1>{title}</h1>
<p class="meta">{head}<br>{reference}<br>renders: {where}<br>{timing}</p>
{cmd}{notes}
<h2>Summary</h2>
{summary}
<h2>Error against cost</h2>
<p class="meta">Each point is a row: hover over it to see it in the panel next to the plots,
click to keep it there.  A bar is the interquartile range of its frame times; the dashed line
is the Pareto front; front members whose ranges overlap are one shaded band (tie: their order
by time is noise); a red ring: GL and CL disagree.</p>
<div class="explore"><div class="plots">{plot}</div>
<div id="detail" data-row="">Hover over or click a point (or a table row) to see its image,
error map, parameters and worst pixels.</div></div>
<h2>Every row</h2>
<p class="meta">Click a column's heading to sort by it. tie: the rows on the same backend whose
frame time ranges overlap (not ranked by time); front: on its backend's Pareto front.</p>
{table}
<h2>Rows</h2>
{cards}
<script>{script}</script>
</body></html>
"""
