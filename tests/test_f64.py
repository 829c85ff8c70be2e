"""The float64 evaluation of a technique (``Compiled.pipeline("cl", precision="f64")``,
docs/internals.md "The float64 evaluation"): the technique's arithmetic in double, every target
stored unquantised in its declared range, the coverage of the float32 run.

- every shipped technique: the float32 CL image is within 1 code of the quantised float64
  image on interior pixels of its rgba8 output (edge pixels: ``compare.py``'s 3x3 match);
- hand-computed values: 1/3 stored in rgba8 and r32f is 1/3 in double, blended twice 2/3,
  clamped to the format's range (unorm [0, 1], half +-65504), literals are their decimal value;
- depth in double: a floor plane's window depth is the ray-plane intersection to ~1e-12 (the
  float32 run is off by d24 codes);
- a technique a user writes (in a temporary folder; a half-size light buffer read with
  ``sample()``, ``load()`` at coordinates, matrices, a user function; with and without 4x
  multisampling) agrees with its float32 run within 1 code on interior pixels;
- the API: keys, shapes and dtypes of the f32 render; a backend without f64 says so; the plan's
  plain-data spelling keeps the precision; the float32 kernels do not change.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyopencl")

pytestmark = pytest.mark.cl

from pipegen.core import formats  # noqa: E402
from pipegen.backends.plan import plan_from_dict  # noqa: E402
from pipegen.proof.compare import compare_target  # noqa: E402
from pipegen.compiler.driver import compile_file, compile_source  # noqa: E402
from pipegen.core.diagnostics import PipegenError  # noqa: E402
from pipegen.proof.precision import quantize_targets  # noqa: E402
from pipegen.scene import load_scene  # noqa: E402

import shipped  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ONE_CODE = formats.Tolerance("code", 1)


@pytest.fixture(scope="module")
def small():
    return load_scene(ROOT / "examples/scenes/small.toml")


def _interior_within_one_code(compiled, f32: dict, f64: dict, target: str):
    """The comparison of the float32 codes of ``target`` with the quantised float64 values:
    ``over`` counts the interior pixels more than one code off (edge pixels, where coverage
    or a discontinuity moves a value to a neighbour, are admitted by the 3x3 match)."""
    fmt = compiled.technique.target(target).format
    exact = quantize_targets(compiled.technique, {target: f64[target]})[target]
    return compare_target(target, fmt, f32[target], exact, tolerance=ONE_CODE)


# the variants of tests/shipped.py with --exhaustive: each is held to its float64 bounds in its
# own test file
@pytest.mark.parametrize("name", shipped.params())
def test_shipped_technique_f32_within_one_code_of_f64(name, small):
    compiled = compile_file(ROOT / "pipelines" / f"{name}.pipe")
    f64 = compiled.pipeline("cl", precision="f64").render(small)
    f32 = compiled.pipeline("cl").render(small)
    assert sorted(f64) == sorted(f32)
    for key in f32:
        assert f64[key].shape == f32[key].shape, key
        assert f64[key].dtype == (np.uint8 if key.endswith(".stencil") else np.float64), key
    out = compiled.technique.output
    assert compiled.technique.target(out).format.name == "rgba8"
    row = _interior_within_one_code(compiled, f32, f64, out)
    assert row.over == 0 and row.max_error <= 1 + (row.edge_admitted > 0) * 255, row.row()
    assert row.edge_admitted <= row.edge_bound, row.row()
    # the float64 image is not the float32 image: it holds values between the codes
    codes = f64[out] * 255.0
    assert np.any(np.abs(codes - np.rint(codes)) > 1e-3)


EXACT_VALUES = """
technique exact_values "hand-computed stores of the float64 evaluation"
target color : rgba8 clear 0
target acc   : rgba8 clear 0
target big   : rgba16f clear 0
target exact : r32f clear 0
target pair  : rg16_snorm clear 0
output color

pass first {
  draw fullscreen
  writes color, acc, big, exact, pair
  fragment {
    float one = frag_coord.x * 0.0 + 1.0;     // not a constant: nothing is folded
    color = vec4(one / 3.0, 1.5 * one, -one, 0.25 * one);
    acc = vec4(one / 3.0);
    big = vec4(70000.0 * one, -70000.0 * one, one / 3.0, 0.1 * one);
    exact = vec4(one / 3.0);
    pair = vec4(-2.0 * one, -one / 3.0, 0.0, 0.0);
  }
}

