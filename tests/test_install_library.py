"""The shared library ships with the package: pipegen installed (not editable) into a fresh
virtual environment compiles a technique in a folder outside the repository that includes
``common/lighting.pipe``, and finds more includes through ``PIPEGEN_PATH``.

The environment is built without network or build isolation: ``venv --without-pip``, the
dependencies (and pip, setuptools) of the running environment made visible by a ``.pth`` line,
then ``pip install --no-deps --no-build-isolation`` of a copy of the sources (so that the build
writes nothing into the checkout).  setuptools older than 70.1 builds wheels only with the
``wheel`` package; where neither is available, the package is installed by setuptools'
``build_py`` into the venv's site-packages instead (the same files a wheel holds, without the
console script, so ``python -m pipegen.cli`` is run).  About 10-20 s.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

TECHNIQUE = """\
technique mine "A technique outside the repository, lit by the shipped library"
include "common/lighting.pipe"
include "extra.pipe"

param max_lights = 16
lights[max_lights] { position: vec3, radius: float, color: vec3 }

target color : rgba8 clear (0, 0, 0, 1)
target ds    : d24s8 clear depth 1.0 stencil 0
output color

pass shade {
  draw scene.opaque
  writes color
  depth ds less write
  fragment {
    vec3 n = normalize(normal);
    vec3 c = ambient * albedo;
    for (int i = 0; i < max_lights; i++) {
      if (uint(i) >= num_lights) break;
      c += shade_light(uint(i), world_pos, n, albedo, specular, shininess);
    }
    color = vec4(tonemap(c), 1.0);
  }
}
"""

EXTRA = "vec3 tonemap(vec3 c) { return c / (c + vec3(1.0)); }\n"


def _run(cmd, **kw) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, **kw)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))}:\n{proc.stdout}\n{proc.stderr}"
    return proc


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """A venv with pipegen installed from a copy of the sources; returns its bin/ folder."""
    tmp = tmp_path_factory.mktemp("install")
    src = tmp / "src"
    src.mkdir()
    skip = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", "build")
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    for name in ("pipegen", "grammar", "templates", "pipelines/common"):
        shutil.copytree(ROOT / name, src / name, ignore=skip)

    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    bindir = venv / ("Scripts" if os.name == "nt" else "bin")
    python = bindir / ("python.exe" if os.name == "nt" else "python")
    purelib = _run([str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"]
                   ).stdout.strip()
    # Dependencies from this environment: plain path lines, so the .pth files there (such as
    # an editable install of pipegen itself) are not run.
    ours = {sysconfig.get_path("purelib"), sysconfig.get_path("platlib")}
    extra = [p for p in os.environ.get("PIPEGEN_INSTALL_TEST_PATH", "").split(os.pathsep) if p]
    Path(purelib, "_pipegen_test_deps.pth").write_text("\n".join(sorted(ours) + extra) + "\n")
    env = _clean_env(tmp)
    if _can_build_wheels(python, env):
        _run([str(python), "-m", "pip", "install", "--no-deps", "--no-build-isolation",
              "--no-index", "--disable-pip-version-check", "-q", str(src)], env=env, cwd=tmp)
    else:
        _run([str(python), "-c", "from setuptools import setup; setup()", "-q", "build_py",
              f"--build-lib={purelib}"], env=env, cwd=src)
    return bindir


def _can_build_wheels(python: Path, env: dict) -> bool:
    probe = ("import importlib.util, setuptools; v = tuple(int(x) for x in "
             "setuptools.__version__.split('.')[:2]); "
             "print(v >= (70, 1) or importlib.util.find_spec('wheel') is not None)")
    return _run([str(python), "-c", probe], env=env).stdout.strip() == "True"


def _pipegen(bindir: Path) -> list[str]:
    script = bindir / ("pipegen.exe" if os.name == "nt" else "pipegen")
    if script.exists():
        return [str(script)]
    return [str(bindir / ("python.exe" if os.name == "nt" else "python")), "-m", "pipegen.cli"]


def _clean_env(tmp: Path) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PIPEGEN_PATH", "VIRTUAL_ENV", "PYTHONHOME",
                        "PIPEGEN_INSTALL_TEST_PATH")}
    env["PIPEGEN_CACHE_DIR"] = str(tmp / "cache")
    return env


@pytest.mark.slow
def test_installed_pipegen_compiles_a_technique_outside_the_repo(installed, tmp_path):
    python = installed / ("python.exe" if os.name == "nt" else "python")
    where = _run([str(python), "-c", "import pipegen, pipegen.core.sources as s; "
                  "print(pipegen.__file__); print(s.library_dir())"],
                 env=_clean_env(tmp_path), cwd=tmp_path).stdout.split("\n")
    venv = installed.parent.resolve()
    assert Path(where[0]).resolve().is_relative_to(venv), where      # not the checkout
    assert Path(where[1]).resolve().is_relative_to(venv), where
    assert (Path(where[1]) / "lighting.pipe").is_file()

    user = tmp_path / "user"
    extra = tmp_path / "extra"
    user.mkdir()
    extra.mkdir()
    (user / "mine.pipe").write_text(TECHNIQUE)
    (extra / "extra.pipe").write_text(EXTRA)
    env = _clean_env(tmp_path)
    env["PIPEGEN_PATH"] = os.pathsep.join([str(tmp_path / "missing"), str(extra)])
    pipegen = _pipegen(installed)
    _run([*pipegen, "compile", "mine.pipe", "-o", "out"], env=env, cwd=user)
    frag = (user / "out" / "gl").glob("*.frag")
    text = "".join(p.read_text() for p in frag)
    assert "blinn_phong" in text and "tonemap" in text

    # Without PIPEGEN_PATH the include is not found, and the error says where it looked.
    del env["PIPEGEN_PATH"]
    proc = subprocess.run([*pipegen, "compile", "mine.pipe", "-o", "out2"], env=env,
                          cwd=user, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, proc.stderr
    assert "mine.pipe:3:1: error: cannot read included file 'extra.pipe'" in proc.stderr
    assert "searched extra.pipe (next to the including file))" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.slow
def test_an_installed_sweep_run_from_the_source_tree_imports_the_installed_pipegen(installed,
                                                                                  tmp_path):
    """Issue 29: run from the repository root (a source tree whose pipegen/ is not the
    installed one), the sweep's render workers and its timing process import the pipegen the
    parent runs, not ./pipegen: the sweep finishes, rows timed."""
    env = _clean_env(tmp_path)
    out = tmp_path / "sweep"
    proc = subprocess.run([*_pipegen(installed), "sweep", "pipelines/forward.pipe",
                           "--size", "32x18", "-p", "pcf_taps=1,4", "--frames", "1",
                           "--backend", "gl", "--no-progress", "-o", str(out)],
                          env=env, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 3 and all(",gl," in r for r in rows[1:])
