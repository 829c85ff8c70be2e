"""Every class of user error the front end reports: a ``PipegenError`` rendered as
``file:line:col``, the source line, a caret under the offending token, and a hint."""

import dataclasses
import re
import sys
import types

import pytest

from pipegen.ir import nodes as ir
from pipegen.frontend.lower import lowerer as lower
from pipegen.frontend import parse as syntax
from pipegen.core.diagnostics import PipegenError

BASE = """\
technique t "error fixture"
lights[8] {{ position: vec3, radius: float, color: vec3 }}
target color : rgba8 clear (0, 0, 0, 1)
target ds : d24s8 clear depth 1.0 stencil 0
target dz : d32f clear depth 1.0
target idx : rgba8 clear 0
target hdr : rgba16f clear 0
target ids : r32ui
{decls}
pass main {{
  {draw}
  writes {writes}
  {depth}
{state}
  fragment {{
{body}
  }}
}}
{after}
"""


def fixture(decls="", state="", body="    color = vec4(albedo, 1.0);", writes="color",
            depth="depth ds less write", draw="draw scene.opaque", after=""):
    return BASE.format(decls=decls, state=state, body=body, writes=writes, depth=depth,
                       draw=draw, after=after)


def without_lights(source):
    return source.replace("lights[8] { position: vec3, radius: float, color: vec3 }\n", "")


def fullscreen(body, decls="", state=""):
    return fixture(decls=decls, state=state, body=body, draw="draw fullscreen", depth="")


def lights_pass(body, decls="", state=""):
    return fixture(decls=decls, state=state, body=body, draw="draw lights as sphere",
                   depth="depth ds gequal nowrite")


@dataclasses.dataclass
class Case:
    id: str
    source: str
    token: str               # the text the caret must point at
    words: tuple             # in the message (case-insensitive)
    line_has: str = ""       # a substring of the reported line (default: token)
    params: dict = None
    files: dict = None       # included files: path -> text


