"""Discontinuities (pipegen/proof/discontinuity.py, docs/tolerances.md): a technique whose own
code steps renders different values where float32 and float64 (or GL and CL) take different
sides of the step.  One verdict: ``check --precision f64``, ``stress`` and
``pipegen.testing`` count those pixels as discontinuities, naming the expression, not as
precision failures.

The toon-shaded technique (examples/techniques/toon_deferred.pipe) quantises its lighting
with ``floor(x * bands)`` on a normal read back from an rgba8 G-buffer: the float32 runs read
the normal rounded to 8 bits, the float64 evaluation the exact one, and at a few pixels the
band differs by a whole step (a quarter of the light)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pipegen
from pipegen.ir import nodes as ir, printer
from pipegen.proof.discontinuity import LEVELS, nudged, sites

ROOT = Path(__file__).resolve().parent.parent
TOON = ROOT / "examples" / "techniques" / "toon_deferred.pipe"
SIZE = (96, 64)


def test_sites_are_the_steps_with_where_they_were_written():
    c = pipegen.compile_file(TOON)
    found = sites(c.technique)
    texts = [s.text for s in found]
    # the band's floor, as written (the parameter not yet substituted in the text); the
    # loop's `uint(i) >= num_lights` compares integers: no step of a float
    assert texts == ["floor(x * bands)"], texts
    s = found[0]
    assert (Path(s.span.file).name, s.span.line, s.span.column) == ("toon_deferred.pipe", 15, 10)
    assert s.where == "function band"
    assert "toon_deferred.pipe:15:10" in s.describe()


def test_every_kind_of_step_is_a_site_and_nudges_only_its_input():
    src = """
technique steps "steps"
target color : rgba8 clear 0
output color
pass p {
  draw fullscreen
  writes color
  fragment {
    float x = frag_coord.x / 64.0;
    float a = x < 0.5 ? 1.0 : 0.0;
    float b = step(0.25, x) + fract(x * 3.0) + sign(x - 0.5) + mod(x, 0.3);
    uint k = uint(x * 7.0);
    float c = round(x) + ceil(x);
    if (x >= 0.75) discard;
    color = vec4(a, b, float(k) / 7.0, c);
  }
}
"""
    c = pipegen.compile_source(src, "steps.pipe")
    texts = [s.text for s in sites(c.technique)]
    assert texts == ["x < 0.5", "step(0.25, x)", "fract(x * 3.0)", "sign(x - 0.5)",
                     "mod(x, 0.3)", "uint(x * 7.0)", "round(x)", "ceil(x)", "x >= 0.75"], texts
    # nudging one site rewrites that expression's input and nothing else
    before = printer.print_technique(c.technique)
    one = printer.print_technique(nudged(c.technique, LEVELS[-1], only=5))
    changed = [(a, b) for a, b in zip(before.splitlines(), one.splitlines()) if a != b]
    assert len(changed) == 1 and "uint(x * 7.0 + 0.015625 * (abs(x * 7.0) + 1.0))" in \
        changed[0][1], changed
    every = printer.print_technique(nudged(c.technique, -LEVELS[0]))
    assert every.count("-0.00024414062 * (") == 9     # 2^-12, as the printer spells it


STEPS = """
technique steps "every kind of step, each on its own channel"
target color : rgba32f clear 0
target more  : rgba32f clear 0
output color
pass p {
  draw fullscreen
  writes color, more
  fragment {
    float x = frag_coord.x / 64.0 + frag_coord.y / 4096.0;
    float a = x < 0.5 ? 1.0 : 0.0;
    float b = step(0.25, x) + fract(x * 3.0) + sign(x - 0.5) + mod(x, 0.3);
    uint k = uint(x * 7.0);
    float c = round(x * 4.0) + ceil(x * 2.0) + floor(x * 5.0);
    color = vec4(a, b, float(k) / 7.0, c);
    more = vec4(floor(vec3(x * 9.0, x * 11.0, x * 13.0)), x >= 0.75 ? 1.0 : 0.0);
  }
}
"""


@pytest.mark.cl
def test_run_time_nudges_render_what_each_recompiled_variant_renders():
    """One float64 program reads every site's nudge at run time (``nudged_at_run_time``):
    nudging nothing renders the technique bit for bit, and each set of sites nudged by a
    level renders what the variant compiled with that constant renders, bit for bit."""
    from pipegen.compiler.driver import Compiled
    from pipegen.proof.discontinuity import nudged_at_run_time
    c = pipegen.compile_source(STEPS, "steps.pipe")
    n = len(sites(c.technique))
    assert n == 11
    scene = pipegen.default_scene().with_size(64, 8)
    run_time = Compiled(nudged_at_run_time(c.technique), c.params).pipeline("cl", precision="f64")
    base = c.pipeline("cl", precision="f64").render(scene)
    run_time.nudge({})
    still = run_time.render(scene)
    for key in base:
        assert np.array_equal(base[key], still[key]), key
    moved = 0
    for delta, only in ((LEVELS[-1], frozenset(range(n))), (-LEVELS[-1], frozenset({1, 5, 10})),
                        (LEVELS[0], frozenset({2})), (LEVELS[-1], frozenset({9}))):
        fixed = Compiled(nudged(c.technique, delta, only), c.params) \
            .pipeline("cl", precision="f64").render(scene)
        run_time.nudge({k: delta for k in only})
        got = run_time.render(scene)
        for key in fixed:
            assert np.array_equal(fixed[key], got[key]), (delta, sorted(only), key)
        moved += any(not np.array_equal(base[k], got[k]) for k in base)
    assert moved == 4          # every nudge flipped something: the comparison is not vacuous


def test_a_technique_without_steps_has_no_sites():
    # a shipped technique's steps are where its source says: each site's text is on its line
    c = pipegen.compile_file(ROOT / "pipelines" / "deferred.pipe")
    found = sites(c.technique)
    assert found
    for s in found:
        if s.span is not None:
            assert s.text in Path(s.span.file).read_text().splitlines()[s.span.line - 1], s
        assert s.passes, s          # every step runs in some pass
    src = """
