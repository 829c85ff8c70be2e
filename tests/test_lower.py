"""Lowering: names, parameters, targets, packings, typed shader IR and pass state; the IR
verifier accepts what lowering produces and rejects broken IR."""

import dataclasses
import sys
import types
from pathlib import Path

import pytest

from pipegen.ir import builtins, nodes as ir, verify
from pipegen.frontend.lower import lowerer as lower
from pipegen.frontend import parse as syntax
from pipegen.core.diagnostics import PipegenError
from pipegen.core.formats import FORMATS

ROOT = Path(__file__).resolve().parent.parent

HEADER = """technique t "test"
lights[16] { position: vec3, radius: float, color: vec3 }
target color : rgba8 clear (0, 0, 0, 1)
target ds : d24s8 clear depth 1.0 stencil 0
"""


def compile_ir(text: str, params=None, files=None, filename="/src/t.pipe") -> ir.Technique:
    """Parse + lower + verify; ``files`` are included files by absolute path."""
    files = files or {}

    def loader(path):
        if path not in files:
            raise FileNotFoundError(2, "No such file or directory")
        return files[path]

    tech = lower.lower(syntax.parse(text, filename), filename, params, loader)
    verify.verify(tech)
    return tech


def frag(body: str, decls: str = "", state: str = "", draw: str = "draw scene") -> ir.Pass:
    """A technique with one pass writing ``color``; returns that pass."""
    text = (HEADER + decls
            + f"\npass p {{\n{draw}\nwrites color\n{state}\nfragment {{\n{body}\n}}\n}}")
    return compile_ir(text).passes[0]


def value_of(body: str, decls: str = "", draw: str = "draw scene") -> ir.Expr:
    """The initialiser of the first declaration in a fragment body."""
    p = frag(body + "\ncolor = vec4(1.0);", decls, draw=draw)
    return p.body[0].init


# A stand-in for pipegen.packing.schemes (written by another part of the project): just enough for the
# front end's side of the contract (internals.md, "Packing schemes").
_STUB_SOURCES = {
    "bitplanes": "vec4 {n}_plane_value(uint index) {{ return vec4(float({n}_low(index))); }}\n"
                 "uint {n}_unpack(vec4 v, int k) {{ return uint(v[k] * 255.0 + 0.5); }}\n"
                 "uint {n}_low(uint i) {{ return i & 3u; }}\n",
    "channel_slots": "vec4 {n}_value(uint index) {{ return vec4(float(index) / 255.0); }}\n",
    "bitfield": "uint {n}_pack(uint a, uint b) {{ return (a << 8u) | b; }}\n",
}


@dataclasses.dataclass
class _StubSpec:
    functions_source: str
    constants: dict
    capacity: object = None
    error: object = None
    notes: tuple = ()


@pytest.fixture
def packing(monkeypatch):
    calls = []

    def build(name, scheme, options, target_format, span):
        calls.append((name, scheme, options, target_format, span))
        consts = {"capacity": (ir.INT, 4), "blend_constant": (ir.FLOAT, 0.25)}
        return _StubSpec(_STUB_SOURCES[scheme].format(n=name), consts, 4, 0.002, ("stub",))

    mod = types.ModuleType("pipegen.packing.schemes")
    mod.build, mod.SCHEMES, mod.calls = build, tuple(_STUB_SOURCES), calls
    monkeypatch.setitem(sys.modules, "pipegen.packing.schemes", mod)
    return mod


# ---------------------------------------------------------------------------------------------
# Shipped techniques
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["forward", "deferred", "forward_multipass"])
def test_shipped_pipelines_lower(name):
    path = ROOT / "pipelines" / f"{name}.pipe"
    tech = lower.lower(syntax.parse(path.read_text(), str(path)), str(path))
    verify.verify(tech)
    assert tech.name == name and tech.output == "color"
    assert {f.name for f in tech.functions} >= {"attenuation", "blinn_phong"}


