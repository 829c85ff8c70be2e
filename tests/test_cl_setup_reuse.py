"""Set-up once, rasterise many: the CL runtime's shared set-ups and bins change no value.

``$PIPEGEN_CL_SHARE_SETUP=0`` makes every pass execution run its own vertex kernel, set-up and
binning (``runtime/cl/geometry.py``).  Every shipped technique renders the same targets and
blend counts, bit for bit, with sharing on and off, on scenes with every light type, shadows,
translucent layers and many lights; and the sharing key keeps apart what changes a set-up:
the cull mode, the view (a moved camera, each light's shadow view) and the viewport size.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

import shipped

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUES = sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe"))
SCENES = ("mixed_lights", "shadows", "many_lights")
SIZE = (72, 40)


@functools.lru_cache(maxsize=None)
def _compiled(technique: str):
    from pipegen import compile_file
    return compile_file(ROOT / "pipelines" / f"{technique}.pipe")


@functools.lru_cache(maxsize=None)
def _scene(name: str):
    from pipegen import load_scene
    return load_scene(ROOT / "examples" / "scenes" / f"{name}.toml")


def _frame(compiled, scene, share: bool, monkeypatch, frames: int = 1):
    """The last of ``frames`` renders of a fresh pipeline, its blend counts and the number of
    pass executions that set up triangles (a ``vertex`` timing), sharing on or off."""
    monkeypatch.setenv("PIPEGEN_CL_SHARE_SETUP", "1" if share else "0")
    pipe = compiled.pipeline("cl", SIZE)
    assert pipe.geometry.share is share
    for _ in range(frames):
        out = pipe.render(scene)
    set_up = sum("vertex" in t for t in pipe.last_timings)
    return out, pipe.last_blend_counts, set_up


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for name in a:
        assert a[name].dtype == b[name].dtype, name
        assert np.array_equal(a[name].view(np.uint8), b[name].view(np.uint8)), name


def test_every_technique_names_a_shipped_pipeline():
    assert {"forward", "forward_multipass", "deferred_calver", "lidr_shadow_volumes",
            "lidr_msaa_texture"} <= set(TECHNIQUES)


@pytest.mark.parametrize("technique", shipped.params())
def test_shared_set_up_renders_what_unshared_renders(technique, monkeypatch):
    compiled = _compiled(technique)
    shared_setups = unshared_setups = 0
    for name in SCENES:
        scene = _scene(name)
        # two frames: what a frame keeps for the next (the full-screen triangle, buffers)
        shared, shared_counts, n_shared = _frame(compiled, scene, True, monkeypatch, frames=2)
        alone, alone_counts, n_alone = _frame(compiled, scene, False, monkeypatch)
        _assert_same(shared, alone)
        _assert_same(shared_counts, alone_counts)
        shared_setups += n_shared
        unshared_setups += n_alone
    # the comparison means something: unshared, more executions set up their own triangles
    # (all but forward: one scene pass, and shadow views per light; inferred: its geometry
    # pass at the L-buffer's size, its material pass at the output's, a volume per light type)
    assert (unshared_setups > shared_setups) == (technique not in ("forward", "inferred"))
    assert unshared_setups >= shared_setups


CULL_PIPE = """
technique cull_pair "Two passes drawing the scene from one view, culling different faces"
target color : rgba8 clear (0, 0, 0, 1)
target ds    : d24s8 clear depth 1.0 stencil 0
output color

pass backs {
  draw scene.opaque
  writes color
  depth ds less write
  cull back
  fragment { color = vec4(albedo, 1.0); }
}

pass fronts {
  draw scene.opaque
  writes color
  cull front
  blend color rgb add(one, one) alpha add(zero, one)
  fragment { color = vec4(0.25 * albedo, 0.0); }
}

