"""Scene specialisation (issue 9): scene features, capabilities derived from the IR, the
mismatch report, the scene phases with a reason for every cut, guards, the variant cache, and
the proof that a specialised pipeline renders bit for bit what the general one renders."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from pipegen.ir import nodes as ir, verify as ir_verify
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.compiler.capabilities import capabilities
from pipegen.compiler.mismatches import mismatches
from pipegen.scene.features import scene_features
from pipegen.scene import Light, load_scene
from pipegen.compiler.specialise import SCENE_PHASES, clear_cache, specialise, verify
from pipegen.passes.manager import run_pipeline

import shipped

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "examples/scenes"
SHIPPED = sorted((ROOT / "pipelines").glob("*.pipe"))

SCHEMA = ("lights[8] { position: vec3, radius: float, color: vec3, type: uint, "
          "direction: vec3, cos_inner: float, cos_outer: float }")


def scene(name: str):
    s = load_scene(SCENES / f"{name}.toml")
    return s.with_size(192, 108) if s.width > 192 else s


def with_lights(base, *lights):
    return dataclasses.replace(base, lights=tuple(lights))


POINT = Light("point", (1, 1, 1), position=(0.0, 1.0, 0.0), radius=3.0)
SPOT = Light("spot", (1, 1, 1), position=(0.0, 2.0, 0.0), radius=4.0,
             direction=(0.0, -1.0, 0.0), inner_deg=20, outer_deg=30)
SUN = Light("directional", (1, 1, 1), direction=(0.0, -1.0, 0.0))


# ---- what a scene calls for ----------------------------------------------------------------


def test_scene_features_of_mixed_lights():
    f = scene_features(scene("mixed_lights"))
    assert f.light_counts == (("point", 2), ("spot", 2), ("directional", 1))
    assert f.lights == 5 and f.translucent_objects == 1 and f.opaque_objects > 0
    facts = f.facts()
    assert facts.light_types == ("point", "spot", "directional")
    assert facts.lights == 8                     # rounded up: similar scenes share a variant
    assert facts.translucent


# ---- what a technique renders: derived from the IR ------------------------------------------

SPHERES_ONLY = f"""
technique spheres "point lights through sphere volumes"
{SCHEMA}
target color : rgba8 clear 0
target ds : d24s8 clear depth 1.0 stencil 0
output color
pass z {{ draw scene.opaque depth ds less write }}
pass lit {{
  draw lights as sphere
  writes color
  depth ds gequal nowrite
  cull front
  blend color add(one, one)
  fragment {{ color = vec4(light.color * 0.1, 1.0); }}
}}
"""

EVERY_TYPE = f"""
technique every_type "cones for spots, quads for directional lights"
{SCHEMA}
target color : rgba8 clear 0
target ds : d24s8 clear depth 1.0 stencil 0
output color
float cone(uint type_, float c) {{
  if (type_ == 1u) return c;
  return 1.0;
}}
pass z {{ draw scene.opaque depth ds less write }}
pass points {{
  draw lights as sphere point
  writes color
  depth ds gequal nowrite
  cull front
  blend color add(one, one)
  fragment {{ color = vec4(light.color * 0.1 * cone(light.type, light.cos_outer), 1.0); }}
}}
pass spots {{
  draw lights as cone spot
  writes color
  depth ds gequal nowrite
  cull front
  blend color add(one, one)
  fragment {{ color = vec4(light.color * 0.1 * cone(light.type, light.cos_outer), 1.0); }}
}}
pass suns {{
  draw lights as quad directional
  writes color
  blend color add(one, one)
  fragment {{ color = vec4(light.direction * 0.1, 1.0); }}
}}
"""


def test_capabilities_are_derived_from_the_draws_and_the_fields_read():
    caps = capabilities(compile_source(SPHERES_ONLY).technique)
    assert caps.light_type("point") == "rendered"
    assert caps.light_type("spot").startswith("lit as point lights")
    assert caps.light_type("directional").startswith("not drawn")
    assert not caps.translucent
    caps = capabilities(compile_source(EVERY_TYPE).technique)
    assert all(how == "rendered" for _, how in caps.light_types)


def test_a_mismatch_is_never_silent():
    base = scene("mixed_lights")
    messages = [m.message for m in mismatches(compile_source(SPHERES_ONLY).technique, base)]
    assert messages == [
        "2 spot lights are lit as point lights (the technique reads no cone angle)",
        "1 directional light is not drawn (its light volumes do not cover a directional light)",
        "1 translucent object is not drawn (no pass draws scene.translucent)"]
    assert [m.kind for m in mismatches(compile_source(EVERY_TYPE).technique, base)] == [
        "translucent"]


def test_capacity_mismatch_names_the_packing():
    c = compile_file(ROOT / "pipelines/lidr_bitplanes.pipe")
    got = mismatches(c.technique, scene("stress_overlap"))
    capacity = [m.message for m in got if m.kind == "capacity"]
    assert len(capacity) == 1 and "the packing `slots` (bitplanes) holds 4" in capacity[0]
    assert int(capacity[0].split()[0]) > 4          # "N point/spot lights reach the surface"
    assert capacity[0].endswith("lights will be dropped")


# ---- the scene phases, with reasons ----------------------------------------------------------

TRANSLUCENT_LAYER = f"""
technique layered "a translucent layer tinted by a table"
{SCHEMA}
target color : rgba8 clear 0
target tint : rgba8 clear 0
target ds : d24s8 clear depth 1.0 stencil 0
output color
pass opaque {{ draw scene.opaque writes color depth ds less write
              fragment {{ color = vec4(albedo, 1.0); }} }}