def test_deferred_repeat_block_is_one_group():
    path = ROOT / "pipelines" / "deferred.pipe"
    tech = lower.lower(syntax.parse(path.read_text(), str(path)), str(path))
    groups = {p.name: p.repeat_group for p in tech.passes}
    assert groups["mark"] == groups["shade_light_volume"] == 0
    assert groups["gbuffer"] is None and groups["resolve"] is None
    mark = next(p for p in tech.passes if p.name == "mark")
    assert mark.clears == (("ds", ir.Clear(stencil=0)),)
    assert mark.state.stencil.back.zfail is ir.StencilOp.INCR_WRAP
    assert mark.state.stencil.front.zfail is ir.StencilOp.DECR_WRAP
    assert mark.body == () and mark.writes == ()


# ---------------------------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------------------------

PARAMS = HEADER + """param scale = 0.5 in {0.5, 1.0}
param n = 4
param mask_bits : uint = 3
param flag = false
param fmt = rgba16f in {rgba8, rgba16f}
target lbuf : fmt size output * scale clear 0
pass p { draw scene writes color fragment {
  float s = scale; int k = n; uint m = mask_bits; bool b = flag;
  color = vec4(s);
} }
"""


def test_param_types_and_defaults():
    tech = compile_ir(PARAMS)
    got = {p.name: (p.type, p.default, p.allowed) for p in tech.params}
    assert got["scale"] == (ir.FLOAT, 0.5, (0.5, 1.0))
    assert got["n"] == (ir.INT, 4, ())
    assert got["mask_bits"] == (ir.UINT, 3, ())
    assert got["flag"] == (ir.BOOL, False, ())
    assert got["fmt"] == (ir.VOID, "rgba16f", ("rgba8", "rgba16f"))   # format parameter
    lbuf = tech.target("lbuf")
    assert lbuf.format is FORMATS["rgba16f"] and lbuf.size == ir.Size(scale=0.5)
    inits = [s.init for s in tech.passes[0].body[:4]]
    assert inits == [ir.Var("scale", ir.FLOAT, "param"), ir.Var("n", ir.INT, "param"),
                     ir.Var("mask_bits", ir.UINT, "param"), ir.Var("flag", ir.BOOL, "param")]


def test_param_overrides_values_and_spellings():
    tech = compile_ir(PARAMS, params={"scale": "1.0", "n": 7, "fmt": "rgba8", "flag": "true"})
    values = {p.name: p.default for p in tech.params}
    assert values == {"scale": 1.0, "n": 7, "mask_bits": 3, "flag": True, "fmt": "rgba8"}
    lbuf = tech.target("lbuf")
    assert lbuf.format is FORMATS["rgba8"] and lbuf.size.scale == 1.0


def test_param_override_errors():
    with pytest.raises(PipegenError, match="not an allowed value"):
        compile_ir(PARAMS, params={"scale": 0.7})
    with pytest.raises(PipegenError, match="unknown parameter 'nope'"):
        compile_ir(PARAMS, params={"nope": 1})
    with pytest.raises(PipegenError, match="is an int"):
        compile_ir(PARAMS, params={"n": 1.5})


def test_params_in_declarations():
    header = HEADER.replace("lights[16] { position: vec3, radius: float, color: vec3 }\n", "")
    tech = compile_ir(header + """param w = 640
param cap = 8
param half = 0.5
lights[cap] { radius: float }
target small : r32f size w x 360 clear half
pass p { draw fullscreen writes small fragment { small = 1.0; } }""")
    small = tech.target("small")
    assert small.size == ir.Size(width=640, height=360)
    assert small.clear.color == (0.5, 0.5, 0.5, 0.5)
    assert tech.lights.capacity == 8


# ---------------------------------------------------------------------------------------------
# Targets, lights, output
# ---------------------------------------------------------------------------------------------

