"""lidr_shadow_indexed.pipe (issue 28; Trebilco, "Shadow Maps", option 2 "Final pass"): the
forward pass looks each unpacked light's shadow map up by its light index, and only a declared
light index range casts ("it is recommended that only a limited light index range has
shadows. eg. Light indexes 0...3 have shadows").

- the language: ``draw scene… from lights … first K`` lowered, in the plan, its errors positioned;
- the declared range against the scene: shadow-casting lights past it are named (API, ``pipegen
  run``, an error with --strict) and both runtimes draw them unshadowed (no tile, light-table
  tile -1: the image of the scene without their shadows), the atlas counted for the range only;
- GL against OpenCL (``check``) on four scenes at 64x36: shadows.toml with every light casting
  (point, spot, directional: 9 tiles), overlapping_spot_shadows.toml (four overlapping spots),
  tests/data/point_shadow.toml (a point light's six tiles) and mixed_lights.toml (no shadows);
- error against float64: the float64 shadow maps run through the technique's lookup
  (``MappedShadows`` on the scene as drawn), exact visibility (``ExactShadows``, ray casting)
  away from shadow edges, and the technique's own float64 evaluation (CL, precision f64).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.reference.lighting import reference_image
from pipegen.reference.metrics import error_image, rgb_error
from pipegen.reference.shadows import ExactShadows, MappedShadows, shadow_maps
from pipegen.scene import load_scene
from pipegen.scene import shadows as S

ROOT = Path(__file__).resolve().parents[1]
PIPE = ROOT / "pipelines/lidr_shadow_indexed.pipe"
OVERLAP = ROOT / "examples/scenes/overlapping_spot_shadows.toml"
W, H = 64, 36
ATLAS, TILES = 768, 3                    # the technique's defaults: 9 tiles of 256 texels
# Calver's jittered 4 taps; bias 0.25 as test_point_shadows.py (the point light's far floor)
PARAMS = {"pcf_taps": 4, "pcf_pattern": "jittered", "shadow_bias": 0.25}


def scenes() -> dict:
    s = load_scene(ROOT / "examples/scenes/shadows.toml")
    every = tuple(dataclasses.replace(l, shadows=True) for l in s.lights)
    return {
        "shadows_all": dataclasses.replace(s, lights=every, width=W, height=H),
        "overlapping": load_scene(OVERLAP).with_size(W, H),
        "point": load_scene(ROOT / "tests/data/point_shadow.toml").with_size(W, H),
        "mixed": load_scene(ROOT / "examples/scenes/mixed_lights.toml").with_size(W, H),
    }


@pytest.fixture(scope="module")
def compiled():
    return compile_file(PIPE, params=PARAMS)


# ---- the language: first K ---------------------------------------------------------------------

TECH = """technique t "t"
lights[4] {{ position: vec3, radius: float, color: vec3 }}
target color : rgba8
target atlas : d32f size 64 x 64 clear depth 1.0
param casters = 2
pass shadow {{
  {draw}
  depth atlas less write
}}
pass shade {{ draw scene writes color fragment {{ float first = 0.5; color = vec4(first); }} }}
"""


def test_first_lowers_into_the_draw_and_the_plan():
    from pipegen.backends.plan import draw_from_dict
    c = compile_source(TECH.format(draw="draw scene.opaque from lights spot first casters tiles 2"),
                       "t.pipe")
    d = c.technique.passes[0].draw
    assert (d.shadow_tiles, d.shadow_first) == (2, 2)
    assert d.describe() == "scene.opaque from lights spot first 2 tiles 2"
    spelled = c.plan("gl").to_dict()["passes"][0]["draw"]
    assert spelled["shadow_first"] == 2 and draw_from_dict(spelled) == d
    plain = compile_source(TECH.format(draw="draw scene from lights"), "t.pipe")
    assert "shadow_first" not in plain.plan("gl").to_dict()["passes"][0]["draw"]
    assert plain.technique.passes[0].draw.shadow_first == 0      # every index may cast


@pytest.mark.parametrize("clause, message", [("first 0", "between 1 and 4, not 0"),
                                             ("first 5", "between 1 and 4, not 5"),
                                             ("first 1.5", "integer")])
def test_first_errors_are_positioned(clause, message):
    with pytest.raises(PipegenError, match=message) as e:
        compile_source(TECH.format(draw=f"draw scene from lights {clause}"), "t.pipe")
    span = e.value.span
    assert (span.line, span.source_line[span.column - 1:].split()[0]) == (7, clause.split()[1])


# ---- the declared range against the scene ------------------------------------------------------

def _late_message(first: int, late: str) -> str:
    line = PIPE.read_text().split("\n").index("pass shadow_maps {") + 1
    taken = "index 0" if first == 1 else f"indices 0..{first - 1}"
    return (f"3 lights cast shadows but their indices lie past the range this technique draws "
            f"shadows for ({taken}: `first {first}` in pass 'shadow_maps' ({PIPE}:{line})): "
            f"lights {late} are lit unshadowed; list the shadow-casting lights first in the "
            f"scene, or declare more in `first`")


def test_casters_past_the_range_are_named_and_the_atlas_counts_the_range():
    # one casting index and one tile: the scene's four casters would need four
    c = compile_file(PIPE, params={**PARAMS, "shadow_lights": 1, "shadow_tiles": 1})
    s = load_scene(OVERLAP)
    assert [m.message for m in c.mismatches(s)] == [
        _late_message(1, "1 (spot), 2 (spot), 3 (spot)")]
    drawn = S.casting_below(s, 1)
    assert S.light_fields(drawn, "shadow_tile")[:, 0].tolist() == [0, -1, -1, -1]
    assert S.casting_below(s, 4) is s and not c.mismatches(drawn)
    # the shipped range holds every test scene's casters
    ours = compile_file(PIPE, params=PARAMS)
    for name, scene in scenes().items():
        assert not [m for m in ours.mismatches(scene) if m.kind in ("shadows", "capacity")], name


@pytest.mark.gl
def test_run_warns_and_strict_refuses(tmp_path, capsys):
    from pipegen.cli.main import main
    args = ["run", str(PIPE), "--scene", str(OVERLAP), "-p", "shadow_lights=1",
            "-p", "shadow_tiles=1", "--size", f"{W}x{H}", "-o", str(tmp_path)]
    assert main(args + ["--strict"]) == 1
    err = capsys.readouterr().err
    assert "lidr_shadow_indexed will not render all of" in err and "(--strict)" in err
    assert _late_message(1, "1 (spot), 2 (spot), 3 (spot)") in err
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "will not be rendered: " + _late_message(1, "1 (spot), 2 (spot), 3 (spot)") in err
    assert (tmp_path / "color.png").is_file()


@pytest.mark.gl
def test_casters_past_the_range_are_drawn_unshadowed():
    """K = 2 on the overlapping spots renders, bit for bit, what K = 4 renders of the scene
    whose lights 2 and 3 cast no shadow; and their shadows are missing (K = 4 on the scene
    itself differs by far more than rounding)."""
    s = load_scene(OVERLAP).with_size(W, H)
    two = compile_file(PIPE, params={**PARAMS, "shadow_lights": 2}).pipeline("gl").render(s)
    four = compile_file(PIPE, params=PARAMS).pipeline("gl")
    without = dataclasses.replace(s, lights=s.lights[:2] + tuple(
        dataclasses.replace(l, shadows=False) for l in s.lights[2:]))
    assert np.array_equal(two["color"], four.render(without)["color"])
    assert np.abs(two["color"].astype(int) - four.render(s)["color"]).max() > 50
    tile = ATLAS // TILES
    assert (two["shadow_atlas"][:tile, :2 * tile] < 1).any()       # tiles 0 and 1 drawn
    assert (two["shadow_atlas"][:tile, 2 * tile:] == 1).all()      # no third tile


# ---- GL against OpenCL ---------------------------------------------------------------------------

@pytest.mark.gl
@pytest.mark.cl
def test_check_gl_against_cl_on_four_scenes(compiled, tmp_path):
    pytest.importorskip("pyopencl")
    from pipegen.proof.check import check
    all_scenes = scenes()
    assert S.tiles_needed(all_scenes["shadows_all"].lights) == 9 and {
        l.type for l in all_scenes["shadows_all"].lights if l.shadows} == {
        "point", "spot", "directional"}
    for name, s in all_scenes.items():
        result = check(compiled, s, tmp_path / name)
        assert result.passed, f"{name}\n" + result.table()
        rows = {r.name: r for r in result.rows}
        assert rows["shadow_atlas"].max_error == 0, name        # the tiles bit for bit
        assert rows["lightidx"].max_error == 0, name            # the same light indices
        assert rows["color"].max_error <= 1, name


# ---- against float64 -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def gl_renders(compiled):
    with compiled.pipeline("gl") as p:
        return {name: p.render(s)["color"] for name, s in scenes().items() if name != "mixed"}


def _technique_reference(s):
    """The technique in float64: its shadow maps (the scene as drawn: casters in the range)
    looked up with its pattern, taps and bias for every light it lights."""
    drawn = S.casting_below(s, 4)
    maps = shadow_maps(drawn, TILES, ATLAS, ATLAS)
    return reference_image(drawn, shadows=MappedShadows(maps, PARAMS["pcf_taps"],
                                                         PARAMS["shadow_bias"],
                                                         PARAMS["pcf_pattern"]))


def _off_shadow_edges(s, gb):
    """Covered, non-silhouette pixels whose 3x3 neighbourhood sees one exact visibility of every
    shadow-casting light (at shadow edges a shadow map's texels and PCF differ from the hard
    shadow by design)."""
    keep = gb.coverage & ~gb.silhouette
    h, w = keep.shape
    for i in S.shadow_lights(s.lights):
        vis = np.ones((h, w))
        vis[gb.coverage] = ExactShadows().factor(s, i, s.lights[i], gb.position[gb.coverage])
        pad = np.pad(vis, 1, mode="edge")
        hood = np.stack([pad[y:y + h, x:x + w] for y in range(3) for x in range(3)])
        keep &= hood.min(axis=0) == hood.max(axis=0)
    return keep


@pytest.mark.gl
@pytest.mark.parametrize("name", ["shadows_all", "overlapping", "point"])
def test_image_against_the_float64_technique_and_exact_visibility(gl_renders, name):
    s = scenes()[name]
    out = gl_renders[name]
    ref, gb = _technique_reference(s)
    mask = ~gb.silhouette
    # measured (GL, 64x36): max 1 code, mean <= 0.006; a PCF tap within float32 rounding of
    # the stored depth may flip (1/4 of a light at 4 taps)
    e = rgb_error(out, ref, mask)
    assert e["max"] <= 16 and e["mean"] <= 0.02, e
    assert int((error_image(out, ref).max(axis=2)[mask] > 2).sum()) <= 2
    # exact visibility (ray casting) away from shadow edges: measured at most 1 code
    exact, _ = reference_image(s, shadows=ExactShadows())
    keep = _off_shadow_edges(s, gb)
    assert keep.sum() >= 0.3 * keep.size
    err = error_image(out, exact).max(axis=2)
    assert err[keep].max() <= 3, (err[keep].max(), np.argwhere(keep & (err > 3)).tolist())
    # the shadows are there: without them the reference is far off
    assert rgb_error(out, reference_image(s)[0], mask)["max"] > 80


@pytest.mark.cl
def test_float64_evaluation_of_the_technique(compiled):
    """The technique's arithmetic in double (CL, precision f64) on shadows.toml with every light
    casting: its atlas is the float32 one up to float32 rounding of the depth planes, its image
    within 1.5 codes of the float32 run and within 0.5 codes of the float64 technique reference."""
    pytest.importorskip("pyopencl")
    s = scenes()["shadows_all"]
    f32 = compiled.pipeline("cl").render(s)
    f64 = compiled.pipeline("cl", precision="f64").render(s)
    a32, a64 = f32["shadow_atlas"].astype(np.float64), f64["shadow_atlas"]
    assert np.mean((a32 < 1) != (a64 < 1)) < 1e-3
    both = (a32 < 1) & (a64 < 1)
    assert np.abs(a32 - a64)[both].max() < 64 * 2.0 ** -24
    rgb = np.clip(f64["color"][..., :3], 0, 1) * 255
    assert np.abs(f32["color"][..., :3] - rgb).max() <= 1.5
    ref, gb = _technique_reference(s)                         # top row first
    d = np.abs(rgb[::-1] - np.clip(ref, 0, 1) * 255).max(axis=2)[~gb.silhouette]
    assert d.max() <= 0.5, d.max()          # measured 0.17 codes (mean 0.002)
