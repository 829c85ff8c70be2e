"""Stage input ``layer``, ``cull auto`` (+ ``depth … inside FUNC``), directional lights in
``draw lights as quad``, and light-type filters on ``repeat per light``.

Front-end and host-side tests run everywhere; the render tests draw on both backends (OpenGL
on llvmpipe, OpenCL on PoCL) and compare them with ``pipegen.proof.compare.compare_target`` and with
the float64 references where there is one.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pipegen.core import formats as F
from pipegen.proof.compare import compare_target
from pipegen.compiler.driver import compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.ir.nodes import CompareFunc, CullMode, Volume
from pipegen.scene.meshes import light_volume
from pipegen.runtime import draws
from pipegen.scene import Light, load_scene

ROOT = Path(__file__).resolve().parents[1]


def cull_runs(cull: str, volume: str, lights, indices, eye, proj) -> list:
    """``draws.light_runs`` as (cull mode, [light, …]) pairs."""
    return [(r.cull.value, list(r.lights)) for r in
            draws.light_runs(CullMode(cull), Volume(volume), lights, indices, eye, proj)]


def volume_cull(volume, position, radius, eye, proj, cos_outer=-2.0,
                direction=(0.0, 0.0, -1.0)) -> str:
    """``draws.volume_cull`` as "front" / "back" for a light given by its fields."""
    light = SimpleNamespace(position=position, radius=radius, cos_outer=cos_outer,
                            direction=direction)
    return draws.volume_cull(volume, light, eye, draws.near_plane_reach(proj)).value


FULL_SCHEMA = ("lights[8] { position: vec3, radius: float, color: vec3, type: uint, "
               "direction: vec3, cos_inner: float, cos_outer: float }")


def technique(body: str, schema: str = FULL_SCHEMA, targets: str = "") -> str:
    return f"""technique t "features"
{schema}
target color : rgba8 clear (0, 0, 0, 0)
target ds : d24s8 clear depth 1.0 stencil 0
{targets}
output color
{body}
"""


def compiles(body: str, **kw):
    return compile_source(technique(body, **kw), verify_each=True)


def error_of(body: str, **kw) -> str:
    with pytest.raises(PipegenError) as e:
        compiles(body, **kw)
    return str(e.value)


# ---------------------------------------------------------------------------------------------
# front end
# ---------------------------------------------------------------------------------------------


def test_layer_is_a_flat_uint_scene_input():
    c = compiles("""pass g { draw scene writes color
        fragment { color = vec4(float(layer) / 3.0, float(object_id), 0.0, 1.0); } }""")
    gl = c.plan("gl").to_dict()["passes"][0]
    assert "a_layer" in gl["attributes"]
    assert "layout(location = 5) in float a_layer;" in gl["vertex"]
    assert "flat out uint v_layer;" in gl["vertex"] and "flat in uint v_layer;" in gl["fragment"]
    cl = c.plan("cl").to_dict()["passes"][0]
    assert "in.layer = flat.w;" in cl["kernel"] and "in.object_id = flat.y;" in cl["kernel"]


def test_layer_only_in_scene_draws():
    msg = error_of("pass a { draw fullscreen writes color "
                   "fragment { color = vec4(float(layer)); } }")
    assert "'layer' exists only in scene draws" in msg


def test_layer_is_reserved():
    msg = error_of("pass a { draw scene writes color "
                   "fragment { float layer = 1.0; color = vec4(layer); } }")
    assert "'layer'" in msg


def test_cull_auto_on_light_volumes():
    c = compiles("""pass a { draw lights as sphere point writes color
        depth ds lequal nowrite clamp inside always cull auto
        blend color add(one, one) fragment { color = vec4(light.color, 1.0); } }
      pass b { draw lights as cone spot writes color depth ds gequal nowrite clamp cull auto
        blend color add(one, one) fragment { color = vec4(light.color, 1.0); } }""")
    a, b = c.technique.passes
    assert a.state.cull is CullMode.AUTO and b.state.cull is CullMode.AUTO
    assert a.state.depth.inside is CompareFunc.ALWAYS and b.state.depth.inside is None
    assert a.state.depth.clamp and a.state.depth.func is CompareFunc.LEQUAL
    for backend in ("gl", "cl"):
        pa, pb = c.plan(backend).to_dict()["passes"]
        assert pa["state"]["cull"] == "auto"
        assert pa["state"]["depth"] == {"func": "lequal", "write": False, "clamp": True,
                                        "inside": "always"}
        assert "inside" not in pb["state"]["depth"]
    kernel = c.plan("cl").to_dict()["passes"][0]["kernel"]
    assert "#define S_DEPTH_FUNC (pg_inside ? S_DEPTH_FUNC_IN : 3)" in kernel
    assert "pg_inside" not in c.plan("cl").to_dict()["passes"][1]["kernel"]


@pytest.mark.parametrize("draw, what", [("draw scene", "scene geometry"),
                                        ("draw lights as quad", "a screen quad"),
                                        ("draw fullscreen", "a full-screen triangle")])
def test_cull_auto_elsewhere_is_an_error(draw, what):
    msg = error_of(f"pass a {{ {draw} cull auto writes color "
                   f"fragment {{ color = vec4(1.0); }} }}")
    assert "`cull auto` chooses the faces of light volumes" in msg and what in msg


def test_depth_inside_needs_cull_auto():
    msg = error_of("pass a { draw lights as sphere cull back depth ds less inside always "
                   "writes color fragment { color = vec4(1.0); } }")
    assert "does not `cull auto`" in msg
    msg = error_of("pass a { draw lights as sphere cull auto "
                   "depth ds less inside always inside less "
                   "writes color fragment { color = vec4(1.0); } }")
    assert "`inside` is given twice" in msg


def test_repeat_per_light_with_types():
    c = compiles("""
      pass d { draw fullscreen repeat per light directional writes color
        blend color add(one, one) fragment { color = vec4(light.color, 1.0); } }
      repeat per light spot point {
        pass m { draw lights as sphere depth ds lequal nowrite }
        pass s { draw fullscreen writes color blend color add(one, one)
                 fragment { color = vec4(light.color, 1.0); } }
      }
      pass all { draw fullscreen repeat per light writes color blend color add(one, one)
        fragment { color = vec4(light.color, 1.0); } }""")
    d, m, s, a = c.technique.passes
    assert d.repeat_types == ("directional",) and d.repeat_group is not None
    assert m.repeat_types == s.repeat_types == ("point", "spot")      # canonical order
    assert m.repeat_group == s.repeat_group != d.repeat_group
    assert a.repeat_types == ()
    plan = c.plan("gl").to_dict()
    assert [p["repeat_types"] for p in plan["passes"]] == [["directional"], ["point", "spot"],
                                                           ["point", "spot"], []]


def test_repeat_types_errors():
    msg = error_of("pass a { draw fullscreen repeat per light spot spot writes color "
                   "fragment { color = vec4(1.0); } }")
    assert "listed twice" in msg
    msg = error_of("repeat per light spot { pass a { draw fullscreen repeat per light point "
                   "writes color fragment { color = vec4(1.0); } } }")
    assert "names light types again" in msg


def test_light_schema_with_every_field():
    c = compiles("""pass a { draw lights as cone spot writes color
        fragment {
          float k = smoothstep(light.cos_outer, light.cos_inner, dot(light.direction, vec3(0.0, -1.0, 0.0)));
          color = vec4(light.color * k, light.type == 1u ? 1.0 : 0.0);
        } }""")
    assert [f.name for f in c.technique.lights.fields] == [
        "position", "radius", "color", "type", "direction", "cos_inner", "cos_outer"]


# ---------------------------------------------------------------------------------------------
# the host-side choice (shared by both runtimes)
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def mixed():
    return load_scene(ROOT / "examples/scenes/mixed_lights.toml")


def test_near_plane_reach(mixed):
    cam = mixed.camera
    P = cam.projection(mixed.aspect)
    ty = np.tan(np.radians(cam.fov_y_deg) / 2)
    expect = cam.near * np.sqrt(1 + ty ** 2 + (ty * mixed.aspect) ** 2)
    assert draws.near_plane_reach(P) == pytest.approx(expect, rel=1e-12)
    P_inf = P.copy()
    P_inf[2, 2], P_inf[2, 3] = -1.0, -2.0 * cam.near          # infinite far plane
    assert draws.near_plane_reach(P_inf) == pytest.approx(expect, rel=1e-12)


def test_light_volume_bound_contains_the_mesh():
    m = light_volume("sphere").astype(np.float64)
    R = np.sqrt((m * m).sum(1)).max()
    assert 1.0 < R < 1.05
    assert draws.volume_bound("sphere", 3.0) == pytest.approx(3.0 * R)
    with pytest.raises(ValueError):
        draws.volume_bound("quad", 1.0)


def test_sphere_rule(mixed):
    P = mixed.camera.projection(mixed.aspect)
    reach = draws.near_plane_reach(P)
    R = draws.volume_bound("sphere", 1.0)
    centre = np.zeros(3)
    for d, expect in ((0.0, "front"), (2.0 * R + 0.99 * reach, "front"),
                      (2.0 * R + reach * 1.01 + 0.01, "back"), (100.0, "back")):
        eye = centre + np.array([0.0, 0.0, d])
        assert volume_cull("sphere", centre, 2.0, eye, P) == expect, d


def _mesh_world(volume: str, light: Light) -> np.ndarray:
    """The light's volume mesh as the vertex stages place it (float64)."""
    m = light_volume(volume).astype(np.float64)
    c = np.asarray(light.position, np.float64)
    if volume == "sphere":
        return c + m * light.radius
    d = np.asarray(light.direction, np.float64)
    w = -d / np.linalg.norm(d)
    up = np.array([0.0, 0.0, 1.0]) if abs(w[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(up, w)
    u /= np.linalg.norm(u)
    v = np.cross(w, u)
    cc = min(max(light.cos_outer, 0.001), 1.0)
    spread = light.radius * np.sqrt(1 - cc * cc) / cc
    local = m * np.array([spread, spread, light.radius])
    return c + local @ np.stack([u, v, w])


def _surface_points(tris: np.ndarray, k: int = 8) -> np.ndarray:
    t = tris.reshape(-1, 3, 3)
    out = []
    for i in range(k + 1):
        for j in range(k + 1 - i):
            a, b = i / k, j / k
            out.append(t[:, 0] + a * (t[:, 1] - t[:, 0]) + b * (t[:, 2] - t[:, 0]))
    return np.concatenate(out)


def test_rule_is_conservative(mixed):
    """Whenever the rule draws front faces, no point of the mesh comes within the near
    plane's reach of the eye (so the near plane cannot cut the front faces)."""
    rng = np.random.default_rng(4)
    P = mixed.camera.projection(mixed.aspect)
    reach = draws.near_plane_reach(P)
    eye = np.asarray(mixed.camera.position, np.float64)
    seen = set()
    for _ in range(300):
        volume = ("sphere", "cone")[rng.integers(2)]
        pos = eye + rng.normal(size=3) * 4.0
        light = Light("spot", (1, 1, 1), position=tuple(pos), radius=float(rng.uniform(0.5, 5)),
                      direction=tuple(rng.normal(size=3)), inner_deg=10.0,
                      outer_deg=float(rng.uniform(11, 70)))
        mode = volume_cull(volume, light.position, light.radius, eye, P,
                                    light.cos_outer, light.direction)
        seen.add(mode)
        if mode == "back":
            pts = _surface_points(_mesh_world(volume, light))
            assert np.linalg.norm(pts - eye, axis=1).min() > reach
        if draws.volume_clearance(volume, light.position, light.radius, eye,
                                     light.cos_outer, light.direction) <= 0:
            assert mode == "front"
    assert seen == {"front", "back"}


def test_cull_runs_keep_light_order(mixed):
    P = mixed.camera.projection(mixed.aspect)
    eye = np.asarray(mixed.camera.position)
    near = Light("point", (1, 1, 1), position=tuple(eye), radius=2.0)
    far = Light("point", (1, 1, 1), position=tuple(eye + [0, 0, -20]), radius=2.0)
    lights = [far, far, near, far, near, near]
    assert cull_runs("auto", "sphere", lights, range(6), eye, P) == [
        ("back", [0, 1]), ("front", [2]), ("back", [3]), ("front", [4, 5])]
    assert cull_runs("back", "sphere", lights, [3, 1], eye, P) == [("back", [3, 1])]
    assert cull_runs("auto", "sphere", lights, [], eye, P) == []


def test_scissor_rect_of_a_directional_light(mixed):
    P = mixed.camera.projection(mixed.aspect)
    V = mixed.camera.view_matrix()
    assert draws.scissor_rect(SimpleNamespace(position=(0, 0, 0), radius=0.0), V, P, 160, 90) == (0, 0, 160, 90)


# ---------------------------------------------------------------------------------------------
# rendering on both backends
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def backends():
    pytest.importorskip("pyopencl")
    try:
        from pipegen.runtime.gl.context import get_context
        get_context()
    except Exception as exc:   # no EGL / llvmpipe here
        pytest.skip(f"no OpenGL context: {exc}")


def render_both(compiled, scene, **kw):
    gl = compiled.pipeline("gl").render(scene, **kw)
    cl = compiled.pipeline("cl").render(scene, **kw)
    return gl, cl


def assert_agree(plan, gl, cl, names, blended=0):
    formats = {t.name: t.format for t in plan.targets}
    for n in names:
        row = compare_target(n, formats[n.split(".")[0]], gl[n], cl[n], blended,
                             stencil=n.endswith(".stencil"))
        assert row.passed, row.row()


STIPPLE = """
pass g {
  draw scene
  writes ids
  depth ds less write
  cull back
  fragment {
    if (layer != 0u && ((uint(frag_coord.x) & 1u) + 2u * (uint(frag_coord.y) & 1u)) != layer) discard;
    ids = uvec4(object_id + 1u, layer, 0u, 0u);
  }
}
"""


@pytest.mark.gl
@pytest.mark.cl
def test_stippled_layers_match_the_reference(backends):
    from pipegen.reference.translucent import stippled_gbuffer
    from pipegen.scene import stipple_map
    scene = load_scene(ROOT / "examples/scenes/translucent_layers.toml")
    schema = "lights[16] { position: vec3, radius: float, color: vec3 }"
    c = compile_source(technique(STIPPLE, schema, targets="target ids : rgba8ui clear 0")
                       .replace("output color", "output ids"), verify_each=True)
    gl, cl = render_both(c, scene)
    assert np.array_equal(gl["ids"], cl["ids"])                 # flat uints: exact
    assert_agree(c.plan("cl"), gl, cl, ["ids"])
    gb, layer = stippled_gbuffer(scene)
    ref_ids = np.where(gb.object_id < 0, 0, gb.object_id + 1)[::-1]     # bottom row first
    ref_layer = layer[::-1]
    inner = ~gb.edge[::-1]
    for got in (gl["ids"], cl["ids"]):
        assert np.array_equal(got[..., 0][inner], ref_ids[inner])
        assert np.array_equal(got[..., 1][inner], ref_layer[inner])
        # a translucent layer only where the stipple pattern gives it the pixel
        owner = stipple_map(scene.width, scene.height, top_down=False)
        lay = got[..., 1].astype(np.int64)
        assert np.all((lay == 0) | (lay == owner))
        assert set(np.unique(lay)) == {0, 1, 2, 3}


COUNT = """
pass vols {
  draw lights as VOLUME
  writes color
  depth ds always nowrite CLAMP
  cull CULL
  blend color add(one, one)
  fragment { color = vec4(1.0 / 255.0); }
}
"""


def count_image(scene, volume, cull, clamp=True):
    src = COUNT.replace("VOLUME", volume).replace("CULL", cull)
    src = src.replace("CLAMP", "clamp" if clamp else "")
    c = compiles(src)
    gl, cl = render_both(c, scene)
    assert np.array_equal(gl["color"], cl["color"]), (volume, cull, clamp)
    return gl["color"][..., 0].astype(int)


def _short_far(scene, far=3.0):
    return dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, far=far))