pass tabulate {{ draw fullscreen writes tint fragment {{ tint = vec4(0.5); }} }}
pass layer {{ draw scene.translucent reads tint writes color depth ds less nowrite
             blend color add(src_alpha, one_minus_src_alpha)
             fragment {{ color = vec4(albedo, 0.5) * load(tint); }} }}
"""


def _phases(tech, facts):
    """The scene phases, the IR verifier after each."""
    tech = dataclasses.replace(tech, scene=facts)
    return run_pipeline(SCENE_PHASES, tech, verify_each=True)[0]


def test_light_type_branches_fold_through_function_parameters():
    tech = compile_source(EVERY_TYPE).technique
    out = _phases(tech, ir.SceneFacts(("point",), 8, False))
    reasons = [c.describe() for c in out.cuts]
    assert ("branch `type_ == spot` removed: in function `cone`: always false, the scene has "
            "no spot lights") in reasons
    assert "pass `spots` culled: it draws lights as cone spot and the scene has no spot " \
           "lights" in reasons
    assert [p.name for p in out.passes] == ["z", "points"]
    # with spots present the branch stays
    kept = _phases(tech, ir.SceneFacts(("point", "spot"), 8, False))
    assert not [c for c in kept.cuts if c.kind == "branch"]


def test_culled_pass_chains_to_its_target():
    out = _phases(compile_source(TRANSLUCENT_LAYER).technique,
                  ir.SceneFacts(("point",), 8, False))
    assert [c.describe() for c in out.cuts] == [
        "pass `layer` culled: it draws scene.translucent and the scene has no translucent "
        "objects",
        "pass `tabulate` culled: it writes `tint`, read only by culled pass `layer`",
        "target `tint` culled: used only by culled passes `tabulate`, `layer`"]
    assert [p.name for p in out.passes] == ["opaque"]
    assert [t.name for t in out.targets] == ["color", "ds"]
    # with translucent objects nothing is cut
    assert not _phases(compile_source(TRANSLUCENT_LAYER).technique,
                       ir.SceneFacts(("point",), 8, True)).cuts


def test_repeat_group_feeds_an_earlier_pass_for_the_next_light():
    """``b`` writes `carry`, which `a` reads for the next light: both stay live."""
    src = f"""