pass second {
  draw fullscreen
  writes acc
  blend acc add(one, one)
  fragment {
    float one = frag_coord.x * 0.0 + 1.0;
    acc = vec4(one / 3.0, one / 3.0, 0.75 * one, one);
  }
}
"""


def test_hand_computed_values(small):
    compiled = compile_source(EXACT_VALUES)
    scene = small.with_size(8, 4)
    got = compiled.pipeline("cl", precision="f64").render(scene)
    third = 1.0 / 3.0

    def every_pixel(name, expected):
        v = got[name]
        assert v.dtype == np.float64
        want = np.broadcast_to(np.asarray(expected, np.float64), v.shape)
        assert np.array_equal(v, want), (name, v[0, 0], expected)

    every_pixel("color", [third, 1.0, 0.0, 0.25])          # unorm: [0, 1], nothing else
    every_pixel("acc", [2.0 / 3.0, 2.0 / 3.0, 1.0, 1.0])   # 1/3 + 1/3 in double; clamped sums
    every_pixel("big", [65504.0, -65504.0, third, 0.1])    # half's finite range; 0.1 is 0.1
    every_pixel("exact", third)                            # not float32(1/3)
    every_pixel("pair", [-1.0, -third])                    # snorm: [-1, 1]
    assert third != float(np.float32(third))
    # and the float32 run stores these values quantised: the same codes
    f32 = compiled.pipeline("cl").render(scene)
    q = quantize_targets(compiled.technique, got)
    for name in ("color", "acc", "pair"):
        assert np.array_equal(f32[name], q[name]), name


DEPTH_PROBE = """
technique depth_probe "window depth, stored and as frag_coord.z"
target color : rgba8 clear 0
target z : r32f clear 1.0
target ds : d24s8 clear depth 1.0 stencil 0
output color
pass floor_depth {
  draw scene.opaque
  writes color, z
  depth ds less write
  fragment {
    color = vec4(1.0);
    z = vec4(frag_coord.z);
  }
}
"""

FLOOR_SCENE = """
name = "floor"
width = 64
height = 48
ambient = [0.1, 0.1, 0.1]

[camera]
position = [0.0, 3.0, 6.0]
target = [0.0, 0.0, 0.0]
fov_y_deg = 45
near = 0.5
far = 40

[[objects]]
name = "floor"
mesh = "plane"
scale = [20, 1, 20]
material = { albedo = [0.7, 0.7, 0.7], specular = 0.2, shininess = 16 }

[[lights]]
position = [0.0, 2.0, 0.0]
radius = 5.0
color = [1.0, 1.0, 1.0]
"""


def _floor_depth(scene) -> np.ndarray:
    """Window depth of the plane y = 0 at every pixel centre (GL rows, bottom first): the
    NDC depth where the pixel's ray meets the plane, in float64."""
    w, h = scene.width, scene.height
    cam = scene.camera
    inv = np.linalg.inv(cam.projection(w / h) @ cam.view_matrix())
    x = (np.arange(w) + 0.5) * 2.0 / w - 1.0
    y = (np.arange(h) + 0.5) * 2.0 / h - 1.0
    xn, yn = np.meshgrid(x, y)
    # world (homogeneous) = inv @ (xn, yn, zn, 1) = a + zn * b; its y vanishes on the plane
    a_y = inv[1, 0] * xn + inv[1, 1] * yn + inv[1, 3]
    zn = -a_y / inv[1, 2]
    return zn * 0.5 + 0.5


def test_depth_is_exact_in_double(tmp_path):
    (tmp_path / "floor.toml").write_text(FLOOR_SCENE)
    scene = load_scene(tmp_path / "floor.toml")
    compiled = compile_source(DEPTH_PROBE)
    got = compiled.pipeline("cl", precision="f64").render(scene)
    f32 = compiled.pipeline("cl").render(scene)
    want = _floor_depth(scene)
    covered = got["ds"] < 1.0
    assert covered.sum() > 0.3 * covered.size
    assert np.array_equal(covered, f32["ds"] < formats.get("d24s8").max_code)   # same coverage
    assert np.abs(got["ds"][covered] - want[covered]).max() < 1e-12
    assert np.array_equal(got["z"][covered], got["ds"][covered])     # frag_coord.z = stored
    assert np.all(got["z"][~covered] == 1.0)
    # the float32 run is the exact depth within its d24 rounding and llvmpipe's plane error
    d24 = formats.get("d24s8").dequantize(f32["ds"])
    assert np.abs(d24[covered] - want[covered]).max() < 8 / 16777215