@pytest.mark.gl
@pytest.mark.cl
def test_cull_auto_camera_inside(mixed, backends):
    """Camera inside a light volume whose back faces lie past the far plane: `cull auto`
    with depth clamp lights every pixel exactly once; front faces are lost behind the near
    plane, back faces without clamp beyond the far plane."""
    scene = _short_far(mixed)
    eye = np.asarray(scene.camera.position)
    fwd = np.asarray(scene.camera.target) - eye
    fwd /= np.linalg.norm(fwd)
    point = Light("point", (1, 1, 1), position=tuple(eye + [0.3, -0.2, -0.5]), radius=5.0)
    spot = Light("spot", (1, 1, 1), position=tuple(eye - 1.0 * fwd), direction=tuple(fwd),
                 radius=8.0, inner_deg=40, outer_deg=60)
    P = scene.camera.projection(scene.aspect)
    for volume, light in (("sphere point", point), ("cone spot", spot)):
        s = dataclasses.replace(scene, lights=(light,))
        shape = volume.split()[0]
        assert cull_runs("auto", shape, s.lights, [0], eye, P) == [("front", [0])]
        assert np.all(count_image(s, volume, "auto") == 1), volume
        assert np.all(count_image(s, volume, "back") == 0), volume
        assert np.all(count_image(s, volume, "auto", clamp=False) == 0), volume