pass backs_again {
  draw scene.opaque
  writes color
  depth ds lequal nowrite
  cull back
  blend color rgb add(one, one) alpha add(zero, one)
  fragment { color = vec4(0.125, 0.0, 0.0, 0.0); }
}
"""


def test_a_different_cull_mode_sets_up_its_own():
    from pipegen.compiler.driver import compile_source
    pipe = compile_source(CULL_PIPE, "cull_pair.pipe").pipeline("cl", SIZE)
    pipe.render(_scene("mixed_lights"))
    set_up = {t["pass"]: "vertex" in t for t in pipe.last_timings}
    # backs and backs_again share one set-up (same draw, view, cull and size); fronts not
    assert set_up == {"backs": True, "fronts": True, "backs_again": False}
    drawn = {t["pass"]: t["triangles"] for t in pipe.last_timings}
    assert drawn["fronts"] != drawn["backs"] == drawn["backs_again"]


def test_light_sets_of_one_volume_share_a_set_up(monkeypatch):
    """lidr_cpu_sort's slot passes draw disjoint light sets of the same spheres outside any
    repeat group: one set-up of all their lights (``DrawGeometry._shared_lights``), each pass
    drawing the triangles of its own lights, as many as its own set-up gives it."""
    slots = ("slot_r", "slot_g", "slot_b", "slot_a")

    def timings(share: bool) -> list:
        monkeypatch.setenv("PIPEGEN_CL_SHARE_SETUP", "1" if share else "0")
        pipe = _compiled("lidr_cpu_sort").pipeline("cl", SIZE)
        pipe.render(_scene("many_lights"))
        return [t for t in pipe.last_timings if t["pass"] in slots]

    shared, alone = timings(True), timings(False)
    assert [t["pass"] for t in shared] == list(slots)
    assert ["vertex" in t for t in shared] == [True, False, False, False]
    assert [t["triangles"] for t in shared] == [t["triangles"] for t in alone]
    assert all(t["triangles"] > 0 for t in shared)


def test_a_moved_camera_is_set_up_again(monkeypatch):
    """A frame's set-ups are the frame's: after the camera moves, a pipeline that rendered the
    old view renders what a fresh one renders."""
    import dataclasses
    compiled = _compiled("forward_multipass")
    scene = _scene("mixed_lights")
    cam = scene.camera
    moved = dataclasses.replace(scene, camera=dataclasses.replace(
        cam, position=tuple(np.asarray(cam.position, float) + (0.7, 0.3, -0.4))))
    pipe = compiled.pipeline("cl", SIZE)
    before = pipe.render(scene)
    after = pipe.render(moved)
    fresh = compiled.pipeline("cl", SIZE).render(moved)
    _assert_same(after, fresh)
    assert not np.array_equal(after["color"], before["color"])


def test_each_shadow_view_and_viewport_size_set_up_on_its_own():
    """Each light's shadow-map tile (its view) and each target size has its own set-up: the
    shadow passes of forward set up once per shadowed light, and inferred's L-buffer at
    another size than its G-buffer sets the scene up again."""
    scene = _scene("shadows")
    pipe = _compiled("forward").pipeline("cl", SIZE)
    pipe.render(scene)
    shadow = [t for t in pipe.last_timings if t["pass"] == "shadow_maps" and t.get("triangles")]
    assert len(shadow) > 1 and all("vertex" in t for t in shadow)
    assert len({t["light"] for t in shadow}) == len(shadow)
    from pipegen import compile_file
    inferred = compile_file(ROOT / "pipelines" / "inferred.pipe",
                            params={"lbuffer_scale": "0.5"}).pipeline("cl", SIZE)
    inferred.render(scene)
    scene_passes = [t for t in inferred.last_timings if "vertex" in t]
    assert len(scene_passes) >= 2


def test_frame_renders_what_render_returns_without_reading_it_back():
    """``CLPipeline.frame`` (timings) queues the frame ``render`` does: the blend counts it
    leaves are the same, and a ``render`` after it returns a fresh pipeline's targets."""
    compiled = _compiled("deferred")
    scene = _scene("mixed_lights")
    pipe = compiled.pipeline("cl", SIZE)
    assert pipe.frame(scene) is None
    counts = pipe.last_blend_counts
    again = pipe.render(scene)
    fresh = compiled.pipeline("cl", SIZE)
    want = fresh.render(scene)
    _assert_same(again, want)
    _assert_same(counts, fresh.last_blend_counts)
    assert any(c.any() for c in counts.values())


@pytest.mark.parametrize("scene_name", SCENES)
def test_a_run_of_lights_in_one_launch_renders_a_launch_per_light(scene_name):
    """Multi-pass forward's light pass draws all its lights in one raster launch
    (``programs.batches_lights``); drained pass by pass (``profile``) it launches once per
    light: the same targets, blend counts and clamps."""
    _one_launch_renders_a_launch_per_light(_compiled("forward_multipass").pipeline("cl", SIZE),
                                           _scene(scene_name))


def _one_launch_renders_a_launch_per_light(pipe, scene) -> list:
    """Render ``scene`` with the light pass's lights in one launch, then drained pass by pass
    (a launch per light): the same targets, blend counts and clamps; the clamps."""
    one = pipe.render(scene)
    one_counts, one_clamps = pipe.last_blend_counts, pipe.last_clamps
    runs = [t for t in pipe.last_timings if t["pass"] == "per_light"]
    assert len(runs) == 1 and runs[0]["lights"] == len(scene.lights)
    pipe.profile = []
    each = pipe.render(scene)
    assert len([t for t in pipe.last_timings if t["pass"] == "per_light"]) == len(scene.lights)
    _assert_same(one, each)
    _assert_same(one_counts, pipe.last_blend_counts)
    assert one_clamps == pipe.last_clamps
    return one_clamps


