"""The tests of a technique, written with pipegen's pytest plugin and pipegen.testing only."""

from pathlib import Path

import pytest

from pipegen.testing import (assert_backends_agree, assert_close_to_f64,
                             assert_matches_golden, render)

HERE = Path(__file__).parent
TECHNIQUE = HERE / "wrap_deferred.pipe"
GOLDENS = HERE / "goldens"
SCENE = pytest.mark.parametrize("pipegen_scene", ["scene.toml"], indirect=True)


@SCENE
def test_matches_golden(pipegen_scene, pipegen_backend):
    targets = render(TECHNIQUE, pipegen_scene, backend=pipegen_backend)
    assert_matches_golden(targets, GOLDENS / pipegen_backend, only=["color"])


@SCENE
def test_backends_agree(pipegen_scene):
    assert_backends_agree(TECHNIQUE, pipegen_scene)


def test_close_to_float64(pipegen_scene):
    assert_close_to_f64(TECHNIQUE, pipegen_scene)