USER_TECHNIQUE = """
technique user_lbuffer "a user's technique: G-buffer, half-size light buffer, bilinear upsample"
lights[8] { position: vec3, radius: float, color: vec3 }
target color  : rgba8 clear (0, 0, 0, 1)
target gpos   : rgba32f SAMPLES clear 0
target gnorm  : rgba16f SAMPLES clear 0
target galb   : rgba8 SAMPLES clear 0
target lbuf   : rgba16f size output * 0.5 clear 0
target ds     : d24s8 SAMPLES clear depth 1.0 stencil 0
output color

float falloff(float d, float r) {
  float x = clamp(1.0 - d * d / (r * r), 0.0, 1.0);
  return x * x;
}

vec3 eye() { return (inv_view * vec4(0.0, 0.0, 0.0, 1.0)).xyz; }

pass gbuffer {
  draw scene.opaque
  writes gpos, gnorm, galb
  depth ds less write
  cull back
  fragment {
    vec4 v = view * vec4(world_pos, 1.0);
    gpos = vec4(world_pos, -v.z);
    gnorm = vec4(normalize(normal), shininess);
    galb = vec4(albedo, specular);
  }
}

pass lighting {
  draw fullscreen
  reads gpos, gnorm, galb
  writes lbuf
  fragment {
    ivec2 at = ivec2(frag_coord.xy * 2.0);
    vec4 p = load(gpos, at);
    if (p.w == 0.0) discard;
    vec4 n = load(gnorm, at);
    vec3 e = normalize(eye() - p.xyz);
    vec3 sum = vec3(0.0);
    for (int i = 0; i < 8; i++) {
      if (uint(i) >= num_lights) break;
      vec3 l = lights[i].position - p.xyz;
      float d = length(l);
      vec3 h = normalize(normalize(l) + e);
      float lit = max(dot(n.xyz, normalize(l)), 0.0) * falloff(d, lights[i].radius);
      sum += lights[i].color * (lit + pow(max(dot(n.xyz, h), 0.0), n.w) * 0.25);
    }
    lbuf = vec4(sum, 1.0);
  }
}

pass compose {
  draw fullscreen
  reads galb, lbuf
  writes color
  fragment {
    vec4 a = load(galb);
    vec4 l = sample(lbuf, frag_coord.xy / output_size);
    color = vec4(a.xyz * (ambient + l.xyz), 1.0);
  }
}
"""


@pytest.mark.parametrize("samples", [1, 4])
def test_a_users_technique_in_a_temp_folder(tmp_path, small, samples):
    src = USER_TECHNIQUE.replace("SAMPLES", f"samples {samples}" if samples > 1 else "")
    path = tmp_path / "mine.pipe"
    path.write_text(src)
    compiled = compile_file(path)
    scene = small.with_size(80, 48)
    f64 = compiled.pipeline("cl", precision="f64").render(scene)
    f32 = compiled.pipeline("cl").render(scene)
    row = _interior_within_one_code(compiled, f32, f64, "color")
    assert row.over == 0 and row.edge_admitted <= row.edge_bound, row.row()
    assert f64["lbuf"].dtype == np.float64 and f64["lbuf"].shape == f32["lbuf"].shape
    lit = f64["color"][..., :3].max(axis=-1) > 0.2
    assert lit.mean() > 0.2                         # the technique does light the scene


def test_a_backend_without_f64_says_so(small):
    compiled = compile_source(EXACT_VALUES)
    with pytest.raises(PipegenError) as e:
        compiled.pipeline("gl", precision="f64")
    assert "f64" in str(e.value.render()) and "--backend cl" in e.value.render()
    with pytest.raises(PipegenError):
        compiled.pipeline("cl", precision="f16")


def test_f64_plan_is_plain_data_and_f32_kernels_unchanged():
    compiled = compile_source(EXACT_VALUES)
    before = [p.code.kernel for p in compiled.plan("cl").passes]
    pipe = compiled.pipeline("cl", precision="f64")
    assert pipe.plan.precision == "f64"
    d = pipe.plan.to_dict()
    assert d["precision"] == "f64" and plan_from_dict(d).precision == "f64"
    assert "precision" not in compiled.plan("cl").to_dict()
    assert [p.code.kernel for p in compiled.plan("cl").passes] == before
    assert all("pg_frame64" not in k and "tri_h" not in k for k in before)
    assert all("pg_frame64" in p.code.kernel for p in pipe.plan.passes)


