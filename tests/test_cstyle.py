"""The shared C-like emitter: precedence, literals, guarded forms, statements, and that a dialect
is data plus hooks (a toy OpenCL-flavoured subclass renders the same IR differently)."""

import math
import random
import struct

import numpy as np
import pytest

from pipegen.ir import nodes as ir
from pipegen.backends.cstyle import FLT_MIN, CStyleLanguage
from pipegen.backends.glsl import GLSLLanguage
from pipegen.ir.nodes import (
    BOOL, FLOAT, INT, MAT4, UINT, VEC2, VEC3, VEC4, Binary, Call, Const, Construct, Swizzle,
    Ternary, Type, Unary, Var)

a, b, c = (Var(n, FLOAT) for n in "abc")
u, w = Var("u", UINT), Var("w", UINT)
p, q = Var("p", BOOL), Var("q", BOOL)
v3 = Var("v", VEC3)


def F(x):
    return Const(FLOAT, x)


def add(x, y, t=FLOAT):
    return Binary("+", x, y, t)


def sub(x, y, t=FLOAT):
    return Binary("-", x, y, t)


def mul(x, y, t=FLOAT):
    return Binary("*", x, y, t)


@pytest.fixture
def gl():
    return GLSLLanguage()


# ---- precedence -----------------------------------------------------------------------------


@pytest.mark.parametrize("e, text", [
    (mul(add(a, b), c), "(a + b) * c"),
    (add(mul(a, b), c), "a * b + c"),
    (add(a, mul(b, c)), "a + b * c"),
    (sub(a, sub(b, c)), "a - (b - c)"),
    (sub(sub(a, b), c), "a - b - c"),
    (add(a, add(b, c)), "a + (b + c)"),                 # float evaluation order is kept
    (Binary("/", a, mul(b, c), FLOAT), "a / (b * c)"),
    (Binary("/", mul(a, b), c, FLOAT), "a * b / c"),
    (Unary("-", F(-1.0), FLOAT), "-(-1.0)"),
    (Unary("-", Unary("-", a, FLOAT), FLOAT), "-(-a)"),
    (Unary("-", add(a, b), FLOAT), "-(a + b)"),
    (sub(a, F(-1.0)), "a - -1.0"),
    (mul(F(-2.0), a), "-2.0 * a"),
    (Unary("!", Binary("<", a, b, BOOL), BOOL), "!(a < b)"),
    (Ternary(p, a, Ternary(q, b, c, FLOAT), FLOAT), "p ? a : (q ? b : c)"),
    (Ternary(Ternary(p, q, p, BOOL), a, b, FLOAT), "(p ? q : p) ? a : b"),
    (add(Ternary(p, a, b, FLOAT), c), "(p ? a : b) + c"),
    (Ternary(Binary("||", p, q, BOOL), add(a, b), c, FLOAT), "p || q ? a + b : c"),
    (Binary("||", Binary("&&", p, q, BOOL), p, BOOL), "(p && q) || p"),
    (Binary("&&", Binary("||", p, q, BOOL), p, BOOL), "(p || q) && p"),
    (Binary("==", Binary("&", u, Const(UINT, 255), UINT), Const(UINT, 0), BOOL),
     "(u & 255u) == 0u"),
    (Binary("|", Binary("<<", u, Const(UINT, 8), UINT), w, UINT), "(u << 8u) | w"),
    (Binary("<<", add(u, w, UINT), Const(UINT, 2), UINT), "(u + w) << 2u"),
    (Binary("+", Binary("&", u, w, UINT), w, UINT), "(u & w) + w"),
    (Binary("<", add(a, b), c, BOOL), "a + b < c"),
    (Swizzle(add(v3, v3, VEC3), "xy", VEC2), "(v + v).xy"),
    (Swizzle(Swizzle(v3, "zyx", VEC3), "x", FLOAT), "v.zyx.x"),
    (Swizzle(a, "xxx", VEC3), "vec3(a)"),
])
def test_precedence(gl, e, text):
    assert gl.expr(e) == text


def test_unary_minus_never_makes_a_decrement(gl):
    e = Unary("-", Unary("-", F(-0.5), FLOAT), FLOAT)
    assert "--" not in gl.expr(e).replace(" ", "")


# ---- literals -------------------------------------------------------------------------------


def _roundtrips(text: str, value: np.float32) -> bool:
    parsed = float(text)
    return np.float32(parsed) == value or (math.isnan(parsed) and math.isnan(value))


def test_float_literals_round_trip_exactly(gl):
    rng = random.Random(7)
    values = [0.0, -0.0, 1.0, 0.1, 1 / 3, 1e-30, 1e30, 2.0 ** -126, 2.0 ** -149, 3.4028234663852886e38,
              16777217.0, 0.45454545454545453, 255.0, 1 / 255]
    values += [struct.unpack("<f", struct.pack("<I", rng.getrandbits(32) & 0x7F7FFFFF))[0]
               for _ in range(2000)]
    for x in values:
        text = gl.literal(x, FLOAT)
        f32 = np.float32(x)
        assert _roundtrips(text, f32), (x, text)
        assert "." in text or "e" in text, text
        if x == 0.0:
            assert text == ("-0.0" if math.copysign(1, x) < 0 else "0.0")


