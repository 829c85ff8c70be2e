"""Materials a scene can set (issue 28): a technique's `material { FIELD: TYPE = DEFAULT }`
block, read as `material.FIELD` (the drawn object's) and `materials[id].FIELD` (any object id's,
e.g. one a G-buffer stored); scene objects set the fields in TOML (`material = { model = 1 }`)
and glTF (`emissiveFactor` -> `emissive`, `extras`); unknown or mistyped fields are errors at
their position in the scene file when a technique renders the scene.

Renders: examples/techniques/deferred_two_brdfs.pipe on examples/scenes/materials.toml, GL and
CL.  The colour target is rgba16f: a value near 1 is stored to 2^-11 relative, so sums that
should be equal are compared to 2e-3 (a float16 step at 2 is 2^-10)."""

from __future__ import annotations

import base64
import json
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.scene import load_scene
from pipegen.scene.load import parse_scene

ROOT = Path(__file__).resolve().parents[1]
PIPE = ROOT / "examples/techniques/deferred_two_brdfs.pipe"
SCENE = ROOT / "examples/scenes/materials.toml"
SCHEMA = [("model", "uint", (0.0,)), ("emissive", "vec3", (0.0, 0.0, 0.0)),
          ("rim", "float", (0.0,)), ("wrap", "float", (0.5,))]

LIGHTS = "lights[4] { position: vec3, radius: float, color: vec3 }\n"


def technique(body: str, material: str = "material { model: uint = 0, rim: float = 0.25 }",
              lights: str = LIGHTS) -> str:
    return (f'technique t "test"\n{lights}{material}\n'
            "target color : rgba8 clear 0\ntarget ds : d24s8 clear depth 1.0\noutput color\n"
            f"pass p {{\n  draw scene\n  writes color\n  depth ds less write\n"
            f"  fragment {{\n    {body}\n  }}\n}}\n")


def compile_error(text: str) -> PipegenError:
    with pytest.raises(PipegenError) as info:
        compile_source(text, "t.pipe")
    return info.value


# ---- the declaration ---------------------------------------------------------------------------

def test_fields_and_defaults_reach_the_plan():
    c = compile_source(technique("color = vec4(material.rim, 0.0, 0.0, 1.0);",
                                 "material { model: uint = 3, tint: vec3 = vec3(0.5, 1, 2),\n"
                                 "           rim: float = -0.25 }"), "t.pipe")
    table = c.technique.materials
    assert [(f.name, str(f.type), f.default) for f in table.fields] == [
        ("model", "uint", (3.0,)), ("tint", "vec3", (0.5, 1.0, 2.0)), ("rim", "float", (-0.25,))]


@pytest.mark.parametrize("material, line, col, words", [
    ("material { model: mat3 = 0 }", 3, 19, "a material field is a float, int or uint"),
    ("material { model: uint = 0.5 }", 3, 26, "must be an unsigned integer"),
    ("material { model: uint = -1 }", 3, 27, "must be an unsigned integer"),
    ("material { tint: vec3 = 1 }", 3, 25, "its default is a vec3"),
    ("material { tint: vec3 = vec2(1) }", 3, 25, "is a vec3, not vec2"),
    ("material { tint: vec3 = vec3(1, 2) }", 3, 25, "takes 1 or 3 values, not 2"),
    ("material { rim: float = rim2 }", 3, 25, "is not a number"),
    ("material { rim: float = 0, rim: float = 1 }", 3, 28, "declared twice"),
    ("material { albedo: vec3 = vec3(0) }", 3, 12, "a scene material key already"),
])
def test_declaration_errors_are_positioned(material, line, col, words):
    e = compile_error(technique("color = vec4(1.0);", material))
    assert words in e.message, e.message
    assert (e.span.line, e.span.column) == (line, col), e.render()


def test_a_material_block_needs_a_light_table():
    e = compile_error(technique("color = vec4(1.0);", lights=""))
    assert "needs a light table" in e.message and e.span.line == 2


@pytest.mark.parametrize("body, words", [
    ("color = vec4(material.rimm);", "materials have no field 'rimm'"),
    ("color = vec4(materials[1].model);", "cannot"),      # a uint into vec4(…) is fine: see below
    ("color = vec4(materials[1.0].rim);", "an index is an int or a uint"),
    ("color = vec4(materials[1]);", "a material is read by field"),
])
def test_reads_are_checked(body, words):
    if words == "cannot":      # the one read that is valid: a uint field converts
        compile_source(technique(body), "t.pipe")
        return
    e = compile_error(technique(body))
    assert words in e.message, e.message
    assert e.span.line == 12


def test_reading_without_a_block_says_how_to_declare_one():
    e = compile_error(technique("color = vec4(material.rim);", material=""))
    assert "declares no material fields" in e.message
    assert "material { rim: float = 0 }" in e.hint