@pytest.mark.gl
@pytest.mark.cl
def test_cull_auto_camera_outside(mixed, backends):
    """Lights away from the camera: front faces, each covered pixel once (cull none covers
    each exactly twice); the far plane cuts them, which clamp undoes."""
    scene = _short_far(mixed, far=6.0)
    P = scene.camera.projection(scene.aspect)
    for volume, kind in (("sphere point", "point"), ("cone spot", "spot")):
        lights = tuple(l for l in scene.lights if l.type == kind)
        shape = volume.split()[0]
        runs = cull_runs("auto", shape, lights, range(len(lights)), scene.camera.position, P)
        assert runs == [("back", list(range(len(lights))))]
        for light in lights:
            s = dataclasses.replace(scene, lights=(light,))
            auto = count_image(s, volume, "auto")
            both = count_image(s, volume, "none")
            assert auto.max() == 1 and auto.sum() > 100
            assert np.array_equal(both, 2 * auto)
            assert count_image(s, volume, "auto", clamp=False).sum() < auto.sum()


CALVER = """
pass z { draw scene.opaque depth ds less write cull back }
pass points {
  draw lights as sphere point
  writes color
  depth ds DEPTH nowrite clamp
  cull auto
  blend color add(one, src_alpha)
  fragment { color = vec4(light.color * 0.3, 0.5); }
}
"""


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("depth, scissor", [("always", ""), ("lequal inside always", ""),
                                            ("lequal inside gequal", ""),
                                            ("lequal inside always", " scissor")])