def test_targets_and_clear_defaults():
    tech = compile_ir(HEADER + """target a : rg16f samples 4
target z : d32f size 1024 x 1024
target u : r32ui clear 7
target h : rg8 clear (1, 0)
pass p { draw scene writes color fragment { color = vec4(1.0); } }""")
    a, z, u, h = (tech.target(n) for n in "azuh")
    assert a.samples == 4 and a.clear == ir.Clear(color=(0.0, 0.0, 0.0, 0.0))
    assert z.size == ir.Size(width=1024, height=1024) and z.clear == ir.Clear(depth=0.0)
    assert u.clear.color == (7.0, 7.0, 7.0, 7.0)
    assert h.clear.color == (1.0, 0.0, 0.0, 0.0)
    assert tech.target("ds").clear == ir.Clear(depth=1.0, stencil=0)
    assert tech.target("color").clear.color == (0.0, 0.0, 0.0, 1.0)


def test_light_schema_and_output_default():
    tech = compile_ir(HEADER + "pass p { draw scene writes color fragment { color = vec4(1.0); } }")
    assert tech.lights.capacity == 16
    assert [(f.name, f.type) for f in tech.lights.fields] == [
        ("position", ir.VEC3), ("radius", ir.FLOAT), ("color", ir.VEC3)]
    assert tech.output == "color"
    no_lights = compile_ir('technique t\ntarget img : rgba8\noutput img\n'
                           'pass p { draw fullscreen writes img fragment { img = vec4(1.0); } }')
    assert no_lights.lights == ir.LightTable((), 0) and no_lights.output == "img"


# ---------------------------------------------------------------------------------------------
# Shader code -> typed IR
# ---------------------------------------------------------------------------------------------

def test_literals_and_negation():
    assert value_of("float x = -1.5;") == ir.Const(ir.FLOAT, -1.5)
    assert value_of("int x = -3;") == ir.Const(ir.INT, -3)
    assert value_of("uint x = -1u;") == ir.Const(ir.UINT, 0xFFFFFFFF)
    assert value_of("bool x = true;") == ir.Const(ir.BOOL, True)
    assert value_of("float x = +specular;") == ir.Var("specular", ir.FLOAT, "input")
    neg = value_of("vec3 x = -albedo;")
    assert neg == ir.Unary("-", ir.Var("albedo", ir.VEC3, "input"), ir.VEC3)


def test_swizzles_are_normalised_to_xyzw():
    s = value_of("vec2 x = frag_coord.ba;")
    assert s == ir.Swizzle(ir.Var("frag_coord", ir.VEC4, "input"), "zw", ir.VEC2)
    assert value_of("float x = albedo.g;").components == "y"
    assert value_of("vec3 x = albedo.stp;") == ir.Var("albedo", ir.VEC3, "input")   # identity


def test_operators_typed():
    e = value_of("vec3 x = albedo * 2.0 + normal;")
    assert isinstance(e, ir.Binary) and e.op == "+" and e.type == ir.VEC3
    assert e.left.type == ir.VEC3 and e.left.right == ir.Const(ir.FLOAT, 2.0)
    m = value_of("vec4 x = proj * view * vec4(world_pos, 1.0);")
    assert m.type == ir.VEC4 and m.left.type == ir.MAT4
    b = value_of("uint x = (object_id << 8u) | normal_group & 255u;")
    assert b.op == "|" and b.type == ir.UINT and b.right.op == "&"
    t = value_of("float x = specular > 0.5 ? 1.0 : 0.0;")
    assert isinstance(t, ir.Ternary) and t.cond.type == ir.BOOL


