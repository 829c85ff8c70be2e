"""The parser: every construct of docs/language.md reaches the AST, with C precedence in shader
code, positions on every node, and syntax errors in the user's words."""

import importlib.resources
from pathlib import Path

import pytest

from pipegen.frontend import ast, parse as syntax, syntax_tree
from pipegen.core.diagnostics import PipegenError

ROOT = Path(__file__).resolve().parent.parent


def parse(text: str) -> ast.Module:
    return syntax.parse(text, "t.pipe")


def items(text: str, kind: type) -> list:
    return [i for i in parse(text).items if isinstance(i, kind)]


def one_pass(body: str) -> ast.PassDecl:
    return items(f"technique t\npass p {{\n{body}\n}}", ast.PassDecl)[0]


def fragment(code: str) -> list:
    p = one_pass(f"draw scene\nfragment {{\n{code}\n}}")
    return next(s for s in p.stmts if isinstance(s, ast.Fragment)).body


def expr(code: str) -> ast.Expr:
    return fragment(f"x = {code};")[0].value


def show(e) -> str:
    """An expression with explicit parentheses, to read precedence off."""
    if isinstance(e, ast.Name):
        return e.name
    if isinstance(e, ast.Number):
        return repr(e.value) + ("u" if e.kind == "uint" else "")
    if isinstance(e, ast.Bool):
        return str(e.value).lower()
    if isinstance(e, ast.BinaryOp):
        return f"({show(e.left)} {e.op} {show(e.right)})"
    if isinstance(e, ast.UnaryOp):
        return f"({e.op}{show(e.operand)})"
    if isinstance(e, ast.Conditional):
        return f"({show(e.cond)} ? {show(e.then)} : {show(e.other)})"
    if isinstance(e, ast.Call):
        return f"{e.func.name}({', '.join(show(a) for a in e.args)})"
    if isinstance(e, ast.MethodCall):
        return f"{show(e.obj)}.{e.method.name}({', '.join(show(a) for a in e.args)})"
    if isinstance(e, ast.Field):
        return f"{show(e.base)}.{e.name.name}"
    if isinstance(e, ast.Subscript):
        return f"{show(e.base)}[{show(e.index)}]"
    raise AssertionError(e)


# ---------------------------------------------------------------------------------------------
# The grammar ships inside the package; the parser is built once
# ---------------------------------------------------------------------------------------------

def test_grammar_is_package_data():
    assert importlib.resources.files("pipegen.grammar").joinpath("pipe.lark").is_file()


def test_parser_is_cached():
    assert syntax_tree.lalr_parser() is syntax_tree.lalr_parser()


@pytest.mark.parametrize("path", sorted(str(p.relative_to(ROOT))
                                        for p in (ROOT / "pipelines").rglob("*.pipe")))
def test_shipped_pipelines_parse(path):
    module = syntax.parse((ROOT / path).read_text(), path)
    assert module.items


# ---------------------------------------------------------------------------------------------
# Top-level declarations
# ---------------------------------------------------------------------------------------------

def test_technique_and_include():
    m = parse('technique fwd "Forward: one pass"\ninclude "common/lighting.pipe"')
    tech, inc = m.items
    assert (tech.name.name, tech.title) == ("fwd", "Forward: one pass")
    assert inc.path == "common/lighting.pipe"
    assert items("technique t", ast.TechniqueDecl)[0].title == ""


def test_params():
    src = """technique t
param a = 0.5
param b : uint = 3 in {1, 3, 5}
param c = -2
param d = true
param fmt = rgba16f in {rgba8, rgba16f,}
param e = 4u"""
    a, b, c, d, fmt, e = items(src, ast.ParamDecl)
    assert (a.value.value, a.value.kind, a.type, a.allowed) == (0.5, "float", None, None)
    assert b.type.name == "uint" and [v.value for v in b.allowed] == [1, 3, 5]
    assert c.value.value == -2 and c.value.kind == "int"
    assert d.value.value is True
    assert fmt.value.name == "rgba16f" and [v.name for v in fmt.allowed] == ["rgba8", "rgba16f"]
    assert (e.value.value, e.value.kind) == (4, "uint")


