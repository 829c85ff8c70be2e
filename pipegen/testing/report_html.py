"""The HTML report of a test run's comparisons (``pytest --pipegen-report=DIR``), in the spirit of
pytest-mpl's summary page: one static page, ``DIR/index.html``, with its pictures beside it.

Failing comparisons come first, then the passing ones (each group by test id, a test's in the
order it made them), one card per target: the pictures kept for it (golden or expected, actual,
difference, ꟻLIP map: whichever exist), its numbers, its summary, the failure message, the
command that reproduces it and the test that made it.  The header counts them and links to the
failing cards; when anything failed, the passing cards are folded (a click opens them).

The page is self-contained (inline CSS, a few lines of script for the copy buttons and to expand
or fold every card, no external resources).  Pictures are PNG files in ``DIR/img``: small ones
drawn at an integer scale with ``image-rendering: pixelated`` (a 64x48 render shows its pixels),
wide ones 320 pixels wide (a click opens them).  The folder is written through ``core.outdir``
like every pipegen output: atomically, never over files pipegen did not write.

Importing this module imports neither numpy nor pillow (it is imported by the pytest plugin).
"""

from __future__ import annotations

import html
import shutil
from pathlib import Path
from typing import Any, Iterable

from pipegen.core.outdir import as_output_dir, safe_name

# picture names in their order on a card, with their captions; others follow under their name
PICTURES = ("expected", "actual", "difference", "flip")
CAPTIONS = {"expected": "expected", "actual": "actual", "difference": "difference",
            "flip": "ꟻLIP map"}
SHOWN_WIDTH = 220    # small renders are scaled up by an integer factor to at most this width
MAX_SCALE = 8
MAX_SHOWN = 320      # wider pictures are shown this wide (a click opens them at full size)


def write_report(out_dir, comparisons: Iterable[Any],
                 title: str = "pipegen comparisons") -> Path:
    """Write ``out_dir/index.html`` (and ``out_dir/img/*.png``) showing ``comparisons``
    (``records.Comparison``); returns the page's path.  Raises ``PipegenError`` when
    ``out_dir`` holds files pipegen did not write."""
    comparisons = list(comparisons)
    out = as_output_dir(out_dir, "report")
    # failing first, then by test id (pytest-xdist's workers report in no fixed order); sorted()
    # is stable, so a test's comparisons keep the order it made them in
    ordered = sorted(comparisons, key=lambda c: (bool(c.passed), c.test or ""))
    any_failed = any(not c.passed for c in ordered)
    with out.staging() as stage:
        cards = [_card(i, c, stage, fold=any_failed and c.passed)
                 for i, c in enumerate(ordered, 1)]
        page = _PAGE.format(title=_e(title), css=_CSS, script=_SCRIPT,
                            header=_header(title, ordered),
                            cards="\n".join(cards))
        (stage / "index.html").write_text(page, encoding="utf-8")
    return Path(out.path) / "index.html"


# -- pictures ---------------------------------------------------------------------------------


def _pictures(c, number: int, stage: Path) -> list[tuple[str, str, int, int]]:
    """Write the comparison's pictures into ``stage/img``: ``[(name, relative path, width,
    height)]`` in card order.  Arrays (``c.images``) win over files already written
    (``c.artifacts``) of the same name; files that are not PNG are only listed on the card."""
    sources: dict[str, Any] = {}
    for name, path in (c.artifacts or {}).items():
        if str(path).lower().endswith(".png") and Path(path).is_file():
            sources[name] = Path(path)
    sources.update(c.images or {})
    names = [n for n in PICTURES if n in sources] + \
        sorted(n for n in sources if n not in PICTURES)
    out = []
    (stage / "img").mkdir(exist_ok=True)
    for name in names:
        rel = "img/" + safe_name(f"{number:03d}-{c.technique}-{c.target}-{name}", ".png")
        source = sources[name]
        if isinstance(source, Path):
            shutil.copyfile(source, stage / rel)
            width, height = _png_size(stage / rel)
        else:
            width, height = _save_png(stage / rel, source)
        out.append((name, rel, width, height))
    return out


def _save_png(path: Path, image) -> tuple[int, int]:
    """Save a uint8 array (H, W), (H, W, 3) or (H, W, 4), top row first; returns (W, H)."""
    import numpy as np
    from PIL import Image
    array = np.ascontiguousarray(np.asarray(image))
    if array.dtype != np.uint8:
        raise TypeError(f"a report picture must be uint8, not {array.dtype}")
    Image.fromarray(array).save(path)
    return array.shape[1], array.shape[0]


def _png_size(path: Path) -> tuple[int, int]:
    from PIL import Image
    with Image.open(path) as im:
        return im.size