def test_float_literal_is_shortest_float32(gl):
    assert gl.literal(0.1, FLOAT) == "0.1"         # not 0.10000000149011612
    assert gl.literal(1 / 2.2, FLOAT) == "0.45454547"
    assert gl.literal(2.0 ** -126, FLOAT) == "1.1754944e-38"


def test_special_float_literals(gl):
    assert gl.literal(math.inf, FLOAT) == "uintBitsToFloat(0x7F800000u)"
    assert gl.literal(-math.inf, FLOAT) == "-uintBitsToFloat(0x7F800000u)"
    assert gl.literal(math.nan, FLOAT) == "uintBitsToFloat(0x7FC00000u)"
    assert gl.literal(1e39, FLOAT) == "uintBitsToFloat(0x7F800000u)"   # overflows float32


def test_integer_literals(gl):
    assert gl.literal(5, UINT) == "5u"
    assert gl.literal(0xFFFFFFFF, UINT) == "4294967295u"
    assert gl.literal(-3, INT) == "-3"
    assert gl.literal(-2 ** 31, INT) == "(-2147483647 - 1)"
    assert gl.literal(True, BOOL) == "true"
    assert gl.expr(Unary("-", Const(INT, -3), INT)) == "-(-3)"


def test_vector_constants(gl):
    assert gl.expr(Const(VEC3, (0.0, 0.0, 0.0))) == "vec3(0.0)"
    assert gl.expr(Const(VEC2, (1.0, -2.0))) == "vec2(1.0, -2.0)"
    assert gl.expr(Const(ir.UVEC4, (1, 2, 3, 4))) == "uvec4(1u, 2u, 3u, 4u)"


# ---- guarded forms --------------------------------------------------------------------------


def test_normalize_is_guarded_by_a_helper(gl):
    assert gl.expr(Call("normalize", (v3,), VEC3)) == "pg_normalize_vec3(v)"
    src = gl.helper_source()
    assert "vec3 pg_normalize_vec3(vec3 x)" in src
    assert "x * inversesqrt(max(dot(x, x), 1.1754944e-38))" in src
    assert np.float32(1.1754944e-38) == np.float32(FLT_MIN)


def test_pow_guard(gl):
    assert gl.expr(Call("pow", (a, F(2.0)), FLOAT)) == "pow(max(a, 0.0), 2.0)"
    assert gl.expr(Call("pow", (a, b), FLOAT)) == "pg_pow_float_float(a, b)"
    assert gl.expr(Call("pow", (v3, v3), VEC3)) == "pg_pow_vec3_vec3(v, v)"
    src = gl.helper_source()
    # the scalar helper is defined before the vector one that calls it
    assert src.index("float pg_pow_float_float") < src.index("vec3 pg_pow_vec3_vec3")
    assert ("x > 0.0 ? pow(x, y) : (y == 0.0 ? 1.0 : (y > 0.0 ? 0.0 : "
            "uintBitsToFloat(0x7F800000u)))") in src
    assert "pg_pow_float_float(x.z, y.z)" in src


def test_other_guards(gl):
    assert gl.expr(Call("sqrt", (a,), FLOAT)) == "sqrt(max(a, 0.0))"
    assert gl.expr(Call("inversesqrt", (a,), FLOAT)) == "pg_inversesqrt_float(a)"
    assert gl.expr(Call("log2", (a,), FLOAT)) == "pg_log2_float(a)"
    assert gl.expr(Construct(UINT, (a,))) == "uint(max(a, 0.0))"
    assert gl.expr(Construct(UINT, (F(3.5),))) == "uint(3.5)"
    assert gl.expr(Construct(FLOAT, (u,))) == "float(u)"
    assert gl.expr(Binary("<<", u, w, UINT)) == "u << (w & 31u)"
    assert gl.expr(Binary(">>", u, Const(UINT, 4), UINT)) == "u >> 4u"
    assert gl.expr(Call("round", (a,), FLOAT)) == "roundEven(a)"
    src = gl.helper_source()
    assert "x > 0.0 ? inversesqrt(x) : uintBitsToFloat(0x7F800000u)" in src
    assert "x > 0.0 ? log2(x) : -uintBitsToFloat(0x7F800000u)" in src


def test_helpers_render_raw_builtins(gl):
    gl.expr(Call("inversesqrt", (Var("x4", VEC4),), VEC4))
    src = gl.helper_source()
    assert "pg_inversesqrt_float(x.w)" in src
    assert "inversesqrt(x)" in src and "pg_inversesqrt_vec4(" in src


# ---- statements -----------------------------------------------------------------------------


