"""pipegen's pytest plugin, registered through the ``pytest11`` entry point (docs/testing.md).

It loads in every pytest run where pipegen is installed, so importing it costs nothing heavy: no
numpy, moderngl, pyopencl or compiler until a fixture or a ``pipegen.testing`` function is used.

- Options: ``--pipegen-update-goldens`` (write or refresh the goldens that
  ``assert_matches_golden`` is given, instead of comparing), ``--pipegen-report=DIR`` (keep
  every comparison's pictures and write ``DIR/index.html`` at the end of the session) and
  ``--pipegen-general`` (render general builds, not the variants compiled for each scene).
- Fixtures: ``pipegen_scene`` (the built-in default scene at 64x36; parametrise it indirectly
  with a scene path, relative to the test file), ``pipegen_backend`` (each test that asks for
  it runs once per backend, ids ``gl`` and ``cl``; skipped where the backend is unavailable),
  ``pipegen_gl_context`` (the process's GL context, made once per session).
- Marker ``@pytest.mark.pipegen_requires("gl", "cl")``: skipped, with the reason, where one of
  the backends is unavailable.
- ``.pipe`` files holding ``expect`` lines are collected as test items
  (``pipegen.testing.pipe_items``).

Every comparison a test makes (``pipegen.testing.records``) is filed under the test's id.  With
pytest-xdist the workers send theirs to the controller in ``workeroutput`` (pictures as raw
bytes), which writes the one report.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path
from typing import Optional

import pytest

from pipegen.testing import records, settings

BACKENDS = ("gl", "cl")
_OUTPUT_KEY = "pipegen_comparisons"          # in an xdist worker's workeroutput

# backend -> None (available) or the reason it is not; probed once per process
_problems: dict[str, Optional[str]] = {}


def backend_problem(backend: str) -> Optional[str]:
    """Why ``backend`` ("gl" or "cl") cannot run in this process, or None when it can.

    Creating the context is the probe (each is a process-wide singleton, so this costs nothing
    more than the first render would).  An ``AssertionError`` is not a missing driver but a
    test-suite guard (pipegen's own tests refuse a backend to a test not marked for it): it
    propagates, and nothing is remembered."""
    if backend not in BACKENDS:
        pytest.fail(f"unknown pipegen backend {backend!r}: use one of {', '.join(BACKENDS)}",
                    pytrace=False)
    if backend not in _problems:
        try:
            if backend == "gl":
                from pipegen.runtime.gl.context import get_context
            else:
                from pipegen.runtime.cl.context import get_context
            get_context()
            _problems[backend] = None
        except AssertionError:
            raise
        except Exception as exc:  # no EGL, no OpenCL platform, a driver that fails to load
            _problems[backend] = f"{type(exc).__name__}: {exc}".strip()
    return _problems[backend]


def _skip_unless_available(backend: str) -> None:
    problem = backend_problem(backend)
    if problem is not None:
        pytest.skip(f"pipegen backend {backend} unavailable: {problem}")


# -- options and markers ---------------------------------------------------------------------

def pytest_addoption(parser):
    group = parser.getgroup("pipegen", "pipegen (testing rendering techniques)")
    group.addoption("--pipegen-update-goldens", action="store_true", default=False,
                    help="write or refresh the goldens that assert_matches_golden is given "
                         "instead of comparing (also PIPEGEN_UPDATE_GOLDENS=1)")
    group.addoption("--pipegen-report", metavar="DIR", default=None,
                    help="write an HTML summary of every comparison to DIR/index.html "
                         "(golden, actual, difference, FLIP map, numbers, the command)")
    group.addoption("--pipegen-general", action="store_true", default=False,
                    help="render the general build of each technique instead of the variant "
                         "compiled for each scene (the default, as pipegen run; also "
                         "PIPEGEN_GENERAL=1; a function's general= argument wins)")


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "pipegen_requires(*backends): skip (with the reason) unless every named "
        "pipegen backend (gl, cl) can run here")
    report = config.getoption("pipegen_report", None)
    config.stash[_STATE] = _State(Path(report) if report else None,
                                  worker=hasattr(config, "workerinput"))
    if config.getoption("pipegen_update_goldens", False):
        settings.update_goldens = True
    if config.getoption("pipegen_general", False):
        settings.general = True
    if report:
        settings.keep_images = True
        if not hasattr(config, "workerinput"):
            _check_report_dir(Path(report))


def _check_report_dir(path: Path) -> None:
    """Before any test runs: the report folder must be one pipegen may write (absent, empty,
    or a report written before), as for every pipegen output."""
    from pipegen.core.diagnostics import PipegenError
    from pipegen.core.outdir import OutputDir
    try:
        OutputDir(path, "report")
    except PipegenError as exc:
        raise pytest.UsageError(f"--pipegen-report={path}: {exc.message}; pass an empty or "
                                f"new folder (files pipegen did not write are never "
                                f"overwritten)") from None


def pytest_unconfigure(config):
    """``settings`` as they were before this session (pytest may run again in the process)."""
    state = config.stash.get(_STATE, None)
    if state is not None:
        for name, value in state.settings.items():
            setattr(settings, name, value)


class _State:
    """What the plugin keeps for one session (in ``config.stash``)."""

    def __init__(self, report: Optional[Path], worker: bool):
        self.report = report
        self.worker = worker
        self.comparisons: list[records.Comparison] = []
        self.written: Optional[Path] = None
        self.error: str = ""
        # what the session found, restored after it; a folder set by the user (e.g. in a
        # conftest.py) holds the per-test folders of error images instead of pytest's
        self.settings = {name: getattr(settings, name) for name in
                         ("update_goldens", "keep_images", "artifacts_dir", "current_test",
                          "general")}


_STATE = pytest.StashKey[_State]()


# -- fixtures --------------------------------------------------------------------------------

def pytest_generate_tests(metafunc):
    """A test asking for ``pipegen_backend`` runs once per backend (ids "gl", "cl"), unless it
    parametrises ``pipegen_backend`` itself."""
    if "pipegen_backend" not in metafunc.fixturenames:
        return
    for marker in metafunc.definition.iter_markers("parametrize"):
        names = marker.args[0] if marker.args else marker.kwargs.get("argnames", "")
        if isinstance(names, str):
            names = [n.strip() for n in names.split(",")]
        if "pipegen_backend" in names:
            return
    metafunc.parametrize("pipegen_backend", list(BACKENDS), ids=list(BACKENDS), indirect=True)


@pytest.fixture
def pipegen_backend(request) -> str:
    """The backend this test runs with ("gl" or "cl"); skipped where it is unavailable."""
    backend = getattr(request, "param", "gl")
    _skip_unless_available(backend)
    return backend


@pytest.fixture(scope="session")
def pipegen_gl_context():
    """The process's GL context (moderngl on EGL), made once; skipped where there is none."""
    _skip_unless_available("gl")
    from pipegen.runtime.gl.context import get_context
    return get_context()


@pytest.fixture
def pipegen_scene(request):
    """A scene to render: the built-in default scene at 64x36 (``pipegen.testing.TEST_SIZE``),
    or (parametrised indirectly) the scene file named, relative to the test file, at the size
    it gives."""
    from pipegen.testing.api import load_test_scene
    path = getattr(request, "param", None)
    if path is not None and not Path(path).is_absolute():
        path = Path(request.path).parent / path
    return load_test_scene(path)


# -- per test --------------------------------------------------------------------------------

def pytest_runtest_setup(item):
    settings.current_test = item.nodeid
    state = item.config.stash.get(_STATE, None)
    # A folder per test for error images, only where pipegen.testing is in use (asking pytest
    # for its temporary folder creates it, which other projects' runs need not see).
    if state is not None and ("pipegen.testing.api" in sys.modules or state.report or any(
            name.startswith("pipegen_") for name in getattr(item, "fixturenames", ()))):
        root = state.settings["artifacts_dir"] or _pytest_temp(item.config)
        settings.artifacts_dir = Path(root) / _slug(item.nodeid)
    for marker in item.iter_markers("pipegen_requires"):
        for backend in marker.args:
            _skip_unless_available(backend)


@pytest.hookimpl(trylast=True)        # after the fixtures' teardown, which may compare too
def pytest_runtest_teardown(item, nextitem):
    taken = records.take()
    state = item.config.stash.get(_STATE, None)
    for c in taken:
        c.test = c.test or item.nodeid
    if state is not None and state.report is not None:
        if state.worker:
            out = item.config.workeroutput.setdefault(_OUTPUT_KEY, [])
            out.extend(_to_wire(c) for c in taken)
        else:
            state.comparisons.extend(taken)
    if state is not None:
        settings.current_test = state.settings["current_test"]
        settings.artifacts_dir = state.settings["artifacts_dir"]


_PACKAGE = str(Path(__file__).resolve().parents[1]) + os.sep


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A failure pipegen raises on purpose (a ``ComparisonFailure``, a ``PipegenError`` for a
    bad technique or scene) is shown from the test's own lines down to its message, without
    pipegen's frames: what failed is in the message, not in pipegen's code.  Any other
    exception keeps its whole traceback, and so does ``--tb=native/line/no`` or
    ``--fulltrace``."""
    outcome = yield
    report = outcome.get_result()
    excinfo = call.excinfo
    config = item.config
    if not report.failed or excinfo is None or not _deliberate(excinfo.value) or \
            config.getoption("tbstyle", "auto") not in ("auto", "long", "short") or \
            config.getoption("fulltrace", False):
        return
    entries = list(excinfo.traceback)
    first = next((i for i, e in enumerate(entries) if Path(str(e.path)) == Path(item.path)),
                 None)
    ours = [e for e in entries[first or 0:] if not str(e.path).startswith(_PACKAGE)]
    if first is None or not ours:          # raised outside the test's code (in a fixture)
        report.longrepr = f"{type(excinfo.value).__name__}: {excinfo.value}"
        return
    style = config.getoption("tbstyle", "auto")
    report.longrepr = excinfo.getrepr(
        funcargs=True, showlocals=config.getoption("showlocals", False),
        style="long" if style == "auto" else style, truncate_locals=True,
        tbfilter=lambda ei: type(ei.traceback)(ours))


def _deliberate(exc: BaseException) -> bool:
    """An exception pipegen raises for its user: a comparison that failed, a bad input."""
    kind = type(exc)
    return kind.__module__.startswith("pipegen.") and (
        isinstance(exc, AssertionError) or kind.__name__ == "PipegenError")


def _pytest_temp(config) -> Path:
    """``pipegen/`` in pytest's temporary folder of this session (the one ``tmp_path`` uses;
    pytest keeps the last three sessions')."""
    factory = getattr(config, "_tmp_path_factory", None)
    if factory is not None:
        return factory.getbasetemp() / "pipegen"
    return settings.artifacts()


def _slug(nodeid: str) -> str:
    from pipegen.core.outdir import safe_name
    return safe_name(re.sub(r"[^A-Za-z0-9_.-]+", "_", nodeid).strip("_") or "test")


# -- .pipe files with expectations -----------------------------------------------------------

def pytest_collect_file(parent, file_path):
    if file_path.suffix != ".pipe":
        return None
    try:
        from pipegen.testing.pipe_items import collect_pipe_file
    except ImportError:      # expectations not in this version of pipegen
        return None
    return collect_pipe_file(parent, file_path)


# -- the report ------------------------------------------------------------------------------

def _to_wire(c: records.Comparison) -> dict:
    """A comparison as execnet can send it (pictures as (height, width, bytes))."""
    wire = dict(vars(c))
    wire["images"] = {name: (int(a.shape[0]), int(a.shape[1]), a.tobytes())
                      for name, a in c.images.items()}
    return wire


def _from_wire(wire: dict) -> records.Comparison:
    import numpy as np
    images = {name: np.frombuffer(data, np.uint8).reshape(h, w, 3)
              for name, (h, w, data) in wire["images"].items()}
    return records.Comparison(**{**wire, "images": images})


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """xdist (controller): a worker is done; take the comparisons it made."""
    state = node.config.stash.get(_STATE, None)
    if state is not None and state.report is not None:
        state.comparisons.extend(_from_wire(w) for w in
                                 getattr(node, "workeroutput", {}).get(_OUTPUT_KEY, []))


def pytest_sessionfinish(session, exitstatus):
    state = session.config.stash.get(_STATE, None)
    if state is None or state.report is None or state.worker:
        return
    try:
        from pipegen.testing.report_html import write_report
    except ImportError as exc:
        state.error = f"no HTML report in this version of pipegen ({exc})"
        return
    from pipegen.core.diagnostics import PipegenError
    try:
        state.written = write_report(state.report, state.comparisons)
    except PipegenError as exc:
        state.error = str(exc)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    state = config.stash.get(_STATE, None)
    if state is None or state.report is None or state.worker:
        return
    if state.written is not None:
        failed = sum(not c.passed for c in state.comparisons)
        terminalreporter.write_line(
            f"pipegen: {len(state.comparisons)} comparisons ({failed} failed), report written "
            f"to {state.written}")
    elif state.error:
        terminalreporter.write_line(f"pipegen: no report written: {state.error}", red=True)
