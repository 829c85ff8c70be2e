"""pipegen's pytest plugin (pipegen/testing/plugin.py), tried as a user meets it: pytest run in a
subprocess on a copy of tests/testproject (a technique, a scene, goldens and a test file that
uses only the plugin and ``pipegen.testing``), outside our suite's conftest and options.

- the project passes; after a one-token change to its technique it fails naming the target,
  the worst pixel and the bound, and ``--pipegen-report=DIR`` lists the failing target;
- a backend that cannot run skips its tests with the reason;
- the plugin works from a non-editable install (tests/test_install_library.py's venv);
- docs/testing.md's example test file runs as it is printed, the way the page tells: a missing
  golden fails naming ``--pipegen-update-goldens``, which writes it, and the report gathers
  the comparisons of pytest-xdist workers;
- importing the plugin (which every pytest run does) imports nothing heavy.

``python tests/test_plugin.py --update-goldens`` rewrites the project's goldens.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PROJECT = ROOT / "tests" / "testproject"
DOCS = ROOT / "docs" / "testing.md"
# The project's own files; its conftest.py only hides it from our suite.
PROJECT_FILES = ("wrap_deferred.pipe", "scene.toml", "test_technique.py", "goldens")


def copy_project(dest: Path) -> Path:
    dest.mkdir(parents=True, exist_ok=True)
    for name in PROJECT_FILES:
        src = PROJECT / name
        if not src.exists():        # no goldens yet
            continue
        if src.is_dir():
            shutil.copytree(src, dest / name)
        else:
            shutil.copy(src, dest / name)
    return dest


def user_env() -> dict:
    """Our environment less what our own pytest run set for its workers."""
    return {k: v for k, v in os.environ.items()
            if not k.startswith(("PYTEST_", "PIPEGEN_UPDATE"))}


def run_pytest(where: Path, *args: str, python: str = sys.executable,
               env: dict | None = None) -> subprocess.CompletedProcess:
    cmd = [python, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-rfs", *args]
    proc = subprocess.run(cmd, cwd=where, env=env or user_env(), capture_output=True,
                          text=True, timeout=300)
    proc.output = proc.stdout + proc.stderr
    return proc


def test_importing_the_plugin_imports_nothing_heavy():
    code = ("import sys, pipegen.testing.plugin; print(sorted(m for m in sys.modules if m in "
            "('numpy', 'moderngl', 'pyopencl', 'OpenGL', 'PIL', 'pipegen.compiler', "
            "'pipegen.runtime', 'pipegen.scene')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, check=True).stdout
    assert out.strip() == "[]"


@pytest.fixture(scope="module")
def one_token_change(tmp_path_factory):
    """The project run as it is (passes), then after a one-token change to its technique
    (``wrap = 0.5`` made ``0.6``) with ``--pipegen-report``: (passing run, failing run, report
    folder)."""
    tmp = tmp_path_factory.mktemp("one_token")
    project = copy_project(tmp / "project")
    ok = run_pytest(project, "-n0", "-vv")
    pipe = project / "wrap_deferred.pipe"
    text = pipe.read_text()
    assert text.count("float wrap = 0.5;") == 1
    pipe.write_text(text.replace("float wrap = 0.5;", "float wrap = 0.6;"))
    report = tmp / "report"
    bad = run_pytest(project, "-n0", f"--pipegen-report={report}")
    return ok, bad, report


@pytest.mark.gl
@pytest.mark.cl
def test_the_project_passes_then_fails_after_a_one_token_change(one_token_change):
    ok, bad, report = one_token_change
    assert ok.returncode == 0, ok.output
    assert "5 passed" in ok.output, ok.output        # 4 in test_technique.py, 1 expect line
    assert re.search(r'wrap_deferred.pipe::line 15: expect color agrees gl cl on "scene\S*" PASSED',
                     ok.output), ok.output

    assert bad.returncode == 1, bad.output
    # only the goldens notice: both backends still agree, and with float64
    assert re.search(r"2 failed, 3 passed", bad.output), bad.output
    for backend in ("gl", "cl"):
        assert f"FAILED test_technique.py::test_matches_golden[{backend}-scene.toml]" in \
            bad.output
    message = _failure_message(bad.output)
    assert re.search(r"target 'color' \(rgba8\): \d+ px differ from the golden by more than "
                     r"the limit \(≤?\d+ codes\); worst at \(x=\d+, y=\d+\): render \(\d+, \d+, \d+, "
                     r"255\) vs golden \(\d+, \d+, \d+, 255\), limit ≤?\d+ codes", message), message
    assert "api.py" not in bad.output            # the test's lines and the message only
    assert "Traceback" not in bad.output

    index = report / "index.html"
    assert f"report written to {index}" in bad.output
    html = index.read_text()
    assert "test_matches_golden[gl-scene.toml]" in html
    assert "wrap_deferred" in html and "color" in html


@pytest.mark.gl
@pytest.mark.cl
def test_the_report_of_the_failing_run_in_a_browser(one_token_change, tmp_path):
    """The failing run's report as Chromium draws it (tests/browser.py, as
    tests/test_report_html.py uses it): the two failing golden comparisons first and open,
    every picture loaded at the render's size, no console message."""
    from browser import find_chromium, render_page
    if find_chromium() is None:
        pytest.skip("no chromium: the report is not checked in a browser (install Debian's "
                    "chromium, as .ci/run does where it can, or set CHROMIUM to one)")
    _, bad, report = one_token_change
    page = render_page(report / "index.html", width=1000, height=700,
                       screenshot=tmp_path / "report.png", evaluate={
        "cards": "[...document.querySelectorAll('details.card')].map(d => "
                 "[d.dataset.target, d.dataset.status, d.open])"})
    assert page.console == []
    cards = page.values["cards"]
    assert cards[:2] == [["color", "failed", True]] * 2, cards
    assert all(status == "passed" for _, status, _ in cards[2:]) and len(cards) > 2, cards
    # the project's scene is 64x40; test_close_to_float64 renders the default scene, 64x36
    sizes = [(i["naturalWidth"], i["naturalHeight"]) for i in page.images if i["complete"]]
    assert len(sizes) == len(page.images) > 6, page.images
    assert sizes[:6] == [(64, 40)] * 6 and set(sizes) == {(64, 40), (64, 36)}, sizes
    assert [i["src"].rsplit("-", 1)[1] for i in page.images[:3]] == \
        ["expected.png", "actual.png", "difference.png"]


