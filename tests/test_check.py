"""``pipegen check``: every shipped technique agrees GL vs CL on the default scene and on the
stress scene (overlapping volumes beyond every packing's capacity, the camera inside a light
volume, a thin tilted slab and a grazing plane); a disagreement is localised to its pass."""

import copy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyopencl")

pytestmark = [pytest.mark.gl, pytest.mark.cl]

from pipegen.proof.check import check, first_divergent_pass  # noqa: E402
from pipegen.compiler.driver import compile_file  # noqa: E402
from pipegen.scene import default_scene, load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUES = ["forward", "forward_multipass", "deferred", "lidr_cpu_sort", "lidr_max_stencil",
              "lidr_bitplanes", "light_prepass", "inferred", "deferred_calver", "lidr_transparent"]
SCENES = {
    "default": lambda: default_scene(),
    "stress_overlap": lambda: load_scene(ROOT / "examples/scenes/stress_overlap.toml"),
}
# Issue 4's scenes, at a test-friendly size: many lights, translucent layers, thin geometry.
ISSUE4_TECHNIQUES = ["light_prepass", "inferred", "deferred_calver"]
ISSUE4_SCENES = {
    "many_lights": lambda: load_scene(ROOT / "examples/scenes/many_lights.toml").with_size(192, 108),
    "translucent_layers": lambda: load_scene(ROOT / "examples/scenes/translucent_layers.toml"),
    "edges": lambda: load_scene(ROOT / "examples/scenes/edges.toml"),
    "mixed_lights": lambda: load_scene(ROOT / "examples/scenes/mixed_lights.toml"),
}


@pytest.mark.parametrize("scene_name", list(SCENES))
@pytest.mark.parametrize("technique", TECHNIQUES)
def test_technique_passes_check(technique, scene_name, tmp_path):
    compiled = compile_file(ROOT / f"pipelines/{technique}.pipe")
    result = check(compiled, SCENES[scene_name](), tmp_path)
    assert result.passed, "\n" + result.table() + f"\nfirst divergence: {result.first_divergence}"
    assert (tmp_path / f"error_{compiled.technique.output}.png").exists()


@pytest.mark.parametrize("scene_name", list(ISSUE4_SCENES))
@pytest.mark.parametrize("technique", ISSUE4_TECHNIQUES)
def test_issue4_technique_passes_check(technique, scene_name, tmp_path):
    compiled = compile_file(ROOT / f"pipelines/{technique}.pipe")
    result = check(compiled, ISSUE4_SCENES[scene_name](), tmp_path)
    assert result.passed, "\n" + result.table() + f"\nfirst divergence: {result.first_divergence}"


class Perturbed:
    """A backend whose captures differ from the wrapped one from pass ``bad_pass`` on."""

    def __init__(self, inner, bad_pass, target):
        self.inner, self.bad_pass, self.target = inner, bad_pass, target

    def render(self, scene, capture_passes=False):
        result, caps = self.inner.render(scene, capture_passes=True)
        caps = copy.deepcopy(caps)
        hit = False
        for c in caps:
            hit = hit or c["pass"] == self.bad_pass
            if hit:
                c["targets"][self.target][5, 5] ^= 0b01000000      # one bit-plane bit
        return (result, caps) if capture_passes else result


def test_first_divergent_pass_is_named():
    compiled = compile_file(ROOT / "pipelines/lidr_bitplanes.pipe")
    scene = load_scene(ROOT / "examples/scenes/small.toml")
    gl = compiled.pipeline("gl")
    bad = Perturbed(gl, "light_indices", "lightidx")
    assert first_divergent_pass(compiled, gl, gl, scene) is None
    assert first_divergent_pass(compiled, gl, bad, scene) == "light_indices: lightidx"



class FlippedBit(Perturbed):
    """``Perturbed`` whose final ``lightidx`` differs too (what ``check`` compares)."""

    def __init__(self, inner):
        super().__init__(inner, "light_indices", "lightidx")

    def render(self, scene, capture_passes=False):
        result, caps = super().render(scene, capture_passes=True)
        result = dict(result, lightidx=result["lightidx"].copy())
        result["lightidx"][5, 5] ^= 0b01000000
        return (result, caps) if capture_passes else result


def test_check_localises_only_when_asked(monkeypatch):
    """``check(localise=False)`` (benchmarks/gpu_check.py's default: on a GPU every row
    disagrees) gives the verdict and the figures without replaying the passes."""
    import pipegen.compiler.driver as driver
    compiled = compile_file(ROOT / "pipelines/lidr_bitplanes.pipe")
    scene = load_scene(ROOT / "examples/scenes/small.toml")
    real = driver.Compiled.pipeline

    def pipeline(self, backend="gl", *args, **kwargs):     # CL: GL with one bit flipped
        if backend == "cl" and kwargs.get("precision", "f32") == "f32":
            return FlippedBit(real(self, "gl", *args, **kwargs))
        return real(self, backend, *args, **kwargs)

    monkeypatch.setattr(driver.Compiled, "pipeline", pipeline)
    quick = check(compiled, scene, localise=False)
    assert not quick.passed and quick.first_divergence is None
    assert [r.name for r in quick.rows if not r.passed] == ["lightidx"]
    assert check(compiled, scene).first_divergence == "light_indices: lightidx"

def test_check_command_exit_codes_and_table(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "pipegen.cli", "check",
                           str(ROOT / "pipelines/lidr_bitplanes.pipe"), "--scene",
                           str(ROOT / "examples/scenes/small.toml"), "-o", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    header = next(l for l in lines if l.startswith("target"))
    assert "max error" in header and "over" in header and "edges" in header
    rows = {l.split()[0]: l for l in lines if l.split() and l.split()[0] in
            ("color", "lightidx", "zcopy", "ds", "ds.stencil")}
    assert set(rows) == {"color", "lightidx", "zcopy", "ds", "ds.stencil"}
    assert "exact" in rows["lightidx"], "packed light indices are compared exactly"
    assert all(l.rstrip().endswith("ok") for l in rows.values())
    assert (tmp_path / "error_color.png").exists()