@pytest.mark.gl
def test_cli_check_and_run_with_precision_f64(tmp_path, capsys):
    try:
        from pipegen.runtime.gl.context import get_context
        get_context()
    except Exception as exc:   # no EGL / llvmpipe here
        pytest.skip(f"no OpenGL context: {exc}")
    from pipegen.cli.main import main
    tech = str(ROOT / "pipelines/forward.pipe")
    scene = str(ROOT / "examples/scenes/small.toml")
    assert main(["check", tech, "--scene", scene, "--precision", "f64",
                 "-o", str(tmp_path / "check")]) == 0
    out = capsys.readouterr().out
    assert "float64 evaluation" in out and "GL (llvmpipe)" in out and "CL (PoCL)" in out
    assert (tmp_path / "check" / "error_gl_color.png").is_file()
    assert main(["run", tech, "--scene", scene, "--precision", "f64", "--backend", "cl",
                 "-o", str(tmp_path / "run")]) == 0
    codes = np.load(tmp_path / "run" / "color.npy")     # the f64 image, quantised
    assert codes.dtype == np.uint8 and codes.shape == (64, 96, 4)
    assert main(["run", tech, "--scene", scene, "--precision", "f64",
                 "-o", str(tmp_path / "run_gl")]) == 1
    assert "--backend cl" in capsys.readouterr().err


BUILTINS = """
technique builtins64 "the language's types and builtins in double"
target color : rgba8 clear 0
output color
pass p {
  draw fullscreen
  writes color
  fragment {
    vec3 v = vec3(frag_coord.x * 0.01, 0.0, 1.0);
    bvec3 b = bvec3(v);
    bvec3 c = bvec3(ivec3(v * 3.0));
    mat3 m = mat3(1.0) * 0.5;
    mat4 m4 = mat4(vec4(1.0, 0.0, 0.0, 0.0), vec4(0.0, 1.0, 0.0, 0.0),
                   vec4(0.0, 0.0, 1.0, 0.0), vec4(0.0, 0.0, 0.0, 1.0));
    vec3 w = m * v + (m4 * vec4(v, 1.0)).xyz / 2.0 + (vec4(v, 1.0) * m4).xyz;
    int k = int(frag_coord.x) % 3;
    float s = b.x ? 1.0 : 0.0;
    float t = c.z ? 0.5 : 0.0;
    color = vec4(s, t,
                 w[k] * 0.2 + smoothstep(0.0, 1.0, v.x) * mod(v.x, 0.3) + fract(v.x) + sign(-v.x),
                 exp(-v.x) * log(2.0 + v.x) + atan(v.x, 1.0) + inversesqrt(2.0 + v.x)
                 + pow(v.x, 2.5) + exp2(-v.x) + log2(1.0 + v.x) - cross(v, w).y * 0.1);
  }
}
"""


def test_builtins_and_bool_vectors_in_double(small):
    compiled = compile_source(BUILTINS)
    scene = small.with_size(16, 4)
    f64 = compiled.pipeline("cl", precision="f64").render(scene)
    f32 = compiled.pipeline("cl").render(scene)
    q = quantize_targets(compiled.technique, f64)["color"]
    assert np.abs(q.astype(int) - f32["color"].astype(int)).max() <= 1
    # the dynamic-state programs (the tests' mode) build in double too
    from pipegen.runtime.cl.pipeline import CLPipeline
    pipe = CLPipeline(compiled.pipeline("cl", precision="f64").plan, dynamic_state=True)
    assert np.array_equal(pipe.render(scene)["color"], f64["color"])


def test_error_split_total_precision_algorithm(small):
    """Two references per image: the scene reference (total error) and the technique's own
    float64 evaluation (precision error); inferred lighting's low-resolution L-buffer is
    what its algorithm gives up, not precision."""
    from pipegen.proof.precision import error_split
    from pipegen.reference.lighting import reference_image
    ref, gb = reference_image(small)
    compiled = compile_file(ROOT / "pipelines/inferred.pipe")
    e = error_split(compiled.pipeline("cl").render(small)["color"],
                    compiled.pipeline("cl", precision="f64").render(small)["color"],
                    ref, ~gb.silhouette)
    assert e["precision"]["max"] <= 1
    assert e["total"]["max"] <= e["precision"]["max"] + e["algorithm"]["max"]
    assert e["algorithm"]["rmse"] > 3 * e["precision"]["rmse"]
