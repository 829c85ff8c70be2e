"""Values the formats clamp (issue 25 item 3): counted per pass and target by the CL backend
where it stores them (runtime/cl/clamps.py), warned about once by run and check
(proof/clamps.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.cli.main import main
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.proof.clamps import Clamped, clamped_values, warning_lines
from pipegen.runtime.cl import clamps
from pipegen.scene import default_scene
from pipegen.scene.load import parse_scene

ROOT = Path(__file__).resolve().parents[1]
DEFERRED = str(ROOT / "pipelines/deferred.pipe")
F82_8 = float(np.float32(82.8))

# a floor drawn first, then one sphere whose specular (82.8, as a glTF material's F0 x
# (shininess + 8) / 8 can be) deferred.pipe stores into galbedo.a (rgba8): nothing is drawn
# after the sphere and its front faces never overlap, so each of its fragments is a pixel
HOT_SCENE = """
name = "hot"
width = 64
height = 48
ambient = [0.1, 0.1, 0.1]
[camera]
position = [0.0, 3.0, 6.0]
target = [0.0, 0.8, 0.0]
fov_y_deg = 45
[[objects]]
name = "floor"
mesh = "plane"
scale = [20, 1, 20]
material = { albedo = [0.7, 0.7, 0.7], specular = 0.2, shininess = 16 }
[[objects]]
name = "hot sphere"
mesh = "sphere"
translate = [0.0, 0.9, 0.0]
scale = 1.8
material = { albedo = [0.9, 0.9, 0.9], specular = 82.8, shininess = 200 }
[[lights]]
position = [1.0, 2.5, 1.0]
radius = 6.0
color = [1.0, 1.0, 1.0]
"""

# full-screen passes writing out-of-range values: a negative and a 2 into unorm (the output),
# 70000 into a half (an intermediate target) with an infinity beside it (a half keeps it)
NEGATIVE = """
technique negative "writes below and above unorm's range into its output"
target color : rgba8 clear 0
output color
pass p {
  draw fullscreen
  writes color
  fragment { color = vec4(-0.5, 0.25, 2.0, 1.0); }
}
"""
HALF = """
technique overflow "writes beyond 65504 into a half"
target hdr : rgba16f clear 0
target color : rgba8 clear 0
output color
pass light {
  draw fullscreen
  writes hdr
  fragment { hdr = vec4(70000.0, 1.0, 0.5, 1.0); }
}
pass resolve {
  draw fullscreen
  reads hdr
  writes color
  fragment { color = vec4(load(hdr).yzw, 1.0); }
}
"""


def hot_scene():
    return parse_scene(HOT_SCENE, "<hot>", name="hot")


# -- without a device ----------------------------------------------------------------------


def clamp(pass_name="p", target="color", count=3, highest=None, lowest=None, lo=0.0, hi=1.0):
    return clamps.Clamp("t", pass_name, target, "rgba8", count, highest, lowest, lo, hi)


def test_the_order_keys_round_trip():
    """The kernel's pg_order_key, as numpy: ordered like the floats, decoded exactly."""
    xs = np.array([-np.inf, -70000.0, -1.5, -0.0, 0.0, 1e-30, 1.0, 82.8, np.inf], np.float32)
    u = xs.view(np.uint32).astype(np.uint64)
    keys = np.where(u >> 31, ~u & 0xFFFFFFFF, u | 0x80000000)
    assert list(keys) == sorted(keys)
    assert [clamps._from_key(int(k)) for k in keys] == [float(x) for x in xs]


def test_a_log_keeps_the_worst_frame_and_the_widest_extremes():
    with clamps.collect() as outer:
        with clamps.collect() as inner:
            clamps.note([clamp(count=3, highest=2.0)])
        clamps.note([clamp(count=5, lowest=-1.0), clamp("q", count=1, highest=9.0)])
    assert inner.frames == 1 and outer.frames == 2
    got = {(c.pass_name, c.count, c.highest, c.lowest) for c in outer.clamps}
    assert got == {("p", 5, 2.0, -1.0), ("q", 1, 9.0, None)}
    assert not clamps.collecting()


def test_a_log_gives_the_float32_frames_clamps_when_it_saw_any():
    """check --precision f64 renders float64 copies around the technique (nudged steps, the
    reference): beside float32 frames their clamps are not the technique's."""
    f64 = clamps.Clamp("t", "p", "color", "rgba8", 7, None, -0.01, 0.0, 1.0, "f64")
    with clamps.collect() as alone:
        clamps.note([f64], "f64")
    assert alone.clamps == [f64]
    with clamps.collect() as both:
        clamps.note([clamp(count=2, highest=1.5)], "f32")
        clamps.note([f64], "f64")
    assert [(c.count, c.lowest, c.precision) for c in both.clamps] == [(2, None, "f32")]