def _failure_message(output: str) -> str:
    """The first failure's assertion message, as pytest prints it (its E lines)."""
    lines = [ln[1:].strip() for ln in output.splitlines() if ln.startswith("E ")]
    assert lines, output
    return "\n".join(lines)


UNAVAILABLE = '''
import pytest
import pipegen.runtime.cl.context as cl


def _no_opencl(*args, **kwargs):
    raise RuntimeError("no OpenCL platform found (simulated)")


cl.get_context = _no_opencl


def test_backends(pipegen_backend):
    assert pipegen_backend == "gl"


@pytest.mark.pipegen_requires("cl")
def test_needs_cl():
    pass


def test_context(pipegen_gl_context):
    assert pipegen_gl_context.version_code >= 330


def test_default_scene(pipegen_scene):
    assert (pipegen_scene.width, pipegen_scene.height) == (64, 36)
'''


@pytest.mark.gl
def test_fixtures_and_a_backend_that_cannot_run(tmp_path):
    (tmp_path / "test_fixtures.py").write_text(UNAVAILABLE)
    proc = run_pytest(tmp_path, "-n0", "-vv")   # -q -vv: one line a test
    assert proc.returncode == 0, proc.output
    assert "test_backends[gl] PASSED" in proc.output
    assert "test_backends[cl] SKIPPED" in proc.output
    reason = "pipegen backend cl unavailable: RuntimeError: no OpenCL platform found (simulated)"
    assert proc.output.count(reason) == 2, proc.output          # both, in the -rs summary
    assert "3 passed, 2 skipped" in proc.output


USER_ERRORS = '''
import pytest
from pipegen.testing import render


@pytest.mark.parametrize("pipegen_scene", ["broken.toml"], indirect=True)
def test_bad_scene(pipegen_scene):
    pass


def test_bad_technique():
    render("broken.pipe")
'''


def test_a_bad_technique_or_scene_shows_pipegen_message_not_its_frames(tmp_path):
    (tmp_path / "test_errors.py").write_text(USER_ERRORS)
    (tmp_path / "broken.toml").write_text("width = 64\nheight = \n")
    (tmp_path / "broken.pipe").write_text('technique t "t"\ntarget color : rgba9\n')
    proc = run_pytest(tmp_path, "-n0")
    assert proc.returncode == 1 and "1 failed, 1 error" in proc.output, proc.output
    # the fixture's error: pipegen's message alone, at the scene file's line
    assert re.search(r"PipegenError: \S*broken.toml:2:\d+: error: ", proc.output), proc.output
    # the test's error: its own line, then pipegen's message with the caret
    assert '>       render("broken.pipe")' in proc.output
    assert re.search(r"broken.pipe:2:\d+: error: .*rgba9", proc.output), proc.output
    assert "pipegen/" not in proc.output.replace(str(tmp_path), "")     # no frame of ours

    # a report folder holding files pipegen did not write: refused before any test runs
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "mine.txt").write_text("mine")
    refused = run_pytest(tmp_path, "-n0", "--pipegen-report=notes")
    assert refused.returncode == 4, refused.output            # pytest's usage error
    assert "--pipegen-report=notes: output folder 'notes' holds files pipegen did not write " \
        "(mine.txt); pass an empty or new folder" in refused.output
    assert (tmp_path / "notes" / "mine.txt").read_text() == "mine"


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.cl
def test_the_plugin_from_a_non_editable_install(installed, tmp_path):
    project = copy_project(tmp_path / "project")
    (project / "test_where.py").write_text(
        "import sys\n\ndef test_where():\n"
        "    print('PLUGIN', sys.modules['pipegen.testing.plugin'].__file__)\n")
    python = str(installed / ("python.exe" if os.name == "nt" else "python"))
    env = {k: v for k, v in _clean_env(tmp_path).items() if not k.startswith("PYTEST_")}
    proc = run_pytest(project, "-n0", "-s", python=python, env=env)
    assert proc.returncode == 0, proc.output
    assert "6 passed" in proc.output, proc.output
    where = Path(re.search(r"PLUGIN (\S+)", proc.output).group(1)).resolve()
    assert where.is_relative_to(installed.parent.resolve()), where       # not the checkout
    assert not where.is_relative_to(ROOT)
    # the built package itself declares the plugin (the wheel's entry points; the test extra
    # brings the `wheel` package setuptools < 70.1 needs to build one)
    purelib = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"]
                        ).stdout.strip())
    entry = [p.read_text() for p in purelib.glob("pipegen-*.dist-info/entry_points.txt")]
    assert entry and "[pytest11]" in entry[0] and \
        "pipegen = pipegen.testing.plugin" in entry[0], (purelib, entry)