CASES = [
    # -- syntax --------------------------------------------------------------------------------
    Case("syntax", fixture(body="    color = vec4(albedo 1.0);"), "1.0", ("expected",)),
    Case("technique_missing", "target color : rgba8\n", "target", ("technique",)),
    # -- unknown things ------------------------------------------------------------------------
    Case("unknown_name", fixture(body="    color = vec4(albdo, 1.0);"), "albdo",
         ("unknown name 'albdo'",)),
    Case("unknown_format", fixture(decls="target gbuf : rgba9"), "rgba9",
         ("unknown format 'rgba9'",)),
    Case("unknown_builtin", fixture(body="    color = vec4(saturate(albedo), 1.0);"),
         "saturate", ("unknown function 'saturate'",)),
    Case("unknown_packing_scheme", fixture(decls="pack p = zigzag(target: idx)"), "zigzag",
         ("unknown packing scheme 'zigzag'",)),
    Case("unknown_type", fixture(body="    vec5 v;\n    color = vec4(1.0);"), "vec5",
         ("unknown type",)),
    Case("unknown_light_field", lights_pass("    color = vec4(light.colour, 1.0);"),
         "colour", ("no field 'colour'",)),
    Case("unknown_schema_field", without_lights(fixture(decls="lights[4] { brightness: float }")),
         "brightness", ("no field",), line_has="lights[4]"),
    Case("unknown_material", fixture(draw="draw scene.glass"), "glass", ("material",)),
    Case("unknown_target_read", fullscreen("    color = load(gbuffer);"), "gbuffer",
         ("unknown target",)),
    Case("unknown_packing_function", fixture(
        decls="pack s = bitplanes(target: idx)",
        body="    color = vec4(float(s.decode(1u)));"), "decode", ("no function 'decode'",)),
    # -- types ---------------------------------------------------------------------------------
    Case("type_mismatch_declaration", fixture(body="    float x = vec3(1.0);\n"
                                                   "    color = vec4(x);"),
         "vec3(1.0)", ("float", "vec3")),
    Case("type_mismatch_vector_sizes", fixture(body="    vec4 v = albedo + frag_coord;\n"
                                                    "    color = v;"),
         "albedo + frag_coord", ("vec3", "vec4")),
    Case("int_float_mixing", fixture(body="    float x = specular * 2;\n    color = vec4(x);"),
         "specular * 2", ("float", "int")),
    Case("no_overload", fixture(body="    vec3 c = clamp(albedo, 0, 1);\n"
                                     "    color = vec4(c, 1.0);"),
         "clamp", ("clamp", "vec3, int, int")),
    Case("wrong_argument_type", fixture(decls="float f(float x) { return x; }",
                                        body="    color = vec4(f(albedo));"),
         "albedo", ("argument 'x'", "float", "vec3"), line_has="color = vec4(f("),
    Case("wrong_argument_count", fixture(decls="float f(float x) { return x; }",
                                         body="    color = vec4(f(1.0, 2.0));"),
         "f(1.0", ("takes 1 argument",), line_has="color = vec4(f("),
    Case("condition_not_bool", fixture(body="    if (specular) discard;\n"
                                            "    color = vec4(1.0);"),
         "specular", ("bool",), line_has="if (specular)"),
    Case("bad_swizzle", fixture(body="    color = vec4(albedo.xyw, 1.0);"), "xyw",
         ("no component 'w'",)),
    Case("index_out_of_range", fixture(body="    color = vec4(albedo[3]);"), "3",
         ("out of range",), line_has="albedo[3]"),
    Case("void_value", fixture(decls="void f() { }",
                               body="    float x = f();\n    color = vec4(x);"),
         "f()", ("returns no value",), line_has="float x"),
    Case("output_too_narrow", fixture(body="    color = albedo;"), "albedo",
         ("vec4", "vec3"), line_has="color = albedo"),
    Case("integer_target_float_write", fixture(writes="color, ids",
                                               body="    color = vec4(1.0);\n"
                                                    "    ids = 1.0;"),
         "1.0", ("uint",), line_has="ids = 1.0"),
    Case("sample_integer_target", fullscreen("    color = vec4(sample(ids, vec2(0.5)));",
                                             state="  reads ids"),
         "sample", ("integer target 'ids'",)),
    Case("format_param_as_value", fixture(decls="param fmt = rgba16f",
                                          body="    color = vec4(fmt);"),
         "fmt", ("format",), line_has="color = vec4(fmt)"),
    # -- attachments ---------------------------------------------------------------------------
    Case("undeclared_write", fixture(body="    idx = vec4(1.0);"), "idx",
         ("does not declare", "idx"), line_has="idx = vec4"),
    Case("undeclared_read", fixture(body="    color = load(hdr);"), "hdr",
         ("does not declare", "hdr"), line_has="load(hdr)"),
    Case("depth_written_as_colour", fixture(body="    color = vec4(1.0);\n    ds = vec4(1.0);"),
         "ds", ("depth target",), line_has="ds = vec4"),
    Case("depth_target_in_writes", fixture(writes="color, ds"), "ds", ("depth target",),
         line_has="writes color, ds"),
    Case("writes_and_reads_same_target", fixture(state="  reads color"), "color",
         ("both writes and reads",), line_has="reads color"),
    Case("depth_write_while_reading_it", fixture(state="  reads ds"), "depth",
         ("writes depth", "reading"), line_has="depth ds less"),
    Case("not_a_depth_target", fixture(depth="depth hdr less"), "hdr", ("not a depth target",)),
    Case("stencil_on_d32f", fixture(depth="depth dz less write",
                                    state="  stencil { func equal ref 1 }"),
         "stencil", ("stencil target",)),
    Case("stencil_without_depth", fullscreen("    color = vec4(1.0);",
                                             state="  stencil { func equal ref 1 }"),
         "stencil", ("stencil target",)),
    Case("blend_integer_target", fixture(writes="color, ids",
                                         state="  blend ids add(one, one)",
                                         body="    color = vec4(1.0);\n    ids = 1u;"),
         "blend ids", ("integer target",)),
    Case("blend_unwritten_target", fixture(state="  blend hdr add(one, one)"), "hdr",
         ("does not write",), line_has="blend hdr"),
    Case("min_with_factors", fixture(state="  blend color min(one, one)"), "one",
         ("ignores factors",), line_has="blend color"),
    Case("add_without_factors", fixture(state="  blend color add"), "add",
         ("needs factors",), line_has="blend color"),
    Case("mask_missing_channel", fixture(decls="target two : rg8", writes="color, two",
                                         state="  mask two rb",
                                         body="    color = vec4(1.0);\n    two = vec2(1.0);"),
         "rb", ("no b channel",)),
    Case("written_never_assigned", fixture(writes="color, hdr"), "writes",
         ("never writes it",), line_has="writes color, hdr"),
    Case("writes_without_fragment", "technique t\ntarget color : rgba8\n"
                                    "pass p { draw scene writes color }\n",
         "writes", ("no fragment body",)),
    Case("draws_nothing", "technique t\ntarget color : rgba8\npass p { writes color }\n",
         "p", ("draws nothing",), line_has="pass p"),
    Case("clear_colour_on_depth", fixture(decls="target d2 : d32f clear (1, 1, 1, 1)"),
         "clear", ("depth target",)),
    Case("clear_stencil_without_bits", fixture(decls="target d2 : d32f clear depth 1.0 stencil 0"),
         "0", ("no stencil",), line_has="target d2"),
    Case("light_set_needs_channel_slots", lights_pass(
        "    color = vec4(1.0);", decls="pack s = bitplanes(target: idx)").replace(
        "draw lights as sphere", "draw lights as sphere in s[0]"),
         "s[0]", ("channel_slots",), line_has="in s[0]"),
    # -- where things are available ------------------------------------------------------------
    Case("cone_without_direction_fields",
         fixture(body="    color = vec4(1.0);", draw="draw lights as cone",
                 depth="depth ds gequal nowrite"), "cone", ("direction", "cos_outer")),
    Case("light_outside_light_pass", fixture(body="    color = vec4(light.color, 1.0);"),
         "light.color", ("light",)),
    Case("scene_input_in_fullscreen_pass", fullscreen("    color = vec4(albedo, 1.0);"),
         "albedo", ("scene",)),
    Case("scene_input_in_light_pass", lights_pass("    color = vec4(normal, 1.0);"),
         "normal", ("scene",)),
    Case("scene_input_through_function", fullscreen(
        "    color = vec4(base(), 1.0);", decls="vec3 base() { return albedo; }"),
         "base", ("scene input 'albedo'",), line_has="color = vec4(base"),
    Case("light_through_function", fixture(
        decls="vec3 lc() { return light.color; }", body="    color = vec4(lc(), 1.0);"),
         "lc", ("light",), line_has="color = vec4(lc"),
    Case("read_through_function", fullscreen(
        "    color = hdr_of();", decls="vec4 hdr_of() { return load(hdr); }"),
         "hdr_of", ("reads target 'hdr'",), line_has="color = hdr_of"),
    Case("write_target_in_function", fixture(decls="void w() { color = vec4(1.0); }"),
         "color", ("writes target",), line_has="void w()"),
    # -- control flow --------------------------------------------------------------------------
    Case("non_constant_loop_bound", fixture(
        body="    for (int i = 0; i < int(num_lights); i++) { }\n    color = vec4(1.0);"),
         "int(num_lights)", ("not a constant",)),
    # a run-time bound of another type: said first that it is run-time (retyping the counter
    # to uint, as a type error would suggest, only meets that error next)
    Case("non_constant_loop_bound_of_another_type", fixture(
        body="    for (int i = 0; i < num_lights; i++) { }\n    color = vec4(1.0);"),
         "num_lights", ("not a constant",)),
    Case("loop_bound_of_another_type", fixture(
        body="    for (int i = 0; i < 4u; i++) { }\n    color = vec4(1.0);"),
         "4u", ("loop counter 'i' is an int, but its bound is a uint",)),
    Case("loop_condition_form", fixture(
        body="    for (int i = 0; i <= 4; i++) { }\n    color = vec4(1.0);"),
         "i <= 4", ("i < BOUND",)),
    Case("loop_step", fixture(
        body="    for (int i = 0; i < 4; i += 2) { }\n    color = vec4(1.0);"),
         "i += 2", ("steps",)),
    Case("assign_loop_counter", fixture(
        body="    for (int i = 0; i < 4; i++) { i = 0; }\n    color = vec4(1.0);"),
         "i = 0; }", ("loop counter",), line_has="i = 0; }"),
    Case("break_outside_loop", fixture(body="    break;\n    color = vec4(1.0);"), "break",
         ("outside a loop",)),
    Case("missing_return", fixture(decls="float f(float x) { if (x > 0.0) { return x; } }"),
         "f(", ("without returning",), line_has="float f"),
    Case("return_value_from_fragment", fixture(body="    color = vec4(1.0);\n    return 1.0;"),
         "1.0;", ("returns no value",), line_has="return 1.0"),
    Case("recursion", fixture(decls="float f(float x) { return f(x); }"), "f(x)",
         ("recursive",), line_has="float f"),
    Case("assign_parameter", fixture(decls="param k = 1.0", body="    k = 2.0;\n"
                                                               "    color = vec4(1.0);"),
         "k", ("parameter 'k'",), line_has="k = 2.0"),
    Case("assign_input", fixture(body="    albedo = vec3(1.0);\n    color = vec4(1.0);"),
         "albedo", ("stage input",), line_has="albedo = vec3"),
    Case("no_effect", fixture(body="    albedo + albedo;\n    color = vec4(1.0);"),
         "albedo + albedo", ("no effect",)),
    # -- duplicates ----------------------------------------------------------------------------
    Case("duplicate_global", fixture(decls="param hdr = 1.0"), "hdr",
         ("duplicate name 'hdr'",), line_has="param hdr"),
    Case("duplicate_target", fixture(decls="target idx : rgba16f"), "idx", ("duplicate",),
         line_has="target idx : rgba16f"),
    Case("duplicate_local", fixture(body="    float a = 1.0;\n    float a = 2.0;\n"
                                         "    color = vec4(a);"),
         "a", ("already declared",), line_has="float a = 2.0"),
    Case("local_shadows_input", fixture(body="    vec3 normal = vec3(1.0);\n"
                                             "    color = vec4(1.0);"),
         "normal", ("stage input",), line_has="vec3 normal"),
    Case("duplicate_pass", fixture(after="pass main { draw fullscreen }"), "main",
         ("duplicate pass",), line_has="pass main { draw"),
    Case("duplicate_statement", fixture(state="  cull back\n  cull front"), "cull front",
         ("two `cull`",)),
    Case("reserved_name", fixture(decls="param normal = 1.0"), "normal", ("reserved",)),
    # -- declarations --------------------------------------------------------------------------
    Case("output_not_declared", fixture(decls="output final"), "final", ("not declared",)),
    Case("param_default_not_allowed", fixture(decls="param q = 3 in {1, 2}"), "3",
         ("allowed",), line_has="param q"),
    Case("param_override_not_allowed", fixture(decls="param q = 1 in {1, 2}"), "q",
         ("allowed",), line_has="param q", params={"q": 5}),
    Case("param_wrong_type", fixture(decls="param q : int = 1.5"), "1.5", ("int",)),
    Case("size_not_integer", fixture(decls="target s : r8 size 100.5 x 20"), "100.5",
         ("integer",)),
    Case("bad_sample_count", fixture(decls="target s : r8 samples 3"), "3", ("samples",),
         line_has="target s"),
    Case("bad_light_capacity", without_lights(fixture(decls="lights[0] { radius: float }")), "0",
         ("capacity",), line_has="lights[0]"),
    Case("light_field_type", without_lights(fixture(decls="lights[4] { radius: vec3 }")), "vec3",
         ("radius",), line_has="lights[4]"),
    Case("pack_target_unknown", fixture(decls="pack s = bitplanes(target: nope)"), "nope",
         ("unknown target",)),
    Case("include_missing", fixture(decls='include "nope.pipe"'), 'include "nope.pipe"',
         ("cannot read",)),
    # reported in b.pipe, at the include that closes the cycle
    Case("include_cycle", fixture(decls='include "a.pipe"'), 'include "a.pipe"',
         ("includes itself",), files={"a.pipe": 'include "b.pipe"',
                                      "b.pipe": 'include "a.pipe"'}),
    Case("include_declares_target", fixture(decls='include "lib.pipe"'), "target",
         ("included file",), files={"lib.pipe": "target x : rgba8"}),
]