def _shown(width: int, height: int) -> tuple[int, int, str]:
    """The size a picture is drawn at and its caption's note: small ones scaled up by an
    integer factor (each pixel a square of pixels), wide ones scaled down to ``MAX_SHOWN``."""
    if width > MAX_SHOWN:
        return MAX_SHOWN, max(1, round(height * MAX_SHOWN / width)), \
            f", shown at {MAX_SHOWN / width:.0%}"
    k = max(1, min(MAX_SCALE, SHOWN_WIDTH // max(1, width)))
    return width * k, height * k, (f", shown ×{k}" if k > 1 else "")


# -- the page ---------------------------------------------------------------------------------


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _kind_label(c) -> str:
    return {"backends": "GL vs CL", "f64": "vs float64", "golden": "vs golden",
            "expect": "expectation"}.get(c.kind, c.kind)


def _header(title: str, ordered: list) -> str:
    failed = sum(1 for c in ordered if not c.passed)
    passed = len(ordered) - failed
    badges = (f'<span class="count fail">{failed} failed</span>' if failed else "") + \
        f'<span class="count pass">{passed} passed</span>'
    tests = len({c.test for c in ordered if c.test})
    what = f"{len(ordered)} comparison{'s' * (len(ordered) != 1)}" + \
        (f" in {tests} test{'s' * (tests != 1)}" if tests else "")
    # the failing targets named at the top, each a link to its card (the cards' order); a name
    # that fails in several tests (a test run per backend) says which test
    failing = [(i, c) for i, c in enumerate(ordered, 1) if not c.passed]
    repeated = {c.target for _, c in failing if sum(d.target == c.target for _, d in failing) > 1}
    links = "".join(
        f'<a href="#c{i}" title="{_e(c.test)}">{_e(c.target)}'
        + (f' <small>{_e(c.test.rpartition("::")[2])}</small>' if c.target in repeated and c.test
           else "") + "</a>" for i, c in failing)
    return (f'<header><h1>{_e(title)}</h1><p class="counts">{badges}'
            f'<span class="what">{what}</span>'
            '<button type="button" data-fold="open">expand all</button>'
            '<button type="button" data-fold="close">collapse all</button></p>'
            + (f'<p class="failed">failed: {links}</p>' if links else "")
            + ("" if ordered else '<p class="failed">No comparisons were made.</p>')
            + "</header>")


def _card(number: int, c, stage: Path, fold: bool) -> str:
    status = "pass" if c.passed else "fail"
    parts = [f'<details class="card {status}" id="c{number}" data-target="{_e(c.target)}"'
             f' data-status="{"passed" if c.passed else "failed"}"{"" if fold else " open"}>',
             f'<summary><span class="badge {status}">{"passed" if c.passed else "FAILED"}'
             f'</span><span class="target">{_e(c.target)}</span>'
             f'<span class="tech">{_e(c.technique)} · {_e(_kind_label(c))}</span>'
             f'<span class="sum">{_e(c.summary)}</span>'
             f'<span class="test">{_e(c.test)}</span></summary>', '<div class="body">']
    figures = []
    for name, rel, width, height in _pictures(c, number, stage):
        shown_w, shown_h, note = _shown(width, height)
        caption = "golden" if (name == "expected" and c.kind == "golden") else \
            CAPTIONS.get(name, name)
        size = f"{width}×{height}{note}"
        pixelated = ' class="px"' if shown_w > width else ""
        figures.append(f'<figure><a href="{_e(rel)}"><img src="{_e(rel)}" alt="{_e(caption)}"'
                       f' width="{shown_w}" height="{shown_h}" data-name="{_e(name)}"'
                       f' title="{_e(caption)}: {size}"{pixelated}></a>'
                       f'<figcaption>{_e(caption)} <small>{size}</small></figcaption></figure>')
    if figures:
        parts.append('<div class="pictures">' + "".join(figures) + "</div>")
    facts = []
    if c.numbers:
        facts.append('<table class="numbers">' + "".join(
            f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in c.numbers.items())
            + "</table>")
    if c.message:
        facts.append(f'<pre class="message">{_e(c.message)}</pre>')
    if facts:
        parts.append('<div class="facts">' + "".join(facts) + "</div>")
    if c.command:
        parts.append(f'<div class="line"><span class="label">reproduce</span>'
                     f'<code class="cmd">{_e(c.command)}</code>'
                     '<button type="button" class="copy">copy</button></div>')
    files = _other_files(c)
    if files:
        parts.append('<div class="line"><span class="label">files</span>' + " ".join(
            f'<code>{_e(name)}: {_e(path)}</code>' for name, path in files) + "</div>")
    parts.append("</div></details>")
    return "\n".join(parts)


def _other_files(c) -> list[tuple[str, str]]:
    """Artifacts that are not drawn on the card (not PNG, or missing)."""
    return [(name, str(path)) for name, path in (c.artifacts or {}).items()
            if not (str(path).lower().endswith(".png") and Path(path).is_file())]


_PAGE = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<link rel="icon" href="data:,">
<title>{title}</title>
<style>{css}</style>
</head>
<body>
{header}
<main>
{cards}
</main>
<script>{script}</script>
</body>
</html>
"""

_CSS = """
:root { --fail: #c62828; --fail-bg: #fdecea; --pass: #2e7d32; --pass-bg: #edf7ee;
  --line: #d9dde3; --muted: #5f6b7a; }
* { box-sizing: border-box; }
body { margin: 0; background: #f4f5f7; color: #1d2330;
  font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif; }
header { background: #1d2330; color: #fff; padding: 14px 24px; }
h1 { margin: 0 0 6px; font-size: 20px; font-weight: 600; }
.counts { margin: 0; display: flex; gap: 10px; align-items: center; flex-wrap: wrap; }
.count { padding: 2px 10px; border-radius: 10px; font-weight: 600; }
.count.fail { background: var(--fail); } .count.pass { background: var(--pass); }
.what { color: #c5cad3; }
header button { margin-left: 4px; background: transparent; color: #c5cad3;
  border: 1px solid #4a5263; border-radius: 4px; padding: 1px 8px; cursor: pointer; }
header .failed { margin: 8px 0 0; color: #c5cad3; }
header .failed a { color: #ffb4ab; font-weight: 600; margin-right: 14px;
  font-family: ui-monospace, "DejaVu Sans Mono", monospace; }
header .failed small { font-weight: 400; color: #e6a49b; }
main { padding: 16px 24px 40px; max-width: 1400px; }
.badge { display: inline-block; min-width: 58px; text-align: center; padding: 1px 8px;
  border-radius: 4px; color: #fff; font-size: 12px; font-weight: 700; letter-spacing: .03em; }
.badge.fail { background: var(--fail); } .badge.pass { background: var(--pass); }
.card { background: #fff; border: 1px solid var(--line); border-left: 6px solid var(--pass);
  border-radius: 6px; margin: 0 0 14px; }
.card.fail { border-left-color: var(--fail); }
.card > summary { display: flex; gap: 12px; align-items: baseline; flex-wrap: wrap;
  padding: 8px 14px; cursor: pointer; background: var(--pass-bg); border-radius: 0 6px 0 0; }
.card.fail > summary { background: var(--fail-bg); }
.card:not([open]) > summary { border-radius: 0 6px 6px 0; }
.target { font-weight: 700; font-size: 16px;
  font-family: ui-monospace, "DejaVu Sans Mono", monospace; }
.tech { color: var(--muted); }
.card .sum { flex: 1 1 300px; }
.card summary .test { color: var(--muted); font-size: 12px; margin-left: auto;
  font-family: ui-monospace, "DejaVu Sans Mono", monospace; }
.body { padding: 12px 14px 14px; }
.pictures { display: flex; gap: 14px; flex-wrap: wrap; margin-bottom: 10px; }
figure { margin: 0; }
figure img { display: block; max-width: 100%; height: auto; outline: 1px solid var(--line);
  background: repeating-conic-gradient(#ddd 0 25%, #fff 0 50%) 0 0 / 16px 16px; }
img.px { image-rendering: pixelated; }
figcaption { font-size: 12px; color: var(--muted); margin-top: 3px; }
figcaption small { color: #8b95a3; }
.facts { display: flex; gap: 16px; flex-wrap: wrap; align-items: flex-start; margin-bottom: 8px; }
table.numbers { border-collapse: collapse; font-size: 13px; }
.numbers th { text-align: left; font-weight: 500; color: var(--muted); padding: 2px 14px 2px 0; }
.numbers td { font-family: ui-monospace, "DejaVu Sans Mono", monospace; padding: 2px 0; }
pre.message { flex: 1 1 420px; margin: 0; padding: 8px 10px; background: #fff7f6;
  border: 1px solid #f3c7c2; border-radius: 4px; white-space: pre-wrap; word-break: break-word;
  font-size: 12.5px; }
.line { display: flex; gap: 10px; align-items: center; margin-top: 6px; flex-wrap: wrap; }
.label { color: var(--muted); font-size: 12px; min-width: 64px; }
code { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 12.5px;
  background: #f0f2f5; padding: 2px 6px; border-radius: 3px; word-break: break-all; }
button.copy { font-size: 12px; padding: 1px 8px; cursor: pointer; }
"""

# copy buttons (select the text where the clipboard is refused) and expand/collapse all
_SCRIPT = """
document.addEventListener("click", function (ev) {
  var b = ev.target;
  if (b.classList.contains("copy")) {
    var code = b.parentNode.querySelector("code"), r = document.createRange();
    r.selectNodeContents(code);
    var s = window.getSelection(); s.removeAllRanges(); s.addRange(r);
    if (navigator.clipboard) navigator.clipboard.writeText(code.textContent).then(
      function () { b.textContent = "copied"; }, function () {});
  } else if (b.dataset && b.dataset.fold) {
    document.querySelectorAll("details.card").forEach(function (d) {
      d.open = b.dataset.fold === "open"; });
  }
});
"""
