"""Per-sample reads and per-sample shading (issue 27, Trebilco's MSAA techniques 1 and 3):
``load_sample(T, s)`` reads sample s of a multisampled colour target, ``sample_id`` makes a
pass run once per covered sample, ``sample_mask`` is the samples the primitive covers
(docs/language.md, "Reading samples").

- misuse is a positioned error (file:line:col at the offending token);
- GL (llvmpipe, gl_SampleID) and CL give the same values bit for bit: frag_coord.xy at the
  sample position, frag_coord.z and the scene inputs at the pixel centre, each sample written
  by its own invocation; the float64 evaluation takes the same positions;
- ``sample_mask`` is the primitive's coverage before the depth test on both backends (what
  llvmpipe's gl_SampleMaskIn holds), in a per-pixel pass;
- the example of docs/language.md renders alike on both backends.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.testing.api import assert_backends_agree, load_test_scene, render

ROOT = Path(__file__).resolve().parent.parent
SIZE = (16, 12)
SCENE = "examples/scenes/edges.toml"

HEAD = """\
technique t "per-sample fixture"
target color : rgba8 samples 4 clear (0, 0, 0, 1)
target zs    : r32f samples 4 clear 1.0
target probe : rgba32f samples 4 clear 0
target ds    : d24s8 samples 4 clear depth 1.0 stencil 0
target flat1 : rgba8 clear 0
target s0 : rgba32f clear 0
target s1 : rgba32f clear 0
target s2 : rgba32f clear 0
target s3 : rgba32f clear 0
output flat1
"""

# A depth pre-pass storing frag_coord.z per sample, a shading pass that reads it back per
# sample and records frag_coord and world_pos.x, and a full-screen pass that splits the four
# samples into single-sampled targets (what the test compares).
PROBE = HEAD + """
pass prepass {
  draw scene.opaque
  writes zs
  depth ds less write
  cull back
  fragment { zs = vec4(frag_coord.z + 0.0 * float(sample_id), 0.0, 0.0, 0.0); }
}
pass shade {
  draw scene.opaque
  reads zs
  writes probe
  depth ds equal nowrite
  cull back
  fragment {
    probe = vec4(fract(frag_coord.x), fract(frag_coord.y), world_pos.x,
                 load_sample(zs, sample_id).x);
  }
}
pass split {
  draw fullscreen
  reads probe
  writes s0, s1, s2, s3, flat1
  fragment {
    s0 = load_sample(probe, 0);
    s1 = load_sample(probe, 1);
    s2 = load_sample(probe, ivec2(frag_coord.xy), 2);
    s3 = load_sample(probe, 7);     // clamped to the last sample
    flat1 = vec4(0.5);
  }
}
"""


def _fixture(body: str, reads: str = "zs", writes: str = "flat1", depth: str = "",
             decls: str = "") -> str:
    return HEAD + decls + f"""