def test_lights_schema():
    (lights,) = items("technique t\nlights[max_lights] { position: vec3, radius: float, }",
                      ast.LightsDecl)
    assert lights.capacity.name == "max_lights"
    assert [(f.name.name, f.type.name) for f in lights.fields] == [("position", "vec3"),
                                                                   ("radius", "float")]


def test_target_options():
    src = """technique t
target color : rgba8 clear (0, 0, 0, 1)
target lbuf : rgba16f size output * scale clear 0
target shadow : d32f size 1024 x 512 clear depth 1.0
target ds : d24s8 clear depth 1 stencil 0
target g : rg16f samples 4
target full : r8 size output"""
    color, lbuf, shadow, ds, g, full = items(src, ast.TargetDecl)
    assert color.format.name == "rgba8"
    assert [n.value for n in color.options[0].color.items] == [0, 0, 0, 1]
    size, clear = lbuf.options
    assert size.scale.name == "scale" and clear.all.value == 0
    size, clear = shadow.options
    assert (size.width.value, size.height.value) == (1024, 512) and clear.depth.value == 1.0
    assert (ds.options[0].depth.value, ds.options[0].stencil.value) == (1, 0)
    assert g.options[0].value.value == 4
    assert full.options[0].scale is None


def test_output_and_pack():
    src = """technique t
output color
pack slots = bitplanes(index_bits: 8, target: lightidx)
pack ids = bitfield(fields: (object: 8, group: 8), label: "x")
pack s16 = split16()
pack s16b = split16"""
    (out,) = items(src, ast.OutputDecl)
    assert out.name.name == "color"
    slots, ids, s16, s16b = items(src, ast.PackDecl)
    assert slots.scheme.name == "bitplanes"
    assert [(o.key.name, getattr(o.value, "value", getattr(o.value, "name", None)))
            for o in slots.options] == [("index_bits", 8), ("target", "lightidx")]
    fields = ids.options[0].value
    assert isinstance(fields, ast.Record)
    assert [(o.key.name, o.value.value) for o in fields.options] == [("object", 8), ("group", 8)]
    assert ids.options[1].value == "x"
    assert s16.options == [] and s16b.options == []


def test_function_definition():
    (f,) = items("technique t\nvec3 f(vec3 a, float b) { return a * b; }\nvoid g() { }",
                 ast.FunctionDef)[:1]
    assert (f.ret.name, f.name.name) == ("vec3", "f")
    assert [(p.type.name, p.name.name) for p in f.params] == [("vec3", "a"), ("float", "b")]
    assert isinstance(f.body[0], ast.Return)


def test_optional_semicolons_and_comments():
    src = """technique t; // a technique
/* a block
   comment */ target color : rgba8;;
pass p { draw scene; writes color; fragment { color = vec4(1.0); }; };"""
    m = parse(src)
    assert [type(i).__name__ for i in m.items] == ["TechniqueDecl", "TargetDecl", "PassDecl"]


# ---------------------------------------------------------------------------------------------
# Pass statements
# ---------------------------------------------------------------------------------------------

def test_draw_forms():
    def draw(text):
        return one_pass(text).stmts[0]

    assert (draw("draw scene").kind, draw("draw scene").material) == ("scene", None)
    assert draw("draw scene.opaque").material.name == "opaque"
    assert draw("draw fullscreen").kind == "fullscreen"
    d = draw("draw lights as cone spot point in slots[2] scissor")
    assert (d.kind, d.volume.value) == ("lights", "cone")
    assert [w.value for w in d.light_types] == ["spot", "point"]
    assert d.light_set[0].name == "slots" and d.light_set[1].value == 2
    assert d.scissor
    assert not draw("draw lights as quad").scissor


def test_attachment_statements():
    p = one_pass("""draw scene
writes a, b
reads c
depth ds lequal nowrite clamp""")
    _, writes, reads, depth = p.stmts
    assert [n.name for n in writes.targets] == ["a", "b"]
    assert [n.name for n in reads.targets] == ["c"]
    assert depth.func.value == "lequal" and [f.value for f in depth.flags] == ["nowrite", "clamp"]
    off = one_pass("draw scene\ndepth ds off").stmts[1]
    assert off.func is None and off.flags == []


