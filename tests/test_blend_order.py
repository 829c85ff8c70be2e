"""Translucent objects in either order (issue 27, "a silently wrong image first"): a pass whose
blend depends on the order of the fragments draws them `back_to_front`, or pipegen says the
image depends on the scene's order (compile warns with the pass located; run/check/the API
report it as a mismatch, an error with --strict).  Every shipped technique renders the same
targets, bit for bit, with the translucent objects of a scene listed in both orders (two
scenes with --exhaustive)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.blend_order import commutes, order_dependent_blends
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.ir import nodes as ir
from pipegen.scene.load import load_scene

import shipped

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "pipelines").glob("*.pipe"))
# the shipped scene of stacked layers, and three panes overlapping one another
SCENES = (ROOT / "examples/scenes/translucent_layers.toml",
          ROOT / "tests/data/overlapping_glass.toml")

OVER = """
technique over "translucent objects over the opaque ones, in scene order"
target color : rgba8 clear (0, 0, 0, 1)
target ds    : d24s8 clear depth 1.0 stencil 0
output color
pass opaque {
  draw scene.opaque
  writes color
  depth ds less write
  fragment { color = vec4(albedo, 1.0); }
}
pass glass {
  draw scene.translucent
  writes color
  depth ds less nowrite
  blend color rgb add(src_alpha, one_minus_src_alpha) alpha add(zero, one)
  fragment { color = vec4(albedo, alpha); }
}
"""


def reversed_translucent(scene):
    """The scene with its translucent objects listed in the opposite order (each keeps its
    id and layer; the opaque objects keep their places)."""
    glass = [o for o in scene.objects if o.material.translucent]
    flipped = iter(glass[::-1])
    objects = tuple(next(flipped) if o.material.translucent else o for o in scene.objects)
    return dataclasses.replace(scene, objects=objects)


def test_which_blends_commute():
    B, F, O = ir.BlendEquation, ir.BlendFactor, ir.BlendOp
    assert commutes(B(O.ADD, F.ONE, F.ONE)) and commutes(B(O.ADD, F.SRC_ALPHA, F.ONE))
    assert commutes(B(O.MIN)) and commutes(B(O.MAX))
    assert commutes(B(O.ADD, F.ZERO, F.SRC_COLOR))          # dst * src: a product
    assert commutes(B(O.ADD, F.DST_COLOR, F.ZERO)) and commutes(B(O.ADD, F.ZERO, F.ONE))
    assert not commutes(B(O.ADD, F.SRC_ALPHA, F.ONE_MINUS_SRC_ALPHA))     # over
    assert not commutes(B(O.ADD, F.ONE_MINUS_DST_ALPHA, F.ONE))           # reads dst
    assert not commutes(B(O.SUB, F.ONE, F.ONE)) and not commutes(B(O.REVSUB, F.ONE, F.ONE))


def test_compile_warns_with_the_pass_located_and_run_reports_it():
    c = compile_source(OVER, "over.pipe")
    (warning,) = c.warnings()
    assert warning.startswith("over.pipe:12:1: warning: pass glass draws translucent objects "
                              "in scene order into color with blend rgb add(src_alpha, "
                              "one_minus_src_alpha) (not order-independent)")
    assert "   12 | pass glass {" in warning and "hint: draw them `back_to_front`" in warning
    scene = load_scene(ROOT / "examples/scenes/translucent_layers.toml")
    order = [m for m in c.mismatches(scene) if m.kind == "order"]
    assert len(order) == 1 and "translucent objects)" in order[0].message
    # sorted, it is quiet; one translucent object cannot be out of order
    sorted_ = compile_source(OVER.replace("draw scene.translucent", "draw scene.translucent "
                                                                    "back_to_front"), "s.pipe")
    assert sorted_.warnings() == [] and not [m for m in sorted_.mismatches(scene)
                                             if m.kind == "order"]


def test_no_shipped_technique_depends_on_the_order():
    assert {p.name: order_dependent_blends(compile_file(str(p)).technique)
            for p in SHIPPED} == {p.name: [] for p in SHIPPED}


# CI: the three overlapping panes (each pair of panes overlaps: every order matters); the
# stacked layers too with --exhaustive (CI's 10-minute budget: a second scene per technique)
@pytest.mark.cl
@pytest.mark.parametrize("scene_name", [
    pytest.param(s, id=s.stem, marks=() if s.stem == "overlapping_glass"
                 else pytest.mark.exhaustive) for s in SCENES])
@pytest.mark.parametrize("path", shipped.params(path=True))
def test_every_shipped_technique_renders_either_order_alike(path, scene_name):
    scene = load_scene(scene_name).with_size(64, 36)
    assert sum(o.material.translucent for o in scene.objects) >= 2
    compiled = compile_file(str(path))
    if compiled.mismatches(scene) and any(m.kind == "table" for m in compiled.mismatches(scene)):
        pytest.skip("the scene has more lights than the technique's table")
    pipe = compiled.pipeline("cl")
    first = pipe.render(scene)
    second = pipe.render(reversed_translucent(scene))
    for name, values in first.items():
        assert np.array_equal(values, second[name]), (path.stem, scene_name, name)


@pytest.mark.cl
def test_the_order_shows_where_nothing_sorts():
    """The control: the same renders tell the orders apart for a technique that blends `over`
    in scene order, and for inferred.pipe as it was (its translucent pass unsorted)."""
    scene = load_scene(SCENES[1]).with_size(64, 36)
    flipped = reversed_translucent(scene)
    over = compile_source(OVER, "over.pipe").pipeline("cl")
    assert not np.array_equal(over.render(scene)["color"], over.render(flipped)["color"])
    text = (ROOT / "pipelines/inferred.pipe").read_text()
    assert text.count("draw scene.translucent back_to_front") == 1
    unsorted = compile_source(text.replace("draw scene.translucent back_to_front",
                                           "draw scene.translucent"),
                              str(ROOT / "pipelines/inferred.pipe"))
    assert unsorted.warnings()
    pipe = unsorted.pipeline("cl")
    a, b = pipe.render(scene)["color"], pipe.render(flipped)["color"]
    changed = np.any(a != b, axis=-1)
    assert changed.sum() > 20, changed.sum()