def test_cull_auto_runs_in_light_order(mixed, backends, depth, scissor):
    """Lights alternating between inside (back faces) and outside (front faces), blended
    with an order-dependent equation: both backends draw the same runs in the same order."""
    eye = np.asarray(mixed.camera.position)
    lights = (Light("point", (1, 0.2, 0.1), position=(-1.2, 1.4, 1.4), radius=3.0),
              Light("point", (0.1, 1, 0.2), position=tuple(eye + [0.3, -0.2, -0.5]), radius=5.0),
              Light("point", (0.2, 0.1, 1), position=(2.5, 1.2, -1.5), radius=3.0),
              Light("point", (1, 1, 0.2), position=tuple(eye + [0.0, -1.0, -2.0]), radius=7.0),
              Light("point", (1, 1, 1), position=(0.3, 0.7, -0.5), radius=2.0))
    scene = dataclasses.replace(mixed, lights=lights)
    P = scene.camera.projection(scene.aspect)
    runs = cull_runs("auto", "sphere", lights, range(5), eye, P)
    assert [m for m, _ in runs] == ["back", "front", "back", "front", "back"]
    c = compiles(CALVER.replace("DEPTH", depth).replace("sphere point", "sphere point" + scissor))
    gl, cl = render_both(c, scene)
    assert_agree(c.plan("cl"), gl, cl, ["color"], blended=len(lights))
    if scissor:     # the scissor rectangles contain the lights' volumes: same image
        plain = compiles(CALVER.replace("DEPTH", depth)).pipeline("gl").render(scene)
        assert np.array_equal(plain["color"], gl["color"])


