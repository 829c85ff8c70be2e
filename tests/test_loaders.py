"""OBJ + MTL and glTF loading (issue 13): every mapping rule, the notes on what was ignored,
the checks (degenerate triangles dropped and counted, non-finite vertices rejected with their
position), ids and names of the objects a file gives, and glTF in scene files."""

from __future__ import annotations

import base64
import math
import warnings
from pathlib import Path

import numpy as np
import pygltflib as gl
import pytest

from pipegen.scene import meshes
from pipegen.core.diagnostics import PipegenError
from pipegen.scene.gltf import GltfError, framing_camera, load_gltf, pbr_material, punctual_light
from pipegen.scene.obj import MtlMaterial, parse_mtl, read_obj
from pipegen.scene import SceneLoadWarning, load_scene, parse_scene

pytestmark = pytest.mark.filterwarnings("ignore::pipegen.scene.model.SceneLoadWarning")

ROOT = Path(__file__).resolve().parents[1]
CORNELL = ROOT / "examples" / "models" / "cornell_box"

SCENE_HEAD = """
width = 64
height = 32

[camera]
position = [0, 2, 6]
target = [0, 0, 0]
fov_y_deg = 45
"""


def _load(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneLoadWarning)
        return load_scene(path)


# -- MTL mapping -------------------------------------------------------------------------------


def test_mtl_mapping_rules():
    mats, notes = parse_mtl("""
newmtl full
Kd 0.5 0.25 0.125
Ks 0.3 0.6 0.9
Ns 50
d 0.4
newmtl grey_kd
Kd 0.7
newmtl empty
newmtl tr_only
Tr 0.25
newmtl both
d 0.9
Tr 0.5
newmtl rough
Ns 0
d 1.5
""", "m.mtl")
    full = mats["full"]
    assert full.albedo == (0.5, 0.25, 0.125)                      # Kd -> albedo
    assert full.specular == pytest.approx(0.6)                     # mean of Ks
    assert full.shininess == 50.0                                  # Ns -> shininess
    assert full.alpha == 0.4 and full.translucent                  # d -> alpha, < 1 translucent
    assert mats["grey_kd"].albedo == (0.7, 0.7, 0.7)               # one number: grey
    e = mats["empty"]                                              # absent: the defaults
    assert (e.albedo, e.specular, e.shininess, e.alpha, e.translucent) == ((0.8, 0.8, 0.8), 0.0, 32.0,
                                                                          1.0, False)
    assert mats["tr_only"].alpha == 0.75                           # Tr: alpha = 1 - Tr
    assert mats["both"].alpha == 0.9                               # d wins over Tr
    assert mats["rough"].shininess == 1.0 and mats["rough"].alpha == 1.0   # clamped
    assert notes == []


def test_mtl_notes_textures_and_ignored_statements_once():
    _, notes = parse_mtl("newmtl a\nKa 1 1 1\nmap_Kd a.png\nmap_Bump -bm 0.5 n.png\nillum 2\n"
                         "newmtl b\nKa 0 0 0\nmap_Kd b.png\nmap_Kd a.png\n", "x.mtl")
    assert notes == ["x.mtl: textures dropped (not supported): a.png, b.png, n.png",
                     "x.mtl: ignored 'Ka' x2, 'illum' x1"]


def test_mtl_bad_number_is_an_error_with_its_line():
    with pytest.raises(meshes.ObjError, match=r"x.mtl:3: cannot read 'kd oops'"):
        parse_mtl("newmtl a\nKs 1 1 1\nKd oops\n", "x.mtl")


# -- OBJ: parts, ids, names, notes -------------------------------------------------------------


