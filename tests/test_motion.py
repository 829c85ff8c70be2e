"""The previous frame's camera (``prev_view``, ``prev_proj``; ``[camera.previous]`` in a scene,
``Scene.prev_camera``): motion vectors ``clip.xy / clip.w - prev_clip.xy / prev_clip.w`` agree
bit for bit across GL and CL, match numpy's reprojection of the rendered world positions for a
moving camera, and are exactly zero when the scene gives no previous camera.  The float64
evaluation reads the previous camera too.  Shaders that do not read it do not declare it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.scene import Camera, load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[1]

MOTION = """
technique motion "motion vectors from the previous frame's camera"
target mv    : rg32f clear 0
target wpos  : rgba32f clear 0
target depth : d32f clear depth 1.0
output mv
pass gbuffer {
  draw scene
  writes mv, wpos
  depth depth less write
  fragment {
    vec4 p = vec4(world_pos, 1.0);
    vec4 now = proj * (view * p);
    vec4 before = prev_proj * (prev_view * p);
    mv = now.xy / now.w - before.xy / before.w;
    wpos = p;
  }
}
"""


@pytest.fixture(scope="module")
def scenes():
    still = load_scene(ROOT / "examples" / "scenes" / "small.toml")
    moved = dataclasses.replace(still.camera, position=(0.4, 4.3, 7.2), target=(0.1, 0.5, 0.0),
                                fov_y_deg=47.0)
    return still, still.with_previous_camera(moved)


def test_scene_previous_camera_from_toml():
    base = """
