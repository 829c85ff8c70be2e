"""opt_hoist_invariants (issue 26 item 6): a value every iteration of a loop computes alike,
even inside the functions the loop calls, is computed once before the loop, and no rendered
value changes by it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler import driver
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.compiler.specialise import clear_cache
from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.passes import pipelines
from pipegen.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
FORWARD = ROOT / "pipelines/forward.pipe"


def _view_normalisations(stmts) -> list[ir.Call]:
    """The calls normalize(camera_pos - …) in ``stmts``."""
    return [e for e in irwalk.walk_exprs(stmts) if isinstance(e, ir.Call)
            and e.name == "normalize" and isinstance(e.args[0], ir.Binary)
            and e.args[0].left == ir.Var("camera_pos", ir.VEC3, "input")]


def test_forward_normalises_the_view_vector_once_before_its_light_loop():
    tech = compile_file(FORWARD, verify_each=True).technique
    shade = next(p for p in tech.passes if p.name == "shade")
    loop = next(k for k, s in enumerate(shade.body) if isinstance(s, ir.For))
    before, inside = shade.body[:loop], shade.body[loop].body
    hoisted = [s for s in before if isinstance(s, ir.Declare)
               and _view_normalisations([ir.ExprStmt(s.init)])]
    assert len(hoisted) == 1
    assert hoisted[0].init.args[0].right == ir.Var("world_pos", ir.VEC3, "input")
    assert not _view_normalisations(inside)
    # and no function the loop calls normalises it again: each takes it as a parameter
    functions = {f.name: f for f in tech.functions}
    assert not any(_view_normalisations(f.body) for f in functions.values())
    assert functions["blinn_phong_along"].params[-1] == (hoisted[0].name, ir.VEC3)


CALLERS = """
technique callers "a function of p, called in a loop with a varying and an invariant p"
target color : rgba8 clear 0
target ds : d24s8 clear depth 1.0 stencil 0
output color
vec3 towards_camera(vec3 p) { return normalize(camera_pos - p); }
vec3 twice(vec3 p) { return towards_camera(p) * 2.0; }
pass shade {
  draw scene.opaque
  writes color
  depth ds less write
  fragment {
    vec3 c = vec3(0.0);
    for (int i = 0; i < 4; i++) {
      c += twice(world_pos) * length(world_pos - camera_pos);
      VARYING
    }
    color = vec4(c, 1.0);
  }
}
"""


@pytest.mark.parametrize("varying, lifted", [
    ("", True),
    ("c += towards_camera(world_pos * float(i));", False),   # one caller's p changes with i
])
def test_a_call_climbs_only_where_every_caller_passes_an_invariant_value(varying, lifted):
    tech = compile_source(CALLERS.replace("VARYING", varying), verify_each=True).technique
    functions = {f.name: f for f in tech.functions}
    body = next(p for p in tech.passes if p.name == "shade").body
    declared = [s.name for s in body if isinstance(s, ir.Declare)]
    assert (len(functions["towards_camera"].params) == 2) is lifted
    assert (len(functions["twice"].params) == 2) is lifted
    # length(world_pos - camera_pos) sits in the loop itself: declared before it either way
    assert len(declared) == (3 if lifted else 2), declared      # c, length (, the normalize)


@pytest.fixture(scope="module")
def without_the_pass():
    """forward compiled with and without the pass (the general build)."""
    with_it = compile_file(FORWARD)
    saved = driver.PHASES
    driver.PHASES = tuple(p for p in pipelines.GENERAL if p.name != "hoist")
    try:
        clear_cache()
        without = compile_file(FORWARD)
    finally:
        driver.PHASES = saved
        clear_cache()
    assert "hoist" not in without.phases_run and "hoist" in with_it.phases_run
    return with_it, without


@pytest.mark.parametrize("backend", [pytest.param("gl", marks=pytest.mark.gl),
                                     pytest.param("cl", marks=pytest.mark.cl)])
def test_hoisting_changes_no_value(without_the_pass, backend):
    scene = load_scene(ROOT / "examples/scenes/mixed_lights.toml").with_size(64, 48)
    with_it, without = without_the_pass
    got = with_it.pipeline(backend).render(scene)
    want = without.pipeline(backend).render(scene)
    assert got.keys() == want.keys()
    for k in want:
        assert np.array_equal(got[k], want[k]), k
    assert np.count_nonzero(want["color"]) > 0.2 * want["color"].size     # a lit image