def docs_block(title: str) -> str:
    blocks = re.findall(rf'^```python title="{re.escape(title)}"\n(.*?)^```$', DOCS.read_text(),
                        re.M | re.S)
    assert len(blocks) == 1, title
    return blocks[0]


@pytest.mark.gl
@pytest.mark.cl
def test_the_example_of_docs_testing_md_runs_as_printed(tmp_path):
    """The page's example file, run the way the page tells: the first run fails on the missing
    goldens naming the command that writes them (and writes nothing); that command writes
    them; then every test passes, here on two pytest-xdist workers with the HTML report."""
    (tmp_path / "test_my_technique.py").write_text(docs_block("test_my_technique.py"))
    # the project's technique, less its expectation (whose scene is not copied): the page's
    # six tests are all that run
    technique = (PROJECT / "wrap_deferred.pipe").read_text()
    (tmp_path / "my_technique.pipe").write_text(re.sub(r"^expect .*\n", "", technique, flags=re.M))
    goldens = tmp_path / "goldens"

    first = run_pytest(tmp_path, "-n0", "-k", "golden")
    assert first.returncode == 1 and "2 failed" in first.output, first.output
    assert re.search(r"no golden for 'color' in \S+goldens/gl: pytest --pipegen-update-goldens",
                     _failure_message(first.output)), first.output
    assert not goldens.exists()                           # never written silently

    written = run_pytest(tmp_path, "-n0", "-k", "golden", "--pipegen-update-goldens")
    assert written.returncode == 0, written.output
    assert sorted(p.relative_to(goldens).as_posix() for p in goldens.rglob("*.*")) == \
        ["cl/color.png", "gl/color.png"]

    report = tmp_path / "report"
    ok = run_pytest(tmp_path, "-n", "2", f"--pipegen-report={report}")
    assert ok.returncode == 0 and "6 passed" in ok.output, ok.output
    # the comparisons made in both workers reach the report, each under its test
    html = (report / "index.html").read_text()
    for test in ("test_backends_agree", "test_close_to_float64", "test_matches_golden[gl]",
                 "test_matches_golden[cl]"):
        assert f"test_my_technique.py::{test}" in html, test
    made = re.search(r"pipegen: (\d+) comparisons \(0 failed\), report written", ok.output)
    assert made and int(made.group(1)) == html.count('<details class="card'), ok.output


@pytest.mark.gl
@pytest.mark.cl
def test_the_python_form_of_check_in_docs_testing_md_runs(tmp_path):
    (tmp_path / "check_my_technique.py").write_text(docs_block("check_my_technique.py"))
    shutil.copy(PROJECT / "wrap_deferred.pipe", tmp_path / "my_technique.pipe")
    shutil.copy(PROJECT / "scene.toml", tmp_path / "scene.toml")
    proc = subprocess.run([sys.executable, "check_my_technique.py"], cwd=tmp_path,
                          env=user_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].split()[:4] == ["target", "format", "max", "error"], proc.stdout
    assert "color True" in lines and "gpos True" in lines, proc.stdout


# The venv with pipegen installed from a copy of the sources (not editable), built the way
# tests/test_install_library.py builds it.
from test_install_library import _clean_env, _run, installed  # noqa: E402,F401


def update_goldens() -> None:
    """Render the project's goldens anew (in a copy, as the tests run it) and store them."""
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        project = copy_project(Path(tmp) / "project")
        proc = run_pytest(project, "-n0", "--pipegen-update-goldens", "-k", "golden")
        print(proc.output)
        if proc.returncode != 0:
            raise SystemExit(1)
        shutil.rmtree(PROJECT / "goldens", ignore_errors=True)
        shutil.copytree(project / "goldens", PROJECT / "goldens")
        print("goldens written:", *sorted(p.relative_to(ROOT) for p in
                                          (PROJECT / "goldens").rglob("*.*")))


if __name__ == "__main__":
    if sys.argv[1:] != ["--update-goldens"]:
        raise SystemExit("usage: python tests/test_plugin.py --update-goldens")
    update_goldens()
