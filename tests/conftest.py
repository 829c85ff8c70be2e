"""Test tiers (README, "Tests"): a test that renders with OpenGL is marked ``gl``, one that runs
the OpenCL backend ``cl``; the rest need no backend (``pytest -m "not gl and not cl"``).

The markers are enforced: while a test not marked ``gl`` (its fixtures included) is set up and
run, asking for a GL context fails, and so does asking for an OpenCL context without ``cl``; a
tier can never silently need a backend it does not declare.  (Tests that run ``pipegen`` in a
subprocess declare what the command renders with.)"""

from __future__ import annotations

import os

import pytest


def pytest_configure(config):
    """The suite runs on every core (pytest-xdist, ``-n auto`` in pyproject.toml).

    - One PoCL kernel cache for the whole run, shared by the workers: each CL program is
      compiled once (0.2-3 s each, ~400 of them in a run), not once per worker.  It outlives
      the run, in the temporary folder, keyed by source text like every PoCL cache.
    - In a worker, llvmpipe and PoCL render on one thread each: the workers already keep
      every core busy, and two renderers on two threads each on two cores only wait on each
      other.  What a test renders does not depend on the thread count (tiles are independent
      and each keeps its primitive order).
    - Python bytecode for the interpreters the tests start (``pipegen`` on the command line,
      sweep and dask workers): where ``PYTHONDONTWRITEBYTECODE`` is set (as on this project's
      machines), each of them would compile pipegen's modules from source again (~0.2 s of
      CPU each); they share compiled modules in a folder of the run's own instead
      (``PYTHONPYCACHEPREFIX``: nothing is written into the source tree).
    Both are defaults: a variable set by the user wins."""
    from pipegen.runtime.cl.context import default_cache_dir
    os.environ.setdefault("POCL_CACHE_DIR", default_cache_dir("pytest"))
    if os.environ.get("PYTHONDONTWRITEBYTECODE") and not os.environ.get("PYTHONPYCACHEPREFIX"):
        import tempfile
        os.environ["PYTHONPYCACHEPREFIX"] = os.path.join(
            tempfile.gettempdir(), "pipegen-pytest-pycache", str(os.getuid()))
        del os.environ["PYTHONDONTWRITEBYTECODE"]
    if os.environ.get("PYTEST_XDIST_WORKER") and int(os.environ.get(
            "PYTEST_XDIST_WORKER_COUNT", "1")) > 1:
        os.environ.setdefault("LP_NUM_THREADS", "1")
        os.environ.setdefault("POCL_MAX_PTHREAD_COUNT", "1")


def pytest_xdist_auto_num_workers(config):
    """``-n auto``: one worker more than the machine has cores.  Many tests wait on what they
    start (``pipegen`` in a subprocess, sweep and dask workers, files written and synced): on
    2 cores, with 2 workers, the CLI, sweep, plugin and check tests kept the CPU ~55 % busy
    and ran in 107-124 s; with 3 in 72-116 s (with 4: 100 s); the compile- and render-bound
    tests (stress, f64, wide path, blend order) took the same time either way (51-61 s)."""
    return (os.cpu_count() or 1) + 1


_GUARDS = "_pipegen_backend_guard"


def _refuse(marker: str):
    def context(*args, **kwargs):
        raise AssertionError(f"this test uses the {marker.upper()} backend: mark it "
                             f"@pytest.mark.{marker} (or its module: pytestmark)")
    return context


def _guard(item) -> pytest.MonkeyPatch:
    mp = pytest.MonkeyPatch()
    if item.get_closest_marker("gl") is None:
        import moderngl
        from pipegen.runtime.gl import context as gl_context, pipeline as gl_pipeline
        for module in (gl_context, gl_pipeline):
            mp.setattr(module, "get_context", _refuse("gl"))
        mp.setattr(moderngl, "create_standalone_context", _refuse("gl"))
    if item.get_closest_marker("cl") is None:
        from pipegen.runtime.cl import context as cl_context
        mp.setattr(cl_context, "get_context", _refuse("cl"))
    return mp


def pytest_addoption(parser):
    parser.addoption("--exhaustive", action="store_true",
                     help="also run the tests marked exhaustive (whole measured tables)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--exhaustive"):
        return
    skip = pytest.mark.skip(reason="exhaustive: run with --exhaustive (README, Tests)")
    for item in items:
        if item.get_closest_marker("exhaustive") is not None:
            item.add_marker(skip)


def pytest_runtest_setup(item):
    setattr(item, _GUARDS, _guard(item))


def pytest_runtest_teardown(item, nextitem):
    mp = getattr(item, _GUARDS, None)
    if mp is not None:
        mp.undo()


@pytest.fixture(scope="module")
def gl():
    """A standalone moderngl context on EGL (llvmpipe without a GPU), for tests marked ``gl``
    that draw with moderngl directly; skipped where there is no EGL."""
    moderngl = pytest.importorskip("moderngl")
    try:
        ctx = moderngl.create_standalone_context(backend="egl")
    except Exception as exc:  # no EGL / no llvmpipe here
        pytest.skip(f"no GL context: {exc}")
    yield ctx
    ctx.release()