@pytest.mark.gl
@pytest.mark.cl
def test_inside_depth_test_applies_to_back_face_lights(mixed, backends):
    """`lequal inside always` equals `lequal` for outside lights and `always` for inside ones."""
    eye = np.asarray(mixed.camera.position)
    inside = Light("point", (0.1, 1, 0.2), position=tuple(eye + [0.3, -0.2, -0.5]), radius=5.0)
    outside = Light("point", (1, 0.2, 0.1), position=(-1.2, 1.4, 1.4), radius=3.0)
    for light, same_as in ((inside, "always"), (outside, "lequal")):
        scene = dataclasses.replace(mixed, lights=(light,))
        both = compiles(CALVER.replace("DEPTH", "lequal inside always"))
        ref = compiles(CALVER.replace("DEPTH", same_as))
        for backend in ("gl", "cl"):
            a = both.pipeline(backend).render(scene)["color"]
            b = ref.pipeline(backend).render(scene)["color"]
            assert np.array_equal(a, b), (backend, same_as)


DIRECTIONAL = """
pass z { draw scene.opaque depth ds less write cull back }
pass dir {
  draw lights as quad directional
  writes color
  depth ds lequal nowrite
  blend color add(one, one)
  fragment { color = vec4(light.color, 1.0 / 255.0); }
}
"""


