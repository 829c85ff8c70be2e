"""``draw scene… within light radius``: a ``repeat per light`` pass draws, per light, only the
objects whose bounds come within the light's radius (multi-pass forward's object-light
selection, Trebilco 2007).  The objects left out would have added zeros, so every image is
bit for bit the one drawing every object, on both backends; the float64 evaluation draws
every object, so a pass whose light does not vanish beyond its radius shows against it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.backends.plan import REACH_WORDS
from pipegen.ir import nodes as ir
from pipegen.runtime import draws
from pipegen.scene import load_scene

pytestmark = [pytest.mark.gl, pytest.mark.cl]

ROOT = Path(__file__).resolve().parents[1]
MIXED = ROOT / "examples/scenes/mixed_lights.toml"        # point, spot and directional lights
MANY = ROOT / "examples/scenes/many_lights.toml"
DRAW = ir.Draw(ir.DrawKind.SCENE, material=("opaque",), within=True)

# a technique of its own: one light pass per light, Lambert with a falloff of its own: VANISHES
# (0 from the radius on) or LINGERS (1 / (1 + d^2), which does not vanish at the radius: the
# {within} clause is then a false claim)
OWN = """technique own_multipass "Lambert per light, inverse-square falloff"
param max_lights = 128
lights[max_lights] {{ position: vec3, radius: float, color: vec3 }}
target accum : rgba16f clear (0, 0, 0, 1)
target ds    : d24s8 clear depth 1.0
output accum
pass base {{
  draw scene.opaque
  writes accum
  depth ds less write
  cull back
  fragment {{ accum = vec4(0.05 * albedo, 1.0); }}
}}
pass per_light {{
  draw scene.opaque {within}
  repeat per light
  writes accum
  depth ds equal nowrite
  cull back
  blend accum rgb add(one, one) alpha add(zero, one)
  fragment {{
    vec3 d = light.position - world_pos;
    float lambert = max(dot(normalize(normal), normalize(d)), 0.0);
    accum = vec4(light.color * albedo * lambert * {falloff}, 0.0);
  }}
}}
"""
VANISHES = "max(1.0 - dot(d, d) / (light.radius * light.radius), 0.0)"
LINGERS = "(1.0 / (1.0 + dot(d, d)))"


def _bits(table: np.ndarray) -> np.ndarray:
    """(lights, 256) bools of a reach table."""
    return np.unpackbits(table.view(np.uint8), axis=1, bitorder="little").astype(bool)


@pytest.mark.parametrize("path, share", [(MIXED, 0.05), (MANY, 0.9)])
def test_an_object_left_out_lies_beyond_the_light_radius(path, share):
    """Conservative: every object id a light does not reach has all its vertices farther from
    the light than its radius; a directional light reaches every object; and the selection
    leaves objects out (of the (point or spot light, object) pairs: mixed_lights 1 of 12,
    many_lights all but about 5 objects per light of 101)."""
    scene = load_scene(path)
    bits = _bits(draws.reach_table(scene, DRAW))
    objects = list(scene.select(("opaque",)))
    left_out = 0
    for i, light in enumerate(scene.lights):
        for o in objects:
            if draws.light_type(light) == "directional":
                assert bits[i, o.id]
                continue
            if not bits[i, o.id]:
                left_out += 1
                d = np.linalg.norm(o.positions - np.asarray(light.position), axis=1)
                assert d.min() > light.radius, (i, o.name)
    pairs = len(objects) * sum(draws.light_type(l) != "directional" for l in scene.lights)
    assert left_out >= share * pairs, (left_out, pairs)


def test_reached_runs_submit_exactly_the_reached_triangles():
    table = np.zeros((1, REACH_WORDS), np.uint32)
    table[0, 0] = 0b1010          # ids 1 and 3
    table[0, 7] = 1 << 31         # id 255
    ids = np.array([0, 1, 1, 2, 3, 3, 3, 0, 255, 1])
    assert draws.reached_runs(table, 0, ids) == [(3, 6), (12, 9), (24, 6)]
    assert draws.reached_runs(table, 0, np.array([0, 2])) == []


def _render_pair(compiled, scene, backend, monkeypatch):
    """(the image with the selection, the image with every light reaching every object)."""
    with_selection = compiled.pipeline(backend).render(scene)
    with monkeypatch.context() as m:
        m.setattr(draws, "reach_table", lambda s, d: np.full(
            (len(s.lights), REACH_WORDS), 0xFFFFFFFF, np.uint32))
        every = compiled.pipeline(backend).render(scene)
    return with_selection, every


def _nothing(compiled, scene, backend, monkeypatch):
    """The image with no light reaching any object."""
    with monkeypatch.context() as m:
        m.setattr(draws, "reach_table", lambda s, d: np.zeros(
            (len(s.lights), REACH_WORDS), np.uint32))
        return compiled.pipeline(backend).render(scene)


@pytest.mark.parametrize("backend", ["gl", "cl"])
def test_multipass_forward_renders_bit_for_bit_what_drawing_every_object_does(
        backend, monkeypatch):
    """forward_multipass (`within light radius`) on a scene with every light type: every
    target's codes equal those of the same pipeline with the selection switched off, and
    selecting nothing changes the image (the selection is in effect)."""
    from pipegen.compiler.driver import compile_file
    scene = load_scene(MIXED).with_size(64, 36)
    compiled = compile_file(ROOT / "pipelines/forward_multipass.pipe")
    selected, every = _render_pair(compiled, scene, backend, monkeypatch)
    for name in every:
        assert np.array_equal(selected[name].view(np.uint8), every[name].view(np.uint8)), name
    nothing = _nothing(compiled, scene, backend, monkeypatch)
    assert not np.array_equal(nothing["accum"].view(np.uint8), every["accum"].view(np.uint8))


@pytest.mark.parametrize("backend", ["gl", "cl"])
def test_a_pass_drawn_light_by_light_selects_alike(backend, monkeypatch, tmp_path):
    """The technique of its own with a second pass in the light's repeat group: CL draws each
    light's passes one launch each (a run of lights in one launch takes a pass alone in its
    group), skipping triangles per light; the image is still bit for bit the one drawing
    every object."""
    from pipegen.compiler.driver import compile_file
    from pipegen.backends.opencl.programs import batches_lights
    text = OWN.format(within="within light radius", falloff=VANISHES)
    light_pass = text[text.index("pass per_light {"):]
    grouped = text[:text.index("pass per_light {")] + "repeat per light {\n" + \
        light_pass.replace("  repeat per light\n", "") + \
        light_pass.replace("  repeat per light\n", "").replace("per_light", "again") + "}\n"
    path = tmp_path / "own_grouped.pipe"
    path.write_text(grouped)
    compiled = compile_file(path)
    plan = compiled.plan("cl")
    assert not any(batches_lights(plan, p) for p in plan.passes)
    scene = load_scene(MANY).with_size(48, 27)
    selected, every = _render_pair(compiled, scene, backend, monkeypatch)
    for name in every:
        assert np.array_equal(selected[name].view(np.uint8), every[name].view(np.uint8)), name
    nothing = _nothing(compiled, scene, backend, monkeypatch)
    assert not np.array_equal(nothing["accum"].view(np.uint8), every["accum"].view(np.uint8))


def test_gl_submits_fewer_vertices_per_light():
    """On many_lights each light's draw submits only the runs of the objects it reaches."""
    scene = load_scene(MANY)
    table = draws.reach_table(scene, DRAW)
    g = draws.scene_geometry(scene, DRAW)
    object_ids = draws.triangle_ids(g)[:, 0]
    counts = [sum(n for _, n in draws.reached_runs(table, i, object_ids))
              for i in range(len(scene.lights))]
    assert max(counts) < g.vertex_count // 2 and min(counts) > 0


