"""``pipegen compile`` imports only what compiling needs (issue 8: a compile is what a user
waits for).  numpy alone costs a third of a compile; the runtimes, the scene code and the
``sweep``/``stress`` subcommands are not needed either.  Checked in a fresh interpreter that
runs the CLI entry point on every shipped technique, with an import hook that records who
imported a forbidden module, so that a failure names the import chain to cut."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import pipegen

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUES = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "pipelines").glob("*.pipe"))

#: Never imported by ``pipegen compile FILE -o DIR`` (without --scene).
FORBIDDEN = ("numpy", "moderngl", "pyopencl", "PIL", "matplotlib", "pipegen.scene.load",
             "pipegen.tools.sweep", "pipegen.tools.stress", "pipegen.runtime")

PROBE = r"""
import json, sys, traceback

FORBIDDEN = tuple(json.loads(sys.argv[1]))
techniques, out, stop = json.loads(sys.argv[2]), sys.argv[3], sys.argv[4] == "stop"
first = {}

class Recorder:
    '''Notes the stack of the first import of each forbidden module (not a mere
    importlib.util.find_spec); imports nothing.'''
    def find_spec(self, name, path=None, target=None):
        if name in FORBIDDEN and name not in first:
            stack = traceback.format_stack(limit=12)[:-1]
            if not any("importlib/util.py" in frame for frame in stack[-3:]):
                first[name] = "".join(stack)
        return None

sys.meta_path.insert(0, Recorder())
from pipegen.cli.main import main
report = []
for i, technique in enumerate(techniques):
    rc = main(["compile", technique, "-o", f"{out}/{i}", "--force"])
    loaded = sorted(m for m in FORBIDDEN if m in sys.modules)
    report.append({"technique": technique, "rc": rc, "loaded": loaded})
    if loaded and stop:
        break
print(json.dumps({"report": report, "stacks": first}))
"""


def run_probe(techniques: list[str], out: Path, forbidden=FORBIDDEN, env=None,
              stop: bool = True) -> dict:
    """Compile ``techniques`` in one fresh interpreter; which of ``forbidden`` each left
    imported (stopping at the first that imports one, unless not ``stop``)."""
    proc = subprocess.run([sys.executable, "-c", PROBE, json.dumps(forbidden),
                           json.dumps(techniques), str(out), "stop" if stop else "all"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_compiling_every_shipped_technique_imports_nothing_it_does_not_need(tmp_path):
    result = run_probe(TECHNIQUES, tmp_path)
    for row in result["report"]:
        assert row["rc"] == 0, row
        assert not row["loaded"], (
            f"compiling {row['technique']} imported {', '.join(row['loaded'])}; first "
            f"imported from:\n" + "\n".join(f"{m}:\n{result['stacks'].get(m, '?')}"
                                           for m in row["loaded"]))
    assert [r["technique"] for r in result["report"]] == TECHNIQUES


def test_with_every_syntax_tree_cached_a_compile_imports_no_lark(tmp_path):
    """The second compile of the same files loads their trees (syntax.parse's cache): neither
    lark nor the transformer (syntax_tree.py) is imported, the parser not loaded."""
    env = {**os.environ, "PIPEGEN_CACHE_DIR": str(tmp_path / "cache")}
    forbidden = FORBIDDEN + ("lark", "pipegen.frontend.syntax_tree")
    first = run_probe(TECHNIQUES, tmp_path / "1", forbidden, env, stop=False)
    assert "lark" in first["report"][0]["loaded"]       # an empty cache: parsed
    second = run_probe(TECHNIQUES, tmp_path / "2", forbidden, env)
    for row in second["report"]:
        assert row["rc"] == 0 and not row["loaded"], (
            f"{row}; first imported from:\n" + "\n".join(
                f"{m}:\n{second['stacks'].get(m, '?')}" for m in row["loaded"]))
    assert len(second["report"]) == len(TECHNIQUES)


def test_the_probe_sees_an_import_when_there_is_one(tmp_path):
    """The check can fail: with --scene a compile loads the scene, which uses numpy."""
    probe = PROBE.replace('"--force"]', '"--force", "--scene", "examples/scenes/small.toml"]')
    proc = subprocess.run([sys.executable, "-c", probe, json.dumps(FORBIDDEN),
                           json.dumps(TECHNIQUES[:1]), str(tmp_path), "stop"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    [row] = result["report"]
    assert "numpy" in row["loaded"] and "pipegen.scene.load" in row["loaded"]
    assert "pipegen/scene/load.py" in result["stacks"]["numpy"]


def test_the_version_is_read_without_importlib_metadata():
    """``pipegen.__version__`` (written into every output manifest) comes from the installed
    metadata folder, the same one importlib.metadata reads."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        expected = version("pipegen")
    except PackageNotFoundError:
        pytest.skip("pipegen is not installed")
    from pipegen.core import defaults
    assert defaults._version_from_metadata_folder() == expected
    assert defaults.version() == expected == pipegen.__version__