def test_stencil_per_face():
    p = one_pass("""draw scene
stencil { func notequal ref 0 }
stencil back { func always zfail incr_wrap read 0x0F write 255 }
stencil front { func greater ref 2 zpass incr fail decr; pass keep }""")
    both, back, front = p.stmts[1:]
    assert both.face is None
    assert [(i.key, getattr(i.value, "value", None)) for i in both.items] == [
        ("func", "notequal"), ("ref", 0)]
    assert back.face.value == "back"
    assert [(i.key, i.value.value) for i in back.items] == [
        ("func", "always"), ("zfail", "incr_wrap"), ("read", 15), ("write", 255)]
    # `zpass` is another spelling of `pass`
    assert [i.key for i in front.items] == ["func", "ref", "pass", "fail", "pass"]


def test_blend_forms():
    p = one_pass("""draw scene
blend a add(one, constant_color)
blend b rgb add(one, one) alpha add(zero, one)
blend c max
blend d off
blend constant (0.25, 0.25, 0.25, 0.25)
blend constant slots.blend_constant""")
    a, b, c, d, const, const2 = p.stmts[1:]
    assert a.rgb is a.alpha and (a.rgb.op.value, a.rgb.src.value, a.rgb.dst.value) == (
        "add", "one", "constant_color")
    assert (b.rgb.dst.value, b.alpha.src.value) == ("one", "zero")
    assert c.rgb.op.value == "max" and c.rgb.src is None
    assert d.rgb is None and d.alpha is None
    assert [v.value for v in const.value.items] == [0.25] * 4
    assert isinstance(const2.value, ast.Field) and const2.value.name.name == "blend_constant"


def test_mask_cull_offset_repeat():
    p = one_pass("draw scene\nmask idx rg\nmask c none\ncull front\noffset -1.5 -2\n"
                 "repeat per light")
    mask, none, cull, offset, repeat = p.stmts[1:]
    assert (mask.target.name, mask.channels.name) == ("idx", "rg")
    assert none.channels.name == "none"
    assert cull.mode.value == "front"
    assert (offset.factor.value, offset.units.value) == (-1.5, -2)
    assert isinstance(repeat, ast.RepeatPerLight)


def test_clears_inside_a_pass():
    p = one_pass("""draw lights as sphere
clear ds depth 1.0 stencil 0
stencil { func equal ref 1 }
clear acc (0, 0, 0, 1)
clear st stencil 3""")
    ds, stencil, acc, st = p.stmts[1:]
    assert (ds.clear.depth.value, ds.clear.stencil.value) == (1.0, 0)
    assert isinstance(stencil, ast.Stencil)      # not swallowed by the clear
    assert len(acc.clear.color.items) == 4
    assert st.clear.stencil.value == 3 and st.clear.depth is None


def test_repeat_block():
    src = """technique t
repeat per light {
  pass mark { draw lights as sphere }
  pass shade { draw lights as sphere }
}"""
    (block,) = items(src, ast.RepeatBlock)
    assert [p.name.name for p in block.passes] == ["mark", "shade"]


# ---------------------------------------------------------------------------------------------
# Shader code
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("code, shown", [
    ("a + b * c", "(a + (b * c))"),
    ("a - b - c", "((a - b) - c)"),
    ("a * b % c / d", "(((a * b) % c) / d)"),
    ("a << 2 + b", "(a << (2 + b))"),
    ("a < b == c > d", "((a < b) == (c > d))"),
    ("a <= b && c >= d", "((a <= b) && (c >= d))"),
    ("a & b == c", "(a & (b == c))"),          # C: & binds looser than ==
    ("a | b ^ c & d", "(a | (b ^ (c & d)))"),
    ("a || b && c", "(a || (b && c))"),
    ("a ? b : c ? d : e", "(a ? b : (c ? d : e))"),
    ("a || b ? c : d", "((a || b) ? c : d)"),
    ("-a * b", "((-a) * b)"),
    ("!a && ~b != c", "((!a) && ((~b) != c))"),
    ("-v.x", "(-v.x)"),
    ("a >> 1u", "(a >> 1u)"),
    ("f(a, b + 1)[2].xy", "f(a, (b + 1))[2].xy"),
    ("lights[i + 1].position", "lights[(i + 1)].position"),
    ("slots.unpack(load(t), k)", "slots.unpack(load(t), k)"),
    ("slots.capacity * 2", "(slots.capacity * 2)"),
    ("vec4(v, 1.0).rgb", "vec4(v, 1.0).rgb"),
    ("(a + b) * c", "((a + b) * c)"),
])
def test_precedence(code, shown):
    assert show(expr(code)) == shown