@pytest.mark.gl
@pytest.mark.cl
def test_directional_quads_cover_the_screen(mixed, backends):
    c = compiles(DIRECTIONAL)
    gl, cl = render_both(c, mixed)
    assert np.array_equal(gl["color"], cl["color"])
    n_dir = sum(l.type == "directional" for l in mixed.lights)
    assert n_dir == 1
    assert np.all(gl["color"][..., 3] == n_dir)            # every pixel, once per light
    d = next(l for l in mixed.lights if l.type == "directional")
    expect = F.get("rgba8").quantize(np.append(d.color, 1.0))[:3]
    assert np.all(gl["color"][..., :3] == expect)
    # the scissored variant too (the light's scissor rectangle is the whole viewport)
    cs = compiles(DIRECTIONAL.replace("quad directional", "quad directional scissor"))
    gls, cls = render_both(cs, mixed)
    assert np.array_equal(gls["color"], gl["color"]) and np.array_equal(cls["color"], gl["color"])


DEFERRED_MIXED = """
pass gbuffer {
  draw scene.opaque
  writes gpos, gnormal
  depth ds less write
  cull back
  fragment { gpos = vec4(world_pos, 1.0); gnormal = vec4(normalize(normal), 0.0); }
}
pass sun {
  draw lights as quad directional
  reads gpos, gnormal
  writes accum
  depth ds always nowrite
  blend accum add(one, one)
  fragment {
    vec3 n = load(gnormal).xyz;
    accum = vec4(light.color * max(dot(n, -normalize(light.direction)), 0.0), 1.0);
  }
}
pass spots {
  draw lights as cone spot
  reads gpos, gnormal
  writes accum
  depth ds lequal nowrite clamp inside always
  cull auto
  blend accum add(one, one)
  fragment {
    vec3 p = load(gpos).xyz;
    vec3 l = light.position - p;
    float d = length(l);
    float spot = smoothstep(light.cos_outer, light.cos_inner, dot(-l / d, normalize(light.direction)));
    float att = clamp(1.0 - d / light.radius, 0.0, 1.0);
    accum = vec4(light.color * spot * att * max(dot(load(gnormal).xyz, l / d), 0.0), 1.0);
  }
}
pass points {
  draw lights as sphere point
  reads gpos, gnormal
  writes accum
  depth ds lequal nowrite clamp inside always
  cull auto
  blend accum add(one, one)
  fragment {
    vec3 l = light.position - load(gpos).xyz;
    float d = length(l);
    float att = clamp(1.0 - d / light.radius, 0.0, 1.0);
    accum = vec4(light.color * att * max(dot(load(gnormal).xyz, l / d), 0.0), 1.0);
  }
}
pass resolve {
  draw fullscreen
  reads accum
  writes color
  fragment { color = vec4(load(accum).xyz, 1.0); }
}
"""