def _two_materials(tmp_path, extra_obj: str = "", mtl: str | None = None) -> Path:
    (tmp_path / "m.mtl").write_text(mtl if mtl is not None else
                                    "newmtl red\nKd 1 0 0\nKs 0.5 0.5 0.5\nNs 64\n"
                                    "newmtl glass\nKd 0.2 0.4 1\nd 0.5\nmap_Kd glass.png\n")
    (tmp_path / "m.obj").write_text(
        "mtllib m.mtl\no thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nvt 0 0\n"
        "usemtl red\nf 1 2 3\nusemtl glass\nf 1 3 4\nusemtl red\nf 1 4 5\n" + extra_obj)
    return tmp_path / "m.obj"


def test_obj_one_object_per_usemtl_material(tmp_path):
    _two_materials(tmp_path)
    (tmp_path / "s.toml").write_text(SCENE_HEAD + '[[objects]]\nobj = "m.obj"\nname = "model"\n\n'
                                     '[[objects]]\nmesh = "box"\nmaterial = { albedo = [1, 1, 1] }\n')
    s = _load(tmp_path / "s.toml")
    red, glass, box = s.objects
    assert (red.name, red.id, glass.name, glass.id, box.id) == ("model/red", 1, "model/glass", 2, 3)
    assert red.triangle_count == 2 and glass.triangle_count == 1        # faces by usemtl
    assert red.material.albedo == (1.0, 0.0, 0.0) and red.material.specular == 0.5
    assert red.material.shininess == 64 and not red.material.translucent
    assert glass.material.alpha == 0.5 and glass.material.translucent and glass.layer == 1
    g = s.geometry()
    assert sorted(set(g.ids[:, 0].astype(int).tolist())) == [1, 2, 3]
    assert s.notes == ("m.obj: ignored 'o' x1 (object names), 'vt' x1 (texture coordinates)",
                       "m.mtl: textures dropped (not supported): glass.png")


def test_obj_explicit_first_id_and_id_clash(tmp_path):
    _two_materials(tmp_path)
    (tmp_path / "s.toml").write_text(SCENE_HEAD + '[[objects]]\nobj = "m.obj"\nid = 10\n')
    assert [o.id for o in _load(tmp_path / "s.toml").objects] == [10, 11]
    (tmp_path / "s.toml").write_text(SCENE_HEAD + '[[objects]]\nobj = "m.obj"\nid = 10\n\n'
                                     '[[objects]]\nmesh = "box"\nid = 11\n'
                                     'material = { albedo = [1, 1, 1] }\n')
    with pytest.raises(PipegenError, match="object id 11 is used by objects.0. and objects.1."):
        _load(tmp_path / "s.toml")
    (tmp_path / "s.toml").write_text(SCENE_HEAD + '[[objects]]\nobj = "m.obj"\nid = 255\n')
    with pytest.raises(PipegenError, match="ids 255..256"):
        _load(tmp_path / "s.toml")


def test_obj_scene_material_replaces_mtl(tmp_path):
    _two_materials(tmp_path)
    (tmp_path / "s.toml").write_text(SCENE_HEAD + '[[objects]]\nobj = "m.obj"\n'
                                     'material = { albedo = [0, 1, 0] }\n')
    s = _load(tmp_path / "s.toml")
    (o,) = s.objects
    assert o.triangle_count == 3 and o.material.albedo == (0.0, 1.0, 0.0) and o.name == "obj0"
    assert any("replaces its 2 MTL material(s) (red, glass)" in n for n in s.notes)


def test_obj_notes_are_warned_once(tmp_path):
    _two_materials(tmp_path)
    (tmp_path / "s.toml").write_text(SCENE_HEAD + '[[objects]]\nobj = "m.obj"\n')
    with pytest.warns(SceneLoadWarning) as record:
        s = load_scene(tmp_path / "s.toml")
    assert [str(w.message) for w in record] == list(s.notes)
    assert record[0].filename == __file__                       # attributed to the caller