def test_constructors_in_normal_form():
    v = ir.Var("frag_coord", ir.VEC4, "input")
    assert value_of("vec3 x = vec3(frag_coord);") == ir.Swizzle(v, "xyz", ir.VEC3)
    assert value_of("vec4 x = vec4(frag_coord);") == v
    ints = value_of("vec4 x = vec4(1, 0, 0, 1);")
    assert ints == ir.Construct(ir.VEC4, tuple(ir.Const(ir.FLOAT, float(c)) for c in (1, 0, 0, 1)))
    conv = value_of("vec2 x = vec2(ivec2(frag_coord.xy));")
    assert conv.type == ir.VEC2 and conv.args[0].type == ir.IVEC2
    mixed = value_of("vec4 x = vec4(albedo.xy, object_id, 1.0);")
    assert [a.type for a in mixed.args] == [ir.VEC2, ir.FLOAT, ir.FLOAT]
    assert mixed.args[1] == ir.Construct(ir.FLOAT, (ir.Var("object_id", ir.UINT, "input"),))
    assert value_of("float x = float(3);") == ir.Const(ir.FLOAT, 3.0)
    assert value_of("uint x = uint(specular);") == ir.Construct(
        ir.UINT, (ir.Var("specular", ir.FLOAT, "input"),))
    bcast = value_of("vec3 x = vec3(1);")
    assert bcast == ir.Construct(ir.VEC3, (ir.Const(ir.FLOAT, 1.0),))
    m3 = value_of("mat3 x = mat3(view);")
    assert m3 == ir.Construct(ir.MAT3, (ir.Var("view", ir.MAT4, "input"),))
    cols = value_of("mat3 x = mat3(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);")
    assert [a.type for a in cols.args] == [ir.VEC3] * 3


def test_builtin_calls_resolve_overloads():
    assert value_of("vec3 x = clamp(albedo, 0.0, 1.0);").type == ir.VEC3
    assert value_of("vec3 x = mix(albedo, normal, 0.5);").type == ir.VEC3
    assert value_of("vec3 x = step(0.5, albedo);").type == ir.VEC3
    assert value_of("int x = max(1, 2);").type == ir.INT
    assert value_of("uint x = min(object_id, 3u);").type == ir.UINT
    assert value_of("float x = dot(normal, albedo);").type == ir.FLOAT
    call = value_of("float x = length(albedo);")
    assert call == ir.Call("length", (ir.Var("albedo", ir.VEC3, "input"),), ir.FLOAT, True)


@pytest.mark.parametrize("name, args, result", [
    ("clamp", ["vec3", "float", "float"], "vec3"),
    ("clamp", ["ivec2", "int", "int"], "ivec2"),
    ("clamp", ["vec3", "float", "int"], None),
    ("mix", ["vec4", "vec4", "vec4"], "vec4"),
    ("mix", ["float", "float", "bool"], None),
    ("smoothstep", ["float", "float", "vec2"], "vec2"),
    ("step", ["vec2", "vec3"], None),
    ("abs", ["int"], "int"),
    ("abs", ["uint"], None),
    ("mod", ["vec3", "float"], "vec3"),
    ("atan", ["float", "float"], "float"),
    ("cross", ["vec3", "vec3"], "vec3"),
    ("cross", ["vec2", "vec2"], None),
    ("normalize", ["ivec3"], None),
    ("pow", ["float", "float", "float"], None),
])
def test_builtin_overload_table(name, args, result):
    types_ = [ir.parse_type(a) for a in args]
    expected = ir.parse_type(result) if result else None
    assert builtins.resolve_builtin(name, types_) == expected


@pytest.mark.parametrize("op, a, b, result", [
    ("+", "vec3", "float", "vec3"), ("*", "float", "vec4", "vec4"), ("+", "vec3", "vec4", None),
    ("+", "float", "int", None), ("*", "mat4", "vec4", "vec4"), ("*", "vec3", "mat3", "vec3"),
    ("*", "mat3", "vec4", None), ("*", "mat4", "mat4", "mat4"), ("%", "int", "int", "int"),
    ("%", "float", "float", None), ("<<", "uint", "int", "uint"), ("<<", "uvec2", "uint", "uvec2"),
    ("&", "uvec4", "uint", "uvec4"), ("&", "float", "float", None), ("<", "vec2", "vec2", None),
    ("<", "uint", "uint", "bool"), ("==", "vec3", "vec3", "bool"), ("&&", "bool", "bool", "bool"),
    ("&&", "int", "int", None),
])
def test_operator_rules(op, a, b, result):
    got = builtins.binary_type(op, ir.parse_type(a), ir.parse_type(b))
    assert got == (ir.parse_type(result) if result else None)