@pytest.mark.gl
@pytest.mark.cl
def test_deferred_mixed_lights_agree(mixed, backends):
    """Calver-style deferred lighting on mixed_lights: directional quads, spot cones and
    point spheres (cull auto, depth clamp) agree between the backends."""
    from pipegen.proof.check import check
    c = compiles(DEFERRED_MIXED, targets="target gpos : rgba32f clear 0\n"
                                         "target gnormal : rgba16f clear 0\n"
                                         "target accum : rgba16f clear 0")
    result = check(c, mixed)
    assert result.passed, result.table() + f"\nfirst divergence: {result.first_divergence}"
    gl = c.pipeline("gl").render(mixed)
    # the light passes count 1 per light fragment in accum.w: the sun covers every pixel
    lit = np.asarray(gl["accum"][..., 3], np.float32)
    assert np.all(lit >= 1.0)
    assert lit.max() >= 3.0     # a pixel lit by the sun, a spot and a point light


REPEAT = """
pass d {
  draw fullscreen
  repeat per light directional
  writes color
  blend color add(one, one)
  fragment { color = vec4(light.color, 1.0 / 255.0); }
}
repeat per light spot point {
  pass m { draw lights as sphere point clear ds stencil 0 depth ds always nowrite }
  pass s { draw fullscreen writes color blend color add(one, one)
           fragment { color = vec4(0.0, 0.0, 0.0, 1.0 / 255.0); } }
}
"""


@pytest.mark.gl
@pytest.mark.cl
def test_repeat_per_light_types(mixed, backends):
    c = compiles(REPEAT)
    (gl, glc), (cl, clc) = render_both(c, mixed, capture_passes=True)
    ran = [(x["pass"], x["light"]) for x in glc]
    assert ran == [(x["pass"], x["light"]) for x in clc]
    types = [l.type for l in mixed.lights]
    assert ran == ([("d", i) for i, t in enumerate(types) if t == "directional"]
                   + [(p, i) for i, t in enumerate(types) if t in ("spot", "point")
                      for p in (("m", "s") if t == "point" else ("s",))])
    assert np.array_equal(gl["color"], cl["color"])
    assert np.all(gl["color"][..., 3] == 1 + types.count("spot") + types.count("point"))