def test_obj_missing_mtl_and_unknown_material(tmp_path):
    (tmp_path / "m.obj").write_text("mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                    "f 1 2 3\nusemtl ghost\nf 3 2 1\n")
    model = read_obj(tmp_path / "m.obj")
    assert [p.material.name for p in model.parts] == ["(default)", "ghost"]
    assert all(p.material.albedo == (0.8, 0.8, 0.8) for p in model.parts)
    assert any("cannot read material library 'nowhere.mtl'" in n for n in model.notes)
    assert any("default material" in n and "'ghost' (no MTL defines it)" in n for n in model.notes)


def test_obj_degenerate_triangles_dropped_and_counted(tmp_path):
    (tmp_path / "d.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n"
                                    "f 1 2 3\nf 1 2 4\nf 1 1 3\n")      # collinear, repeated
    model = read_obj(tmp_path / "d.obj")
    assert model.triangles_read == 3 and model.dropped == 2 and model.parts[0].dropped == 2
    assert model.parts[0].mesh.triangle_count == 1
    assert "d.obj: dropped 2 degenerate (zero-area) triangles of 3" in model.notes


@pytest.mark.parametrize("text,line,match", [
    ("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", 2, "vertex 2 is not finite: 'v 1 nan 0'"),
    ("v 0 0 0\nv 1 0 0\n\nv 0 1 inf\nv inf 0 0\nf 1 2 3\n", 4, r"vertex 3 is not finite.*\(2 such"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", 4, "vertex index 7 out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", 4, "vertex index -4 out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", 4, "vertex index 0 out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n", 5, "at least three vertices"),
    ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", 2, "needs three coordinates"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n", 5, "normal index 2 out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", 4, "cannot read 'f 1 2 x'"),
])
def test_obj_errors_have_lines(tmp_path, text, line, match):
    (tmp_path / "e.obj").write_text(text)
    with pytest.raises(meshes.ObjError, match=match) as info:
        read_obj(tmp_path / "e.obj")
    assert info.value.line == line


def test_obj_nan_vertex_through_a_scene_names_file_and_line(tmp_path):
    (tmp_path / "e.obj").write_text("v 0 0 0\nv 1 NaN 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "s.toml").write_text(SCENE_HEAD + '[[objects]]\nobj = "e.obj"\n')
    with pytest.raises(PipegenError, match=r"e.obj:2: vertex 2 is not finite"):
        _load(tmp_path / "s.toml")


def test_obj_formats_relative_indices_and_polygons(tmp_path):
    # v/vt/vn, v//vn and v/vt corners mixed across faces, negative indices, a pentagon,
    # comments, tabs, CRLF and leading blanks
    (tmp_path / "f.obj").write_text(
        "# header\r\nv 0 0 0\r\nv 1 0 0\r\n  v 1 1 0 # corner\r\nv 0 1 0\r\nv 0.5 1.5 0\r\n"
        "vt 0 0\r\nvn 0 0 1\r\nf 1/1/1 2/1/1 3/1/1\r\nf\t1//1 3//1 4//1\r\nf -5/1 -3/1 -1/1\r\n"
        "f 1 2 3 5 4\r\n")
    m = read_obj(tmp_path / "f.obj")
    assert m.triangles_read == 1 + 1 + 1 + 3
    tris = m.mesh.positions.reshape(-1, 3, 3)
    np.testing.assert_array_equal(tris[2], [[0, 0, 0], [1, 1, 0], [0.5, 1.5, 0]])
    np.testing.assert_allclose(m.mesh.normals, np.tile([0, 0, 1.0], (len(m.mesh.normals), 1)))
    assert m.notes == ["f.obj: ignored 'vt' x1 (texture coordinates)"]


def test_obj_relative_indices_count_records_before_the_face(tmp_path):
    (tmp_path / "r.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n"
                                    "v 5 0 0\nv 6 0 0\nv 5 1 0\nf -3 -2 -1\n")
    tris = read_obj(tmp_path / "r.obj").mesh.positions.reshape(-1, 3, 3)
    assert tris[0, 0, 0] == 0 and tris[1, 0, 0] == 5


def test_cornell_box_materials():
    model = read_obj(CORNELL / "cornell_box.obj")
    albedo = {p.material.name: p.material.albedo for p in model.parts}
    assert albedo == {"white": (1.0, 1.0, 1.0), "light": (1.0, 1.0, 1.0), "green": (0.0, 1.0, 0.0),
                      "red": (1.0, 0.0, 0.0)}
    assert model.triangles_read == 36 and model.dropped == 0


# -- glTF mapping rules ------------------------------------------------------------------------


def test_pbr_mapping_rules():
    d = pbr_material((0.5, 0.4, 0.3, 0.6), metallic=0.0, roughness=0.5)
    a = 0.5 ** 2
    n = 2 / a ** 2 - 2                                             # 30
    assert d.albedo == pytest.approx((0.5, 0.4, 0.3))              # dielectric: base colour
    assert d.shininess == pytest.approx(n)
    assert d.specular == pytest.approx(0.04 * (n + 8) / 8)
    assert d.alpha == 1.0 and not d.translucent                   # OPAQUE ignores alpha
    m = pbr_material((0.9, 0.6, 0.3, 1.0), metallic=1.0, roughness=0.25)
    assert m.albedo == (0.0, 0.0, 0.0)                             # metal: no diffuse
    nm = 2 / (0.25 ** 2) ** 2 - 2
    assert m.shininess == pytest.approx(nm)
    assert m.specular == pytest.approx(0.6 * (nm + 8) / 8)         # F0 = mean base colour
    half = pbr_material((1, 1, 1, 1), metallic=0.5, roughness=1.0)
    assert half.albedo == (0.5, 0.5, 0.5) and half.shininess == 1.0   # rough: clamped to 1
    assert half.specular == pytest.approx((0.02 + 0.5) * 9 / 8)
    assert pbr_material(roughness=0.0).shininess == 1024.0         # mirror: clamped to 1024
    b = pbr_material((1, 1, 1, 0.35), 0.0, 1.0, "BLEND")
    assert b.translucent and b.alpha == 0.35                       # BLEND -> translucent
    k = pbr_material((1, 1, 1, 0.35), 0.0, 1.0, "MASK")
    assert not k.translucent and k.alpha == 1.0
    default = pbr_material()                                       # the spec's defaults
    assert default.albedo == (0, 0, 0) and default.shininess == 1.0


def _world(translation=(0, 0, 0), down=False):
    m = np.eye(4)
    m[:3, 3] = translation
    if down:                                                       # -z turned to -y
        m[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    return m


def test_punctual_light_rules():
    p = punctual_light({"type": "point", "color": [1, 0.5, 0.25], "intensity": 2, "range": 7},
                       _world((1, 2, 3)))
    assert (p.type, p.color, p.position, p.radius) == ("point", (2.0, 1.0, 0.5), (1, 2, 3), 7.0)
    no_range = punctual_light({"type": "point", "intensity": 4}, _world())
    assert no_range.radius == pytest.approx(16 * math.sqrt(4))     # I/d² = 1/256
    s = punctual_light({"type": "spot", "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
                       _world((0, 5, 0), down=True))
    assert s.type == "spot" and s.direction == pytest.approx((0, -1, 0))
    assert s.inner_deg == pytest.approx(math.degrees(0.2)) and s.outer_deg == pytest.approx(math.degrees(0.5))
    assert s.radius == pytest.approx(16.0)
    sd = punctual_light({"type": "spot"}, _world())                 # defaults: 0 and pi/4
    assert sd.inner_deg == 0 and sd.outer_deg == pytest.approx(45) and sd.direction == (0, 0, -1)
    wide = punctual_light({"type": "spot", "spot": {"innerConeAngle": 1.57, "outerConeAngle": 1.5708}},
                          _world())
    assert wide.outer_deg == 89.9 and wide.inner_deg < wide.outer_deg
    d = punctual_light({"type": "directional", "intensity": 0.5}, _world(down=True), 2.0)
    assert d.type == "directional" and d.color == (1.0, 1.0, 1.0) and d.direction == pytest.approx((0, -1, 0))
    with pytest.raises(GltfError, match="area"):
        punctual_light({"type": "area"}, _world())


# -- glTF files --------------------------------------------------------------------------------


def _tri_gltf(path: Path, *, nodes=None, extra=None, positions=None, indices=None,
              normals=True, binary=False, stride=None) -> Path:
    """A glTF with one triangle mesh (a unit right triangle in z = 0, facing +z, plus its
    mirror image as a second triangle when ``indices`` says so)."""
    pos = np.asarray(positions if positions is not None else
                     [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], dtype=np.float32)
    nrm = np.tile(np.float32([0, 0, 1]), (len(pos), 1))
    idx = np.asarray(indices if indices is not None else [0, 1, 2], dtype=np.uint8)
    blob = bytearray()
    views, accs = [], []

    def add(arr, kind, ctype, interleave=None):
        while len(blob) % 4:
            blob.append(0)
        data = arr.tobytes()
        if interleave:                                      # pad each element to `stride` bytes
            elem = arr.itemsize * arr.shape[1]
            data = b"".join(arr[i].tobytes() + b"\xee" * (interleave - elem) for i in range(len(arr)))
        views.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(data),
                                   byteStride=interleave))
        blob.extend(data)
        accs.append(gl.Accessor(bufferView=len(views) - 1, componentType=ctype, count=len(arr),
                                type=kind))
        return len(accs) - 1

    pa = add(pos, "VEC3", gl.FLOAT, stride)
    na = add(nrm, "VEC3", gl.FLOAT) if normals else None
    ia = add(idx, "SCALAR", gl.UNSIGNED_BYTE)
    extra = dict(extra or {})
    scenes = extra.pop("scenes", [gl.Scene(nodes=list(range(len(nodes))) if nodes else [0])])
    doc = gl.GLTF2(
        asset=gl.Asset(version="2.0"), scene=0, scenes=scenes,
        nodes=nodes or [gl.Node(mesh=0)],
        meshes=[gl.Mesh(name="tri", primitives=[gl.Primitive(
            attributes=gl.Attributes(POSITION=pa, NORMAL=na), indices=ia, material=0)])],
        materials=[gl.Material(name="m", pbrMetallicRoughness=gl.PbrMetallicRoughness(
            baseColorFactor=[0.2, 0.4, 0.6, 1.0], metallicFactor=0.0, roughnessFactor=0.5,
            baseColorTexture=gl.TextureInfo(index=0)))],
        accessors=accs, bufferViews=views,
        buffers=[gl.Buffer(byteLength=len(blob))],
        **extra)
    if binary:
        doc.set_binary_blob(bytes(blob))
        doc.save_binary(str(path))
    else:
        doc.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
        doc.save_json(str(path))
    return path


@pytest.mark.parametrize("binary", [False, True])
def test_gltf_mesh_material_and_notes(tmp_path, binary):
    path = _tri_gltf(tmp_path / ("t.glb" if binary else "t.gltf"), binary=binary)
    imp = load_gltf(path)
    (o,) = imp.objects
    assert o.id == 1 and o.name == "tri" and o.triangle_count == 1
    np.testing.assert_allclose(o.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert o.material == pbr_material((0.2, 0.4, 0.6, 1.0), 0.0, 0.5)
    assert imp.camera is None and imp.lights == ()
    assert imp.notes == (f"{path.name}: textures dropped (not supported): m.baseColorTexture",)


def test_gltf_node_transforms_hierarchy_and_matrix(tmp_path):
    q = [0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4)]       # 90° about +y
    mat = np.eye(4)
    mat[:3, 3] = [0, 0, -5]
    nodes = [gl.Node(translation=[10, 0, 0], children=[1], scale=[2, 2, 2]),
             gl.Node(rotation=q, mesh=0),
             gl.Node(matrix=mat.T.reshape(-1).tolist(), mesh=0, name="by matrix")]
    imp = load_gltf(_tri_gltf(tmp_path / "n.gltf", nodes=[nodes[0], nodes[1], nodes[2]],
                              extra={"scenes": [gl.Scene(nodes=[0, 2])]}))
    a, b = imp.objects
    # T(10,0,0) S(2) R_y(90°): (1,0,0) -> (0,0,-1) -> (0,0,-2) -> (10,0,-2)
    np.testing.assert_allclose(a.positions[1], [10, 0, -2], atol=1e-6)
    np.testing.assert_allclose(a.normals[0], [1, 0, 0], atol=1e-6)   # +z turned to +x
    assert b.name == "by matrix" and b.id == 2
    np.testing.assert_allclose(b.positions[2], [0, 1, -5])


def test_gltf_mirroring_node_keeps_ccw_outside(tmp_path):
    imp = load_gltf(_tri_gltf(tmp_path / "m.gltf", nodes=[gl.Node(mesh=0, scale=[-1, 1, 1])]))
    (o,) = imp.objects
    fn = meshes.face_normals(o.positions)
    np.testing.assert_allclose(fn[0], [0, 0, 1], atol=1e-9)          # winding fixed up
    np.testing.assert_allclose(o.normals[0], [0, 0, 1], atol=1e-9)


def test_gltf_strided_accessor_and_flat_normals(tmp_path):
    imp = load_gltf(_tri_gltf(tmp_path / "s.gltf", stride=16, normals=False))
    (o,) = imp.objects
    np.testing.assert_allclose(o.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_allclose(o.normals, [[0, 0, 1]] * 3)           # flat, as the spec says


def test_gltf_degenerate_dropped_and_nan_rejected(tmp_path):
    imp = load_gltf(_tri_gltf(tmp_path / "d.gltf", indices=[0, 1, 2, 0, 1, 3]))   # 2nd: collinear
    assert imp.dropped == 1 and imp.objects[0].triangle_count == 1
    assert any("dropped 1 degenerate" in n for n in imp.notes)
    bad = _tri_gltf(tmp_path / "nan.gltf", positions=[[0, 0, 0], [1, np.nan, 0], [0, 1, 0]])
    with pytest.raises(GltfError, match=r"mesh 0 \('tri'\) primitive 0: POSITION \(accessor 0\) "
                                        r"vertex 1 is not finite"):
        load_gltf(bad)
    with pytest.raises(PipegenError, match="bad glTF file.*vertex 1 is not finite"):
        load_scene(bad)


def test_gltf_camera_and_lights(tmp_path):
    nodes = [gl.Node(mesh=0),
             gl.Node(camera=0, translation=[0, 0, 5]),
             gl.Node(translation=[0, 3, 0], extensions={"KHR_lights_punctual": {"light": 0}}),
             gl.Node(extensions={"KHR_lights_punctual": {"light": 1}},
                     rotation=[-math.sin(math.pi / 4), 0, 0, math.cos(math.pi / 4)]),
             gl.Node(translation=[1, 4, 0], extensions={"KHR_lights_punctual": {"light": 2}},
                     rotation=[-math.sin(math.pi / 4), 0, 0, math.cos(math.pi / 4)])]
    lights = [{"type": "point", "color": [1, 0, 0], "range": 4},
              {"type": "directional", "intensity": 0.5},
              {"type": "spot", "intensity": 9, "spot": {"outerConeAngle": 0.6}}]
    path = _tri_gltf(tmp_path / "cl.gltf", nodes=nodes, extra=dict(
        cameras=[gl.Camera(type="perspective", perspective=gl.Perspective(yfov=0.8, znear=0.25))],
        extensionsUsed=["KHR_lights_punctual"], extensions={"KHR_lights_punctual": {"lights": lights}}))
    imp = load_gltf(path)
    cam = imp.camera
    assert cam.position == (0, 0, 5) and cam.target == (0, 0, 4) and cam.up == (0, 1, 0)
    assert cam.fov_y_deg == pytest.approx(math.degrees(0.8)) and cam.near == 0.25
    far = 2 * math.dist((0, 0, 5), (1, 1, 0))                         # no zfar: the stated rule
    assert cam.far == pytest.approx(far)
    assert any("camera without zfar" in n for n in imp.notes)
    point, sun, spot = imp.lights
    assert point.position == (0, 3, 0) and point.radius == 4
    assert sun.direction == pytest.approx((0, -1, 0)) and sun.color == (0.5, 0.5, 0.5)
    assert spot.radius == pytest.approx(48) and spot.outer_deg == pytest.approx(math.degrees(0.6))
    scene = load_scene(path)                                           # directly, as --scene does
    from pipegen import DEFAULT_SIZE
    assert (scene.width, scene.height) == DEFAULT_SIZE and scene.name == "cl"
    assert scene.light_types == {"point", "spot", "directional"} and scene.camera == cam


def test_gltf_without_camera_is_framed(tmp_path):
    path = _tri_gltf(tmp_path / "f.gltf")
    with pytest.warns(SceneLoadWarning, match="no perspective camera"):
        s = load_scene(path)
    assert s.camera == framing_camera(s.objects)
    centre = np.array([0.5, 0.5, 0.0])
    assert np.allclose(s.camera.target, centre)
    assert s.camera.near < np.linalg.norm(np.subtract(s.camera.position, centre)) - 0.5 ** 0.5 * 1.0


def test_gltf_required_extension_refused(tmp_path):
    path = _tri_gltf(tmp_path / "d.gltf", extra=dict(extensionsUsed=["KHR_draco_mesh_compression"],
                                                     extensionsRequired=["KHR_draco_mesh_compression"]))
    with pytest.raises(GltfError, match="requires KHR_draco_mesh_compression"):
        load_gltf(path)


def test_scene_toml_references_gltf(tmp_path):
    nodes = [gl.Node(mesh=0), gl.Node(camera=0, translation=[0, 0, 5]),
             gl.Node(translation=[0, 3, 0], extensions={"KHR_lights_punctual": {"light": 0}})]
    _tri_gltf(tmp_path / "m.gltf", nodes=nodes, extra=dict(
        cameras=[gl.Camera(type="perspective", perspective=gl.Perspective(yfov=0.8, znear=0.5, zfar=50))],
        extensionsUsed=["KHR_lights_punctual"],
        extensions={"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 2}]}}))
    # the file's camera and lights, size defaulted, a light and an object added
    s = parse_scene('[gltf]\nfile = "m.gltf"\nlight_intensity = 0.5\n\n'
                    '[[objects]]\nmesh = "box"\nmaterial = { albedo = [1, 1, 1] }\n\n'
                    '[[lights]]\ntype = "directional"\ndirection = [0, -1, 0]\ncolor = [1, 1, 1]\n',
                    base_dir=tmp_path)
    from pipegen import DEFAULT_SIZE
    assert (s.width, s.height) == DEFAULT_SIZE
    assert s.camera.position == (0, 0, 5) and s.camera.far == 50
    assert [o.id for o in s.objects] == [1, 2]
    assert [l.type for l in s.lights] == ["point", "directional"]
    assert s.lights[0].color == (1.0, 1.0, 1.0)                       # 2 x 0.5
    # overrides: camera from the TOML, the file's lights dropped
    s = parse_scene(SCENE_HEAD + '[gltf]\nfile = "m.gltf"\nlights = false\n', base_dir=tmp_path)
    assert s.camera.position == (0, 2, 6) and s.lights == () and (s.width, s.height) == (64, 32)
    # camera = false: the framing camera
    s = parse_scene('[gltf]\nfile = "m.gltf"\ncamera = false\n', base_dir=tmp_path)
    assert s.camera == framing_camera(s.objects)
    with pytest.raises(PipegenError, match="cannot read glTF file"):
        parse_scene('[gltf]\nfile = "nope.gltf"\n', base_dir=tmp_path)
    with pytest.raises(PipegenError, match="unknown key 'scale'"):
        parse_scene('[gltf]\nfile = "m.gltf"\nscale = 2\n', base_dir=tmp_path)


def test_cornell_gltf_matches_its_generator():
    s = load_scene(CORNELL / "cornell_box.gltf")
    assert [o.name for o in s.objects] == ["white", "light", "green", "red"]
    assert s.light_types == {"point", "spot", "directional"}
    obj = read_obj(CORNELL / "cornell_box.obj")
    for o, part in zip(s.objects, obj.parts):
        np.testing.assert_allclose(o.positions, part.mesh.positions * 0.01, rtol=1e-6, atol=1e-6)
        assert o.material.albedo == part.material.albedo
    assert s.notes == ()


def test_shipped_gltf_scene_file():
    s = load_scene(ROOT / "examples/scenes/cornell_box_gltf.toml")
    assert [o.id for o in s.objects] == [1, 2, 3, 4] and (s.width, s.height) == (320, 240)
    assert [l.type for l in s.lights] == ["point", "spot", "directional", "point", "spot"]
    assert s.camera.position == (1.2, 3.6, -3.5)                     # the TOML's camera
    file_lights = load_scene(CORNELL / "cornell_box.gltf").lights
    assert s.lights[0].color == pytest.approx(tuple(0.8 * c for c in file_lights[0].color))


def test_gltf_sparse_normalized_and_data_uri_media_types(tmp_path):
    import json
    pos = np.float32([[0, 0, 0], [1, 0, 0], [0, 1, 0]]).tobytes()           # 36 bytes
    nrm = np.int8([[0, 0, 127, 0]] * 3).tobytes()                          # 12: normalised
    sparse_idx = np.uint16([2, 0]).tobytes()                               # 4
    sparse_val = np.float32([[0, 3, 0]]).tobytes()                         # 12
    blob = pos + nrm + sparse_idx + sparse_val
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}}]}],
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/gltf-buffer;base64," + base64.b64encode(blob).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 12, "byteStride": 4},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 2},
                        {"buffer": 0, "byteOffset": 52, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "sparse": {"count": 1, "indices": {"bufferView": 2, "componentType": 5123},
                                  "values": {"bufferView": 3}}},
                      {"bufferView": 1, "componentType": 5120, "normalized": True, "count": 3,
                       "type": "VEC3"}],
    }
    (tmp_path / "s.gltf").write_text(json.dumps(doc))
    imp = load_gltf(tmp_path / "s.gltf")
    (o,) = imp.objects
    np.testing.assert_allclose(o.positions, [[0, 0, 0], [1, 0, 0], [0, 3, 0]])   # sparse applied
    np.testing.assert_allclose(o.normals, [[0, 0, 1]] * 3)                       # 127 -> 1.0
    assert any("default (white, metallic 1, roughness 1)" in n for n in imp.notes)
    doc["bufferViews"][0]["byteLength"] = 30                                     # too short
    (tmp_path / "bad.gltf").write_text(json.dumps(doc))
    with pytest.raises(GltfError, match=r"^accessors\[0\]: reads past the end of bufferView 0"):
        load_gltf(tmp_path / "bad.gltf")


def test_command_lines_say_each_load_note_once_as_a_note(tmp_path, capsys):
    """``load_scene_noting`` (every command that takes --scene: run, check, stress, sweep...):
    what the loader ignored is one ``note:`` line on stderr, not also a Python warning with its
    source line."""
    import warnings
    from pipegen.scene.load import load_scene_noting
    _two_materials(tmp_path)
    (tmp_path / "s.toml").write_text(SCENE_HEAD + '[[objects]]\nobj = "m.obj"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("error")                      # any warning would raise
        s = load_scene_noting(tmp_path / "s.toml")
    err = capsys.readouterr().err
    assert s.notes and err.splitlines() == [f"note: {n}" for n in s.notes]
    said = []
    load_scene_noting(tmp_path / "s.toml", said.append)
    assert said == [f"note: {n}" for n in s.notes] and capsys.readouterr().err == ""