width = 8
height = 8
[camera]
position = [0, 1, 5]
target = [0, 0, 0]
fov_y_deg = 40
near = 0.5
{previous}
[[objects]]
mesh = "box"
material = {{ albedo = [0.5, 0.5, 0.5] }}
"""
    s = parse_scene(base.format(previous=""))
    assert s.previous_camera is None and s.prev_camera is s.camera
    s = parse_scene(base.format(previous="[camera.previous]\nposition = [0.5, 1, 5]"))
    assert s.prev_camera == dataclasses.replace(s.camera, position=(0.5, 1.0, 5.0))
    assert s.prev_camera.near == 0.5 and s.prev_camera.fov_y_deg == 40
    with pytest.raises(PipegenError, match="previous"):
        parse_scene(base.format(previous="[camera.previous]\npositon = [0.5, 1, 5]"))
    with pytest.raises(PipegenError):
        parse_scene(base.format(previous="[camera.previous]\nprevious = {}"))


def test_only_passes_that_read_it_declare_it():
    c = compile_source(MOTION)
    gl = c.plan("gl").passes[0].code
    assert "uniform mat4 u_prev_view;" in gl.fragment and "uniform mat4 u_prev_proj;" in gl.vertex
    assert "pg_mat4 prev_view, prev_proj;" in c.plan("cl").passes[0].code.kernel
    plain = compile_source(MOTION.replace("prev_proj * (prev_view * p)", "proj * (view * p)"))
    assert "u_prev" not in plain.plan("gl").passes[0].code.fragment
    assert "prev_view" not in plain.plan("cl").passes[0].code.kernel


def _ndc(cam: Camera, aspect: float, p: np.ndarray) -> np.ndarray:
    clip = p @ (cam.projection(aspect) @ cam.view_matrix()).T
    return clip[..., :2] / clip[..., 3:4]


@pytest.mark.gl
@pytest.mark.cl
def test_motion_vectors_gl_cl_numpy(scenes):
    still, moving = scenes
    c = compile_source(MOTION)
    got = {b: c.pipeline(b).render(moving) for b in ("gl", "cl")}
    assert np.array_equal(got["gl"]["mv"], got["cl"]["mv"])
    assert np.array_equal(got["gl"]["wpos"], got["cl"]["wpos"])
    wpos = np.asarray(got["cl"]["wpos"], np.float64)
    covered = wpos[..., 3] == 1.0
    assert covered.mean() > 0.5
    aspect = moving.width / moving.height
    p = wpos[covered]
    want = _ndc(moving.camera, aspect, p) - _ndc(moving.prev_camera, aspect, p)
    mv = np.asarray(got["cl"]["mv"], np.float64)[covered]
    assert np.abs(want).max() > 0.02                      # the camera did move
    assert np.abs(mv - want).max() < 1e-4, np.abs(mv - want).max()
    # without a previous camera the two projections are the same arithmetic: exactly zero
    zero = {b: c.pipeline(b).render(still) for b in ("gl", "cl")}
    for b in ("gl", "cl"):
        assert not np.any(zero[b]["mv"]), b


@pytest.mark.cl
def test_float64_evaluation_reads_the_previous_camera(scenes):
    still, moving = scenes
    c = compile_source(MOTION)
    got = c.pipeline("cl", precision="f64").render(moving)
    wpos = np.asarray(got["wpos"], np.float64)
    covered = wpos[..., 3] == 1.0
    aspect = moving.width / moving.height
    p = wpos[covered]
    want = _ndc(moving.camera, aspect, p) - _ndc(moving.prev_camera, aspect, p)
    assert np.abs(np.asarray(got["mv"], np.float64)[covered] - want).max() < 1e-6
    assert not np.any(c.pipeline("cl", precision="f64").render(still)["mv"])


KILLZONE2 = ROOT / "examples" / "techniques" / "killzone2_gbuffer.pipe"


def test_killzone2_example_compiles_with_the_new_builtins():
    from pipegen.compiler.driver import compile_file
    c = compile_file(KILLZONE2)
    gl_passes = {p.name: p for p in c.plan("gl").passes}
    cl_passes = {p.name: p for p in c.plan("cl").passes}
    gl = gl_passes["gbuffer"].code.fragment
    assert "packHalf2x16(" in gl and "uniform mat4 u_prev_proj;" in gl
    assert "pg_pack_half2x16(" in cl_passes["gbuffer"].code.kernel
    lights = gl_passes["local_lights"].code.fragment
    assert "unpackHalf2x16(" in lights and "u_prev" not in lights


@pytest.mark.gl
@pytest.mark.cl
def test_killzone2_example_on_a_moving_camera(scenes):
    """GL and CL agree exactly on every G-buffer target (the lit image within a code); the
    G-buffer decodes to numpy's motion (within the 8-bit step) and the view normal (within the
    half and 8-bit rounding); the lit image is deferred.pipe's to 2 codes (same lighting,
    another G-buffer)."""
    from pipegen.compiler.driver import compile_file
    still, moving = scenes
    c = compile_file(KILLZONE2)
    got = {b: c.pipeline(b).render(moving) for b in ("gl", "cl")}
    for name in got["gl"]:
        if name != "lacc":
            assert np.array_equal(got["gl"][name], got["cl"][name]), name
    # the light passes decode the specular power with exp2, whose last bit GL and CL may round
    # differently: a code apart at most
    lacc = [np.asarray(got[b]["lacc"], int) for b in ("gl", "cl")]
    assert np.abs(lacc[0] - lacc[1]).max() <= 1
    g = got["cl"]
    from pipegen.core import formats
    z = formats.get("d24s8").dequantize(g["ds"])      # the light passes read D24S8 directly
    covered = z < 1.0
    h, w = z.shape
    aspect = w / h
    # world positions from depth (float64), as the light passes rebuild them
    ys, xs = np.nonzero(covered)
    ndc = np.stack([(xs + 0.5) / w * 2 - 1, (ys + 0.5) / h * 2 - 1, z[covered] * 2 - 1,
                    np.ones(len(xs))], 1)
    cam = moving.camera
    inv = np.linalg.inv(cam.projection(aspect) @ cam.view_matrix())
    p = ndc @ inv.T
    p /= p[:, 3:4]
    want = (_ndc(cam, aspect, p) - _ndc(moving.prev_camera, aspect, p)) * 0.5 * np.array([w, h])
    m = np.asarray(g["gmotion"], np.float64)[covered][:, :2] / 255.0
    px = (m - 0.5) * 2.0 * 32.0
    assert np.abs(want).max() > 1.0
    assert np.abs(px - np.clip(want, -32, 32)).max() <= 32.0 / 255.0 + 0.05
    # the normals: unit length after decoding
    from pipegen.reference.bitcasts import unpack_half2x16
    b = np.asarray(g["gnormal"], np.uint32)[covered]
    xy = unpack_half2x16(b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16) | (b[:, 3] << 24))
    assert np.all(np.abs(np.sum(xy.astype(np.float64) ** 2, 1)) <= 1.0 + 1e-3)
    ref = compile_file(ROOT / "pipelines" / "deferred.pipe").pipeline("cl").render(moving)
    diff = np.abs(np.asarray(g["lacc"], int)[..., :3] - np.asarray(ref["color"], int)[..., :3])
    assert diff.max() <= 2, diff.max()
