"""Issue 26 item 1: every command that renders a scene renders the variant compiled for it by
default (docs/specialise.md), and ``--general`` / ``general=True`` the general build: sweep
(its rows and their commands), stress (a variant per case scene's facts), tune, and the
testing API (``pytest --pipegen-general``).  The variant renders what the general build
renders, bit for bit, on the targets it keeps."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file, for_scene
from pipegen.compiler.specialise import verify
from pipegen.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
FORWARD = ROOT / "pipelines/forward.pipe"
SMALL = ROOT / "examples/scenes/small.toml"


def small(size=(32, 18)):
    return load_scene(SMALL).with_size(*size)


def test_for_scene_gives_the_variant_and_general_gives_the_build_itself():
    general = compile_file(FORWARD)
    variant = for_scene(general, small(), path=FORWARD)
    cut = {c.name for c in variant.specialisation.cuts}
    assert {"shadow_maps", "shadow_atlas", "lights"} <= cut
    assert variant.technique.lights.capacity == 4               # shrunk from the file
    assert for_scene(general, small()).technique.lights.capacity == 128   # no file: kept
    assert for_scene(general, small(), general=True) is general
    assert for_scene(variant, load_scene(ROOT / "examples/scenes/mixed_lights.toml")) \
        is variant                                               # guarded, not respecialised


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("technique, scene", [("forward", "small"),
                                              ("deferred_calver", "mixed_lights")])
def test_the_default_variant_renders_what_the_general_build_renders(technique, scene):
    """``specialise --verify``'s comparison, of the build ``run`` now renders by default."""
    s = load_scene(ROOT / f"examples/scenes/{scene}.toml").with_size(48, 27)
    path = ROOT / f"pipelines/{technique}.pipe"
    general = compile_file(path)
    result = verify(general, for_scene(general, s, path=path), s)
    assert result.identical, result.differences
    assert len(result.compared["gl"]) >= 2


# -- sweep -------------------------------------------------------------------------------------

def sweep(out: Path, *extra: str) -> dict:
    r = subprocess.run([sys.executable, "-m", "pipegen", "sweep", str(FORWARD), "--scene",
                        str(SMALL), "--size", "32x18", "-p", "max_lights=128", "--backend", "gl",
                        "--frames", "0", "--jobs", "1", "--no-progress", *extra, "-o", str(out)],
                       capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    return json.loads((out / "results.json").read_text())


@pytest.mark.gl
def test_sweep_renders_variants_and_general_on_request(tmp_path):
    special, general = sweep(tmp_path / "s"), sweep(tmp_path / "g", "--general")
    (row,), (grow,) = special["rows"], general["rows"]
    assert "--general" not in row["command"] and grow["command"].endswith("--general -o "
                                                                         "out/sweep-row")
    assert any(n.startswith("every variant rendered and timed as compiled for the scene")
               for n in special["notes"])
    assert any("(--general)" in n for n in general["notes"])
    # the variant has no shadow atlas: fewer target bytes, the same picture
    assert row["target_bytes"] < grow["target_bytes"]
    image = row["image"]
    assert (tmp_path / "s" / image).read_bytes() == (tmp_path / "g" / image).read_bytes()


# -- stress ------------------------------------------------------------------------------------

@pytest.mark.gl
@pytest.mark.cl
def test_stress_renders_each_case_with_its_scenes_variant():
    from pipegen.tools.stress.cases import build
    from pipegen.tools.stress.run import Stress
    general = compile_file(FORWARD)
    cases = build(small(), ["base", "lights_16"])
    runner, plain = Stress(general, path=FORWARD), Stress(general, general=True)
    ours = [runner.run_case(c, keep_images=False) for c in cases]
    theirs = [plain.run_case(c, keep_images=False) for c in cases]
    variants = runner.builds()
    assert all(v.specialisation is not None for v in variants)
    assert {v.technique.lights.capacity for v in variants} == {4, 16}   # one per facts
    assert plain.builds() == [general]
    assert "variants" in runner.builds_text() and "--general" in plain.builds_text()
    for a, b in zip(ours, theirs):       # the same status, the same errors where both render
        assert a.status == b.status and a.mismatches == b.mismatches
        errors = {(t.backend, t.key): t.worst_error for t in b.targets}
        assert a.targets and all(t.worst_error == errors[t.backend, t.key] for t in a.targets)


# -- tune --------------------------------------------------------------------------------------

@pytest.mark.gl
def test_tune_measures_and_renders_the_variant():
    from pipegen.tools.tune.measure import Evaluator, Reference
    general = compile_file(FORWARD)
    scenes = [small()]
    ours = Evaluator(str(FORWARD), scenes, Reference("scene", general), frames=0)
    theirs = Evaluator(str(FORWARD), scenes, Reference("scene", general), frames=0,
                       general=True)
    assert ours.rendered({}, scenes[0]).specialisation is not None
    assert theirs.rendered({}, scenes[0]).specialisation is None
    a, b = ours.render((), {}), theirs.render((), {})
    assert a.memory < b.memory                                   # no shadow atlas
    assert a.figures["p99"] == b.figures["p99"] and a.figures["max"] == b.figures["max"]


# -- the testing API ---------------------------------------------------------------------------

@pytest.mark.gl
def test_testing_api_renders_the_variant_unless_general(monkeypatch):
    from pipegen.testing import render, settings
    special = render(FORWARD, SMALL, size=(32, 18))
    general = render(FORWARD, SMALL, size=(32, 18), general=True)
    assert special.compiled.specialisation is not None and "--general" not in special.command
    assert general.compiled.specialisation is None and general.command.endswith("--general "
                                                                                 "--backend gl")
    assert "shadow_atlas" in general and "shadow_atlas" not in special
    np.testing.assert_array_equal(special["color"].values, general["color"].values)
    monkeypatch.setattr(settings, "general", True)        # pytest --pipegen-general
    assert render(FORWARD, SMALL, size=(32, 18)).compiled.specialisation is None
    assert render(FORWARD, SMALL, size=(32, 18), general=False).compiled.specialisation \
        is not None


PROBE = """
from pipegen.testing import settings

def test_general_is_{want}():
    assert settings.general is {want}
"""


@pytest.mark.parametrize("args, want", [((), False), (("--pipegen-general",), True)])
def test_the_pytest_option_sets_general(tmp_path, args, want):
    """``pytest --pipegen-general`` (the plugin's option) reaches ``settings.general``."""
    import os
    (tmp_path / "test_probe.py").write_text(PROBE.format(want=want))
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PYTEST_", "PIPEGEN_GENERAL"))}
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        "-p", "no:xdist", "-p", "no:benchmark", *args], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "1 passed" in r.stdout, r.stdout + r.stderr