def test_the_outputs_highlights_are_counted_not_warned():
    """Above the output's range: the final image saturating, which the picture shows; below
    it, or any clamp of an intermediate target, is warned with the pass and the target."""
    assert warning_lines([clamp(highest=1.38)], "color") == []
    lines = warning_lines([clamp(count=1, lowest=-0.5), clamp("g", "galbedo", 108, F82_8)],
                          "color")
    assert lines[0] == ("warning: pass p wrote 1 value outside what color holds (rgba8: 0 to 1), "
                        "as low as -0.5; the format clamped them (counted on the CL backend, "
                        "per frame)")
    assert "pass g wrote 108 values outside what galbedo holds (rgba8: 0 to 1), as high as " \
           "82.8;" in lines[1]
    assert lines[2].startswith("  hint: ")
    figures = Clamped([clamp(count=4, highest=1.5), clamp("q", count=2, highest=3.0)], "color")
    assert dict(figures) == {"color": 6} and figures.passes("color") == {"p": 4, "q": 2}
    assert figures.warnings() == []


# -- on the CL backend ---------------------------------------------------------------------


@pytest.mark.cl
@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_a_material_beyond_rgba8_is_counted_per_pass_and_target(precision):
    """specular 82.8 into deferred.pipe's galbedo.a: one value per fragment of the sphere
    (the pixels whose stored specular saturated), its value as the highest, in the float32
    run and in the float64 evaluation alike; nothing else but the output's highlights."""
    c = compile_file(DEFERRED)
    pipe = c.pipeline("cl", precision=precision)
    targets = pipe.render(hot_scene())
    alpha = targets["galbedo"][..., 3]
    saturated = int(np.sum(alpha == (255 if precision == "f32" else 1.0)))
    got = {(x.pass_name, x.target): x for x in pipe.last_clamps}
    g = got.pop(("gbuffer", "galbedo"))
    assert saturated > 200 and g.count == saturated
    assert g.highest == F82_8 and g.lowest is None and (g.lo, g.hi) == (0.0, 1.0)
    assert set(got) <= {("resolve", "color")}
    figures = clamped_values(pipe, c.technique.output)
    assert figures["galbedo"] == saturated and figures.passes("galbedo") == {"gbuffer": saturated}


