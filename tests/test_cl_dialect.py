"""The OpenCL dialect of the shared emitter: spellings only (no device needed).

What the emitted code computes is checked against llvmpipe in test_cl_techniques.py; here the
text of constructs whose OpenCL spelling differs from GLSL.
"""

from __future__ import annotations

import pytest

from pipegen.ir import nodes as ir
from pipegen.backends.opencl.abi import state_values
from pipegen.backends.opencl.dialect import OpenCLLanguage
from pipegen.backends.opencl.emit import emit_cl
from pipegen.backends.opencl.formats import cl_format
from pipegen.backends.opencl.programs import pass_program
from pipegen.compiler.driver import compile_source

F, I, U, B = ir.FLOAT, ir.INT, ir.UINT, ir.BOOL
V2, V3, V4 = ir.VEC2, ir.VEC3, ir.VEC4


def v(name, t):
    return ir.Var(name, t)


@pytest.fixture
def lang():
    return OpenCLLanguage()


def test_types_and_literals(lang):
    assert lang.type_name(V3) == "float3"
    assert lang.type_name(ir.Type(ir.Scalar.UINT, 4)) == "uint4"
    assert lang.type_name(ir.MAT4) == "pg_mat4"
    assert lang.literal(0.1, F) == "0.1f"          # never a double literal
    assert lang.literal(3, U) == "3u"


def test_vector_equality_is_one_bool(lang):
    e = ir.Binary("==", v("a", V3), v("b", V3), B)
    assert lang.expr(e) == "all(a == b)"
    e = ir.Binary("!=", v("a", V3), v("b", V3), B)
    assert lang.expr(e) == "any(a != b)"


def test_constructors_and_conversions(lang):
    assert lang.expr(ir.Construct(V4, (v("p", V3), ir.Const(F, 1.0)))) == "((float4)(p, 1.0f))"
    assert lang.expr(ir.Construct(V3, (v("x", F),))) == "((float3)(x))"
    assert lang.expr(ir.Construct(ir.IVEC2, (v("u", V2),))) == "convert_int2(u)"
    assert lang.expr(ir.Construct(V3, (v("q", V4),))) == "(q).xyz"
    assert lang.expr(ir.Construct(ir.MAT3, (v("m", ir.MAT4),))) == "pg_m3_from_m4(m)"


def test_matrix_products(lang):
    e = ir.Binary("*", v("m", ir.MAT4), v("p", V4), V4)
    assert lang.expr(e) == "pg_m4_mul_v4(m, p)"
    e = ir.Binary("*", v("p", V3), v("m", ir.MAT3), V3)
    assert lang.expr(e) == "pg_v3_mul_m3(p, m)"


def test_dynamic_index(lang):
    assert lang.expr(ir.Index(v("q", V4), v("k", I), F)) == "(((float *)&q)[k])"
    assert lang.expr(ir.Index(v("q", V4), ir.Const(I, 2), F)) == "q.s2"
    assert lang.expr(ir.Index(v("m", ir.MAT4), v("k", I), V4)) == "m.c[k]"


def test_builtins_follow_llvmpipe(lang):
    call = lambda name, *args, t=F: lang.expr(ir.Call(name, tuple(args), t))  # noqa: E731
    assert call("dot", v("a", V3), v("b", V3)) == "pg_dot(a, b)"
    assert call("mod", v("a", F), v("b", F)) == "pg_mod(a, b)"
    assert call("atan", v("y", F), v("x", F)) == "atan2(y, x)"
    assert call("round", v("x", F)) == "rint(x)"
    assert call("mix", v("a", F), v("b", F), ir.Const(F, 0.25)) == "(a * 0.75f + b * 0.25f)"
    assert call("mix", v("a", F), v("b", F), v("t", F)) == "pg_mix(a, b, t)"


SOURCE = """
technique t "t"
lights[4] { position: vec3, radius: float, color: vec3 }
target color : rgba8 clear 0
target ds : d24s8 clear depth 1.0 stencil 0
output color
float f(float x) { return x * 2.0; }
pass a {
  draw scene
  writes color
  depth ds less write
  stencil front { func equal ref 3 pass incr }
  blend color add(one, constant_color)
  blend constant (0.25, 0.25, 0.25, 0.25)
  fragment { if (albedo.x < 0.1) discard; color = vec4(f(albedo.y)); }
}
"""


def test_emit_cl_plan():
    plan = emit_cl(compile_source(SOURCE).technique)
    assert plan.backend == "cl"
    p = plan.passes[0]
    assert p.code.discard and p.code.inputs == ("albedo",)
    assert "static inline float f(const pg_in *in, float x)" in p.code.fragment
    assert "return false;" in p.code.fragment          # discard
    src = p.code.kernel
    assert "void pg_raster(" in src and "__kernel void pg_vertex(" in src
    assert "#define S_ST_FUNC_F 2" in src and "#define S_BCONST_R 0.25f" in src
    assert "late depth/stencil" in src                    # discard: tests after the fragment
    assert pass_program(plan, p) == src
    dyn = pass_program(plan, p, dynamic=True)
    assert "#define S_DEPTH_FUNC (pg_st[1])" in dyn
    names = [n for n, _, _ in state_values(p)]
    assert names[:3] == ["S_DEPTH_TEST", "S_DEPTH_FUNC", "S_DEPTH_WRITE"]


def test_formats_have_layouts():
    from pipegen.core.formats import FORMATS
    for name in FORMATS:
        f = cl_format(name)
        assert f["storage"] and f["load"] and f["store"]