def test_material_is_the_drawn_objects_only_in_scene_draws():
    text = technique("color = vec4(1.0);").replace(
        "output color\n", "output color\npass q {\n  draw fullscreen\n  writes color\n"
        "  fragment { color = vec4(material.rim); }\n}\n")
    e = compile_error(text)
    assert "does not draw the scene" in e.message and "materials[id]" in e.hint


# ---- scenes: TOML, glTF, checking against the schema ------------------------------------------

def test_toml_fields_fill_the_table_with_defaults_elsewhere():
    table = load_scene(SCENE).material_table(SCHEMA)
    assert table.shape == (256, 4, 4)
    # ids: floor 1, box 2, sphere 3, cylinder 4, lamp 5; 0 and ids past 5 hold the defaults
    assert table[:, 0, 0].tolist()[:7] == [0, 0, 0, 1, 1, 0, 0]
    assert table[3, 2, 0] == 0.35 and table[2, 2, 0] == 0.0
    np.testing.assert_array_equal(table[5, 1, :3], [0.9, 0.6, 0.2])
    np.testing.assert_array_equal(table[4, 1, :3], [0, 0, 0])


SMALL = """width = 8
height = 8
[camera]
position = [0, 0, 5]
target = [0, 0, 0]
fov_y_deg = 45
near = 0.5
far = 10
[[objects]]
mesh = "box"
material = {{ albedo = [0.5, 0.5, 0.5], {fields} }}
"""


@pytest.mark.parametrize("fields, col, words", [
    ("modle = 1", 40, "sets material field 'modle', which the technique does not declare"),
    ("model = 1.5", 40, "1.5 is not a whole number >= 0"),
    ("model = -1", 40, "is not a whole number >= 0"),
    ("emissive = 1.0", 40, "so its value is a list of 3 numbers"),
    ("emissive = [1, 2]", 40, "so its value is a list of 3 numbers"),
    ("rim = [1.0]", 40, "so its value is one number"),
])
def test_scene_fields_are_checked_at_their_position(fields, col, words):
    scene = parse_scene(SMALL.format(fields=fields), "s.toml")     # loads: no schema yet
    with pytest.raises(PipegenError) as info:
        scene.material_table(SCHEMA)
    e = info.value
    assert words in e.message, e.message
    assert (e.span.file, e.span.line, e.span.column) == ("s.toml", 11, col), e.render()


def test_a_value_that_is_not_a_number_is_refused_when_loading():
    with pytest.raises(PipegenError) as info:
        parse_scene(SMALL.format(fields='model = "one"'), "s.toml")
    assert "must be a number or a list of numbers" in info.value.message
    assert info.value.span.line == 11


def _gltf(path: Path, material: dict) -> Path:
    """One triangle with ``material``."""
    blob = np.float32([[0, 0, 0], [1, 0, 0], [0, 1, 0]]).tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
           "materials": [material],
           "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                        + base64.b64encode(blob).decode()}],
           "bufferViews": [{"buffer": 0, "byteLength": len(blob)}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]}]}
    path.write_text(json.dumps(doc))
    return path


def test_gltf_emissive_and_extras_equal_the_same_fields_in_toml(tmp_path):
    gltf = _gltf(tmp_path / "tri.gltf", {"emissiveFactor": [0.25, 0.5, 1.0],
                                         "extras": {"model": 1, "rim": 0.75, "note": "x"}})
    from_gltf = load_scene(gltf).material_table(SCHEMA)
    toml = parse_scene(SMALL.format(fields="model = 1, rim = 0.75, emissive = [0.25, 0.5, 1.0]"),
                       "s.toml").material_table(SCHEMA)
    np.testing.assert_array_equal(from_gltf, toml)
    assert from_gltf[1, 0, 0] == 1 and from_gltf[1, 2, 0] == 0.75


def test_gltf_fields_a_technique_does_not_declare_are_ignored_but_declared_ones_checked(tmp_path):
    gltf = _gltf(tmp_path / "tri.gltf", {"emissiveFactor": [1, 0, 0],
                                         "extras": {"model": 2.5}})
    scene = load_scene(gltf)
    table = scene.material_table([("rim", "float", (0.5,))])      # neither declared: defaults
    assert table[1, 0, 0] == 0.5
    with pytest.raises(PipegenError) as info:
        scene.material_table(SCHEMA)
    assert "extras: material field 'model' is a uint: 2.5 is not a whole number" \
        in info.value.message


@pytest.mark.gl
def test_rendering_a_scene_with_an_undeclared_field_fails_with_its_position(tmp_path):
    text = SCENE.read_text().replace("model = 1, rim = 0.35", "model = 1, rimm = 0.35")
    scene = parse_scene(text, "m.toml")
    pipe = compile_file(PIPE).pipeline("gl")
    with pytest.raises(PipegenError) as info:
        pipe.render(scene)
    e = info.value
    assert "'rimm'" in e.message and "did you mean 'rim'" in e.hint
    line = next(i for i, t in enumerate(text.split("\n"), 1) if "rimm" in t)
    assert (e.span.file, e.span.line) == ("m.toml", line)