technique loop "a repeat group whose second pass feeds the first"
{SCHEMA}
target color : rgba8 clear 0
target carry : rgba8 clear 0
target spare : rgba8 clear 0
output color
repeat per light {{
  pass a {{ draw fullscreen reads carry writes color
           fragment {{ color = load(carry) + vec4(0.1); }} }}
  pass b {{ draw fullscreen reads color writes carry
           fragment {{ carry = load(color); }} }}
}}
pass unused {{ draw fullscreen writes spare fragment {{ spare = vec4(1.0); }} }}
"""
    out = _phases(compile_source(src).technique, ir.SceneFacts(("point",), 8, False))
    assert [p.name for p in out.passes] == ["a", "b"]
    assert [c.describe() for c in out.cuts] == [
        "pass `unused` culled: it writes `spare`, which nothing reads",
        "target `spare` culled: used only by culled pass `unused`"]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_every_shipped_technique_specialises_and_verifies(path):
    for name in ("small", "translucent_layers", "mixed_lights"):
        special = compile_file(path, scene=scene(name), verify_each=True)
        ir_verify.verify(special.technique)
        assert special.specialisation.facts == scene_features(scene(name)).facts()


def test_cuts_where_the_scene_lacks_something():
    """inferred without translucent objects, Calver without spot lights."""
    small = scene("small")
    inferred = compile_file(ROOT / "pipelines/inferred.pipe", scene=small)
    assert any(c.kind == "pass" and "no translucent objects" in c.reason
               for c in inferred.specialisation.cuts)
    calver = compile_file(ROOT / "pipelines/deferred_calver.pipe", scene=small)
    assert any(c.kind == "pass" and "no spot lights" in c.reason
               for c in calver.specialisation.cuts)
    assert "scene specialisation" in calver.report()


def test_light_table_shrinks_to_a_power_of_two():
    c = compile_file(ROOT / "pipelines/forward.pipe", scene=scene("small"))
    assert c.technique.lights.capacity == 4 and dict(c.specialisation.params) == {
        "max_lights": 4}
    assert c.specialisation.cuts[0].describe().startswith("table `lights` shrunk: 128 -> 4")


def test_variants_are_cached_by_scene_features():
    clear_cache()
    small = scene("small")
    first = compile_file(ROOT / "pipelines/deferred.pipe", scene=small)
    moved = dataclasses.replace(small, lights=tuple(
        dataclasses.replace(l, position=(l.position[0] + 0.5,) + tuple(l.position[1:]))
        for l in small.lights))
    again = compile_file(ROOT / "pipelines/deferred.pipe", scene=moved)
    assert not first.specialisation.reused and again.specialisation.reused
    assert again.technique is first.technique
    other = compile_file(ROOT / "pipelines/deferred.pipe", scene=with_lights(small, SPOT))
    assert not other.specialisation.reused


# ---- guards and proof (render) -----------------------------------------------------------------


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("backend", ["gl", "cl"])
def test_specialised_pipeline_refuses_a_scene_that_breaks_its_facts(backend):
    points = with_lights(scene("small"), POINT)
    c = compile_file(ROOT / "pipelines/deferred.pipe", scene=points)
    pipe = c.pipeline(backend)
    pipe.render(points)
    with pytest.raises(PipegenError, match="specialised for 0 spot lights; this scene has 1"):
        pipe.render(with_lights(points, POINT, SPOT))


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("path", shipped.params(path=True))
def test_specialised_renders_what_the_general_renders(path):
    """For every shipped technique and example scene: bit for bit on both backends."""
    general = compile_file(path)
    for name in ("small", "mixed_lights", "translucent_layers", "edges", "stress_overlap",
                 "many_lights"):
        s = scene(name)
        special = compile_file(path, scene=s)
        result = verify(general, special, s)
        assert result.identical, (name, result.differences, result.first_difference)
        assert all(result.compared.values())


@pytest.mark.gl
@pytest.mark.cl
def test_verify_finds_a_wrong_specialisation():
    """A "specialisation" that wrongly drops a live pass is caught and the pass named."""
    general = compile_file(ROOT / "pipelines/forward_multipass.pipe")
    s = scene("small")
    special = specialise(general, s)
    tech = special.technique
    broken = dataclasses.replace(tech, passes=tuple(p for p in tech.passes
                                                    if p.name != tech.passes[-1].name))
    wrong = dataclasses.replace(special, technique=broken, _plans={})
    result = verify(general, wrong, s, backends=("gl",))
    assert not result.identical
    assert result.first_difference["gl"] is not None


def test_specialised_plan_carries_its_facts_through_plain_data():
    from pipegen.backends.plan import plan_from_dict
    c = compile_file(ROOT / "pipelines/deferred.pipe", scene=scene("small"))
    for backend in ("gl", "cl"):
        plan = c.plan(backend)
        assert plan.scene == c.specialisation.facts
        assert plan_from_dict(plan.to_dict()) == plan
    assert "scene" not in compile_file(ROOT / "pipelines/deferred.pipe").plan("gl").to_dict()


def test_folded_branch_keeps_its_scope():
    """``if (type_ != 1u) { float r …; return …; } float r …``: folded to always-true, the
    branch must stay a block (spliced, ``r`` would be declared twice)."""
    src = f"""