def test_statements(gl):
    body = (
        ir.Declare("acc", VEC3, None),
        ir.For("k", INT, Const(INT, 0), Const(INT, 4), (
            ir.If(Binary("==", Var("k", INT), Const(INT, 2), BOOL), (ir.Continue(),)),
            ir.If(Binary(">", a, b, BOOL), (ir.Break(),),
                  (ir.If(p, (ir.Assign(Var("acc", VEC3), "+=", v3),), (ir.Discard(),)),)),
        )),
        ir.ExprStmt(Call("f", (a,), FLOAT, builtin=False)),
        ir.Return(None),
    )
    assert gl.stmts(body, 0) == [
        "vec3 acc = vec3(0.0);",
        "for (int k = 0; k < 4; k++) {",
        "    if (k == 2) {",
        "        continue;",
        "    }",
        "    if (a > b) {",
        "        break;",
        "    } else if (p) {",
        "        acc += v;",
        "    } else {",
        "        discard;",
        "    }",
        "}",
        "f(a);",
        "return;",
    ]


def test_reserved_identifiers_are_renamed(gl):
    assert gl.expr(Var("texture", VEC4)) == "texture_"
    assert gl.expr(Var("input", FLOAT)) == "input_"
    assert gl.expr(Var("u_view", FLOAT)) == "u_view_"      # never our own uniform
    assert gl.expr(Var("gl_Foo", FLOAT)) == "gl_Foo_"
    f = ir.Function("mix", (("sample", FLOAT),), FLOAT, (ir.Return(Var("sample", FLOAT)),))
    assert gl.function(f) == "float mix_(float sample_) {\n    return sample_;\n}"


def test_vector_comparisons_use_functions(gl):
    e = Binary("<", v3, v3, Type(ir.Scalar.BOOL, 3))
    assert gl.expr(e) == "lessThan(v, v)"
    assert gl.expr(Unary("!", Var("bv", Type(ir.Scalar.BOOL, 3)), Type(ir.Scalar.BOOL, 3))) \
        == "not(bv)"


def test_matrix_arithmetic_is_infix_in_glsl(gl):
    m = Var("m", MAT4)
    e = Swizzle(Binary("*", m, Construct(VEC4, (v3, F(1.0))), VEC4), "xyz", VEC3)
    assert gl.expr(e) == "(m * vec4(v, 1.0)).xyz"


# ---- a dialect is data plus hooks -------------------------------------------------------------


class ToyCL(CStyleLanguage):
    """Just enough of an OpenCL-flavoured dialect to show what a subclass provides."""

    type_names = {FLOAT: "float", VEC2: "float2", VEC3: "float3", VEC4: "float4",
                  UINT: "uint", INT: "int", BOOL: "bool", MAT4: "mat4_t"}
    builtin_map = {"inversesqrt": "rsqrt", "max": "fmax", "atan": "atan2({0}, {1})"}
    # OpenCL's fmod truncates: GLSL's mod becomes a helper, x - y * floor(x / y)
    guards = {**CStyleLanguage.guards, "mod": lambda x, y: Binary("-", x, Binary(
        "*", y, Call("floor", (Binary("/", x, y, x.type),), x.type), x.type), x.type)}
    float_suffix = "f"
    function_qualifier = "static inline "

    def render_construct(self, t, args, types):
        if t.is_scalar:
            return f"convert_{self.type_name(t)}({args[0]})" if types[0] != t else args[0]
        return f"({self.type_name(t)})({', '.join(args)})"

    def render_matrix_op(self, op, left, right, lt, rt, result):
        return f"pg_mul_{self.type_name(lt)}_{self.type_name(rt)}({left}, {right})"


def test_toy_cl_dialect():
    cl = ToyCL()
    assert cl.expr(mul(add(a, b), F(0.5))) == "(a + b) * 0.5f"
    assert cl.expr(Construct(VEC4, (v3, F(1.0)))) == "(float4)(v, 1.0f)"
    assert cl.expr(Call("atan", (a, b), FLOAT)) == "atan2(a, b)"
    assert cl.expr(Call("mod", (a, b), FLOAT)) == "pg_mod_float_float(a, b)"
    m = Var("m", MAT4)
    assert cl.expr(Binary("*", m, Var("h", VEC4), VEC4)) == "pg_mul_mat4_t_float4(m, h)"
    assert cl.expr(Call("normalize", (v3,), VEC3)) == "pg_normalize_vec3(v)"
    src = cl.helper_source()
    assert src == ("static inline float pg_mod_float_float(float x, float y) {\n"
                   "    return x - y * floor(x / y);\n}\n\n"
                   "static inline float3 pg_normalize_vec3(float3 x) {\n"
                   "    return x * rsqrt(fmax(dot(x, x), 1.1754944e-38f));\n}")
    with pytest.raises(NotImplementedError):
        cl.expr(ir.Load("color", None, VEC4))
