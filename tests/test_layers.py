"""The import rule of the package's layers (pipegen/layers.py): the package keeps it, and each
kind of breach planted in a copy of the package is caught, named by file and line."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from pipegen import layers

PACKAGE_DIR = Path(layers.__file__).resolve().parent


def test_the_package_keeps_the_rule():
    assert layers.violations(PACKAGE_DIR) == []


def test_every_folder_is_in_a_layer():
    folders = {p.name for p in PACKAGE_DIR.iterdir()
               if p.is_dir() and (p / "__init__.py").exists()}
    assert folders == set(layers.LAYER_OF)


def _plant(root: Path, rel: str, text: str) -> tuple[str, int]:
    """Append ``text`` to the module at ``rel`` (created if missing); (file, first line)."""
    path = root / "pipegen" / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    old = path.read_text(encoding="utf-8") if path.exists() else ""
    if old and not old.endswith("\n"):
        old += "\n"
    path.write_text(old + text, encoding="utf-8")
    return f"pipegen/{rel}", old.count("\n") + 1


@pytest.fixture
def copy(tmp_path):
    shutil.copytree(PACKAGE_DIR, tmp_path / "pipegen",
                    ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


def test_planted_breaches_are_each_caught_at_their_line(copy):
    planted = {
        "from the later layer cli/": _plant(
            copy, "core/formats.py", "def _late():\n    from pipegen.cli.main import main\n"),
        "imports its sibling scene/": _plant(
            copy, "passes/cull_unread.py", "from pipegen.scene import meshes\n"),
        "imports the private name _Scheme": _plant(
            copy, "views/info.py", "from pipegen.core.formats import _Scheme\n"),
        "reads the private name formats._table": _plant(
            copy, "views/report.py", "from pipegen.core import formats\nX = formats._table\n"),
        "imports the package facade": _plant(
            copy, "core/outdir.py", "from pipegen import DEFAULT_SIZE\n"),
        "imports by string": _plant(
            copy, "views/graph.py", "import importlib\nM = importlib.import_module('x')\n"),
        "never import each other": _plant(
            copy, "runtime/draws.py", "from pipegen.reference import raster\n"),
        "imports pyopencl outside runtime/": _plant(
            copy, "proof/check.py", "def _cl():\n    import pyopencl\n"),
        "is in no layer": _plant(
            copy, "extras/tool.py", "from pipegen.core import formats\n"),
    }
    # an upward import under TYPE_CHECKING counts like any other
    planted["from the later layer runtime/"] = _plant(
        copy, "ir/walk.py",
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
        "    from pipegen.runtime import draws\n")
    (copy / "pipegen/extras/__init__.py").write_text("")
    found = layers.violations(copy / "pipegen")
    for what, (file, line) in planted.items():
        lines = {"reads the private name formats._table": line + 1,
                 "imports by string": line + 1,
                 "from the later layer cli/": line + 1,
                 "imports pyopencl outside runtime/": line + 1,
                 "from the later layer runtime/": line + 2}.get(what, line)
        hits = [v for v in found if v.startswith(f"{file}:{lines}:") and what in v]
        assert hits, f"{what!r} planted at {file}:{lines} not reported; got {found}"


def test_a_cycle_inside_one_folder_is_caught(copy):
    # one folder may import itself freely, but not in a loop
    _plant(copy, "core/ping.py", "from pipegen.core import pong\n")
    _plant(copy, "core/pong.py", "def f():\n    from pipegen.core import ping\n")
    found = layers.violations(copy / "pipegen")
    assert "pipegen/core/ping.py: import cycle pipegen.core.ping <-> pipegen.core.pong" in found


def test_an_import_from_an_earlier_layer_or_its_own_folder_is_allowed(copy):
    _plant(copy, "views/info.py", "from pipegen.ir import walk\nfrom pipegen.views import graph\n")
    assert layers.violations(copy / "pipegen") == layers.violations(PACKAGE_DIR)


def test_the_wheel_lists_every_folder():
    # setuptools ships only the packages pyproject.toml names: a new folder left out of the
    # list imports in the repository and fails in a non-editable install
    import tomllib
    config = tomllib.loads((PACKAGE_DIR.parent / "pyproject.toml").read_text(encoding="utf-8"))
    listed = set(config["tool"]["setuptools"]["packages"])
    on_disk = {".".join(p.parent.relative_to(PACKAGE_DIR.parent).parts)
               for p in PACKAGE_DIR.rglob("__init__.py")}
    assert on_disk <= listed, sorted(on_disk - listed)
