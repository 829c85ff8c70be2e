"""A repeat group's passes in one raster launch (``backends/opencl/group.py``,
``runtime/cl/group_launch.py``) change no value.

``$PIPEGEN_CL_FUSE_GROUPS=0`` runs every pass execution as its own launch.  Deferred's
stencil-marked light volumes (two passes per light, the first clearing the stencil) render
the same targets, blend counts and clamps bit for bit fused and not: specialised to a
point-only scene (two members), general on a scene with point and spot lights (four members,
two clearing), general on the point-only scene (two members no light reaches: never called),
with one point light, a group of one pass (the shadow-volume LIDR's light volumes, where the
scene has no shadow volumes), and a frame that does not fit (targets sharing storage) falling
back to a launch per execution.  A group that reads what it writes is not fused.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]
SIZE = (64, 36)


@functools.lru_cache(maxsize=None)
def _compiled(name: str, scene: str = ""):
    from pipegen import compile_file
    from pipegen.compiler.driver import for_scene
    c = compile_file(ROOT / "pipelines" / f"{name}.pipe")
    return for_scene(c, _scene(scene)) if scene else c


@functools.lru_cache(maxsize=None)
def _scene(name: str):
    from pipegen import load_scene
    return load_scene(ROOT / "examples" / "scenes" / f"{name}.toml")


def _render(compiled, scene, fuse: bool, monkeypatch):
    """(targets, blend counts, clamps, launches, fused executions, fused groups' member
    counts) of a second frame."""
    monkeypatch.setenv("PIPEGEN_CL_FUSE_GROUPS", "1" if fuse else "0")
    pipe = compiled.pipeline("cl", SIZE)
    pipe.render(scene)
    out = pipe.render(scene)
    launches = len(pipe._events)
    fused = sum(bool(t.get("fused")) for t in pipe.last_timings)
    members = [len(gp.members) for gp, _ in pipe.groups.groups.values()]
    return out, pipe.last_blend_counts, pipe.last_clamps, launches, fused, members


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for name in a:
        assert a[name].dtype == b[name].dtype, name
        assert np.array_equal(a[name].view(np.uint8), b[name].view(np.uint8)), name


@pytest.mark.parametrize("scene, specialised, members", [
    ("many_lights", True, 2),       # mark, shade_light_volume
    ("mixed_lights", False, 4),     # and mark_cone, shade_cone: spot lights
    ("many_lights", False, 4),      # the cone passes run for no light
])
def test_deferred_light_volumes_fused_render_what_launches_per_pass_render(
        scene, specialised, members, monkeypatch):
    compiled = _compiled("deferred", scene if specialised else "")
    s = _scene(scene)
    fused = _render(compiled, s, True, monkeypatch)
    alone = _render(compiled, s, False, monkeypatch)
    assert fused[5] == [members] and alone[5] == []
    _assert_same(fused[0], alone[0])
    _assert_same(fused[1], alone[1])
    assert fused[2] == alone[2]
    lights = sum(1 for l in s.lights if l.type in ("point", "spot"))
    # every light's executions went into the one launch; per pass, they were a launch each
    assert fused[4] >= 2 * lights
    assert alone[4] == 0
    assert fused[3] < alone[3] - lights



def test_a_group_of_one_light_volume_pass_is_fused(monkeypatch):
    """The shadow-volume LIDR compiled for a scene without shadow volumes keeps one pass in
    its group (its light volumes writing indices where the stencil is 0): fused, its 81
    lights' executions are one launch, and the targets, blend counts and clamps are those of
    a launch per light."""
    compiled = _compiled("lidr_shadow_volumes", "many_lights")
    s = _scene("many_lights")
    fused = _render(compiled, s, True, monkeypatch)
    alone = _render(compiled, s, False, monkeypatch)
    assert fused[5] == [1] and alone[5] == []
    _assert_same(fused[0], alone[0])
    _assert_same(fused[1], alone[1])
    assert fused[2] == alone[2]
    lights = sum(1 for l in s.lights if l.type == "point")
    assert fused[4] == lights and fused[3] == alone[3] - lights + 1


def test_a_light_alone_of_its_type_is_fused_too(monkeypatch):
    """One point light: a group of one light's executions (no bins per light are made for
    it either way) renders the same in one launch."""
    import dataclasses
    s = _scene("many_lights")
    one = dataclasses.replace(s, lights=tuple(l for l in s.lights if l.type == "point")[:1])
    compiled = _compiled("deferred")
    fused = _render(compiled, one, True, monkeypatch)
    alone = _render(compiled, one, False, monkeypatch)
    _assert_same(fused[0], alone[0])
    _assert_same(fused[1], alone[1])
    assert fused[4] == 2 and fused[3] == alone[3] - 1


def test_a_frame_that_does_not_fit_falls_back_to_launches_per_pass(monkeypatch):
    """Targets sharing storage (``alias``): the executions run one by one, and render the
    same as without it."""
    compiled = _compiled("deferred", "many_lights")
    s = _scene("many_lights")
    monkeypatch.setenv("PIPEGEN_CL_FUSE_GROUPS", "1")
    pipe = compiled.pipeline("cl", SIZE)
    pipe.alias = True
    out = pipe.render(s)
    assert pipe.groups.groups and not any(t.get("fused") for t in pipe.last_timings)
    plain = _render(compiled, s, True, monkeypatch)[0]
    for name in out:
        if name not in pipe.store.memory.aliased:
            assert np.array_equal(out[name].view(np.uint8), plain[name].view(np.uint8)), name


def test_a_group_reading_what_it_writes_is_not_fused():
    """A member reading a target another member writes may read other pixels: no fusion."""
    from pipegen import compile_source
    from pipegen.backends.opencl.group import fusable, group_members
    src = (ROOT / "pipelines" / "deferred.pipe").read_text()
    # the shading pass also reads accum, which it writes
    src = src.replace("reads galbedo, gnormal, gpos\n    writes accum\n    depth ds off\n    cull front",
                      "reads galbedo, gnormal, gpos, accum2\n    writes accum\n    depth ds off\n    cull front", 1)
    assert "accum2" in src
    src = src.replace("target accum   : rgba16f clear (0, 0, 0, 1)",
                      "target accum   : rgba16f clear (0, 0, 0, 1)\ntarget accum2  : rgba16f clear 0", 1)
    # the marking pass writes accum2
    src = src.replace("    clear ds stencil 0\n    depth ds lequal nowrite\n    cull none\n",
                      "    clear ds stencil 0\n    writes accum2\n    depth ds lequal nowrite\n"
                      "    cull none\n    fragment { accum2 = vec4(1.0); }\n", 1)
    plan = compile_source(src, "deferred_reads.pipe").plan("cl")
    groups = group_members(plan)
    assert groups and not any(fusable(plan, m) for m in groups.values())
    plan = _compiled("deferred").plan("cl")
    assert all(fusable(plan, m) for m in group_members(plan).values())