technique scoped "a folded branch that declares a local"
{SCHEMA}
target color : rgba8 clear 0
output color
float reach(uint type_, float radius) {{
  if (type_ != 1u) {{
    float r = radius * 2.0;
    return r;
  }}
  float r = radius * 0.5;
  return r;
}}
repeat per light {{
  pass p {{ draw fullscreen writes color blend color add(one, one)
           fragment {{ color = vec4(reach(light.type, light.radius) * 0.01); }} }}
}}
"""
    out = _phases(compile_source(src).technique, ir.SceneFacts(("point",), 8, False))
    assert [c.name for c in out.cuts] == ["type_ != spot"]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_mismatch_report_of_every_shipped_technique_on_mixed_lights(path):
    """Every shipped technique draws every light type (issue 12); all but inferred lighting
    and lidr_transparent leave translucent objects out, and none runs out of light-index
    capacity here (the LIDRs keep directional lights in a buffer of their own, so 2 point + 2
    spot lights fit in 4)."""
    got = [m.message for m in compile_file(path).mismatches(scene("mixed_lights"))]
    expected = [] if path.stem in ("inferred", "lidr_transparent") else [
        "1 translucent object is not drawn (no pass draws scene.translucent)"]
    assert got == expected


def test_a_variant_without_the_shrunk_table_is_not_reused_for_one_with_it():
    """Compiled.specialise keeps the light table (it cannot recompile); compile_file(scene=)
    shrinks it.  Both are cached by technique and facts: the one asked for first must not be
    handed out for the other (the suite once got a 128-light 'variant' from compile_file)."""
    clear_cache()
    small = scene("small")
    kept = compile_file(ROOT / "pipelines/forward.pipe").specialise(small)
    assert kept.technique.lights.capacity == 128
    shrunk = compile_file(ROOT / "pipelines/forward.pipe", scene=small)
    assert shrunk.technique.lights.capacity == 4 and not shrunk.specialisation.reused
    again = compile_file(ROOT / "pipelines/forward.pipe").specialise(small)
    assert again.technique.lights.capacity == 128 and again.specialisation.reused


def test_a_pass_looping_over_the_light_table_reaches_every_light_type():
    """StarCraft II's layout forward-lits directional lights in its G-buffer pass (a loop over
    the light table) and draws volumes for the rest: no light type is reported undrawn.  A
    LIDR's loop over the indices its packing holds is not such a loop: its directional lights
    are covered by their own index buffer, not by this rule."""
    from pipegen.compiler.capabilities import _table_loop_passes, capabilities
    from pipegen.compiler.driver import compile_file
    root = Path(__file__).resolve().parents[1]
    sc2 = compile_file(str(root / "examples/techniques/starcraft2_gbuffer.pipe")).technique
    assert [p.name for p in _table_loop_passes(sc2)] == ["gbuffer"]
    assert dict(capabilities(sc2).light_types)["directional"] == "rendered"
    lidr = compile_file(str(root / "pipelines/lidr_bitplanes.pipe")).technique
    assert _table_loop_passes(lidr) == []