def test_statements_lowered():
    p = frag("""
vec3 c = vec3(0.0);
for (int i = 0; i < 4; i++) {
  if (i == 2) continue;
  c.xy += vec2(1.0);
  c[i % 3] = 1.0;
  if (c.x > 3.0) break;
}
if (alpha < 0.5) discard; else c *= 2.0;
color = vec4(c, 1.0);""")
    decl, loop, branch, out = p.body
    assert isinstance(loop, ir.For) and loop.var == "i" and loop.type == ir.INT
    assert loop.start == ir.Const(ir.INT, 0) and loop.bound == ir.Const(ir.INT, 4)
    assert isinstance(loop.body[0].then[0], ir.Continue)
    swz = loop.body[1]
    assert swz.op == "+=" and swz.target == ir.Swizzle(ir.Var("c", ir.VEC3), "xy", ir.VEC2)
    assert isinstance(loop.body[2].target, ir.Index)
    assert isinstance(branch.then[0], ir.Discard) and branch.other[0].op == "*="
    assert isinstance(out, ir.Output) and out.target == "color"


def test_loop_bound_may_be_a_parameter():
    p = frag("for (int i = 0; i < n; i++) { }\ncolor = vec4(1.0);", decls="param n = 8\n")
    assert p.body[0].bound == ir.Var("n", ir.INT, "param")


@pytest.mark.parametrize("fmt, value, widened", [
    ("rgba8", "vec4(1.0)", None),
    ("r32f", "1.0", "vec4(x, 0, 0, 0)"),
    ("rg16f", "vec2(1.0)", "vec4(v, 0, 0)"),
    ("rg16f", "vec3(1.0)", "vec4(v, 0)"),
    ("r32ui", "7u", "uvec4(x, 0, 0, 0)"),
    ("rgba8ui", "uvec4(1u)", None),
])
def test_output_widening(fmt, value, widened):
    tech = compile_ir(HEADER + f"target o : {fmt}\n"
                      f"pass p {{ draw fullscreen writes o fragment {{ o = {value}; }} }}")
    out = tech.passes[0].body[0]
    want = builtins.target_write_type(FORMATS[fmt])
    assert out.value.type == want
    if widened is None:
        assert not (isinstance(out.value, ir.Construct) and len(out.value.args) > 1)
    else:
        pad = 4 - out.value.args[0].type.size
        assert len(out.value.args) == 1 + pad
        assert all(a == ir.Const(want.element, 0 if fmt.endswith("ui") else 0.0)
                   for a in out.value.args[1:])


def test_target_reads():
    tech = compile_ir(HEADER + """target g : rgba16f
target ids : r32ui
pass a { draw scene writes g, ids fragment { g = vec4(1.0); ids = 1u; } }
pass b { draw fullscreen reads g, ids, ds writes color fragment {
  vec4 x = load(g);
  uvec4 i = load(ids, ivec2(0, 0));
  vec4 s = sample(g, frag_coord.xy / output_size);
  ivec2 n = size(g);
  float z = load(ds);
  color = x;
} }""")
    body = tech.passes[1].body
    assert body[0].init == ir.Load("g", None, ir.VEC4)
    assert body[1].init.type == ir.UVEC4 and body[1].init.coord.type == ir.IVEC2
    assert isinstance(body[2].init, ir.Sample) and body[2].init.type == ir.VEC4
    assert body[3].init == ir.TargetSize("g", ir.IVEC2)
    assert body[4].init == ir.Load("ds", None, ir.FLOAT)