def test_the_float64_evaluation_draws_every_object():
    from pipegen.backends import registry
    from pipegen.backends.opencl.programs import reaches_by_object
    from pipegen.compiler.driver import compile_file
    compiled = compile_file(ROOT / "pipelines/forward_multipass.pipe")
    f32 = compiled.plan("cl")
    f64 = registry.get("cl").emit(compiled.technique, "f64")
    k = next(i for i, p in enumerate(f32.passes) if p.name == "per_light")
    assert reaches_by_object(f32, f32.passes[k]) and not reaches_by_object(f64, f64.passes[k])
    assert "pg_reach" in compiled.pipeline("cl").source(k)
    assert "pg_reach" not in compiled.pipeline("cl", precision="f64").source(k)


def test_a_false_claim_shows_against_the_float64_evaluation(tmp_path):
    """A user's pass whose light does not vanish at the radius: with `within light radius`
    both backends still agree (they draw the same objects), but the float32 render leaves
    light out that the float64 evaluation (every object drawn) has."""
    from pipegen.testing import assert_backends_agree, assert_close_to_f64
    scene = load_scene(MANY).with_size(48, 27)
    honest = tmp_path / "honest.pipe"
    honest.write_text(OWN.format(within="", falloff=LINGERS))
    claimed = tmp_path / "claimed.pipe"
    claimed.write_text(OWN.format(within="within light radius", falloff=LINGERS))
    assert_close_to_f64(honest, scene, backends=("cl",))
    assert_backends_agree(claimed, scene)
    with pytest.raises(AssertionError, match="float64 evaluation") as e:
        assert_close_to_f64(claimed, scene, backends=("cl",))
    assert "only the objects within each light's radius" in str(e.value)


