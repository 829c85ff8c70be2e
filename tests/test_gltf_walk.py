"""glTF node walk and primitive rules that tests/test_loaders.py does not reach (issue 23):
strips and fans, skipped primitive modes, object names and ids, the tree check, the 8-bit id
limit, a camera that is not perspective, and the notes on what was dropped."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

from pipegen.scene import meshes
from pipegen.scene.gltf import GltfError, load_gltf, pbr_material

CORNELL = Path(__file__).resolve().parents[1] / "examples/models/cornell_box/cornell_box.gltf"

QUAD = np.float32([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])


def _write(path: Path, primitives, nodes=None, roots=None, **rest) -> Path:
    """A glTF whose accessor 0 is the unit square's corners, 1 the indices 0 1 3 2 (a strip)
    and 2 the indices 0 1 2 3 (a fan); ``primitives`` refer to them."""
    blob = QUAD.tobytes() + np.uint8([0, 1, 3, 2, 0, 1, 2, 3]).tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0,
           "scenes": [{"nodes": roots if roots is not None else [0]}],
           "nodes": nodes or [{"mesh": 0}], "meshes": [{"name": "sq", "primitives": primitives}],
           "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                        + base64.b64encode(blob).decode()}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                           {"buffer": 0, "byteOffset": 48, "byteLength": 4},
                           {"buffer": 0, "byteOffset": 52, "byteLength": 4}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                         {"bufferView": 1, "componentType": 5121, "count": 4, "type": "SCALAR"},
                         {"bufferView": 2, "componentType": 5121, "count": 4, "type": "SCALAR"}],
           **rest}
    path.write_text(json.dumps(doc))
    return path


def test_strip_fan_and_skipped_modes(tmp_path):
    prims = [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 5},
             {"attributes": {"POSITION": 0}, "mode": 0},
             {"attributes": {"POSITION": 0}, "indices": 2, "mode": 6, "material": 0},
             {"attributes": {"POSITION": 0}, "mode": 1}]
    mats = [{"name": "fan", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 0.5]},
             "alphaMode": "BLEND"}]
    path = _write(tmp_path / "sf.gltf", prims, nodes=[{"mesh": 0, "translation": [0, 0, 2]}],
                  materials=mats)
    strip, fan = load_gltf(path, first_id=3).objects
    assert (strip.name, strip.id, strip.mesh) == ("sq/0", 3, "sf.gltf#mesh0/0")
    assert (fan.name, fan.id, fan.mesh) == ("sq/2", 4, "sf.gltf#mesh0/2")
    for o in (strip, fan):                  # both cover the square as two ccw triangles
        assert o.triangle_count == 2 and set(o.positions[:, 2]) == {2.0}
        np.testing.assert_allclose(meshes.face_normals(o.positions), [[0, 0, 1]] * 2)
        np.testing.assert_allclose(o.normals, [[0, 0, 1]] * 6)          # flat: no NORMAL
        t = o.positions.reshape(-1, 3, 3)
        area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        np.testing.assert_allclose(area, [0.5, 0.5])
    assert strip.material == pbr_material() and fan.material == pbr_material((1, 0, 0, 0.5), 1, 1, "BLEND")
    assert load_gltf(path).notes == (
        "sf.gltf: primitives without a material get the glTF default (white, metallic 1, roughness 1)",
        "sf.gltf: primitives skipped (not triangles): LINES, POINTS")


def test_node_names_roots_without_scenes_and_textures_note(tmp_path):
    tex = {"index": 0}
    mats = [{"name": f"t{i}", "pbrMetallicRoughness": {"baseColorTexture": tex,
                                                       "metallicRoughnessTexture": tex},
             "normalTexture": tex} for i in range(3)]
    prims = [{"attributes": {"POSITION": 0}, "indices": 2, "mode": 6, "material": 0}]
    path = _write(tmp_path / "n.gltf", prims, materials=mats,
                  nodes=[{"mesh": 0, "name": "first"}, {"children": [2]}, {"mesh": 0}])
    doc = json.loads(path.read_text())
    del doc["scenes"], doc["scene"]                   # roots: nodes nobody lists as a child
    doc["meshes"][0]["primitives"] = [dict(prims[0], material=i) for i in range(3)]
    doc["meshes"][0].pop("name")
    path.write_text(json.dumps(doc))
    imp = load_gltf(path)
    assert [o.name for o in imp.objects] == ["first/0", "first/1", "first/2",
                                             "node2/0", "node2/1", "node2/2"]
    assert imp.notes == ("n.gltf: textures dropped (not supported): t0.baseColorTexture, "
                         "t0.metallicRoughnessTexture, t0.normalTexture, t1.baseColorTexture, "
                         "t1.metallicRoughnessTexture, t1.normalTexture, t2.baseColorTexture, "
                         "t2.metallicRoughnessTexture and 1 more",)


def test_tree_check_and_id_limit(tmp_path):
    prims = [{"attributes": {"POSITION": 0}, "indices": 2, "mode": 6}]
    twice = _write(tmp_path / "t.gltf", prims, nodes=[{"mesh": 0, "children": [1]}, {"mesh": 0}],
                   roots=[0, 1])
    with pytest.raises(GltfError, match=r"^scenes\[0\]\.nodes\[1\]: node 1 is reached twice \(the node hierarchy must "
                                         r"be a tree\)$"):
        load_gltf(twice)
    many = _write(tmp_path / "m.gltf", prims * 128)
    assert load_gltf(many, first_id=128).objects[-1].id == 255
    with pytest.raises(GltfError, match=r"^meshes\[0\]\.primitives\[127\]: more than 255 mesh primitives: object ids are 8-bit"):
        load_gltf(many, first_id=129)


def test_orthographic_camera_is_ignored_with_a_note(tmp_path):
    prims = [{"attributes": {"POSITION": 0}, "indices": 2, "mode": 6}]
    path = _write(tmp_path / "o.gltf", prims, nodes=[{"mesh": 0}, {"camera": 0}], roots=[0, 1],
                  cameras=[{"type": "orthographic",
                            "orthographic": {"xmag": 1, "ymag": 1, "znear": 0, "zfar": 1}}])
    imp = load_gltf(path)
    assert imp.camera is None
    assert imp.notes[0] == "o.gltf: orthographic camera ignored (only perspective cameras)"


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["meshes"][0]["primitives"][0].update(material=99),
     "mesh 0 primitive 0 refers to material 99, which does not exist (the file has 4)"),
    (lambda d: d["meshes"][0]["primitives"][0].update(material=-1),
     "meshes[0].primitives[0].material: -1 is less than the minimum of 0"),   # the schema
    (lambda d: d["nodes"][0].update(mesh=99), "node 0 refers to mesh 99, which does not exist"),
    (lambda d: d.update(scene=5), "the file's `scene` refers to scene 5, which does not exist"),
])
def test_an_index_the_file_does_not_hold_is_the_files_error(tmp_path, edit, message):
    # an index out of range (or negative, which Python would count from the end) is a clear
    # error naming who refers to what, never an IndexError traceback
    doc = json.loads(CORNELL.read_text())
    edit(doc)
    path = tmp_path / "bad.gltf"
    path.write_text(json.dumps(doc))          # the buffer is a data URI: the file stands alone
    with pytest.raises(GltfError, match=re.escape(message)):
        load_gltf(path)