pass p {{
  draw fullscreen
  reads {reads}
  writes {writes}
  {depth}
  fragment {{
{body}
  }}
}}
"""


ERRORS = [
    ("single_sampled_target", _fixture("    flat1 = load_sample(s0, 0);", reads="s0"),
     "s0, 0)", "single-sampled"),
    ("depth_target", _fixture("    flat1 = vec4(load_sample(ds, 0));", reads="ds"),
     "ds, 0)", "depth target"),
    ("uint_index", _fixture("    flat1 = load_sample(zs, 1u);"), "1u", "an int, not a uint"),
    ("sample_id_single_sampled", _fixture("    flat1 = vec4(float(sample_id));", reads="zs"),
     "sample_id", "single-sampled targets"),
    ("sample_id_through_a_function",
     _fixture("    flat1 = vec4(which());", decls="float which() { return float(sample_id); }\n"),
     "which()", "reads sample_id"),
    ("per_sample_and_resolved",
     _fixture("    vec4 a = load(zs);\n    flat1 = a + load_sample(zs, 0);"),
     "load_sample(zs, 0)", "per sample and resolved"),
    ("arity", _fixture("    flat1 = load_sample(zs);"), "load_sample(zs)", "called as"),
]


@pytest.mark.parametrize("source, token, words", [c[1:] for c in ERRORS],
                         ids=[c[0] for c in ERRORS])
def test_misuse_is_a_positioned_error(source, token, words):
    with pytest.raises(PipegenError) as info:
        compile_source(source, "t.pipe")
    rendered = info.value.render()
    m = re.search(r"^t\.pipe:(\d+):(\d+): error: (.*)$", rendered, re.M)
    assert m, rendered
    line = source.splitlines()[int(m.group(1)) - 1]
    assert line[int(m.group(2)) - 1:].startswith(token), (line, rendered)
    assert words in m.group(3), rendered


@pytest.fixture(scope="module")
def probes():
    compiled = compile_source(PROBE, "probe.pipe")
    scene = load_test_scene(SCENE, SIZE)
    return {b: {k: t.values for k, t in render(compiled, scene, b).items()}
            for b in ("gl", "cl")}, compiled, scene


@pytest.mark.gl
@pytest.mark.cl
def test_gl_and_cl_shade_each_sample_alike(probes):
    out, _, _ = probes
    gl, cl = out["gl"], out["cl"]
    for name in ("s0", "s1", "s2", "s3"):
        assert np.array_equal(gl[name], cl[name]), name       # bit for bit (rgba32f)
    covered = cl["s0"][..., 3] < 1.0
    assert covered.sum() > 100
    # frag_coord.xy at llvmpipe's 4x positions (x, y): (.375, .125) (.875, .375) (.125, .625);
    # s3 asked for sample 7 and got sample 3 (.625, .875)
    for name, (fx, fy) in {"s0": (.375, .125), "s1": (.875, .375), "s2": (.125, .625),
                           "s3": (.625, .875)}.items():
        v = cl[name][covered]
        v = v[v[:, 3] < 1.0]
        assert np.all(v[:, 0] == fx) and np.all(v[:, 1] == fy), name
    # world_pos is interpolated at the pixel centre: where samples 0 and 3 show the same
    # surface (same depth) they hold the same value, to a float32 rounding of an adjacent
    # triangle's plane (1e-4), where sample positions (0.25 px apart in x) would differ by
    # a quarter of a pixel's step of world x (0.31 here: 0.08)
    same = covered & (cl["s0"][..., 3] == cl["s3"][..., 3])
    assert same.sum() > 100
    assert np.abs(cl["s0"][same][:, 2] - cl["s3"][same][:, 2]).max() < 1e-4
    step = np.abs(np.diff(cl["s0"][..., 2], axis=1))[covered[:, 1:] & covered[:, :-1]]
    assert np.median(step) > 0.1


@pytest.mark.cl
def test_the_float64_evaluation_takes_the_same_sample_positions(probes):
    out, compiled, scene = probes
    f64 = compiled.pipeline("cl", size=SIZE, precision="f64").render(scene)
    for name in ("s0", "s1", "s2", "s3"):
        a, b = f64[name], out["cl"][name]
        assert np.array_equal(a[..., :2], b[..., :2]), name
        # world_pos.x and window depth: float32 rounding of the same values (|x| < 10)
        assert np.abs(a[..., 2:] - b[..., 2:]).max() < 1e-5, name


def _doc_example() -> str:
    text = (ROOT / "docs" / "language.md").read_text()
    m = re.search(r"```pipe\n(technique per_sample_demo .*?)```", text, re.S)
    assert m, "docs/language.md lost its per-sample example"
    return m.group(1)


@pytest.mark.gl
@pytest.mark.cl
def test_the_documented_example_renders_alike_on_both_backends():
    compiled = compile_source(_doc_example(), str(ROOT / "pipelines" / "doc_per_sample.pipe"))
    result = assert_backends_agree(compiled, SCENE, (32, 18))
    assert {r.name for r in result.rows} >= {"color", "index"}


MASK_PROBE = """\
technique m "coverage probe"
target color : rgba32f samples 4 clear 0
target ds    : d24s8 samples 4 clear depth 1.0 stencil 0
target s0    : rgba32f clear 0
output s0
pass prepass {
  draw scene.opaque
  depth ds less write
  cull back
}
pass shade {
  draw scene.opaque
  writes color
  depth ds equal nowrite
  cull back
  fragment { color = vec4(float(sample_mask), 0.0, 0.0, 1.0); }
}
pass split {
  draw fullscreen
  reads color
  writes s0
  fragment { s0 = load_sample(color, 0); }
}
"""


@pytest.mark.gl
@pytest.mark.cl
def test_sample_mask_is_the_primitive_coverage_on_both_backends():
    compiled = compile_source(MASK_PROBE, "mask.pipe")
    scene = load_test_scene(SCENE, (32, 18))
    gl, cl = (render(compiled, scene, b)["s0"].values[..., 0] for b in ("gl", "cl"))
    assert np.array_equal(gl, cl)
    shaded = cl[cl > 0]
    # every mask holds sample 0 (the pixel was read at sample 0); interior pixels all four,
    # silhouettes fewer -- including where the depth test rejected some of the covered
    # samples (the mask is taken before it, as llvmpipe's gl_SampleMaskIn is)
    assert set(np.unique(shaded).astype(int)) <= {1, 3, 5, 7, 9, 11, 13, 15}
    assert (shaded == 15).mean() > 0.7 and (shaded < 15).sum() >= 20   # 76 % full at 32x18