def test_only_a_lone_repeat_pass_that_writes_no_depth_draws_lights_in_one_launch():
    from pipegen.backends.opencl.programs import batches_lights
    from pipegen.compiler.driver import compile_source
    batched = {}
    for technique in TECHNIQUES:
        plan = _compiled(technique).plan("cl")
        batched[technique] = [p.name for p in plan.passes if batches_lights(plan, p)]
    assert batched == {t: (["per_light"] if t == "forward_multipass" else [])
                       for t in TECHNIQUES}
    source = (ROOT / "pipelines" / "forward_multipass.pipe").read_text()
    writes_depth = source.replace("depth ds equal nowrite", "depth ds lequal write")
    assert writes_depth != source
    plan = compile_source(writes_depth, str(ROOT / "pipelines" / "x.pipe")).plan("cl")
    assert not any(batches_lights(plan, p) for p in plan.passes)


# blend states and formats multi-pass forward's own light pass does not use: the run of lights
# blends each batch of pixels in registers, PG_W lanes at a time (cl_pass.cl.j2's
# once_wide_lights), where a launch per light blends pixel by pixel (the scalar blend)
BLEND_VARIANTS = {
    "src_alpha over half, clamped": (
        "blend accum rgb add(src_alpha, one_minus_src_alpha) alpha add(one, one_minus_src_alpha)",
        "accum = vec4(c * 4.0e5, 0.4);", "rgba16f"),
    "revsub with a constant, float, rgb only": (
        "blend accum rgb revsub(dst_color, one_minus_constant_color) alpha max\n"
        "  blend constant (0.25, 0.5, 0.75, 0.2)\n  mask accum rgb",
        "accum = vec4(c - vec3(0.05), 0.3);", "rgba32f"),
    "min and saturate": (
        "blend accum rgb min alpha add(src_alpha_saturate, one_minus_dst_alpha)",
        "accum = vec4(c, 0.7) * 3.0e5;", "rgba16f"),
}


@pytest.mark.parametrize("variant", BLEND_VARIANTS)
def test_a_run_of_lights_blends_every_state_as_a_launch_per_light(variant):
    from pipegen.compiler.driver import compile_source
    blend, store, fmt = BLEND_VARIANTS[variant]
    source = (ROOT / "pipelines" / "forward_multipass.pipe").read_text()
    edited = (source.replace("blend accum rgb add(one, one) alpha add(zero, one)", blend)
              .replace("accum = vec4(c, 0.0);", store)
              .replace("target accum : rgba16f", f"target accum : {fmt}"))
    assert edited.count(blend) == 1 and store in edited
    compiled = compile_source(edited, str(ROOT / "pipelines" / "blend_variant.pipe"))
    pipe = compiled.pipeline("cl", SIZE)
    assert "float8 acc0[4];" in pipe.source(1)      # the batch's pixels held across the lights
    clamps = _one_launch_renders_a_launch_per_light(pipe, _scene("many_lights"))
    # the clamp counts were compared where there were some (half beyond 65504)
    assert any(c.pass_name == "per_light" for c in clamps) == (fmt == "rgba16f")


def test_passes_sharing_a_set_up_run_one_vertex_kernel_for_their_varyings():
    """Light pre-pass's geometry pass (normals) and material pass (albedo, materials) share
    the scene's set-up: one vertex kernel computes the union of their varyings
    (``programs.scene_vertex_program``), where each pass's own computed the positions again
    and their outputs were gathered; the image is the unshared one (tested above)."""
    from pipegen.backends.opencl.programs import scene_vertex_program
    pipe = _compiled("light_prepass").pipeline("cl", SIZE)
    built = [key[1] for key in pipe.device.kernels if key[0] == "scene_vertex"]
    assert len(built) == 1          # with the pipeline's programs, before any frame
    pipe.render(_scene("many_lights"))
    unions = [key[1] for key in pipe.device.kernels if key[0] == "scene_vertex"]
    assert unions == built and len(unions[0]) > 2
    source = scene_vertex_program(unions[0])
    assert source.count("o_vary[") == len(unions[0])
    scene_passes = {k for k, p in enumerate(pipe.plan.passes) if p.draw.kind.value == "scene"}
    assert len(scene_passes) == 2
    assert not any(key[0] in scene_passes and key[1] == "pg_vertex" for key in pipe.device.kernels)