technique smooth "no steps"
target color : rgba8 clear 0
output color
pass p { draw fullscreen writes color fragment { color = vec4(frag_coord.x / 64.0); } }
"""
    assert sites(pipegen.compile_source(src).technique) == []


@pytest.mark.gl
@pytest.mark.cl
def test_toon_precision_verdict_passes_and_reports_the_discontinuity_as_one():
    """The issue's two verdicts made one: the float32 runs are within the bound of the float64
    evaluation everywhere except at pixels that took the other side of `floor(x * bands)`,
    and those are reported as discontinuities of that expression with their locations."""
    from pipegen.proof.precision import precision_check
    c = pipegen.compile_file(TOON)
    scene = pipegen.default_scene().with_size(*SIZE)
    result = precision_check(c, scene)
    for backend in ("gl", "cl"):
        rows = {r.key: r for r in result.rows[backend]}
        assert all(r.passed for r in rows.values()), \
            [(k, r.over, r.worst_ratio) for k, r in rows.items() if not r.passed]
        color = rows["color"]
        assert color.discontinuity_count > 0
        assert {d.site.text for d in color.discontinuities} == {"floor(x * bands)"}
        d = color.discontinuities[0]
        assert len(d.locations) == min(d.count, 20)
        # at each location the float32 value really is a band away from the float64 one,
        # more than the pixel's bound: a choice the step made, not rounding
        h = color.discontinuity_mask.shape[0]
        for x, y in d.locations:
            assert color.discontinuity_mask[h - 1 - y, x]
        # the intermediate targets are continuous
        assert all(rows[k].discontinuity_count == 0 for k in ("galbedo", "gnormal", "gpos"))
    # the same verdict in stress (the quick cases' base scene is this one)
    from pipegen.tools.stress import stress
    res = stress(c, scene, cases="base", size=SIZE)[0]
    assert res.status == "ok", res.status
    disc = {t.backend: t.discontinuity_count for t in res.targets if t.key == "color"}
    assert disc == {b: {r.key: r for r in result.rows[b]}["color"].discontinuity_count
                    for b in ("gl", "cl")}


@pytest.mark.gl
@pytest.mark.cl
def test_toon_with_the_testing_api_needs_the_discontinuities_allowed():
    from pipegen.testing import ComparisonFailure, assert_close_to_f64
    with pytest.raises(ComparisonFailure) as e:
        assert_close_to_f64(TOON, size=SIZE)
    msg = str(e.value)
    assert "different sides of a step" in msg and "floor(x * bands)" in msg
    assert "toon_deferred.pipe:15:10" in msg and "max_discontinuities=0" in msg
    result = assert_close_to_f64(TOON, size=SIZE, max_discontinuities=64)
    assert 0 < result.discontinuities() <= 64


BLEND8 = """
technique blend8 "Multi-pass forward, each light added straight into the rgba8 output"
include "common/lighting.pipe"
param max_lights = 16
lights[max_lights] { position: vec3, radius: float, color: vec3, type: uint,
                     direction: vec3, cos_inner: float, cos_outer: float }
