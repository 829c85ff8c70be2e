"""The typed plan (backends/plan.py), its plain-data spelling, the backend registry, and the
host-side draw decisions both runtimes share (runtime/draws.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipegen.ir import nodes as ir
from pipegen.backends import registry
from pipegen.backends.plan import (
    CLPassCode, GLPassCode, Plan, plan_from_dict, state_from_dict, state_to_dict)
from pipegen.compiler.driver import compile_file, compile_source

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "pipelines").glob("*.pipe"))


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
@pytest.mark.parametrize("backend", sorted(registry.BACKENDS))
def test_plan_round_trips_through_its_plain_data(path, backend):
    """Generated pipeline modules hold ``plan.to_dict()`` and load it with ``plan_from_dict``:
    the typed plan they run is the one the compiler built."""
    plan = compile_file(path).plan(backend)
    assert isinstance(plan, Plan) and plan.backend == backend
    code_type = {"gl": GLPassCode, "cl": CLPassCode}[backend]
    assert all(isinstance(p.code, code_type) for p in plan.passes)
    assert plan_from_dict(plan.to_dict()) == plan


def test_plan_carries_ir_enums_and_formats():
    plan = compile_file(ROOT / "pipelines/lidr_bitplanes.pipe").plan("gl")
    assert plan.target("lightidx").format.name == "rgba8"
    shade = {p.name: p for p in plan.passes}
    indices = next(p for p in plan.passes if p.draw.kind is ir.DrawKind.LIGHTS)
    blend = indices.state.blend_for("lightidx")
    assert blend.enabled and blend.rgb.dst is ir.BlendFactor.CONSTANT_COLOR
    assert indices.state.blend_constant == (0.25, 0.25, 0.25, 0.25)
    assert all(isinstance(p.state, ir.PassState) for p in shade.values())


def test_hand_written_state_takes_the_defaults():
    s = state_from_dict({"depth": {"func": "less"}, "blend": {"c": {"enabled": True,
                                                                    "rgb": ["max"]}}}, ("c",))
    assert s.depth == ir.DepthState(ir.CompareFunc.LESS, False, False)
    assert not s.stencil.enabled and s.cull is ir.CullMode.NONE and s.polygon_offset is None
    b = s.blend_for("c")
    assert b.enabled and b.rgb.op is ir.BlendOp.MAX and b.alpha == ir.BlendEquation()
    assert state_from_dict(state_to_dict(s, ("c",)), ("c",)) == s


def test_registry_names_every_backend_once():
    assert sorted(registry.BACKENDS) == ["cl", "gl"]
    with pytest.raises(ValueError, match="unknown backend 'vk'.*gl, cl"):
        registry.get("vk")
    gl = registry.get("gl")
    assert gl.module_name == "pipeline_gl.py"
    c = compile_file(ROOT / "pipelines/forward.pipe")
    files = gl.pass_files("01_shade", c.plan("gl").passes[0])
    assert sorted(files) == ["01_shade.frag", "01_shade.vert"]


def test_compile_writes_what_the_registry_lists(tmp_path):
    c = compile_file(ROOT / "pipelines/deferred.pipe")
    out = c.write(tmp_path / "build")
    for name, backend in registry.BACKENDS.items():
        assert (out / backend.module_name).is_file()
        assert len(list((out / name).iterdir())) >= len(c.plan(name).passes)


CULL_AUTO_REPEAT = """
technique cull_auto_repeat "cull auto inside a repeat-per-light group"
lights[16] { position: vec3, radius: float, color: vec3 }
target acc : rgba8 clear 0
target ds  : d24s8 clear depth 1.0 stencil 0
output acc
pass depth_only { draw scene.opaque  depth ds less write  cull back }
repeat per light {
  pass vol {
    draw lights as sphere
    writes acc
    depth ds lequal nowrite clamp inside always
    cull auto
    blend acc add(one, one)
    fragment { acc = vec4(0.1); }
  }
}
"""


@pytest.mark.gl
@pytest.mark.cl
def test_cull_auto_inside_a_repeat_group_agrees_across_backends(tmp_path):
    """Regression: CL drew light 0's volume for every light of a repeat group under
    ``cull auto`` (an index array was taken for a mask): 78 codes off at light 1."""
    pytest.importorskip("pyopencl")
    from pipegen.proof.check import check
    from pipegen.scene import load_scene
    scene = load_scene(ROOT / "examples/scenes/small.toml")
    assert len(scene.lights) >= 2
    result = check(compile_source(CULL_AUTO_REPEAT), scene, tmp_path)
    assert result.passed, "\n" + result.table() + f"\n{result.first_divergence}"
    acc = next(r for r in result.rows if r.name == "acc")
    assert acc.max_error <= 1


def test_included_replaces_the_first_whole_prelude_as_str_replace_would():
    # ``included`` finds a long prelude by its first 80 characters and compares the rest
    # there: a kernel holding the head alone first, then the whole prelude, and one holding
    # it nowhere, are written as str.replace(prelude, include line, 1) writes them
    prelude = "// prelude\n" + "float pg_f(float x) { return x; }\n" * 40
    near = prelude[:100] + "different tail\n"
    for kernel in ("// header\n" + prelude + "kernel void k() {}\n",
                   near + prelude + "kernel void k() {}\n" + prelude,
                   near + "kernel void k() {}\n"):
        code = CLPassCode(kernel, None, prelude=("prelude.cl", prelude))
        assert code.included == kernel.replace(prelude, '#include "prelude.cl"\n', 1)
