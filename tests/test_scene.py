"""Scenes and meshes: loading, errors, geometry/light-table layout, mesh and volume properties."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from pipegen.scene import meshes, obj as objfile
from pipegen.core.diagnostics import PipegenError
from pipegen.scene import (
    Camera, Geometry, assign_layers, default_scene, load_scene, parse_scene, stipple_map,
    stipple_owner)

SCENES = Path(__file__).resolve().parent.parent / "examples" / "scenes"

MINIMAL = """
width = 64
height = 32

[camera]
position = [0, 2, 5]
target = [0, 0, 0]
fov_y_deg = 45

[[objects]]
mesh = "box"
material = { albedo = [1, 0, 0] }

[[lights]]
position = [0, 1, 1]
radius = 2
color = [1, 1, 1]
"""


# -- loading -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["small", "many_lights", "stress_overlap", "mixed_lights",
                                  "translucent_layers", "edges"])
def test_example_scenes_load(name):
    s = load_scene(SCENES / f"{name}.toml")
    assert s.name == name
    assert s.objects and s.lights
    assert all(1 <= o.id <= 255 for o in s.objects)
    assert len({o.id for o in s.objects}) == len(s.objects)


def test_example_scene_sizes():
    small = load_scene(SCENES / "small.toml")
    assert (small.width, small.height) == (96, 64)
    assert len(small.objects) == 4 and len(small.lights) == 4
    many = load_scene(SCENES / "many_lights.toml")
    assert (many.width, many.height) == (1280, 720)
    assert len(many.objects) >= 100 and len(many.lights) >= 80
    stress = load_scene(SCENES / "stress_overlap.toml")
    assert (stress.width, stress.height) == (128, 72)
    cam = np.array(stress.camera.position)
    assert any(np.linalg.norm(cam - l.position) < l.radius for l in stress.lights)
    mixed = load_scene(SCENES / "mixed_lights.toml")
    assert mixed.light_types == {"point", "spot", "directional"}
    assert mixed.has_translucent
    layers = load_scene(SCENES / "translucent_layers.toml")
    assert (layers.width, layers.height) == (192, 108)
    assert 8 <= len(layers.lights) <= 12 and layers.light_types == {"point"}
    glass = [o for o in layers.objects if o.material.translucent]
    assert len(glass) >= 3 and {o.layer for o in glass} == {1, 2, 3}
    assert all(0.3 <= o.material.alpha <= 0.6 for o in glass)
    assert all(o.layer == 0 for o in layers.objects if not o.material.translucent)
    edges = load_scene(SCENES / "edges.toml")
    assert (edges.width, edges.height) == (192, 108)
    assert 8 <= len(edges.lights) <= 16 and edges.light_types == {"point"}
    assert not edges.has_translucent


def test_default_scene():
    s = default_scene()
    assert (s.width, s.height) == (320, 180)
    assert len(s.lights) == 8 and {l.type for l in s.lights} == {"point"}
    assert len(s.objects) >= 5
    t = s.with_size(64, 36)
    assert (t.width, t.height) == (64, 36) and (s.width, s.height) == (320, 180)
    assert t.objects is s.objects


def test_minimal_defaults():
    s = parse_scene(MINIMAL)
    (o,) = s.objects
    assert o.id == 1 and o.material.kind == "opaque"
    assert o.material.alpha == 1.0
    assert s.camera.up == (0.0, 1.0, 0.0)
    assert np.all(s.ambient == 0)
    assert s.lights[0].type == "point"


def test_transform_order_scale_rotate_translate():
    text = MINIMAL.replace('mesh = "box"', 'mesh = "box"\nscale = [2, 1, 1]\nrotate_deg = [0, 90, 0]\n'
                                           'translate = [10, 0, 0]')
    o = parse_scene(text).objects[0]
    lo, hi = o.positions.min(axis=0), o.positions.max(axis=0)
    # scaled along x to 2, rotated so that it lies along z, then moved to x = 10
    np.testing.assert_allclose(lo, [9.5, -0.5, -1.0], atol=1e-12)
    np.testing.assert_allclose(hi, [10.5, 0.5, 1.0], atol=1e-12)


def test_mirroring_transform_keeps_ccw_outside():
    text = MINIMAL.replace('mesh = "box"', 'mesh = "box"\nscale = [-1, 1, 1]')
    o = parse_scene(text).objects[0]
    fn = meshes.face_normals(o.positions)
    centroid = o.positions.reshape(-1, 3, 3).mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, centroid) > 0)
    assert np.all(np.einsum("ij,ij->i", fn, o.normals[::3]) > 0.99)


# -- stipple layers ------------------------------------------------------------------------------


def _pane(z: float, extra: str = "", alpha: float = 0.5) -> str:
    return (f'[[objects]]\nmesh = "box"\ntranslate = [0, 0, {z}]\nscale = [1, 1, 0.05]\n{extra}'
            f'material = {{ albedo = [0, 0, 1], alpha = {alpha}, translucent = true }}\n\n')


def test_layers_automatic_far_to_near_cycle():
    # camera at z = 5; panes listed in a shuffled depth order
    zs = [-1.0, -4.0, 2.0, -2.0, 0.0, 1.0, -3.0]
    s = parse_scene(MINIMAL.replace("[[lights]]", "".join(_pane(z) for z in zs) + "[[lights]]"))
    assert s.objects[0].layer == 0                                        # the opaque box
    panes = s.objects[1:]
    by_depth = sorted(panes, key=lambda o: o.bounds_centre[2])            # far (most negative z) first
    assert [o.layer for o in by_depth] == [1, 2, 3, 1, 2, 3, 1]
    g = s.geometry()
    for o in s.objects:
        assert np.all(g.layer[g.ids[:, 0] == o.id] == o.layer)


def test_layers_explicit_and_mixed():
    text = MINIMAL.replace("[[lights]]", _pane(-2.0, "layer = 3\n") + _pane(-1.0) + _pane(0.0)
                           + _pane(1.0, "layer = 1\n") + "[[lights]]")
    s = parse_scene(text)
    # explicit layers are kept; the others cycle far -> near among themselves
    assert [o.layer for o in s.objects] == [0, 3, 1, 2, 1]
    # same ordering through the helper
    again = assign_layers(list(s.objects), s.camera.position, [None, 3, None, None, 1])
    assert [o.layer for o in again] == [0, 3, 1, 2, 1]
    # ties keep file order
    tie = parse_scene(MINIMAL.replace("[[lights]]", _pane(-1.0) + _pane(-1.0) + "[[lights]]"))
    assert [o.layer for o in tie.objects] == [0, 1, 2]


def test_layer_errors():
    err = _error(MINIMAL.replace('mesh = "box"', 'mesh = "box"\nlayer = 2'))
    assert "translucent objects only" in err.message and err.span.source_line.startswith("layer")
    err = _error(MINIMAL.replace("[[lights]]", _pane(0.0, "layer = 4\n") + "[[lights]]"))
    assert "layer" in err.message and "[1, 3]" in err.message
    err = _error(MINIMAL.replace("[[lights]]", _pane(0.0, "layer = 0\n") + "[[lights]]"))
    assert "layer" in err.message


def test_geometry_layer_array():
    s = load_scene(SCENES / "translucent_layers.toml")
    g = s.geometry()
    assert g.layer.dtype == np.float32 and g.layer.shape == (g.vertex_count,)
    assert g.interleaved().shape == (g.vertex_count, 14)                 # layout unchanged
    t = s.geometry(("translucent",))
    assert set(np.unique(t.layer).tolist()) == {1.0, 2.0, 3.0}
    assert np.all(s.geometry(("opaque",)).layer == 0)
    # a Geometry built without layers (fakes in the runtime tests) is all layer 0
    z = np.zeros((3, 3), np.float32)
    assert Geometry(z, z, z, z, np.zeros((3, 2), np.float32)).layer.tolist() == [0, 0, 0]


def test_stipple_owner_partitions_2x2_blocks():
    for x0 in (0, 2, 10):
        for y0 in (0, 4, 6):
            owners = sorted(stipple_owner(x0 + dx, y0 + dy) for dx in (0, 1) for dy in (0, 1))
            assert owners == [0, 1, 2, 3]
    assert stipple_owner(0, 0) == 0 and stipple_owner(1, 0) == 1 and stipple_owner(0, 1) == 2
    xs, ys = np.meshgrid(np.arange(6), np.arange(4))
    counts = np.bincount(stipple_owner(xs, ys).ravel())
    assert counts.tolist() == [6, 6, 6, 6]
    # the map is in GL window coordinates: y counts from the bottom row
    m = stipple_map(4, 3)                                                  # top row first
    assert m[-1].tolist() == [0, 1, 0, 1] and m[-2].tolist() == [2, 3, 2, 3]
    assert m[0].tolist() == [0, 1, 0, 1]
    np.testing.assert_array_equal(stipple_map(4, 3, top_down=False), m[::-1])


# -- errors --------------------------------------------------------------------------------------


def _error(text: str) -> PipegenError:
    with pytest.raises(PipegenError) as info:
        parse_scene(text, "bad.toml")
    err = info.value
    assert "Traceback" not in err.render()
    return err


def test_error_invalid_toml_has_position():
    err = _error("width = 64\nheight = = 3\n")
    assert err.span is not None and err.span.line == 2
    assert "invalid TOML" in err.message
    assert err.render().startswith("bad.toml:2:")


def test_error_missing_key_is_named_and_located():
    err = _error(MINIMAL.replace("position = [0, 2, 5]\n", ""))
    assert "position" in err.message and "camera" in err.message
    assert err.span is not None and "[camera]" in err.span.source_line
    err = _error(MINIMAL.replace("material = { albedo = [1, 0, 0] }", "material = { specular = 1.0 }"))
    assert "albedo" in err.message
    err = _error(MINIMAL.replace("width = 64\n", ""))
    assert "width" in err.message


def test_error_bad_values_point_at_their_key():
    err = _error(MINIMAL.replace("radius = 2", "radius = -2"))
    assert "radius" in err.message and "> 0" in err.message
    assert err.span.source_line.startswith("radius")
    err = _error(MINIMAL.replace('mesh = "box"', 'mesh = "teapot"'))
    assert "teapot" in err.message and err.span.source_line.startswith("mesh")
    err = _error(MINIMAL.replace("albedo = [1, 0, 0]", "albedo = [1, 0]"))
    assert "albedo" in err.message and "three numbers" in err.message
    assert err.span.source_line.startswith("material") and err.span.column > 1
    err = _error(MINIMAL.replace('mesh = "box"', 'mesh = "box"\ncolour = 3'))
    assert "unknown key 'colour'" in err.message and "material" in err.hint
    err = _error(MINIMAL.replace('mesh = "box"', 'mesh = "box"\nid = 300'))
    assert "id" in err.message


def test_error_duplicate_ids_and_bad_spot():
    two = MINIMAL.replace('[[lights]]', '[[objects]]\nmesh = "sphere"\nid = 1\n'
                          'material = { albedo = [1, 1, 1] }\n\n[[lights]]')
    err = _error(two)
    assert "id 1" in err.message and err.span.line == two.splitlines().index("id = 1") + 1
    spot = MINIMAL.replace("position = [0, 1, 1]", 'type = "spot"\ndirection = [0, -1, 0]\n'
                           "inner_deg = 30\nouter_deg = 20\nposition = [0, 1, 1]")
    assert "inner_deg < outer_deg" in _error(spot).message
    no_dir = MINIMAL.replace("position = [0, 1, 1]", 'type = "spot"\ninner_deg = 10\nouter_deg = 20\n'
                             "position = [0, 1, 1]")
    assert "direction" in _error(no_dir).message


def test_error_mesh_and_obj(tmp_path):
    assert "exactly one of" in _error(MINIMAL.replace('mesh = "box"', 'mesh = "box"\nobj = "x.obj"')).message
    scene = tmp_path / "s.toml"
    scene.write_text(MINIMAL.replace('mesh = "box"', 'obj = "missing.obj"'))
    with pytest.raises(PipegenError, match="missing.obj"):
        load_scene(scene)
    (tmp_path / "broken.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    scene.write_text(MINIMAL.replace('mesh = "box"', 'obj = "broken.obj"'))
    with pytest.raises(PipegenError, match=r"broken.obj:3"):
        load_scene(scene)
    with pytest.raises(PipegenError, match="cannot read scene"):
        load_scene(tmp_path / "nope.toml")


def test_error_camera():
    assert "far" in _error(MINIMAL.replace("fov_y_deg = 45", "fov_y_deg = 45\nnear = 5\nfar = 1")).message
    assert "parallel" in _error(MINIMAL.replace("position = [0, 2, 5]", "position = [0, 5, 0]")).message


# -- geometry and the light table ----------------------------------------------------------------


def test_geometry_layout_and_filters():
    s = load_scene(SCENES / "mixed_lights.toml")
    g = s.geometry(())
    tris = sum(o.triangle_count for o in s.objects)
    assert g.positions.shape == (3 * tris, 3)
    for a, c in [(g.positions, 3), (g.normals, 3), (g.albedo, 3), (g.material, 3), (g.ids, 2)]:
        assert a.dtype == np.float32 and a.shape == (3 * tris, c)
    # object order, ids and material per vertex
    first = s.objects[0]
    n0 = 3 * first.triangle_count
    assert np.all(g.ids[:n0, 0] == first.id)
    np.testing.assert_allclose(g.albedo[:n0], np.tile(first.material.albedo, (n0, 1)), rtol=1e-7)
    np.testing.assert_allclose(g.material[n0 - 1], [first.material.specular, first.material.shininess,
                                                    first.material.alpha], rtol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(g.normals, axis=1), 1.0, atol=1e-6)
    opaque, translucent = s.geometry(("opaque",)), s.geometry(("translucent",))
    assert opaque.vertex_count + translucent.vertex_count == g.vertex_count
    assert translucent.vertex_count == 3 * s.objects[-1].triangle_count
    assert np.all(translucent.material[:, 2] == 0.5)
    assert g.interleaved().shape == (3 * tris, 14)
    with pytest.raises(PipegenError):
        s.geometry(("glass",))


def test_geometry_normal_groups_per_object():
    s = load_scene(SCENES / "small.toml")
    g = s.geometry()
    box_id = next(o.id for o in s.objects if o.mesh == "box")
    groups = g.ids[g.ids[:, 0] == box_id, 1]
    assert sorted(set(groups.tolist())) == list(range(6))


def test_light_table():
    s = load_scene(SCENES / "mixed_lights.toml")
    fields = [("position", "vec3"), ("radius", "float"), ("color", "vec3"), ("direction", "vec3"),
              ("type", "uint"), ("cos_inner", "float"), ("cos_outer", "float")]
    t = s.light_table(fields, 8)
    assert t.shape == (8, 7, 4) and t.dtype == np.float32
    assert np.all(t[len(s.lights):] == 0)
    for i, light in enumerate(s.lights):
        np.testing.assert_allclose(t[i, 2, :3], light.color, rtol=1e-7)
        assert t[i, 4, 0] == {"point": 0, "spot": 1, "directional": 2}[light.type]
        assert np.all(t[i, :, 3] == 0) and t[i, 1, 1:].tolist() == [0, 0, 0]
        if light.type != "point":
            np.testing.assert_allclose(np.linalg.norm(t[i, 3, :3]), 1.0, rtol=1e-6)
        if light.type == "spot":
            np.testing.assert_allclose(t[i, 5, 0], np.cos(np.radians(light.inner_deg)), rtol=1e-6)
            np.testing.assert_allclose(t[i, 6, 0], np.cos(np.radians(light.outer_deg)), rtol=1e-6)
            np.testing.assert_allclose(t[i, 0, :3], light.position, rtol=1e-7)
            assert t[i, 1, 0] == np.float32(light.radius)
    spot = next(l for l in s.lights if l.type == "spot")
    np.testing.assert_allclose(spot.direction, np.array([0.45, -1.0, -0.5]) / np.linalg.norm([0.45, -1.0, -0.5]))
    # a subset in another order
    sub = s.light_table([("color", "vec3"), ("position", "vec3")], 5)
    assert sub.shape == (5, 2, 4)
    np.testing.assert_allclose(sub[0, 1, :3], s.lights[0].position)


def test_light_table_errors():
    s = load_scene(SCENES / "small.toml")
    with pytest.raises(PipegenError, match="4 lights"):
        s.light_table([("position", "vec3")], 3)
    with pytest.raises(PipegenError, match="unknown light field"):
        s.light_table([("intensity", "float")], 8)
    with pytest.raises(PipegenError, match="vec3"):
        s.light_table([("position", "float")], 8)


def test_camera_matrices():
    cam = Camera(position=(1.0, 2.0, 3.0), target=(4.0, 2.0, -1.0), fov_y_deg=60.0, near=0.5, far=20.0)
    v = cam.view_matrix()
    eye_view = v @ np.array([1.0, 2.0, 3.0, 1.0])
    np.testing.assert_allclose(eye_view, [0, 0, 0, 1], atol=1e-12)
    tgt = v @ np.array([4.0, 2.0, -1.0, 1.0])
    np.testing.assert_allclose(tgt[:3], [0, 0, -5.0], atol=1e-12)        # straight ahead, -z
    np.testing.assert_allclose(v[:3, :3] @ v[:3, :3].T, np.eye(3), atol=1e-12)
    p = cam.projection(2.0)
    for z, ndc in ((-0.5, -1.0), (-20.0, 1.0)):
        c = p @ np.array([0.0, 0.0, z, 1.0])
        assert c[2] / c[3] == pytest.approx(ndc)
    top = p @ np.array([0.0, np.tan(np.radians(30.0)) * 4.0, -4.0, 1.0])
    assert top[1] / top[3] == pytest.approx(1.0)
    right = p @ np.array([2 * np.tan(np.radians(30.0)) * 4.0, 0.0, -4.0, 1.0])
    assert right[0] / right[3] == pytest.approx(1.0)


# -- meshes --------------------------------------------------------------------------------------


def _edge_balance(positions: np.ndarray) -> Counter:
    """Directed edges (as rounded position pairs) of a triangle list: in a closed, consistently
    wound mesh every edge a->b is matched by exactly one b->a."""
    p = [tuple(np.round(v, 9)) for v in positions]
    edges = Counter()
    for t in range(0, len(p), 3):
        for k in range(3):
            edges[(p[t + k], p[t + (k + 1) % 3])] += 1
    return edges


@pytest.mark.parametrize("name", ["box", "sphere", "cylinder"])
def test_closed_primitives_are_ccw_outside(name):
    m = meshes.PRIMITIVES[name]()
    edges = _edge_balance(m.positions)
    assert all(n == 1 and edges[(b, a)] == 1 for (a, b), n in edges.items())
    fn = meshes.face_normals(m.positions)
    centroid = m.positions.reshape(-1, 3, 3).mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, centroid) > 0)             # outward, hence ccw outside
    vn = m.normals.reshape(-1, 3, 3).mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, vn) > 0)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0)
    assert np.abs(m.positions).max() == pytest.approx(0.5)


def test_normal_groups():
    assert len(set(meshes.box().groups)) == 6
    assert set(meshes.sphere().groups) == {0}
    assert set(meshes.sphere(segments=7, rings=5).groups) == {0}
    assert len(set(meshes.cylinder().groups)) == 3
    assert set(meshes.plane(divisions=4).groups) == {0}
    # two faces of a box share a group exactly when they share a face normal
    b = meshes.box()
    fn = np.round(meshes.face_normals(b.positions), 6)
    for g in range(6):
        assert len({tuple(n) for n in fn[b.groups == g]}) == 1


def test_geometry_normal_groups_every_object_type(tmp_path):
    (tmp_path / "cube.obj").write_text(_CUBE_OBJ)
    text = MINIMAL.replace('mesh = "box"', 'obj = "cube.obj"')
    text = text.replace("[[lights]]", "".join(
        f'[[objects]]\nmesh = "{m}"\ntranslate = [{3 * k}, 0, 0]\nmaterial = {{ albedo = [1, 1, 1] }}\n\n'
        for k, m in enumerate(["box", "sphere", "cylinder", "plane"], 1)) + "[[lights]]")
    (tmp_path / "s.toml").write_text(text)
    s = load_scene(tmp_path / "s.toml")
    g = s.geometry()
    expect = {"cube.obj": 6, "box": 6, "sphere": 1, "cylinder": 3, "plane": 1}
    for o in s.objects:
        groups = g.ids[g.ids[:, 0] == o.id, 1]
        np.testing.assert_array_equal(groups, np.repeat(o.groups, 3))
        assert len(set(groups.tolist())) == expect[Path(o.mesh).name]


def _ridge_obj(path, normals: str) -> None:
    """A 'tent': two curved height-field patches y = -|x| + 0.1 z² meeting at a 90° ridge
    along x = 0, sharing the ridge vertices.  ``normals``: "smooth" (none: the loader
    smooths within its 45° crease angle), "explicit" (vn records: each patch's own normals,
    so two different normals at every ridge vertex) or "shared" (one normal per ridge vertex,
    used by both patches: no discontinuity)."""
    xs, zs = np.linspace(-1, 1, 9), np.linspace(-1, 1, 5)
    vid = {}
    lines = []
    for i, x in enumerate(xs):
        for j, z in enumerate(zs):
            vid[i, j] = len(vid) + 1
            lines.append(f"v {x} {-abs(x) + 0.1 * z * z} {z}")
    vn = {}
    if normals != "smooth":
        for side, sx in (("L", -1.0), ("R", 1.0)):
            for j, z in enumerate(zs):
                n = np.array([sx, 1.0, -0.2 * z])   # (-dy/dx, 1, -dy/dz) of y = -|x| + 0.1 z²
                vn[side, j] = len(vn) + 1
                lines.append(f"vn {n[0]} {n[1]} {n[2]}")
        for j, z in enumerate(zs):
            vn["M", j] = len(vn) + 1
            lines.append(f"vn 0 1 {-0.2 * z}")
    for i in range(len(xs) - 1):
        side = "L" if xs[i + 1] <= 0 else "R"
        for j in range(len(zs) - 1):
            quad = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)]
            if normals == "smooth":
                lines.append("f " + " ".join(str(vid[c]) for c in quad))
            else:
                def nid(c):
                    ridge = xs[c[0]] == 0 and normals == "shared"
                    return vn["M" if ridge else side, c[1]]
                lines.append("f " + " ".join(f"{vid[c]}//{nid(c)}" for c in quad))
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("normals,expect", [("smooth", 2), ("explicit", 2), ("shared", 1)])
def test_normal_groups_two_smooth_parts_joined_at_a_crease(tmp_path, normals, expect):
    obj = tmp_path / "ridge.obj"
    _ridge_obj(obj, normals)
    m = objfile.load_obj(obj)
    assert m.triangle_count == 8 * 4 * 2
    left = m.positions.reshape(-1, 3, 3)[:, :, 0].mean(axis=1) < 0
    # each side is one group (smooth, and curved: its normals vary) ...
    for side in (left, ~left):
        assert len(set(m.groups[side].tolist())) == 1
        nz = m.normals.reshape(-1, 3, 3)[side][:, :, 2]
        assert np.ptp(nz) > 0.1
    # ... and the ridge separates them exactly when the normals are discontinuous there
    assert len(set(m.groups.tolist())) == expect
    # through a scene: Geometry.ids[:, 1] carries the groups
    scene = tmp_path / "s.toml"
    scene.write_text(MINIMAL.replace('mesh = "box"', 'obj = "ridge.obj"'))
    g = load_scene(scene).geometry()
    assert len(np.unique(g.ids[:, 1])) == expect
    np.testing.assert_array_equal(g.ids[:, 1], np.repeat(m.groups, 3))


def test_normal_groups_non_manifold_edge():
    # three triangles on one edge: the first and last agree on the normals, the middle not
    e0, e1 = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]
    pos = np.array([e0, e1, [0.5, 1, 0], e0, e1, [0.5, 0, 1], e1, e0, [0.5, -1, 0]])
    nrm = np.array([[0, 0, 1.0]] * 3 + [[0, 1.0, 0]] * 3 + [[0, 0, 1.0]] * 3)
    g = meshes.normal_groups(pos, nrm)
    assert g[0] == g[2] != g[1]


def test_normal_groups_wrap_at_256():
    # 300 disconnected triangles: group ids stay 8-bit
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    pos = np.concatenate([tri + [0, 0, 3 * k] for k in range(300)])
    nrm = np.tile([0.0, 0.0, 1.0], (len(pos), 1))
    g = meshes.normal_groups(pos, nrm)
    assert g.max() == 255 and g[256] == 0 and g[0] == 0 and g[255] == 255


_CUBE_OBJ = """# cube
v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6
"""


def test_obj_loader(tmp_path):
    # a unit cube as quads without normals: triangulated, faceted by the crease angle
    cube = tmp_path / "cube.obj"
    cube.write_text(_CUBE_OBJ)
    m = objfile.load_obj(cube)
    assert m.triangle_count == 12 and len(set(m.groups)) == 6
    fn = meshes.face_normals(m.positions)
    np.testing.assert_allclose(np.einsum("ij,ij->i", fn, m.normals[::3]), 1.0)
    assert np.all(np.einsum("ij,ij->i", fn, m.positions.reshape(-1, 3, 3).mean(axis=1)) > 0)
    # explicit normals with v//vn and negative (relative) indices
    tri = tmp_path / "tri.obj"
    tri.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 2\nf -3//1 -2//1 -1//1\n")
    m = objfile.load_obj(tri)
    np.testing.assert_allclose(m.normals, [[0, 0, 1]] * 3)
    # through a scene, relative to the scene file
    scene = tmp_path / "s.toml"
    scene.write_text(MINIMAL.replace('mesh = "box"', 'obj = "cube.obj"\nscale = 0.5'))
    s = load_scene(scene)
    assert s.objects[0].triangle_count == 12
    np.testing.assert_allclose(s.objects[0].positions.max(axis=0), [0.5, 0.5, 0.5])


# -- light volumes -------------------------------------------------------------------------------


def _face_planes(p: np.ndarray):
    fn = meshes.face_normals(p)
    return fn, np.einsum("ij,ij->i", fn, p[::3])


def test_sphere_volume_circumscribes_unit_sphere():
    p = meshes.light_volume("sphere").astype(np.float64)
    assert p.dtype == np.float64 and len(p) % 3 == 0
    fn, dist = _face_planes(p)
    assert dist.min() >= 1.0                     # every face plane lies outside the unit sphere
    assert np.linalg.norm(p, axis=1).max() < 1.03
    centroid = p.reshape(-1, 3, 3).mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, centroid) > 0)             # ccw seen from outside
    edges = _edge_balance(p)
    assert all(edges[(b, a)] == 1 for (a, b) in edges)
    # random unit vectors lie inside every face plane
    rng = np.random.default_rng(1)
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.all(d @ fn.T <= dist + 1e-12)
    assert meshes.light_volume("sphere").dtype == np.float32


def test_cone_volume_contains_45_degree_cone():
    p = meshes.light_volume("cone").astype(np.float64)
    fn, dist = _face_planes(p)
    edges = _edge_balance(p)
    assert all(edges[(b, a)] == 1 for (a, b) in edges)
    interior = np.array([0.0, 0.0, -0.6])
    assert np.all(fn @ interior < dist)                                # outward = ccw outside
    # the circular cone: apex at 0, axis -z, length 1, radius |z| (half-angle 45°)
    rng = np.random.default_rng(2)
    z = -rng.uniform(0, 1, 3000)
    a = rng.uniform(0, 2 * np.pi, 3000)
    pts = np.stack([-z * np.cos(a), -z * np.sin(a), z], axis=1)
    assert np.all(pts @ fn.T <= dist + 1e-6)
    assert p[:, 2].min() == -1.0 and p[:, 2].max() == 0.0


def test_quad_volume():
    p = meshes.light_volume("quad")
    assert p.shape == (6, 3)
    assert np.all(p[:, 2] == 0) and set(p[:, 0]) == {-1, 1} and set(p[:, 1]) == {-1, 1}
    assert np.all(meshes.face_normals(p.astype(np.float64))[:, 2] == 1.0)
    with pytest.raises(ValueError):
        meshes.light_volume("torus")


def test_view_matrix_is_the_look_at_numpy_builds():
    """``Camera.view_matrix`` takes its cross products by hand (``model._cross``): bit for bit
    the look-at ``np.cross`` gives, on random cameras across scales."""
    from pipegen.scene.model import Camera
    rng = np.random.default_rng(7)
    for _ in range(200):
        eye, target, up = (tuple(rng.normal(size=3) * 10.0 ** rng.uniform(-3, 3))
                           for _ in range(3))
        e = np.asarray(eye, np.float64)
        f = np.asarray(target, np.float64) - e
        f /= np.linalg.norm(f)
        s = np.cross(f, np.asarray(up, np.float64))
        s /= np.linalg.norm(s)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = s, np.cross(s, f), -f
        m[:3, 3] = -m[:3, :3] @ e
        assert np.array_equal(Camera(eye, target, up).view_matrix(), m)