# ---- renders ------------------------------------------------------------------------------------

@lru_cache(maxsize=None)
def _pipeline(backend: str):
    return compile_file(PIPE).pipeline(backend)


def render(backend: str, edit=lambda t: t) -> dict:
    scene = parse_scene(edit(SCENE.read_text()), str(SCENE), base_dir=SCENE.parent)
    return _pipeline(backend).render(scene)


BACKENDS = [pytest.param("gl", marks=pytest.mark.gl), pytest.param("cl", marks=pytest.mark.cl)]


@pytest.mark.parametrize("backend", BACKENDS)
def test_emissive_adds_its_value_on_the_objects_pixels_only(backend):
    lit = render(backend)
    dark = render(backend, lambda t: t.replace("emissive = [0.9, 0.6, 0.2]", "emissive = [0, 0, 0]"))
    lamp = lit["gpos"][..., 3] == 5
    assert lamp.sum() > 10
    diff = lit["color"][..., :3].astype(np.float64) - dark["color"][..., :3]
    np.testing.assert_allclose(diff[lamp], np.broadcast_to([0.9, 0.6, 0.2], diff[lamp].shape),
                               atol=2e-3)
    assert np.abs(diff[~lamp]).max() == 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_model_one_is_wrapped_diffuse_without_a_lobe(backend):
    """The cylinder (id 4) with model 1 and wrap 0 equals model 0 without a specular lobe
    (Lambert: both are color x att x albedo x max(n.l, 0)); wrap 1 is brighter (half-Lambert
    is >= Lambert), by more than a float16 step near the terminator."""
    cyl = 'translate = [1.7, 0.5, 0.6]\nscale = [0.8, 1.0, 0.8]\nmaterial = { albedo = [0.3, 0.5, 0.9], '
    lambert = render(backend, lambda t: t.replace(
        cyl + "specular = 0.4, shininess = 24, model = 1, wrap = 1.0 }",
        cyl + "specular = 0.0, shininess = 24, model = 0 }"))
    wrap0 = render(backend, lambda t: t.replace("model = 1, wrap = 1.0", "model = 1, wrap = 0.0"))
    wrap1 = render(backend)
    on = wrap1["gpos"][..., 3] == 4
    assert on.sum() > 50
    a, b, c = (r["color"][..., :3][on].astype(np.float64) for r in (lambert, wrap0, wrap1))
    np.testing.assert_allclose(b, a, atol=2e-3)
    assert (c >= b - 2e-3).all()
    assert (c - b).max() > 0.05


@pytest.mark.gl
@pytest.mark.cl
def test_gl_and_cl_agree_on_the_material_scene():
    gl, cl = render("gl"), render("cl")
    np.testing.assert_allclose(gl["color"].astype(np.float64), cl["color"], atol=2e-3)


FORWARD = """technique fwd "material.FIELD in a scene draw"
lights[4] { position: vec3, radius: float, color: vec3 }
material { model: uint = 0, emissive: vec3 = vec3(0), rim: float = 0, wrap: float = 0.5 }
target color : rgba32f clear 0
target ids : rgba32f clear 0
target ds : d24s8 clear depth 1.0
output color
pass p {
  draw scene
  writes color, ids
  depth ds less write
  fragment {
    color = vec4(material.emissive, float(material.model) + material.rim + material.wrap);
    ids = vec4(float(object_id));
  }
}
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_material_fields_of_the_drawn_object_in_a_scene_draw(backend):
    """Each object's pixels hold exactly its fields (rgba32f: the float32 values themselves)."""
    out = compile_source(FORWARD, "fwd.pipe").pipeline(backend).render(load_scene(SCENE))
    table = load_scene(SCENE).material_table(SCHEMA).astype(np.float32)
    ids = out["ids"][..., 0].astype(int)
    for object_id in range(1, 6):
        on = ids == object_id
        assert on.sum() > 10
        fields = table[object_id]
        want = [*fields[1, :3], fields[0, 0] + fields[2, 0] + fields[3, 0]]
        np.testing.assert_array_equal(out["color"][on], np.broadcast_to(np.float32(want),
                                                                        out["color"][on].shape))


def test_the_ir_printer_writes_the_block_as_declared():
    from pipegen.frontend import parse as syntax
    from pipegen.ir.printer import print_technique
    text = print_technique(compile_file(PIPE).technique)
    assert ("material { model: uint = 0, emissive: vec3 = vec3(0.0, 0.0, 0.0), rim: float = 0.0,"
            in text)
    assert "materials[id].emissive" in text
    syntax.parse(text, "two.ir")                     # reads like .pipe


def test_materials_with_fields_stay_hashable():
    scene = load_scene(SCENE)
    assert len({o.material for o in scene.objects}) == 5