def test_light_access():
    p = frag("""
vec3 a = light.position;
uint i = light.index;
vec3 b = lights[i + 1u].color;
float r = lights[2].radius;
color = vec4(a + b, r);""", draw="draw lights as sphere")
    assert p.body[0].init == ir.LightField(None, "position", ir.VEC3)
    assert p.body[1].init == ir.LightField(None, "index", ir.UINT)
    assert p.body[2].init.index.type == ir.UINT and p.body[2].init.field == "color"
    assert p.body[3].init.index == ir.Const(ir.INT, 2)


def test_functions_are_ordered_callees_first():
    tech = compile_ir(HEADER + """
vec3 outer(vec3 x) { return inner(x) * 2.0; }
vec3 inner(vec3 x) { if (x.x > 0.0) { return x; } else { return -x; } }
void nothing() { }
pass p { draw scene writes color fragment { nothing(); color = vec4(outer(albedo), 1.0); } }""")
    assert [f.name for f in tech.functions] == ["inner", "outer", "nothing"]
    outer = tech.functions[1]
    assert outer.params == (("x", ir.VEC3),) and outer.ret == ir.VEC3
    call = outer.body[0].value.left
    assert call == ir.Call("inner", (ir.Var("x", ir.VEC3),), ir.VEC3, builtin=False)
    assert tech.passes[0].body[0] == ir.ExprStmt(ir.Call("nothing", (), ir.VOID, False))


def test_function_may_use_scene_inputs_when_called_from_scene_pass():
    tech = compile_ir(HEADER + """
vec3 lit() { return albedo * light.color; }
pass p { draw scene repeat per light writes color fragment { color = vec4(lit(), 1.0); } }""")
    assert tech.passes[0].repeat_group == 0


# ---------------------------------------------------------------------------------------------
# Includes
# ---------------------------------------------------------------------------------------------

def test_includes_resolve_relative_to_the_including_file():
    # lib/b.pipe is included twice (by t.pipe and lib/a.pipe) and spliced in once.
    files = {
        "/src/lib/a.pipe": 'include "b.pipe"\nparam k = 2.0\n'
                           'float twice(float x) { return helper(x) * k; }',
        "/src/lib/b.pipe": 'float helper(float x) { return x; }',
    }
    tech = compile_ir(HEADER + 'include "lib/a.pipe"\ninclude "lib/b.pipe"\n'
                      "pass p { draw scene writes color fragment { color = vec4(twice(1.0)); } }",
                      files=files)
    assert [f.name for f in tech.functions] == ["helper", "twice"]
    assert [p.name for p in tech.params] == ["k"]


# ---------------------------------------------------------------------------------------------
# Packings
# ---------------------------------------------------------------------------------------------

def test_packing_functions_and_constants(packing):
    tech = compile_ir(HEADER + """target idx : rgba8 clear 0
pack slots = bitplanes(index_bits: 8, target: idx, opts: (a: 1, b: 2))
pass mark { draw lights as sphere writes idx
  blend idx add(one, constant_color)
  blend constant slots.blend_constant
  fragment { idx = slots.plane_value(light.index + 1u); } }
pass shade { draw scene reads idx writes color fragment {
  vec3 c = vec3(0.0);
  for (int k = 0; k < slots.capacity; k++) { uint i = slots.unpack(load(idx), k); }
  color = vec4(c, 1.0);
} }""")
    ((name, scheme, options, fmt, span),) = packing.calls
    assert (name, scheme) == ("slots", "bitplanes")
    assert options == {"index_bits": 8, "target": "idx", "opts": {"a": 1, "b": 2}}
    assert fmt is FORMATS["rgba8"] and (span.line, span.column) == (6, 14)
    (pk,) = tech.packings
    assert pk.options == (("index_bits", 8), ("target", "idx"), ("opts", (("a", 1), ("b", 2))))
    assert [f.name for f in pk.functions] == ["slots_low", "slots_plane_value", "slots_unpack"]
    assert dict(pk.constants)["capacity"] == ir.Const(ir.INT, 4)
    assert (pk.capacity, pk.error, pk.notes) == (4, 0.002, ("stub",))
    assert tech.functions == ()                       # packing functions live in the packing
    mark, shade = tech.passes
    assert mark.state.blend_constant == (0.25,) * 4
    call = mark.body[0].value
    assert call.name == "slots_plane_value" and not call.builtin
    loop = shade.body[1]
    assert loop.bound == ir.Const(ir.INT, 4)
    assert loop.body[0].init.name == "slots_unpack"


