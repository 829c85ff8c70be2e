"""passes/lower_mix_constant: the CL backend's split of ``mix(x, y, constant t)`` (llvmpipe's
NIR lowering) is a compiler pass, not emitter code; the dialects override only public hooks."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from pipegen.ir import nodes as ir, walk as irwalk, verify
from pipegen.backends.cstyle import CStyleLanguage
from pipegen.backends.glsl import GLSLLanguage, emit_gl
from pipegen.backends.opencl.dialect import OpenCLLanguage
from pipegen.backends.opencl.emit import emit_cl
from pipegen.compiler.driver import compile_source
from pipegen.passes import lower_mix_constant

SOURCE = """
technique t "mix with constant weights"
target color : rgba16f clear 0
output color
vec3 tint(vec3 c) { return mix(c, vec3(1.0, 0.5, 0.25), 0.3); }
pass p {
  draw scene
  writes color
  fragment {
    float a = mix(albedo.x, albedo.y, 0.25);
    vec3 b = mix(albedo, normal, vec3(0.1, 0.2, 0.7));
    float c = mix(albedo.x, albedo.z, albedo.y);
    color = vec4(tint(b) * a, c);
  }
}
"""


def _mixes(tech: ir.Technique) -> list[ir.Call]:
    code = [s for f in tech.all_functions() for s in f.body] + [s for p in tech.passes
                                                                for s in p.body]
    return [e for e in irwalk.walk_exprs(code) if isinstance(e, ir.Call) and e.name == "mix"]


def test_pass_lowers_only_constant_weights_and_verifies():
    tech = compile_source(SOURCE, verify_each=True).technique
    assert len(_mixes(tech)) == 4
    lowered = lower_mix_constant.run(tech)
    verify.verify(lowered)
    left = _mixes(lowered)
    assert len(left) == 1 and not isinstance(left[0].args[2], ir.Const)   # variable weight


def test_lowered_form_is_x_times_one_minus_t_plus_y_times_t():
    F, V3 = ir.FLOAT, ir.VEC3
    x, y = ir.Var("x", V3), ir.Var("y", V3)
    t = ir.Const(V3, (0.1, 0.2, 0.7))
    e = lower_mix_constant.lower_call(ir.Call("mix", (x, y, t), V3))
    assert isinstance(e, ir.Binary) and e.op == "+" and e.type == V3
    assert e.left.op == "*" and e.left.left is x and e.right.op == "*" and e.right.right is t
    want = tuple(float(np.float32(1) - np.float32(v)) for v in t.value)
    assert e.left.right.value == want                    # 1 - t folded in float32
    splat = ir.Construct(V3, (ir.Const(F, 0.25),))               # vec3(0.25): NIR's constant
    e = lower_mix_constant.lower_call(ir.Call("mix", (x, y, splat), V3))
    assert e.left.right == ir.Const(V3, (0.75, 0.75, 0.75)) and e.right.right is splat
    assert lower_mix_constant.lower_call(ir.Call("mix", (x, y, ir.Var("w", F)), V3)) is None
    assert lower_mix_constant.lower_call(ir.Call("max", (x, y), V3)) is None


def test_only_the_cl_backend_lowers():
    tech = compile_source(SOURCE).technique
    gl = emit_gl(tech).passes[0].code.fragment
    cl = emit_cl(tech).passes[0].code.fragment
    assert gl.count("mix(") == 4
    assert cl.count("pg_mix(") == 1 and "* 0.75f + " in cl and "* 0.7f" in cl
    assert tech == compile_source(SOURCE).technique       # the IR itself is not changed


def test_dialects_override_only_public_hooks():
    base = {n for n, _ in inspect.getmembers(CStyleLanguage, inspect.isfunction)}
    for dialect in (GLSLLanguage, OpenCLLanguage):
        private = [n for n in vars(dialect) if n in base and n.startswith("_")
                   and not n.startswith("__")]
        assert private == [], (dialect.__name__, private)


MIX_PROBE = """
technique m "mix weights as llvmpipe evaluates them"
target a : rgba32f size 160 x 96
target b : rgba32f size 160 x 96
target c : rgba32f size 160 x 96
output a
pass p {
  draw fullscreen
  writes a, b, c
  fragment {
    uint h = (uint(frag_coord.x) * 2654435761u) ^ (uint(frag_coord.y) * 40503u + 12345u);
    h = h ^ (h >> 13);
    float v = float(h & 65535u) / 65536.0;
    // no products in the operands: NIR's reassociation ((x * 3.0) * 0.7 -> x * 2.1) and
    // its multiply-add fusion (not mirrored) stay out of the comparison
    vec3 x = vec3(1.0 - v, sqrt(v), v + 0.25);
    vec3 y = vec3(2.0 - v, v + 1.5, sqrt(v + 1.0));
    a = vec4(mix(x, y, 0.3), 1.0);
    b = vec4(mix(x, y, vec3(0.1, 0.3, 0.7)), 1.0);
    c = vec4(mix(x, y, v), 1.0);
  }
}
"""


@pytest.mark.gl
@pytest.mark.cl
def test_mix_bit_exact_with_llvmpipe():
    """Constant weights (a literal, a vector of literals) split, variable ones lerp: both
    bit-exact with llvmpipe (when the emitter split literals only, vec3(...) weights were
    lerped and 11644 of the 61440 values of ``b`` differed)."""
    pytest.importorskip("pyopencl")
    from pathlib import Path
    from pipegen.scene import load_scene
    try:
        from pipegen.runtime.gl.context import get_context
        get_context()
    except Exception as exc:   # pragma: no cover - no EGL here
        pytest.skip(f"no OpenGL context: {exc}")
    compiled = compile_source(MIX_PROBE)
    scene = load_scene(Path(__file__).resolve().parents[1] / "examples/scenes/small.toml")
    gl = compiled.pipeline("gl").render(scene)
    cl = compiled.pipeline("cl").render(scene)
    for name in "abc":
        np.testing.assert_array_equal(gl[name], cl[name], err_msg=name)