@pytest.mark.parametrize("text, value, kind", [
    ("1.0", 1.0, "float"), ("1.", 1.0, "float"), (".5", 0.5, "float"), ("1e-6", 1e-6, "float"),
    ("2.5E3", 2500.0, "float"), ("3", 3, "int"), ("3u", 3, "uint"), ("0xFF", 255, "int"),
    ("0xFFFFFFFFu", 0xFFFFFFFF, "uint"), ("2147483647", 2147483647, "int"),
    ("0xFFFFFFFF", -1, "int"),
])
def test_numbers(text, value, kind):
    n = expr(text)
    assert (n.value, n.kind) == (value, kind)


def test_statements():
    body = fragment("""
float a = 1.0, b;
vec3 c;
a += 2.0; a -= 1.0; a *= 2.0; a /= 2.0;
c.xy = vec2(a);
c[0] = b;
f(a);
if (a > 0.0) discard; else { a = 0.0; }
if (a < 1.0) if (b > 0.0) a = 1.0; else a = 2.0;
for (int i = 0; i < 4; i++) { if (i == 2) continue; break; }
for (uint k = 0u; k < n; ++k) a = a;
return;""")
    kinds = [type(s).__name__ for s in body]
    assert kinds == ["VarDecl", "VarDecl", "VarDecl", "Assign", "Assign", "Assign", "Assign",
                     "Assign", "Assign", "ExprStmt", "If", "If", "For", "For", "Return"]
    assert [s.op for s in body[3:7]] == ["+=", "-=", "*=", "/="]
    assert body[1].init is None
    first_if, dangling = body[10], body[11]
    assert isinstance(first_if.then[0], ast.Discard) and len(first_if.other) == 1
    # the else belongs to the inner if
    assert dangling.other is None and dangling.then[0].other is not None
    loop = body[12]
    assert (loop.var_type.name, loop.var.name, loop.step.value) == ("int", "i", 1)
    assert [type(s).__name__ for s in loop.body[0].then] == ["Continue"]
    assert body[13].step_var.name == "k"


def test_pass_keywords_are_names_in_shader_code():
    # `depth`, `mask`, `size`, `alpha`… are keywords only where pass statements expect them.
    body = fragment("""
float depth = 1.0;
if (depth > 0.5) { depth = 0.0; }
depth = size(t).x > 0 ? alpha : depth;
float mask = offset(target, blend);""")
    assert [s.name.name for s in body if isinstance(s, ast.VarDecl)] == ["depth", "mask"]
    assert isinstance(body[2], ast.Assign) and body[2].target.name == "depth"


def test_spans_locate_nodes():
    m = parse('technique t\ntarget color : rgba8\npass p {\n  draw scene\n'
              '  fragment { color = vec4(albedo, 1.0); }\n}')
    target = m.items[1]
    assert (target.span.line, target.span.column) == (2, 1)
    assert (target.format.span.line, target.format.span.column) == (2, 16)
    assign = m.items[2].stmts[1].body[0]
    call = assign.value
    assert (call.span.line, call.span.column, call.span.end_column) == (5, 22, 39)
    assert (call.args[0].span.column, call.args[0].span.end_column) == (27, 33)
    assert call.span.source_line.strip().startswith("fragment")


# ---------------------------------------------------------------------------------------------
# Syntax errors
# ---------------------------------------------------------------------------------------------