def test_channel_slots_light_sets(packing):
    tech = compile_ir(HEADER + """target idx : rgba8 clear 0
pack slots = channel_slots(target: idx, slots: 4)
pass r { draw lights as sphere in slots[0] writes idx mask idx r
  fragment { idx = slots.value(light.index + 1u); } }
pass g { draw lights as sphere in slots[3] scissor writes idx mask idx g
  fragment { idx = slots.value(light.index + 1u); } }""")
    r, g = tech.passes
    assert r.draw.light_set == ("slots", 0) and g.draw.light_set == ("slots", 3)
    assert g.draw.scissor and g.draw.volume is ir.Volume.SPHERE
    assert r.state.blend == (("idx", ir.TargetBlend(write_mask=(True, False, False, False))),)


# ---------------------------------------------------------------------------------------------
# Pass state
# ---------------------------------------------------------------------------------------------

def test_depth_stencil_blend_state():
    # a cone volume needs the spot fields in the light schema
    tech = compile_ir(HEADER.replace("color: vec3 }", "color: vec3, direction: vec3, "
                                     "cos_outer: float }") + """target acc : rgba16f
target n : rgba8
pass p {
  draw lights as cone spot point scissor
  writes acc, n
  depth ds gequal nowrite clamp
  stencil front { func notequal ref 1 read 3 write 1 fail zero zfail invert pass replace }
  stencil back { func always }
  blend acc rgb add(one, one) alpha revsub(src_alpha, one_minus_src_alpha)
  blend n max
  mask n rgb
  blend constant 0.5
  cull front
  offset 1.0 -2
  clear acc (0, 0, 0, 1)
  fragment { acc = vec4(1.0); n = vec4(0.0); }
}""")
    p = tech.passes[0]
    assert p.draw == ir.Draw(ir.DrawKind.LIGHTS, volume=ir.Volume.CONE,
                             light_types=("point", "spot"), scissor=True)
    assert p.depth_target == "ds"
    assert p.state.depth == ir.DepthState(ir.CompareFunc.GEQUAL, write=False, clamp=True)
    assert p.state.stencil.front == ir.StencilFace(
        ir.CompareFunc.NOTEQUAL, 1, 3, 1, ir.StencilOp.ZERO, ir.StencilOp.INVERT,
        ir.StencilOp.REPLACE)
    assert p.state.stencil.back == ir.StencilFace()
    acc, n = p.state.blend
    assert acc == ("acc", ir.TargetBlend(
        True, ir.BlendEquation(ir.BlendOp.ADD, ir.BlendFactor.ONE, ir.BlendFactor.ONE),
        ir.BlendEquation(ir.BlendOp.REVSUB, ir.BlendFactor.SRC_ALPHA,
                         ir.BlendFactor.ONE_MINUS_SRC_ALPHA)))
    assert n == ("n", ir.TargetBlend(True, ir.BlendEquation(ir.BlendOp.MAX),
                                     ir.BlendEquation(ir.BlendOp.MAX), (True, True, True, False)))
    assert p.state.blend_constant == (0.5,) * 4
    assert p.state.cull is ir.CullMode.FRONT
    assert p.state.polygon_offset == ir.PolygonOffset(1.0, -2.0)
    assert p.clears == (("acc", ir.Clear(color=(0.0, 0.0, 0.0, 1.0))),)


