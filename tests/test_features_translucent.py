"""``mismatches.mismatches`` on translucent objects lit from a light index written by light-volume
back faces (no backend).

A light-indexed technique whose index pass draws the light volumes' back faces behind the
opaque surface (``cull front``, ``depth gequal``) indexes the lights reaching the *opaque*
surface.  A pass drawing ``scene.translucent`` that shades from that index misses the lights
whose volume reaches a translucent surface but not the opaque surface behind it (measured on
the GL backend in tests/test_lidr_transparent.py: mean 32.8 codes off where translucent layers
cover translucent_layers).  ``mismatches`` reports it, naming the missed lights, found by a
float64 rasterisation (``mismatches.translucent_missed_lights``); the front-face variant
(pipelines/lidr_transparent.pipe) and scenes without such lights get no report.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import pytest

from pipegen.compiler import capabilities, mismatches
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.scene import load_scene, parse_scene

from scenes_for_tests import WALL, plane, planes_scene

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUE = ROOT / "pipelines/lidr_transparent.pipe"
FRONT = "depth dsi lequal nowrite clamp inside always\n  cull auto"
BACK = "depth dsi gequal nowrite\n  cull front"


@lru_cache(maxsize=None)
def front():
    return compile_file(TECHNIQUE).technique


@lru_cache(maxsize=None)
def back(replacement: str = BACK):
    src = TECHNIQUE.read_text()
    assert src.count(FRONT) == 6
    return compile_source(src.replace(FRONT, replacement), filename=str(TECHNIQUE)).technique


def scene(name):
    return load_scene(ROOT / f"examples/scenes/{name}.toml")


def translucent_messages(tech, s):
    return [m.message for m in mismatches.mismatches(tech, s) if m.kind == "translucent"]


def test_capabilities_find_the_translucent_pass_reading_back_face_indices():
    cap = capabilities.capabilities(back())
    assert cap.translucent_back_reads == tuple(
        ("shade_translucent", pack, frozenset({"point", "spot"})) for pack in ("b0", "b1", "b2"))
    # front faces (the shipped technique): nothing; the directional index (a quad with no
    # depth test, classified "back") reaches every pixel and is not listed either
    assert capabilities.capabilities(front()).translucent_back_reads == ()
    # back faces without a depth test write the whole projection of a volume: nothing missed
    assert capabilities.capabilities(back("depth dsi always nowrite\n  cull front")) \
        .translucent_back_reads == ()


def test_reads_without_unpack_calls_are_found():
    """A translucent pass that only lists the index target in ``reads`` (and loads it itself)
    counts as a reader too."""
    src = TECHNIQUE.read_text().replace(FRONT, BACK)
    body = """fragment {
    color = vec4(indexed_lighting(world_pos, normalize(normal), albedo, specular, shininess),
                 alpha);
  }
}"""
    assert src.rstrip().endswith(body)
    reads = "reads bank0, bank1, bank2, diridx"
    head, tail = src.rsplit(reads, 1)            # the translucent pass's reads
    src = head + "reads bank0" + tail
    src = src.rstrip()[:-len(body)] + """fragment {
    vec4 i0 = load(bank0);
    color = vec4(albedo * i0.rgb, alpha);
  }
}
"""
    cap = capabilities.capabilities(compile_source(src, filename=str(TECHNIQUE)).technique)
    assert [(p, k) for p, k, _ in cap.translucent_back_reads] == [("shade_translucent", "b0")]


@pytest.mark.parametrize("name, objects, lights", [
    ("translucent_layers", 15, "9 lights that reach them but not the opaque surface behind are "
                               "missed (lights 3, 4, 5, 6, 7, 8, 9, 10, 11)"),
    ("mixed_lights", 1, "2 lights that reach it but not the opaque surface behind are missed "
                        "(lights 2, 3)"),
])
def test_back_faces_warn_on_scenes_with_translucent_objects(name, objects, lights):
    found = translucent_messages(back(), scene(name))
    assert len(found) == 1, found
    noun = "translucent object is" if objects == 1 else "translucent objects are"
    assert found[0] == (f"{objects} {noun} lit from a light index written by light-volume back "
                        f"faces (`b0`, `b1`, `b2`, read by pass shade_translucent): {lights}")


@pytest.mark.parametrize("name", ["translucent_layers", "mixed_lights", "street_lamps", "small",
                                  "edges", "stress_overlap"])
def test_front_faces_never_warn(name):
    assert translucent_messages(front(), scene(name)) == []


@pytest.mark.parametrize("name", ["street_lamps", "small", "edges"])
def test_back_faces_do_not_warn_without_translucent_objects(name):
    s = scene(name)
    assert not s.has_translucent
    assert translucent_messages(back(), s) == []


# One translucent plane (z = 1) in front of an opaque wall (z = -2), camera on the z axis at 5.
GLASS = plane("glass", [0, 1, 0], translate=[0, 0, 1], scale=2, alpha=0.5)
PLANE = planes_scene(GLASS, WALL, width=48, height=32, ambient=0.1)

LIGHT = """
[[lights]]
type = "point"
position = [0, 0, {z}]
radius = {r}
color = [1, 1, 1]
"""


def plane_scene(*lights):
    return parse_scene(PLANE + "".join(LIGHT.format(z=z, r=r) for z, r in lights))


def test_only_lights_between_the_translucent_and_the_opaque_surface_are_missed():
    """Light 0 reaches the glass only (0.3 from it, 3.3 from the wall): missed.  Light 1
    reaches the wall only (2.5 from the glass): not the glass's light.  Light 2 reaches both
    (1.5 from each): its back faces lie behind the wall, it is in the index."""
    s = plane_scene((1.3, 0.8), (-1.5, 1.5), (-0.5, 3.0))
    assert mismatches.translucent_missed_lights(s, [0, 1, 2]) == ([0], 1)
    assert mismatches.translucent_missed_lights(s, [1, 2]) == ([], 0)
    assert translucent_messages(back(), s) == [
        "1 translucent object is lit from a light index written by light-volume back faces "
        "(`b0`, `b1`, `b2`, read by pass shade_translucent): 1 light that reaches it but not "
        "the opaque surface behind is missed (lights 0)"]
    # the banks: light 0 is in b0 (index % 3 == 0) only; with it alone the report is the same
    assert translucent_messages(back(), plane_scene((1.3, 0.8))) == translucent_messages(
        back(), s)
    assert translucent_messages(back(), plane_scene((-1.5, 1.5), (-0.5, 3.0))) == []
    assert translucent_messages(front(), s) == []


def test_translucent_over_the_sky_misses_every_light_reaching_it():
    """Without an opaque surface behind (sky: the depth buffer holds the clear value), back
    faces behind it never pass ``gequal``: every light reaching the glass is missed."""
    src = planes_scene(GLASS, width=48, height=32, ambient=0.1)
    s = parse_scene(src + LIGHT.format(z=-0.5, r=3.0))
    assert mismatches.translucent_missed_lights(s, [0]) == ([0], 1)


def test_a_light_pass_writing_through_a_helper_function_is_a_writer():
    """The packing's writers are found through the functions a light pass calls, not only in
    its body: lidr_bitplanes with its index writes (point and spot passes) moved into a
    helper reports the same per-pixel capacity as the original on stress_overlap."""
    path = ROOT / "pipelines/lidr_bitplanes.pipe"
    src = path.read_text()
    direct = "    lightidx = slots.plane_value(light.index + 1u);\n"
    assert src.count(direct) == 2
    helper = "vec4 index_value(uint i) {\n  return slots.plane_value(i + 1u);\n}\n\n"
    wrapped = src.replace(direct, "    lightidx = index_value(light.index);\n").replace(
        "pass light_indices {", helper + "pass light_indices {", 1)
    s = scene("stress_overlap")
    original = [m.message for m in mismatches.mismatches(compile_file(path).technique, s)]
    via_helper = compile_source(wrapped, filename=str(path)).technique
    assert any("holds 4" in m for m in original)
    assert [m.message for m in mismatches.mismatches(via_helper, s)] == original