def syntax_error(text: str) -> PipegenError:
    with pytest.raises(PipegenError) as info:
        parse(text)
    return info.value


def assert_points_at(err: PipegenError, text: str, line: int, token: str) -> None:
    rendered = err.render()
    src_line = text.splitlines()[line - 1]
    assert f"t.pipe:{line}:{err.span.column}: error:" in rendered
    assert src_line[err.span.column - 1:].startswith(token), rendered
    lines = rendered.splitlines()
    quoted = next(i for i, l in enumerate(lines) if l.endswith(src_line))
    gutter = lines[quoted].index(src_line)
    assert lines[quoted + 1].index("^") - gutter == err.span.column - 1, rendered
    assert lines[-1].startswith("hint: "), rendered


def test_missing_comma_names_what_was_expected():
    text = "technique t\npass p { draw scene fragment { c = vec4(albedo 1.0); } }"
    err = syntax_error(text)
    assert_points_at(err, text, 2, "1.0")
    assert "unexpected number '1.0'" in err.message
    assert "','" in err.message and "')'" in err.message
    assert "separate arguments" in err.hint


def test_missing_semicolon_points_at_end_of_line():
    text = "technique t\npass p { draw scene fragment {\n  float x = 1.0\n  c = vec4(x);\n} }"
    err = syntax_error(text)
    assert err.span.line == 3 and err.span.column == len("  float x = 1.0") + 1
    assert "';'" in err.message and "';'" in err.hint


def test_misspelt_pass_statement():
    text = "technique t\npass p {\n  draw scene\n  dpeth ds less\n}"
    err = syntax_error(text)
    assert_points_at(err, text, 4, "dpeth")
    assert "name 'dpeth'" in err.message and "pass statement" in err.message
    assert err.hint == "did you mean 'depth'?"


def test_pass_statement_hint_lists_the_statements():
    text = "technique t\npass p {\n  draw scene\n  zzz ds less\n}"
    err = syntax_error(text)
    assert "draw" in err.hint and "fragment" in err.hint


def test_bad_keyword_argument_lists_the_choices():
    text = "technique t\npass p {\n  draw scene\n  depth ds lesser\n}"
    err = syntax_error(text)
    assert_points_at(err, text, 4, "lesser")
    for word in ("'less'", "'lequal'", "'always'"):
        assert word in err.message
    assert err.hint == "did you mean 'less'?"


def test_misspelt_declaration_keyword():
    text = "technique t\ntargt x : rgba8"
    err = syntax_error(text)
    assert "did you mean 'target'?" in err.hint


def test_keywords_of_other_contexts_are_names():
    # The contextual lexer reserves a keyword only where the grammar can accept it.
    p = one_pass("draw scene\nwrites target, pass\nreads clear")
    assert [n.name for n in p.stmts[1].targets] == ["target", "pass"]
    assert p.stmts[2].targets[0].name == "clear"


def test_unclosed_brace_at_end_of_file():
    text = "technique t\npass p {\n  draw scene\n  fragment { c = vec4(1.0); }\n"
    err = syntax_error(text)
    assert "end of file" in err.message
    assert "not closed" in err.hint
    assert err.span.line == 4


@pytest.mark.parametrize("text, token, words", [
    ("technique t\npass p { draw scene fragment { x = @; } }", "@", "unexpected character"),
    ("technique t\n/* never closed", "/*", "unterminated comment"),
    ('technique t "title', '"', "unterminated string"),
    ("technique t\npass p { draw scene fragment { x = 1.5u; } }", "1.5u", "not a valid literal"),
    ("technique t\npass p { draw scene fragment { x = 4294967296u; } }", "4294967296u",
     "does not fit"),
    ("technique t\ntarget s : d32f size 1024x768", "x768", "expected 'x'"),
    ("technique t\npass p { draw scene\n stencil 0 }", "stencil", "clear"),
])
def test_other_syntax_errors(text, token, words):
    err = syntax_error(text)
    line = err.span.line
    assert_points_at(err, text, line, token)
    assert words in err.message