@pytest.mark.cl
def test_run_warns_once_naming_the_pass_and_the_target(tmp_path, capsys):
    scene = tmp_path / "hot.toml"
    scene.write_text(HOT_SCENE)
    assert main(["run", DEFERRED, "--scene", str(scene), "--backend", "cl",
                 "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1, err
    assert warnings[0].startswith("warning: pass gbuffer wrote ")
    assert " values outside what galbedo holds (rgba8: 0 to 1), as high as 82.8; the format " \
           "clamped them" in warnings[0]


@pytest.mark.cl
def test_a_negative_value_into_unorm():
    c = compile_source(NEGATIVE, "negative.pipe")
    pipe = c.pipeline("cl", size=(24, 16))
    codes = pipe.render(default_scene())["color"]
    assert (codes[0, 0] == [0, 64, 255, 255]).all()          # stored clamped
    (x,) = pipe.last_clamps
    assert (x.pass_name, x.target, x.count) == ("p", "color", 2 * 24 * 16)   # x and z
    assert (x.lowest, x.highest) == (-0.5, 2.0)
    lines = warning_lines(pipe.last_clamps, c.technique.output)      # below the output's range
    assert "as high as 2 and as low as -0.5" in lines[0]


@pytest.mark.cl
def test_a_half_overflow_is_counted_an_infinity_is_not():
    c = compile_source(HALF, "overflow.pipe")
    pipe = c.pipeline("cl", size=(24, 16))
    values = pipe.render(default_scene())
    assert values["hdr"][0, 0, 0] == np.float16(65504.0)
    (x,) = pipe.last_clamps
    assert (x.pass_name, x.target, x.format, x.count) == ("light", "hdr", "rgba16f", 24 * 16)
    assert (x.highest, x.lowest, x.hi) == (70000.0, None, 65504.0)
    inf = compile_source(HALF.replace("70000.0", "1.0 / 0.0"), "inf.pipe")
    pipe = inf.pipeline("cl", size=(24, 16))
    assert np.isinf(pipe.render(default_scene())["hdr"][0, 0, 0])
    assert pipe.last_clamps == []


@pytest.mark.cl
@pytest.mark.parametrize("name", sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe")))
def test_no_shipped_technique_clamps_on_the_default_scene(name):
    """Only the output's highlights saturate (the shipped techniques write HDR light into an
    rgba8 output): no warning, no intermediate target clamped."""
    c = compile_file(ROOT / "pipelines" / f"{name}.pipe")
    pipe = c.pipeline("cl", size=(64, 36))
    pipe.render(default_scene())
    assert warning_lines(pipe.last_clamps, c.technique.output) == []
    assert {x.target for x in pipe.last_clamps} <= {c.technique.output}


@pytest.mark.cl
@pytest.mark.parametrize("wmin", [1, 64])
def test_the_wide_path_counts_as_the_scalar_path(monkeypatch, wmin):
    """The wide fragment functions (PG_W pixels per call; fewer than WMIN pixels of a batch
    one by one) reach the same count and extremes: the test sits in the blend every path
    shares."""
    from pipegen.backends.opencl import wide as cl_wide
    monkeypatch.setattr(cl_wide, "MIN_COST", 0)
    monkeypatch.setattr(cl_wide, "WMIN", wmin)
    got = {}
    for enabled in (False, True):
        monkeypatch.setattr(cl_wide, "ENABLED", enabled)
        pipe = compile_source(NEGATIVE, "negative.pipe").pipeline("cl", size=(40, 20))
        assert (cl_wide.MARK in pipe.plan.passes[0].code.fragment) == enabled
        pipe.render(default_scene())
        got[enabled] = pipe.last_clamps
    assert got[True] == got[False] and got[True][0].count == 2 * 40 * 20


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_check_warns_once_with_the_cl_backends_count(tmp_path, capsys, precision):
    """check renders both backends (and with --precision f64 the float64 evaluation too); GL
    cannot see the values before its store clamps them, the CL renders count for both: one
    warning, the check itself unchanged."""
    scene = tmp_path / "hot.toml"
    scene.write_text(HOT_SCENE)
    assert main(["check", DEFERRED, "--scene", str(scene), "--precision", precision,
                 "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and "what galbedo holds (rgba8: 0 to 1)" in warnings[0], err
    assert "pass gbuffer" in warnings[0] and "as high as 82.8" in warnings[0]


@pytest.mark.cl
def test_a_sweep_counts_clamps_per_row_and_warns_once(tmp_path):
    """run_sweep on the hot scene (given as a loaded Scene): the CL rows count the specular
    values galbedo clamped, results.json keeps the records, and the sweep warns once per pass
    and target, naming the rows."""
    from pipegen.tools.sweep.run import run_sweep
    from pipegen.tools.sweep.outputs import csv_text
    result = run_sweep([DEFERRED], scene=parse_scene(HOT_SCENE, "hot.toml"),
                       axes={"max_lights": [4, 8]}, backends=("cl",), frames=0, jobs=1,
                       progress=False)
    assert [r["clamped"] for r in result.rows] == [result.rows[0]["clamped"]] * 2
    assert result.rows[0]["clamped"] > 200
    records = {(c["pass_name"], c["target"]) for c in result.rows[0]["clamps"] if c["warned"]}
    assert records == {("gbuffer", "galbedo")}
    assert len(result.warnings) == 1
    assert result.warnings[0].startswith("warning: deferred: pass gbuffer wrote ")
    assert "galbedo holds (rgba8: 0 to 1), as high as 82.8" in result.warnings[0]
    assert "(rows 1,2;" in result.warnings[0] and result.warnings[0] in result.summary()
    assert ",clamped," in csv_text(result.rows).splitlines()[0] + ","


@pytest.mark.cl
def test_the_testing_api_counts_and_warns():
    """pipegen.testing.render on CL: ``Targets.clamped`` per target and pass, and a
    ClampWarning naming the pass and the target; on GL nothing can be counted: None."""
    import pipegen.testing as pt
    scene = parse_scene(HOT_SCENE, "hot.toml")
    with pytest.warns(pt.ClampWarning, match=r"deferred: pass gbuffer wrote \d+ values outside "
                                             r"what galbedo holds \(rgba8: 0 to 1\), as high "
                                             r"as 82\.8"):
        cl = pt.render(DEFERRED, scene, backend="cl")
    assert cl.clamped["galbedo"] > 200 and cl.clamped.passes("galbedo") == \
        {"gbuffer": cl.clamped["galbedo"]}
    saturated = int(np.sum(cl["galbedo"].values[..., 3] == 255))
    assert cl.clamped["galbedo"] == saturated


@pytest.mark.gl
def test_the_testing_api_on_gl_has_no_clamp_counts():
    import pipegen.testing as pt
    assert pt.render(DEFERRED, parse_scene(HOT_SCENE, "hot.toml"), backend="gl").clamped is None
