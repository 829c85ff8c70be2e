"""Shadow maps with percentage-closer filtering (issue 12, part 2).

- scenes: ``shadows = true`` on lights (a point light takes six tiles: test_point_shadows.py);
- the language: ``draw scene… from lights TYPES tiles N`` and its errors;
- GL against OpenCL (``pipegen check``): the d32f atlas bit for bit, the image within the
  format's tolerance; the atlas against the float64 reference's shadow maps;
- forward.pipe and deferred_calver.pipe against the float64 reference with its shadow test
  (``reference/shadows.py``) for pcf_taps 1 and 16;
- what a technique that draws no shadows reports, the atlas's capacity, and scene
  specialisation (no shadow-casting light: no shadow pass, no atlas, no lookup).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pipegen.scene import shadows as S
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.reference.lighting import reference_image
from pipegen.reference.metrics import error_image, rgb_error
from pipegen.reference.shadows import ExactShadows, MappedShadows, shadow_factor, shadow_maps
from pipegen.scene import load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "examples/scenes/shadows.toml"
ATLAS = 512                              # a small atlas keeps the tests fast


def scene():
    return load_scene(SCENE)


# ---- scenes ------------------------------------------------------------------------------------

HEAD = """
width = 32
height = 18
[camera]
position = [0, 4, 8]
target = [0, 0, 0]
fov_y_deg = 45
[[objects]]
mesh = "box"
material = { albedo = [0.5, 0.5, 0.5] }
"""


def test_scene_marks_shadow_casting_lights():
    s = scene()
    assert [l.shadows for l in s.lights] == [True, True, True, False]
    assert S.shadow_lights(s.lights) == [0, 1, 2]
    t = s.light_table([("shadow_tile", "float"), ("shadow_m3", "vec4")], 8)
    assert list(t[:5, 0, 0]) == [0.0, 1.0, 2.0, -1.0, 0.0]
    # a spot's last row is -(view z): the distance along its axis; a sun's is (0, 0, 0, 1)
    v, p = S.light_view_proj(s, s.lights[0])
    assert np.array_equal(t[0, 1], (p @ v)[3].astype(np.float32))
    assert np.array_equal(t[2, 1], np.float32([0, 0, 0, 1]))


def test_a_point_light_casts_shadows_into_six_tiles():
    text = HEAD + ('[[lights]]\ntype = "spot"\nposition = [0, 2, 0]\nradius = 4\ncolor = [1, 1, 1]\n'
                   'direction = [0, -1, 0]\ninner_deg = 10\nouter_deg = 30\nshadows = true\n'
                   '[[lights]]\nposition = [0, 2, 0]\nradius = 4\ncolor = [1, 1, 1]\nshadows = true\n')
    s = parse_scene(text)
    assert s.lights[1].shadows and S.first_tiles(s.lights) == {0: 0, 1: 1}
    assert S.tiles_needed(s.lights) == 7 and S.tile_owner(s.lights, 6) == (1, 5)


def test_shadows_need_a_boolean_and_a_narrow_spot():
    spot = ('[[lights]]\ntype = "spot"\nposition = [0, 2, 0]\nradius = 4\ncolor = [1, 1, 1]\n'
            'direction = [0, -1, 0]\ninner_deg = 10\n')
    with pytest.raises(PipegenError, match="must be true or false"):
        parse_scene(HEAD + spot + 'outer_deg = 30\nshadows = "yes"\n')
    with pytest.raises(PipegenError, match="outer_deg <= 84"):
        parse_scene(HEAD + spot + 'outer_deg = 85\nshadows = true\n')
    assert parse_scene(HEAD + spot + 'outer_deg = 85\n').lights[0].shadows is False


def test_tiles_and_projections():
    assert [S.tile_rect(k, 2, 512, 512) for k in range(4)] == [
        (0, 0, 256, 256), (256, 0, 256, 256), (0, 256, 256, 256), (256, 256, 256, 256)]
    assert S.tile_rect(4, 3, 100, 100) == (33, 33, 33, 33)
    s = scene()
    # every object corner lies inside the sun's box, and the spot's apex-side points inside
    # its frustum's depth range map into [0, 1]
    lo, hi = S.scene_bounds(s)
    v, p = S.light_view_proj(s, s.lights[2])
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    c = corners @ (p @ v).T
    assert np.all(np.abs(c[:, :3] / c[:, 3:]) < 1.0)
    light = s.lights[0]
    v, p = S.light_view_proj(s, light)
    axis = np.asarray(light.position) + np.asarray(light.direction) * np.array([[0.5], [9.5]])
    c = np.concatenate([axis, np.ones((2, 1))], axis=1) @ (p @ v).T
    z = c[:, 2] / c[:, 3]
    assert np.all(np.abs(c[:, :2] / c[:, 3:]) < 1e-9) and np.all((z > -1) & (z < 1))


def test_reference_pcf_taps_average_the_compares():
    s = scene()
    maps = shadow_maps(s, 2, ATLAS, ATLAS)
    sm = maps[0]
    P = reference_image(s)[1].position[reference_image(s)[1].coverage]
    f1, f16 = shadow_factor(sm, P, 1, 0.1), shadow_factor(sm, P, 16, 0.1)
    assert set(np.unique(f1)) <= {0.0, 1.0}
    assert set(np.unique(f16 * 16)) <= set(range(17))
    assert 0 < f1.mean() < 1 and np.unique(f16).size > 2      # penumbra steps
    with pytest.raises(ValueError):
        shadow_factor(sm, P, 5, 0.1)


# ---- the language ------------------------------------------------------------------------------

TECH = """technique t "t"
lights[4] {{ position: vec3, radius: float, color: vec3 }}
target color : rgba8
target atlas : d32f size 64 x 64 clear depth 1.0
pass shadow {{
  {draw}
  {extra}
}}
pass shade {{ draw scene writes color fragment {{ color = vec4(1.0); }} }}
"""


def _compile(draw, extra="depth atlas less write"):
    return compile_source(TECH.format(draw=draw, extra=extra), "t.pipe")


def test_draw_from_lights_lowers_to_a_shadow_draw():
    c = _compile("draw scene.opaque from lights spot tiles 3")
    d = c.technique.passes[0].draw
    assert (d.shadow, d.shadow_tiles, d.light_types) == (True, 3, ("spot",))
    assert d.describe() == "scene.opaque from lights spot tiles 3"
    d = _compile("draw scene from lights").technique.passes[0].draw
    assert (d.shadow_tiles, d.light_types) == (1, ("point", "spot", "directional"))
    plan = c.plan("gl").to_dict()
    assert plan["passes"][0]["draw"]["shadow_tiles"] == 3
    # a plain scene draw's plan keeps its old spelling
    assert "shadow_tiles" not in plan["passes"][1]["draw"]


@pytest.mark.parametrize("draw, extra, message", [
    ("draw scene from lights spot spot", "depth atlas less write", "listed twice"),
    ("draw scene from lights tiles 0", "depth atlas less write", "between 1 and 64"),
    ("draw scene from lights", "", "attaches no depth target"),
    ("draw scene from lights", "depth atlas less write writes color fragment { color = vec4(1.0); }",
     "writes only depth"),
    ("draw scene from lights", "depth atlas less write clear atlas depth 1.0", "writes only depth"),
    ("draw scene from lights", "depth atlas less write repeat per light", "cannot also repeat"),
    ("draw scene back_to_front from lights", "depth atlas less write", "keeps the scene order"),
])
def test_draw_from_lights_errors_are_positioned(draw, extra, message):
    with pytest.raises(PipegenError, match=message) as e:
        _compile(draw, extra)
    assert e.value.span is not None and e.value.span.line >= 5


# ---- GL against OpenCL, and against the float64 reference --------------------------------------

@pytest.fixture(scope="module")
def renders():
    """{(technique, taps): {backend: targets}} on the shadow scene."""
    pytest.importorskip("pyopencl")
    return {}


def _render(renders, technique, taps, backend):
    key = (technique, taps, backend)
    if key not in renders:
        c = compile_file(ROOT / f"pipelines/{technique}.pipe",
                         params={"pcf_taps": taps, "shadow_size": ATLAS})
        renders[key] = (c, c.pipeline(backend).render(scene()))
    return renders[key]


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("technique", ["forward", "deferred_calver"])
def test_check_gl_against_cl(technique, tmp_path):
    from pipegen.proof.check import check
    c = compile_file(ROOT / f"pipelines/{technique}.pipe",
                     params={"pcf_taps": 16, "shadow_size": ATLAS})
    result = check(c, scene(), tmp_path)
    assert result.passed, "\n" + result.table()
    rows = {r.name: r for r in result.rows}
    assert rows["shadow_atlas"].max_error == 0          # the atlas bit for bit
    assert rows["color"].max_error <= 1


@pytest.mark.gl
@pytest.mark.cl
def test_atlas_gl_equals_cl_and_matches_the_reference(renders):
    _, gl = _render(renders, "forward", 1, "gl")
    _, cl = _render(renders, "forward", 1, "cl")
    assert np.array_equal(gl["shadow_atlas"].view(np.uint32), cl["shadow_atlas"].view(np.uint32))
    ref = np.ones((ATLAS, ATLAS))
    for sm in shadow_maps(scene(), 2, ATLAS, ATLAS).values():
        x, y, w, h = sm.rect
        ref[y:y + h, x:x + w] = sm.depth
    d = np.abs(gl["shadow_atlas"].astype(np.float64) - ref)
    # float32 depth planes against float64 ones; coverage differs only on primitive edges
    assert np.mean(d < 1e-5) > 0.995, np.mean(d < 1e-5)
    assert np.mean(d) < 2e-6
    assert (gl["shadow_atlas"] < 1).sum() > 0.3 * ATLAS * ATLAS


# Allowance against the reference: a PCF tap whose depth compare lies within float32 rounding
# of the stored depth may flip (float32 runtime against the float64 reference), changing a
# pixel by up to 1/taps of a light; measured (GL and CL alike): forward max 1 / 3 codes (pcf 1 /
# 16), 0 / 2 pixels over 2 codes, mean 0.0007 / 0.0009; deferred_calver max 1 / 2 codes, mean
# 0.074 (its half-float G-buffer and lookup tables), none over 2 codes.
BOUNDS = {"forward": dict(max=3, mean=0.01), "deferred_calver": dict(max=3, mean=0.1)}


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("taps", [1, 16])
@pytest.mark.parametrize("technique", ["forward", "deferred_calver"])
@pytest.mark.parametrize("backend", ["gl", "cl"])
def test_image_against_the_float64_reference(renders, technique, taps, backend):
    c, out = _render(renders, technique, taps, backend)
    s = scene()
    tiles, bias = c.plan(backend).params["shadow_tiles"], c.plan(backend).params["shadow_bias"]
    maps = shadow_maps(s, tiles, ATLAS, ATLAS)
    ref, gb = reference_image(s, shadows=MappedShadows(maps, taps, bias))
    mask = ~gb.silhouette
    e = rgb_error(out["color"], ref, mask)
    over = int((error_image(out["color"], ref).max(axis=2)[mask] > 2).sum())
    assert e["max"] <= BOUNDS[technique]["max"], e
    assert e["mean"] <= BOUNDS[technique]["mean"], e
    assert over <= 0.002 * mask.sum(), over
    # the shadows are there: without them the reference is far off
    unshadowed = rgb_error(out["color"], reference_image(s)[0], mask)
    assert unshadowed["max"] > 100 and unshadowed["mean"] > 0.5, unshadowed


# ---- reports, capacity, specialisation ---------------------------------------------------------

def test_a_technique_without_shadows_says_so():
    c = compile_file(ROOT / "pipelines/deferred.pipe")
    got = [m.message for m in c.mismatches(scene())]
    assert "2 spot lights cast shadows that are not drawn (this technique does not render " \
           "shadows): lit unshadowed" in got
    assert "1 directional light casts shadows that are not drawn (this technique does not " \
           "render shadows): lit unshadowed" in got
    assert not [m for m in compile_file(ROOT / "pipelines/forward.pipe").mismatches(scene())
                if m.kind in ("shadows", "capacity")]


def test_a_draw_from_spot_lights_only_reports_the_suns():
    src = (ROOT / "pipelines/forward.pipe").read_text().replace(
        "from lights point spot directional", "from lights spot")
    c = compile_source(src, str(ROOT / "pipelines/forward.pipe"))
    got = [m.message for m in c.mismatches(scene())]
    assert got == ["1 directional light casts shadows that are not drawn (no shadow-map pass "
                   "draws from directional lights): lit unshadowed"]


@pytest.mark.parametrize("backend", [pytest.param("gl", marks=pytest.mark.gl),
                                     pytest.param("cl", marks=pytest.mark.cl)])
def test_more_shadow_casting_lights_than_tiles_is_refused(backend):
    c = compile_file(ROOT / "pipelines/forward.pipe", params={"shadow_tiles": 1,
                                                              "shadow_size": 256})
    assert [m.kind for m in c.mismatches(scene())] == ["capacity"]
    with pytest.raises(PipegenError, match="3 shadow-casting lights .* 1 x 1 tiles") as e:
        c.pipeline(backend).render(scene())
    assert "shadow_tiles=2" in e.value.hint


def test_specialised_for_a_scene_without_shadows():
    small = load_scene(ROOT / "examples/scenes/small.toml")
    c = compile_file(ROOT / "pipelines/forward.pipe", scene=small)
    plan = c.plan("gl")
    assert [p.name for p in plan.passes] == ["shade"]
    assert "shadow_atlas" not in [t.name for t in plan.targets]
    frag = plan.passes[0].code.fragment
    assert "t_shadow_atlas" not in frag                      # no lookup left
    body = frag.split("float shadow_factor(uint i, vec3 p, vec3 n) {")[1].split("}")[0]
    assert body.split() == ["return", "1.0;"]
    reasons = [cut.reason for cut in c.specialisation.cuts]
    assert any("no light of the scene casts a shadow" in r for r in reasons)
    assert plan.to_dict()["scene"]["shadows"] is False


@pytest.mark.gl
def test_a_no_shadow_variant_refuses_a_scene_with_shadows():
    small = load_scene(ROOT / "examples/scenes/small.toml")
    c = compile_file(ROOT / "pipelines/forward.pipe", scene=small)
    s = dataclasses.replace(small, lights=small.lights + (scene().lights[2],))
    with pytest.raises(PipegenError, match="no shadow-casting lights; this scene has 1"):
        c.pipeline("gl").render(s)


# ---- the sweep's truth: exact visibility -------------------------------------------------------

def test_exact_visibility_agrees_with_the_float64_shadow_maps_off_edges():
    from pipegen.reference.shadows import visibility
    s = scene()
    sun = s.lights[2]
    box = next(o for o in s.objects if o.name == "box")
    centre = box.bounds_centre
    # straight "up the sun" from a floor point behind the box is the box; far away is sky
    behind = centre + np.asarray(sun.direction) * (centre[1] / -sun.direction[1])
    assert visibility(s, sun, np.array([behind, [5.5, 0.0, 5.5]])).tolist() == [0.0, 1.0]
    exact, gb = reference_image(s, shadows=ExactShadows())
    mapped, _ = reference_image(s, shadows=MappedShadows(shadow_maps(s, 2, 2048, 2048), 1, 0.1))
    d = np.abs(exact - mapped).max(axis=2) * 255
    assert np.mean(d <= 2) > 0.98, np.mean(d <= 2)       # shadow edges aside
    assert np.abs(exact - reference_image(s)[0]).max() * 255 > 100   # and there are shadows


@pytest.mark.cl
def test_float64_evaluation_draws_the_same_tiles():
    """The f64 evaluation sets shadow tiles up through their viewport too
    (``cl_geometry.homogeneous_planes(viewport=…)``): its atlas is the float32 one up to
    float32 rounding of the depth plane (measured: 28 ulp), its image within 1 code."""
    c = compile_file(ROOT / "pipelines/forward.pipe", params={"shadow_size": ATLAS})
    s = scene()
    f32 = c.pipeline("cl").render(s)
    f64 = c.pipeline("cl", precision="f64").render(s)
    a32, a64 = f32["shadow_atlas"].astype(np.float64), f64["shadow_atlas"]
    assert np.array_equal(a32 < 1, a64 < 1) or np.mean((a32 < 1) != (a64 < 1)) < 1e-3
    both = (a32 < 1) & (a64 < 1)
    assert np.abs(a32 - a64)[both].max() < 64 * 2.0 ** -24
    rgb = np.clip(f64["color"][..., :3], 0, 1) * 255
    assert np.abs(f32["color"][..., :3] - rgb).max() <= 1.5
