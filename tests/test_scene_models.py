"""The shipped real model (examples/models/cornell_box, issue 13) rendered on both backends:
the OBJ + MTL scene under many lights, and its glTF version with one light of each type
through deferred_calver, which renders all three; ``check`` agrees on every target."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyopencl")

from pipegen.proof.check import check  # noqa: E402
from pipegen.compiler.driver import compile_file  # noqa: E402
from pipegen.scene import load_scene  # noqa: E402

pytestmark = [pytest.mark.gl, pytest.mark.cl,
              pytest.mark.filterwarnings("ignore::pipegen.scene.model.SceneLoadWarning")]

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("technique", ["forward", "deferred"])
def test_cornell_box_obj_mtl_check(technique, tmp_path):
    scene = load_scene(ROOT / "examples/scenes/cornell_box.toml").with_size(64, 64)
    assert len(scene.objects) == 4 and len(scene.lights) == 32
    compiled = compile_file(ROOT / f"pipelines/{technique}.pipe")
    result = check(compiled, scene, tmp_path)
    assert result.passed, "\n" + result.table()
    # the MTL colours in the picture: the red wall on the left, the green one on the right
    color = compiled.pipeline("gl").render(scene)["color"].astype(float)
    left, right = color[8:56, :6, :3].mean(axis=(0, 1)), color[8:56, -6:, :3].mean(axis=(0, 1))
    assert left[0] > 3 * left[1] and left[0] > 40
    assert right[1] > 3 * right[0] and right[1] > 40


def test_cornell_gltf_three_light_types_check(tmp_path):
    scene = load_scene(ROOT / "examples/models/cornell_box/cornell_box.gltf").with_size(96, 54)
    assert [l.type for l in scene.lights] == ["point", "spot", "directional"]
    compiled = compile_file(ROOT / "pipelines/deferred_calver.pipe")
    result = check(compiled, scene, tmp_path)
    assert result.passed, "\n" + result.table()
    # every light shows: taking any one away changes the picture
    gl = compiled.pipeline("gl")
    full = gl.render(scene)["color"].astype(int)
    for i, light in enumerate(scene.lights):
        less = dataclasses.replace(scene, lights=scene.lights[:i] + scene.lights[i + 1:])
        diff = np.abs(full - gl.render(less)["color"].astype(int))[..., :3]
        assert (diff.max(axis=-1) > 8).sum() > 50, light.type
