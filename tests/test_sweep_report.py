"""``sweep -o DIR`` writes ``DIR/index.html`` (issue 25 item 5): the page as written (every row
in a plain table, a card per row, the plot's points, ties drawn as one band, nothing fetched
from elsewhere) and as Chromium draws it (tests/browser.py): no console message, every picture
loaded, a click on a point shows that row, a column's heading sorts the table.

The sweep here is made up (no renders): six rows whose numbers are chosen so that two of them
tie on the front, each with pictures of its own colour, so the page's behaviour is checked
where there is no GL or OpenCL; tests/test_sweep_api.py sweeps for real."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from browser import find_chromium, render_page
from pipegen.core.outdir import safe_name
from pipegen.proof.accuracy import png_bytes
from pipegen.tools.sweep.outputs import write_outputs
from pipegen.tools.sweep.pareto import mark_front_and_ties
from pipegen.tools.sweep.result import SweepResult

# (params, backend, rmse, frame ms, q1, q3): on GL rows 1 and 3 are equally accurate and
# their times overlap (a tie on the front, one band); on CL row 2 beats rows 4 and 6
SPEC = [("k=1", "gl", 0.4, 10.0, 9.0, 11.0), ("k=1", "cl", 0.4, 20.0, 19.0, 21.0),
        ("k=2", "gl", 0.4, 10.5, 9.5, 11.5), ("k=2", "cl", 0.4, 30.0, 29.0, 31.0),
        ("k=3", "gl", 5.0, 2.0, 1.9, 2.1), ("k=3", "cl", 5.0, 25.0, 24.0, 26.0)]


def made_up_result() -> SweepResult:
    rows, maps, images = [], {}, {}
    for n, (params, b, rmse, ms, q1, q3) in enumerate(SPEC, 1):
        name = safe_name(f"{n:02d}_toy_{params}_{b}", ".png")
        colour = np.zeros((18, 32, 3), np.uint8)
        colour[...] = (40 * n, 255 - 40 * n, 128)
        images[name] = png_bytes(colour)
        maps[name] = png_bytes(colour[::-1] // 2)
        rows.append(dict(
            technique="toy", params=params, backend=b, frame_ms=ms, frame_ms_q1=q1,
            frame_ms_q3=q3, cpu_ms=ms, target_bytes=3 << 20, rmse_scene=rmse,
            p99_scene=2 * rmse, max_scene=10 * rmse, flip_scene=0.01, rmse_f64=0.1,
            p99_f64=1.0, max_f64=1.0, rmse_interior=rmse, max_interior=rmse, agree=True,
            file="toy.pipe", width=32, height=18, notes="", reference="self",
            error_map=f"errors/{name}", image=f"images/{name}",
            worst=[[3, 4, [10, 20, 30], [12, 20, 41]], [0, 17, [0, 0, 0], [5, 0, 0]]],
            command=f"pipegen sweep toy.pipe -p {params} --backend {b} -o out/sweep-row"))
    mark_front_and_ties(rows)
    refs = {"toy": dict(label="self", text="self: toy at its most accurate values (k=1), "
                        "float64", why="toy calls no function of the shipped lighting library")}
    return SweepResult(rows, "/x/scenes/edges.toml", 32, 18, 3, ("gl", "cl"), "here",
                       "frame times: made up", [], maps, images, refs,
                       command="pipegen sweep toy.pipe -o out")


@pytest.fixture(scope="module")
def page_path(tmp_path_factory) -> Path:
    out = write_outputs(made_up_result(), tmp_path_factory.mktemp("report") / "s")
    return out / "index.html"


def test_the_page_as_written(page_path):
    text = page_path.read_text(encoding="utf-8")
    rows = json.loads((page_path.parent / "results.json").read_text())["rows"]
    assert [r["pareto"] for r in rows] == [True, True, True, False, True, False]
    assert rows[0]["ties"] == [3] and rows[2]["ties"] == [1]
    # readable without script: every row in the table and as a card, the reference named
    assert len(re.findall(r'<tr data-row="\d+"', text)) == 6
    assert len(re.findall(r'<section class="card" id="row-\d+"', text)) == 6
    assert "reference: self: toy at its most accurate values (k=1), float64 (the default: " \
           "toy calls no function" in text
    assert "error vs self" in text and "RMSE vs self reference" in text
    assert text.count('class="pt') == 6
    # the GL tie on the front: one band naming both rows
    assert re.search(r'<g class="tie"><title>times tie \(interquartile ranges overlap\): '
                     r'#1, #3</title>', text)
    assert "<dt>ties with</dt><dd>#3 (frame times not ranked)</dd>" in text   # row 1's card
    assert 'most accurate: <a href="#row-1">#1 toy k=1 (gl)</a>, rmse 0.400, p99 1, max 4 ' \
           'codes (the same error: <a href="#row-3">#3</a>)' in text
    # self-contained: no address elsewhere, every picture a file of the folder
    assert not re.search(r'(src|href)="(https?:)?//', text)
    srcs = re.findall(r'<img src="([^"]+)"', text)
    assert len(srcs) == 12 and all((page_path.parent / s).is_file() for s in srcs)
    assert "pipegen sweep toy.pipe -p k=2 --backend cl -o out/sweep-row" in text


CLICK = """(() => {{
  const p = document.querySelector('circle.pt[data-row="{n}"]');
  p.dispatchEvent(new MouseEvent('click', {{bubbles: true}}));
  const d = document.getElementById('detail');
  return {{row: d.getAttribute('data-row'), head: d.querySelector('h3').textContent,
          imgs: [...d.querySelectorAll('img')].map(i => i.getAttribute('src')),
          selected: [...document.querySelectorAll('circle.pt.sel')].map(
              c => c.getAttribute('data-row'))}};
}})()"""

HOVER_THEN_LEAVE = """(() => {
  const p = document.querySelector('circle.pt[data-row="2"]');
  p.dispatchEvent(new MouseEvent('mouseenter'));
  const during = document.getElementById('detail').getAttribute('data-row');
  p.dispatchEvent(new MouseEvent('mouseleave'));
  return [during, document.getElementById('detail').getAttribute('data-row')];
})()"""

SORT = """(() => {
  const col = [...document.querySelectorAll('#table th')].findIndex(
      th => th.textContent === 'rmse');
  const order = () => [...document.querySelectorAll('#table tbody tr')].map(
      t => +t.getAttribute('data-row'));
  const button = document.querySelectorAll('#table th')[col].querySelector('button');
  button.click();
  const up = order();
  button.click();
  return [up, order()];
})()"""

TABLE_CLICK = """(() => {
  document.querySelector('#table tbody tr[data-row="6"] td:nth-child(3)').click();
  return document.getElementById('detail').getAttribute('data-row');
})()"""


def test_the_page_in_chromium(page_path, tmp_path):
    if find_chromium() is None:
        pytest.skip("no chromium: none that runs was found, so the sweep report is not "
                    "checked in a browser (install Debian's chromium, as .ci/run does where it "
                    "can, or set CHROMIUM to one)")
    page = render_page(page_path, 1300, 900, screenshot=tmp_path / "page.png",
                       evaluate={"points": "document.querySelectorAll('circle.pt').length",
                                 "click5": CLICK.format(n=5), "hover": HOVER_THEN_LEAVE,
                                 "sort": SORT, "table": TABLE_CLICK})
    assert page.console == []
    assert len(page.images) == 12
    for img in page.images:
        assert img["complete"] and (img["naturalWidth"], img["naturalHeight"]) == (32, 18), img
        assert img["width"] == 256 + 2              # 8x, pixelated, with its border
    v = page.values
    assert v["points"] == 6
    name = "05_toy_k=3_gl.png"
    assert v["click5"] == {"row": "5", "head": "#5 toy k=3 (gl) front",
                           "imgs": [f"images/{name}", f"errors/{name}"], "selected": ["5"]}
    assert v["hover"] == ["2", "5"]                 # hover shows a row; leaving, the pinned one
    rmse = {n: spec[2] for n, spec in enumerate(SPEC, 1)}
    up, down = v["sort"]
    assert sorted(up) == list(range(1, 7))
    assert [rmse[n] for n in up] == sorted(rmse.values())
    assert [rmse[n] for n in down] == sorted(rmse.values(), reverse=True)
    assert v["table"] == "6"
    assert not math.isnan(page.seconds)
