"""The HTML report of comparisons (pipegen/testing/report_html.py), opened in headless Chromium
and checked as drawn: the pictures load at their sizes, the failing target comes first, the page
says nothing on its console, and its screenshot shows the failing card's red badge.  Where no
Chromium is installed (.ci/run installs Debian's where it can) those tests skip with the reason;
the rest check the page's text and how its folder is written."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from browser import find_chromium, render_page
from pipegen.core.diagnostics import PipegenError
from pipegen.testing.records import Comparison
from pipegen.testing.report_html import write_report

FAIL_RED = np.array([198, 40, 40])      # --fail in the page's CSS: the FAILED badge
ROOT = Path(__file__).resolve().parent.parent


def chromium() -> str:
    exe = find_chromium()
    if exe is None:
        pytest.skip("no chromium: none that runs was found, so the HTML report is not checked "
                    "in a browser (install Debian's chromium, as .ci/run does where it can, or "
                    "set CHROMIUM to one)")
    return exe


def gradient(w: int, h: int) -> np.ndarray:
    x, y = np.meshgrid(np.linspace(0, 255, w), np.linspace(0, 255, h))
    return np.stack([x, y, np.full_like(x, 96)], axis=-1).astype(np.uint8)


def comparisons(tmp_path: Path) -> list[Comparison]:
    """A passing golden comparison made first, a failing one after it (64x48, with an error
    image already written to disk, as the testing API does), and a passing one at 32x16."""
    golden, actual = gradient(64, 48), gradient(64, 48)
    actual[8:16, 40:52] = (255, 0, 255)
    error = np.zeros_like(actual)
    error[8:16, 40:52] = (255, 0, 0)
    error_png = tmp_path / "color-error.png"
    Image.fromarray(error).save(error_png)
    return [
        Comparison("golden", "toon", "normal", True, "max error 0 codes (bound 1 code)",
                   {"max error": "0 codes", "bound": "1 code"},
                   {"expected": gradient(64, 48), "actual": gradient(64, 48)},
                   command="pytest tests/test_toon.py::test_normal", test="t.py::test_normal"),
        Comparison("golden", "toon", "color", False, "96 pixels over the bound",
                   {"max error": "255 codes", "bound": "2 codes", "pixels over": "96"},
                   {"expected": golden, "actual": actual},
                   command="pytest tests/test_toon.py::test_color",
                   message="color: 96 pixels differ by more than 2 codes; worst at (40, 8): "
                           "(255, 0, 255) vs (163, 43, 96) <script>alert(1)</script>",
                   test="t.py::test_color", artifacts={"difference": str(error_png),
                                                       "values": "/tmp/x/color.npy"}),
        Comparison("backends", "toon", "ids", True, "identical", {"max error": "0"},
                   {"expected": gradient(32, 16), "actual": gradient(32, 16),
                    "difference": np.zeros((16, 32, 3), np.uint8)}, test="t.py::test_ids"),
    ]


def test_report_as_drawn_in_chromium(tmp_path):
    exe = chromium()
    index = write_report(tmp_path / "report", comparisons(tmp_path))
    start = time.monotonic()
    page = render_page(index, width=1000, height=700, chromium=exe,
                       screenshot=tmp_path / "report.png", evaluate={
        "cards": "[...document.querySelectorAll('details.card')].map(d => "
                 "[d.dataset.target, d.dataset.status, d.open, "
                 "d.querySelector('summary').getBoundingClientRect().top + scrollY, "
                 "d.querySelector('summary').getBoundingClientRect().bottom + scrollY])",
        "failed": "[...document.querySelectorAll('header .failed a')].map(a => [a.textContent, "
                  "document.querySelector(a.getAttribute('href')).dataset.target])"})
    assert time.monotonic() - start < 20, f"chromium took {page.seconds:.1f} s"
    assert page.console == []

    # every picture loaded, at its size; an open card draws it at an integer scale
    sizes = {"color": (64, 48), "normal": (64, 48), "ids": (32, 16)}
    drawn = {i["src"]: i for i in page.images}
    assert len(page.images) == 8 and len(drawn) == 8
    for src, image in drawn.items():
        target = src.split("-")[2]
        assert image["complete"] and (image["naturalWidth"], image["naturalHeight"]) == \
            sizes[target], image
    shown = [i for i in page.images if "-color-" in i["src"]]
    assert [i["src"].rsplit("-", 1)[1] for i in shown] == \
        ["expected.png", "actual.png", "difference.png"]
    assert all((i["width"], i["height"]) == (192, 144) for i in shown), shown

    # the failing target first, open, though made after a passing one; the passing ones after
    # it by test id, folded (something failed)
    cards = page.values["cards"]
    assert [c[:3] for c in cards] == [["color", "failed", True], ["ids", "passed", False],
                                      ["normal", "passed", False]]
    assert page.values["failed"] == [["color", "color"]]    # the header links to its card
    assert "<script>alert(1)" not in page.dom and "&lt;script&gt;alert(1)" in page.dom

    # the screenshot: not blank; the red FAILED badge drawn in the first card's header, and
    # nothing of that red in the passing cards' headers
    shot = np.asarray(Image.open(page.screenshot).convert("RGB")).astype(int)
    assert shot.shape[1] == 1000 and shot.std() > 30
    red = np.abs(shot - FAIL_RED).max(axis=2) <= 12
    def badge_rows(card):     # rows with a badge's width of red (the card's border is 6 wide)
        return int((red[round(card[3]):round(card[4])].sum(axis=1) > 40).sum())
    assert badge_rows(cards[0]) >= 10, "no red FAILED badge on the failing card"
    assert badge_rows(cards[1]) == badge_rows(cards[2]) == 0


@pytest.mark.gl
def test_report_of_a_failing_golden_as_drawn(tmp_path, monkeypatch):
    """A real run: ``deferred`` rendered with GL, its goldens written, one of them altered (a
    magenta block painted into galbedo.png), compared again with a ꟻLIP threshold: galbedo
    fails, color passes.  The report, in Chromium, draws the failing target first though it
    was compared second, and every picture pixel for pixel as written (3x3 blocks)."""
    exe = chromium()
    from pipegen.testing import ComparisonFailure, assert_matches_golden, render, settings
    monkeypatch.setattr(settings, "keep_images", True)       # as --pipegen-report sets it
    monkeypatch.setattr(settings, "artifacts_dir", tmp_path / "artifacts")
    targets = render(ROOT / "pipelines/deferred.pipe", backend="gl")        # 64x36
    goldens, only = tmp_path / "goldens", {"color", "galbedo"}
    assert_matches_golden(targets, goldens, only=only, update=True)
    albedo = np.array(Image.open(goldens / "galbedo.png"))
    albedo[10:18, 20:36] = (255, 0, 255, 255)
    Image.fromarray(albedo).save(goldens / "galbedo.png")
    with pytest.raises(ComparisonFailure, match="target 'galbedo' .*ꟻLIP over") as failure:
        assert_matches_golden(targets, goldens, only=only, flip_percentile=(99, 0.1))
    made = failure.value.comparisons
    assert [(c.target, c.passed) for c in made] == [("color", True), ("galbedo", False)]

    index = write_report(tmp_path / "report", made)
    page = render_page(index, width=1000, height=700, chromium=exe,
                       screenshot=tmp_path / "report.png", evaluate={
                           "cards": "[...document.querySelectorAll('details.card')]"
                                    ".map(d => [d.dataset.target, d.dataset.status, d.open])",
                           # the page's few lines of script, clicked (after the above)
                           "copy": "document.querySelector('button.copy').click(), "
                                   "getSelection().toString()",
                           "expand": "document.querySelector('[data-fold=open]').click(), "
                                     "[...document.querySelectorAll('details.card')]"
                                     ".map(d => d.open)"})
    assert page.console == []
    assert page.values["cards"] == [["galbedo", "failed", True], ["color", "passed", False]]
    assert page.values["copy"] == made[1].command and page.values["expand"] == [True, True]
    names = [i["src"].rsplit("-", 1)[1] for i in page.images]
    assert names == ["expected.png", "actual.png", "difference.png", "flip.png"] * 2
    assert all(i["complete"] and (i["naturalWidth"], i["naturalHeight"]) == (64, 36)
               for i in page.images), page.images
    shot = np.asarray(Image.open(page.screenshot).convert("RGB"))
    for image in page.images[:4]:            # the failing card's, drawn at 3x
        left, top = round(image["left"]), round(image["top"])
        assert (image["width"], image["height"]) == (192, 108)
        drawn = shot[top:top + 108, left:left + 192]
        written = np.asarray(Image.open(index.parent / image["src"]).convert("RGB"))
        assert np.array_equal(drawn[1::3, 1::3], written), image["src"]
        assert np.array_equal(drawn[0::3, 0::3], drawn[2::3, 2::3])     # square pixels
    golden_drawn = shot[round(page.images[0]["top"]):, round(page.images[0]["left"]):]
    assert tuple(golden_drawn[3 * 14, 3 * 28]) == (255, 0, 255)        # the painted block


def test_browser_sees_a_broken_page(tmp_path):
    """What the report test relies on: a picture that does not load and a script error are
    seen (a test that could not fail would prove nothing)."""
    exe = chromium()
    page_html = tmp_path / "broken.html"
    page_html.write_text('<!doctype html><link rel="icon" href="data:,">'
                         '<img src="missing.png" width="10" height="10">'
                         '<script>console.warn("careful"); undefinedThing();</script>')
    page = render_page(page_html, width=300, height=200, chromium=exe,
                       screenshot=tmp_path / "broken.png")
    assert page.images[0]["complete"] and page.images[0]["naturalWidth"] == 0
    said = sorted(m.split("\n")[0] for m in page.console)    # the load fails while scripts run
    assert said == ["error: Failed to load resource: net::ERR_FILE_NOT_FOUND "
                    + (tmp_path / "missing.png").as_uri(),
                    "exception: ReferenceError: undefinedThing is not defined",
                    "warning: careful"], page.console


def test_report_of_nothing_in_chromium(tmp_path):
    exe = chromium()
    page = render_page(write_report(tmp_path / "r", []), width=600, height=300, chromium=exe,
                       screenshot=tmp_path / "empty.png")
    assert page.console == [] and page.images == []
    assert "No comparisons were made." in page.dom and "0 passed" in page.dom


def test_page_text_and_pictures(tmp_path):
    index = write_report(tmp_path / "report", comparisons(tmp_path), title="toon <tests>")
    text = index.read_text()
    assert "<title>toon &lt;tests&gt;</title>" in text
    assert '<span class="count fail">1 failed</span><span class="count pass">2 passed</span>' \
        in text and "3 comparisons in 3 tests" in text
    # self-contained: no URL leaves the folder
    links = re.findall(r'(?:src|href)="([^"]*)"', text)
    assert links and all(re.fullmatch(r"img/[\w.-]+\.png|#c\d+|data:,", u) for u in links), links
    assert "@import" not in text and "url(" not in text
    # pictures as the arrays were given (top row first), and the error image copied
    color = np.asarray(Image.open(index.parent / "img/001-toon-color-actual.png"))
    assert color.shape == (48, 64, 3) and tuple(color[8, 40]) == (255, 0, 255)
    assert (index.parent / "img/001-toon-color-difference.png").read_bytes() == \
        (tmp_path / "color-error.png").read_bytes()
    assert '<img src="img/001-toon-color-actual.png" alt="actual" width="192" height="144"' \
        in text
    assert "<code>values: /tmp/x/color.npy</code>" in text        # a file not drawn is named
    assert "pytest tests/test_toon.py::test_color</code>" in text
    # a target failing in two tests: the header's links say which
    twice = [Comparison("golden", "t", "color", False, "bad", test=f"t.py::test_a[{b}]")
             for b in ("gl", "cl")]
    text = write_report(tmp_path / "twice", twice).read_text()
    assert '<a href="#c1" title="t.py::test_a[cl]">color <small>test_a[cl]</small></a>' \
        '<a href="#c2" title="t.py::test_a[gl]">color <small>test_a[gl]</small></a>' in text
    # a wide picture is shown 320 wide (smoothly), a click opens it at full size
    wide = Comparison("golden", "t", "atlas", True, "ok", images={"actual": gradient(800, 100)})
    text = write_report(tmp_path / "wide", [wide]).read_text()
    assert '<a href="img/001-t-atlas-actual.png"><img src="img/001-t-atlas-actual.png" ' \
        'alt="actual" width="320" height="40" data-name="actual" ' \
        'title="actual: 800×100, shown at 40%"></a>' in text


def test_report_folder_is_written_as_pipegen_outputs_are(tmp_path):
    out = tmp_path / "report"
    write_report(out, comparisons(tmp_path))
    first = sorted(p.name for p in (out / "img").iterdir())
    assert len(first) == 8
    # a later report replaces the pictures of the earlier one, and nothing else is left
    write_report(out, comparisons(tmp_path)[2:])
    assert sorted(p.name for p in (out / "img").iterdir()) == \
        ["001-toon-ids-actual.png", "001-toon-ids-difference.png", "001-toon-ids-expected.png"]
    # a folder holding files pipegen did not write is refused, and left as it was
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(PipegenError, match="holds files pipegen did not write"):
        write_report(foreign, comparisons(tmp_path))
    assert [p.name for p in foreign.iterdir()] == ["notes.txt"]


def test_import_is_cheap():
    code = ("import sys, pipegen.testing.report_html; "
            "print(sorted(m for m in ('numpy', 'PIL') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