def test_depth_defaults_and_off():
    tech = compile_ir(HEADER + """
pass a { draw scene depth ds less }
pass b { draw scene depth ds off stencil { func equal ref 1 } }
pass c { draw fullscreen writes color fragment { color = vec4(1.0); } }""")
    a, b, c = tech.passes
    assert a.state.depth == ir.DepthState(ir.CompareFunc.LESS, write=True)
    assert b.depth_target == "ds" and not b.state.depth.enabled and b.state.stencil.enabled
    assert c.depth_target is None and c.state.blend == (("color", ir.TargetBlend()),)
    assert c.state.cull is ir.CullMode.NONE


def test_repeat_groups():
    tech = compile_ir(HEADER + """
pass a { draw scene repeat per light depth ds less }
repeat per light {
  pass b { draw lights as sphere depth ds less }
  pass c { draw lights as sphere depth ds less }
}
pass d { draw fullscreen repeat per light depth ds less }
pass e { draw scene depth ds less }""")
    assert [p.repeat_group for p in tech.passes] == [0, 1, 1, 2, None]


# ---------------------------------------------------------------------------------------------
# The verifier rejects broken IR
# ---------------------------------------------------------------------------------------------

def _base() -> ir.Technique:
    return compile_ir(HEADER + """target g : rgba8
pass a { draw scene writes g fragment { vec3 c = albedo * 2.0; g = vec4(c, 1.0); } }
pass b { draw fullscreen reads g writes color fragment { color = load(g); } }""")


def _replace_pass(tech, i, **changes):
    passes = list(tech.passes)
    passes[i] = dataclasses.replace(passes[i], **changes)
    return dataclasses.replace(tech, passes=tuple(passes))


@pytest.mark.parametrize("breakage, words", [
    (lambda t: _replace_pass(t, 0, body=(ir.Declare("c", ir.VEC3, ir.Const(ir.FLOAT, 1.0)),)),
     "initialised"),
    (lambda t: _replace_pass(t, 0, body=(ir.ExprStmt(ir.Call("nope", (), ir.VOID, False)),)),
     "nope"),
    (lambda t: _replace_pass(t, 0, body=(ir.Output("g", ir.Var("zz", ir.VEC4)),)), "zz"),
    (lambda t: _replace_pass(t, 0, body=(ir.Declare("x", ir.VEC3, ir.Binary(
        "+", ir.Var("albedo", ir.VEC3, "input"), ir.Const(ir.FLOAT, 1.0), ir.VEC4)),)),
     r"vec3 \+ float"),
    (lambda t: _replace_pass(t, 1, body=(ir.Output("color", ir.Load("g", None, ir.VEC4)),),
                             reads=()), "without declaring"),
    (lambda t: _replace_pass(t, 1, body=(ir.Declare("x", ir.VEC3, ir.Var(
        "albedo", ir.VEC3, "input")),)), "scene input"),
    (lambda t: _replace_pass(t, 1, state=ir.PassState(blend=(("g", ir.TargetBlend()),))),
     "does not write"),
    (lambda t: _replace_pass(t, 0, depth_target="color"), "not a depth target"),
    (lambda t: dataclasses.replace(t, passes=tuple(
        dataclasses.replace(p, repeat_group=0 if i != 1 else None)
        for i, p in enumerate(t.passes + t.passes[:1]))), "duplicate pass"),
    (lambda t: dataclasses.replace(t, output="ds"), "not a colour target"),
    (lambda t: _replace_pass(t, 1, body=(ir.Break(),)), "outside a loop"),
])
def test_verify_rejects_broken_ir(breakage, words):
    tech = _base()
    verify.verify(tech)
    with pytest.raises(AssertionError, match=words):
        verify.verify(breakage(tech))


def test_verify_repeat_groups_must_be_contiguous():
    tech = compile_ir(HEADER + """
pass a { draw scene repeat per light depth ds less }
pass b { draw scene depth ds less }
pass c { draw scene depth ds less }""")
    broken = _replace_pass(tech, 2, repeat_group=0)
    with pytest.raises(AssertionError, match="contiguous"):
        verify.verify(broken)