target color : rgba8 clear (0, 0, 0, 1)
target ds    : d24s8 clear depth 1.0 stencil 0
output color
pass ambient_pass {
  draw scene.opaque
  writes color
  depth ds less write
  cull back
  fragment { color = vec4(ambient * albedo, 1.0); }
}
pass per_light {
  draw scene.opaque
  repeat per light
  writes color
  depth ds equal nowrite
  cull back
  blend color rgb add(one, one) alpha add(zero, one)
  fragment {
    vec3 c = light_any(light.type, light.position, light.radius, light.color, light.direction,
                       light.cos_inner, light.cos_outer,
                       world_pos, normalize(normal), albedo, specular, shininess);
    color = vec4(c, 0.0);
  }
}
"""


@pytest.mark.gl
@pytest.mark.cl
def test_lights_blended_into_rgba8_are_held_to_the_bound_not_one_code(tmp_path):
    """The newcomer's first disagreement: five lights blended into an rgba8 target drift by two
    codes from the float64 evaluation at some pixels; the precision verdict held every target
    to one code ("more than rounding") while stress allowed the blends.  Now both hold it to
    the one bound, which counts the blend steps into each pixel."""
    from pipegen.proof.precision import precision_check, quantize_targets
    path = tmp_path / "blend8.pipe"
    path.write_text(BLEND8)
    c = pipegen.compile_file(path)
    scene = pipegen.load_scene(ROOT / "examples" / "scenes" / "mixed_lights.toml").with_size(*SIZE)
    assert len(scene.lights) == 5
    exact = quantize_targets(c.technique, c.pipeline("cl", precision="f64").render(scene))
    result = precision_check(c, scene)
    for backend in ("gl", "cl"):
        got = c.pipeline(backend).render(scene)["color"]
        codes = np.abs(got.astype(int) - exact["color"].astype(int)).max(axis=-1)
        assert (codes > 1).sum() > 0          # what a one-code limit called an error
        color = {r.key: r for r in result.rows[backend]}["color"]
        assert color.passed and color.over == 0 and color.discontinuity_count == 0
        assert 1.0 < color.worst_error * 255 <= color.bound_at_worst * 255


@pytest.mark.gl
@pytest.mark.cl
def test_the_cli_output_docs_tolerances_quotes(tmp_path, monkeypatch, capsys):
    """docs/tolerances.md's example is what `pipegen check --precision f64` prints; and
    `--max-discontinuities` takes a count, 0 or more."""
    from pipegen.cli.main import main
    monkeypatch.chdir(ROOT)
    assert main(["check", "examples/techniques/toon_deferred.pipe", "--size", "96x64",
                 "--precision", "f64", "-o", str(tmp_path / "check")]) == 0
    out = capsys.readouterr().out
    doc = (ROOT / "docs" / "tolerances.md").read_text()
    quoted = [line.strip() for line in doc.split("$ pipegen check examples/techniques/"
                                                  "toon_deferred.pipe")[1].split("\n\n")[0]
              .splitlines()[1:] if line.strip() and line.strip() != "..."]
    printed = [line.strip() for line in out.splitlines()]
    for line in quoted:
        assert line in printed, (line, out)
    assert (tmp_path / "check" / "error_gl_color.png").is_file()
    assert main(["check", "examples/techniques/toon_deferred.pipe", "--size", "96x64",
                 "--max-discontinuities", "4", "-o", str(tmp_path / "c2")]) == 0
    with pytest.raises(SystemExit) as e:
        main(["check", "examples/techniques/toon_deferred.pipe", "--max-discontinuities", "-1"])
    assert e.value.code == 2
    assert "bad count '-1'" in capsys.readouterr().err
