"""The clipper's vertices appended in place (``setup_device.clip_room``): on the device, a
draw whose last frame clipped triangles leaves room after each varying slot's vertices, and
the clipper writes its new vertices there instead of copying every slot into a buffer with
room (inferred's scene pass at 160x90: 42,834 vertices a slot, ~1 ms of device time).

Two triangles of many_lights' scene cross the near plane.  The first frame copies (no room
yet), the second appends in place; both frames render the same targets, blend counts and
clamps bit for bit, and the same as the numpy set-up (``$PIPEGEN_CL_DEVICE_SETUP=0``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]
SIZE = (64, 36)


def _same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for name in a:
        assert np.array_equal(a[name].view(np.uint8), b[name].view(np.uint8)), name


def test_clip_room_counts():
    from pipegen.runtime.cl.setup_device import _MAXV, clip_room
    assert clip_room(0) == 0
    assert clip_room(1) == clip_room(8) == 8 * _MAXV
    assert clip_room(9) == 16 * _MAXV


@pytest.mark.parametrize("technique", ["inferred", "light_prepass"])
def test_second_frame_appends_in_place_and_renders_the_same(technique, monkeypatch):
    from pipegen import compile_file, load_scene
    from pipegen.compiler.driver import for_scene
    scene = load_scene(ROOT / "examples" / "scenes" / "many_lights.toml")
    compiled = for_scene(compile_file(ROOT / "pipelines" / f"{technique}.pipe"), scene)
    monkeypatch.setenv("PIPEGEN_CL_DEVICE_SETUP", "1")
    pipe = compiled.pipeline("cl", SIZE)
    setup = pipe.geometry.device_setup
    first = pipe.render(scene)
    assert setup.appended_in_place == 0
    assert any(n > 0 for n in pipe.geometry.clip_seen.values())    # this scene clips
    counts1, clamps1 = pipe.last_blend_counts, pipe.last_clamps
    second = pipe.render(scene)
    assert setup.appended_in_place > 0
    _same(first, second)
    _same(counts1, pipe.last_blend_counts)
    assert clamps1 == pipe.last_clamps
    monkeypatch.setenv("PIPEGEN_CL_DEVICE_SETUP", "0")
    numpy_setup = compiled.pipeline("cl", SIZE)
    numpy_setup.render(scene)
    _same(second, numpy_setup.render(scene))