def _compile_error(text: str) -> str:
    from pipegen.compiler.driver import compile_source
    from pipegen.core.diagnostics import PipegenError
    with pytest.raises(PipegenError) as e:
        compile_source(text, "t.pipe")
    return e.value.render()


def test_outside_a_repeat_group_is_a_positioned_error():
    text = OWN.format(within="", falloff=VANISHES).replace("  draw scene.opaque\n  writes accum\n  depth ds less",
                                         "  draw scene.opaque within light radius\n"
                                         "  writes accum\n  depth ds less")
    got = _compile_error(text)
    line = text[:text.index("within")].count("\n") + 1
    col = text.index("within") - text.rfind("\n", 0, text.index("within"))
    assert got.startswith(f"t.pipe:{line}:{col}: error: pass 'base' draws the objects within "
                          f"a light's radius but does not repeat per light"), got
    assert "^" in got and "hint" in got


def test_a_schema_without_radius_is_a_positioned_error():
    text = OWN.format(within="within light radius", falloff=VANISHES).replace(
        "lights[max_lights] { position: vec3, radius: float, color: vec3 }",
        "lights[max_lights] { position: vec3, color: vec3 }")
    got = _compile_error(text)
    assert "`within light radius` needs the light field(s) radius" in got, got
    assert got.startswith("t.pipe:") and "^" in got


def test_the_clause_round_trips_through_the_plan_and_names_itself():
    from pipegen.backends.plan import plan_from_dict
    from pipegen.compiler.driver import compile_file
    compiled = compile_file(ROOT / "pipelines/forward_multipass.pipe")
    p = next(p for p in compiled.technique.passes if p.name == "per_light")
    assert p.draw.within and p.draw.describe() == "scene.opaque within light radius"
    d = compiled.plan("gl").to_dict()
    again = plan_from_dict(d).passes[[q["name"] for q in d["passes"]].index("per_light")]
    assert again.draw == p.draw


def test_at_more_than_one_sample_is_a_positioned_error():
    """Shading at the pixel centre of a partly covered pixel reads positions outside the
    triangle: no bound on how far outside the object's box they lie."""
    text = OWN.format(within="within light radius", falloff=VANISHES).replace(
        ": rgba16f clear", ": rgba16f samples 4 clear").replace(
        ": d24s8 clear", ": d24s8 samples 4 clear")
    got = _compile_error(text)
    at = text.index("within light radius")
    line, col = text[:at].count("\n") + 1, at - text.rfind("\n", 0, at)
    assert got.startswith(f"t.pipe:{line}:{col}: error: pass 'per_light' draws the objects "
                          f"within a light's radius at 4 samples"), got