@pytest.fixture
def packing(monkeypatch):
    """A stand-in for pipegen.packing.schemes (another part of the project)."""
    @dataclasses.dataclass
    class Spec:
        functions_source: str
        constants: dict
        capacity: object = None
        error: object = None
        notes: tuple = ()

    def build(name, scheme, options, target_format, span):
        return Spec(f"vec4 {name}_value(uint i) {{ return vec4(float(i)); }}",
                    {"capacity": (ir.INT, 4)})

    mod = types.ModuleType("pipegen.packing.schemes")
    mod.build, mod.SCHEMES = build, ("bitplanes", "channel_slots")
    monkeypatch.setitem(sys.modules, "pipegen.packing.schemes", mod)


def front_end(source: str, params=None, files=None):
    files = files or {}

    def loader(path):
        if path not in files:
            raise FileNotFoundError(2, "No such file or directory")
        return files[path]

    return lower.lower(syntax.parse(source, "t.pipe"), "t.pipe", params, loader)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_error_is_located_and_explained(case, packing):
    with pytest.raises(PipegenError) as info:
        front_end(case.source, case.params, case.files)
    err = info.value
    rendered = err.render()
    text = case.files.get(err.span.file, case.source) if case.files else case.source
    marker = case.line_has or case.token
    candidates = [i + 1 for i, l in enumerate(text.splitlines()) if marker in l]
    m = re.search(r"^(\S+):(\d+):(\d+): error: (.*)$", rendered, re.M)
    assert m, rendered
    line = int(m.group(2))
    assert line in candidates, rendered
    col = int(m.group(3))
    src_line = text.splitlines()[line - 1]
    assert src_line[col - 1:].startswith(case.token), (src_line, col, rendered)
    lines = rendered.splitlines()
    quoted = next(i for i, l in enumerate(lines) if l.endswith(src_line))
    gutter = lines[quoted].index(src_line)
    assert lines[quoted + 1].index("^") - gutter == col - 1, rendered
    assert lines[-1].startswith("hint: ") and len(lines[-1]) > len("hint: "), rendered
    for word in case.words:
        assert word.lower() in err.message.lower(), rendered


def test_unknown_override_has_no_location_but_a_hint(packing):
    with pytest.raises(PipegenError) as info:
        front_end(fixture(decls="param q = 1"), params={"z": 1})
    assert info.value.span is None
    assert "unknown parameter 'z'" in info.value.render()
    assert "q" in info.value.hint


def test_hint_suggests_a_close_name(packing):
    with pytest.raises(PipegenError) as info:
        front_end(fixture(body="    color = vec4(albdo, 1.0);"))
    assert info.value.hint == "did you mean 'albedo'?"


def test_errors_in_included_files_name_that_file(packing):
    files = {"lib.pipe": "float f(float x) {\n  return x + 1;\n}\n"}
    with pytest.raises(PipegenError) as info:
        front_end(fixture(decls='include "lib.pipe"'), files=files)
    assert info.value.render().startswith("lib.pipe:2:10: error:")
