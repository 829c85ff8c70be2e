"""Each class of malformed scene file (issue 29 item 3) is a PipegenError that says where:
the file and a byte offset, JSON path or line; never a traceback, a hang or an unbounded
read (``pipegen/scene/limits.py``, docs/scenes.md "Limits").  tests/test_fuzz_scenes.py
mutates the shipped files at random; these are the classes one by one."""

from __future__ import annotations

import base64
import json
import os
import re
import struct
from pathlib import Path

import numpy as np
import pytest

from pipegen.core.diagnostics import PipegenError
from pipegen.scene import limits, load_scene, meshes
from pipegen.scene.load import parse_scene

ROOT = Path(__file__).resolve().parents[1]
CORNELL = ROOT / "examples/models/cornell_box/cornell_box.gltf"
SMALL = (ROOT / "examples/scenes/small.toml").read_text()


def _gltf_error(tmp_path: Path, edit, name: str = "bad.gltf") -> str:
    """The message of loading the Cornell box glTF after ``edit`` of its JSON."""
    doc = json.loads(CORNELL.read_text())
    edit(doc)
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    with pytest.raises(PipegenError) as info:
        load_scene(path)
    assert info.value.message.startswith(f"bad glTF file: {path}: ")
    return info.value.message[len(f"bad glTF file: {path}: "):]


def _external(tmp_path: Path, uri: str):
    def edit(doc):
        doc["buffers"][0]["uri"] = uri
    return edit


# -- glTF: files a buffer uri names ------------------------------------------------------------


def test_a_buffer_uri_leaving_the_folder_is_refused(tmp_path):
    # the finding: this file loaded and rendered /etc/passwd as geometry
    message = _gltf_error(tmp_path, _external(tmp_path, "../../../../etc/passwd"))
    assert message.startswith("buffers[0].uri: '../../../../etc/passwd' leads outside the folder")
    os.symlink("/etc/passwd", tmp_path / "inside.bin")          # a link out counts as out
    assert "leads outside" in _gltf_error(tmp_path, _external(tmp_path, "inside.bin"))
    assert "leads outside" in _gltf_error(tmp_path, _external(tmp_path, "%2e%2e/x.bin"))


@pytest.mark.parametrize("uri, message", [
    ("/dev/zero", "is not a relative path"),               # read until killed for memory
    ("http://example.com/b.bin", "is not a relative path"),
    ("fifo", "cannot read 'fifo': not a regular file"),
    ("folder", "cannot read 'folder': Is a directory"),
    ("short.bin", "the buffer holds 4 bytes, fewer than its byteLength 2808"),
    ("data:application/octet-stream;base64,!!!", "cannot decode the data: URI"),
])
def test_a_buffer_uri_must_name_a_regular_file_or_data(tmp_path, uri, message):
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "folder").mkdir()
    (tmp_path / "short.bin").write_bytes(b"\0" * 4)
    got = _gltf_error(tmp_path, _external(tmp_path, uri))
    assert got.startswith("buffers[0]") and message in got


def test_a_buffer_file_is_read_only_up_to_its_byte_length(tmp_path):
    doc = json.loads(CORNELL.read_text())
    blob = base64.b64decode(doc["buffers"][0]["uri"].partition(",")[2])
    (tmp_path / "b.bin").write_bytes(blob + b"\xff" * 100_000)    # more than it says
    doc["buffers"][0]["uri"] = "b.bin"
    (tmp_path / "ext.gltf").write_text(json.dumps(doc))
    ext, shipped = load_scene(tmp_path / "ext.gltf"), load_scene(CORNELL)
    for a, b in zip(ext.objects, shipped.objects, strict=True):
        np.testing.assert_array_equal(a.positions, b.positions)


def test_sizes_past_the_limits_are_refused(tmp_path, monkeypatch):
    message = _gltf_error(tmp_path, lambda d: d["buffers"][0].update(byteLength=10 ** 12))
    assert message.startswith("buffers[0].byteLength: the buffer is 953674 MiB, more than the "
                              "limit of 256 MiB (PIPEGEN_SCENE_MAX_BYTES raises it)")
    monkeypatch.setenv("PIPEGEN_SCENE_MAX_BYTES", "1000")                # the file itself
    with pytest.raises(PipegenError, match=r"cannot read glTF file .*: \d+\.\d KiB, more than the "
                                           r"limit of 1000 bytes"):
        load_scene(CORNELL)
    monkeypatch.setenv("PIPEGEN_SCENE_MAX_BYTES", "lots")
    with pytest.raises(PipegenError, match="PIPEGEN_SCENE_MAX_BYTES='lots' is not a positive"):
        load_scene(CORNELL)


# -- glTF: accessors ---------------------------------------------------------------------------


@pytest.mark.parametrize("edit, message", [
    # count x stride past the view
    (lambda d: d["accessors"][0].update(count=91),
     r"accessors\[0\]: reads past the end of bufferView 0: 91 elements of 12 bytes at "
     r"byteOffset 0, stride 12 need 1092 bytes, it has 1080"),
    (lambda d: d["bufferViews"][0].update(byteStride=4),
     r"bufferViews\[0\]\.byteStride: byteStride 4 is less than the 12 bytes of an element"),
    (lambda d: d["bufferViews"][0].update(byteLength=10 ** 6),
     r"bufferViews\[0\]: bytes 0\.\.1000000 run past the end of buffer 0 \(2808 bytes\)"),
    # a count that would allocate without end: no bufferView means zeros
    (lambda d: (d["accessors"][0].pop("bufferView"), d["accessors"][0].update(count=10 ** 12)),
     r"accessors\[0\]\.count: count 1000000000000 is more than the limit of 4194304 "
     r"\(PIPEGEN_SCENE_MAX_ELEMENTS raises it\)"),
    (lambda d: d["accessors"][0].update(count=2.0), r"accessors\[0\]\.count: 2\.0 is not of type 'integer'"),
    (lambda d: d["accessors"][0].update(type="MAT4"), r"accessors\[0\]\.type: POSITION must be VEC3"),
])
def test_accessors_stay_inside_what_holds_them(tmp_path, edit, message):
    assert re.match(message, _gltf_error(tmp_path, edit))


def test_indices_and_sparse_accessors_out_of_range(tmp_path):
    doc = json.loads(CORNELL.read_text())
    mesh0 = doc["meshes"][0]["primitives"][0]
    indices = mesh0["indices"]
    blob = bytearray(base64.b64decode(doc["buffers"][0]["uri"].partition(",")[2]))
    view = doc["bufferViews"][doc["accessors"][indices]["bufferView"]]
    dtype = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32}[doc["accessors"][indices]["componentType"]]
    at = view.get("byteOffset", 0) + doc["accessors"][indices].get("byteOffset", 0)
    blob[at: at + np.dtype(dtype).itemsize] = np.array([200], dtype=dtype).tobytes()   # 90 vertices

    def patched(d):
        d["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
    assert re.match(rf"accessors\[{indices}\]: mesh 0 primitive 0: index 200 \(entry 0\) out of "
                    r"range \(90 vertices\)", _gltf_error(tmp_path, patched))

    def sparse(d, index_view, count=1):
        d["accessors"][0]["sparse"] = {"count": count,
                                       "indices": {"bufferView": index_view, "componentType": 5121},
                                       "values": {"bufferView": 0}}
    d_view = len(doc["bufferViews"])
    assert re.match(r"accessors\[0\]\.sparse\.indices\.bufferView: accessors\[0\]\.sparse\.indices "
                    rf"refers to bufferView {d_view}, which does not exist",
                    _gltf_error(tmp_path, lambda d: sparse(d, d_view)))
    assert re.match(r"accessors\[0\]\.sparse\.count: count 91 is more than the accessor's 90",
                    _gltf_error(tmp_path, lambda d: sparse(d, 0, 91)))
    # the first byte of view 0 (a float32 0.0's low byte... any value) read as an index < 90
    # loads; one past the count is refused with its entry
    blob2 = bytearray(blob)
    blob2[:1] = bytes([95])

    def sparse_far(d):
        patched(d)
        d["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob2)).decode()
        sparse(d, 0)
    assert re.match(r"accessors\[0\]\.sparse\.indices: index 95 \(entry 0\) is out of range: the "
                    r"accessor has 90 elements", _gltf_error(tmp_path, sparse_far))


# -- glTF: node graphs -------------------------------------------------------------------------


def test_node_cycles_and_absurd_depth(tmp_path):
    assert _gltf_error(tmp_path, lambda d: d["nodes"][1].update(children=[0])) == (
        "nodes[1].children[0]: node 0 is reached twice (the node hierarchy must be a tree)")
    assert _gltf_error(tmp_path, lambda d: d["nodes"][1].update(children=[1])) == (
        "nodes[1].children[0]: node 1 is reached twice (the node hierarchy must be a tree)")

    def chain(d):                       # 3,000 nodes, each the child of the one before
        n = len(d["nodes"])
        d["nodes"][0]["children"].append(n)
        d["nodes"] += [{"children": [n + k + 1]} for k in range(2_999)] + [{"mesh": 0}]
    doc = json.loads(CORNELL.read_text())
    chain(doc)
    (tmp_path / "deep.gltf").write_text(json.dumps(doc))
    scene = load_scene(tmp_path / "deep.gltf")            # walked with a stack: no RecursionError
    assert len(scene.objects) == 5


def test_a_glTF_with_too_many_nodes_is_refused_before_they_are_read(tmp_path):
    """100,000 nodes (pygltflib alone would take two minutes over them): refused at once."""
    import time
    t0 = time.perf_counter()
    message = _gltf_error(tmp_path, lambda d: d["nodes"].extend({} for _ in range(100_000)))
    assert message.startswith("nodes: 100") and message.endswith(
        " nodes: more than the 4096 a scene may hold")
    assert time.perf_counter() - t0 < 30            # a hang guard, not a timing


def test_a_singular_node_transform_skips_its_meshes_with_a_note(tmp_path):
    doc = json.loads(CORNELL.read_text())
    doc["nodes"][1]["scale"] = [0, 0, 0]                   # hides the white walls
    (tmp_path / "hidden.gltf").write_text(json.dumps(doc))
    with pytest.warns(Warning):
        scene = load_scene(tmp_path / "hidden.gltf")
    assert len(scene.objects) == 3
    assert any("singular or overflowing transform skipped" in n and "node 1" in n
               for n in scene.notes)


# -- glTF: the file itself ---------------------------------------------------------------------


def _glb(tmp_path: Path) -> bytes:
    import pygltflib
    g = pygltflib.GLTF2().load(str(CORNELL))
    g.convert_buffers(pygltflib.BufferFormat.BINARYBLOB)
    g.save_binary(str(tmp_path / "c.glb"))
    return (tmp_path / "c.glb").read_bytes()


def test_glb_lengths_that_lie(tmp_path):
    data = _glb(tmp_path)
    assert len(load_scene(tmp_path / "c.glb").objects) == 4
    json_len = struct.unpack_from("<I", data, 12)[0]
    cases = [(8, len(data) + 1, rf"byte 8: the header gives a length of {len(data) + 1} bytes"),
             (12, 2 ** 31, r"byte 12: the chunk's length of 2147483648 bytes runs past the end"),
             (20 + json_len, 2 ** 32 - 1, rf"byte {20 + json_len}: the chunk's length of "
                                          r"4294967295 bytes runs past"),
             (4, 1, r"byte 4: GLB version 1")]
    for at, value, message in cases:
        (tmp_path / "bad.glb").write_bytes(data[:at] + struct.pack("<I", value) + data[at + 4:])
        with pytest.raises(PipegenError, match=r"bad glTF file: .*bad\.glb: " + message):
            load_scene(tmp_path / "bad.glb")
    (tmp_path / "cut.glb").write_bytes(data[:len(data) // 2])
    with pytest.raises(PipegenError, match=r"cut\.glb: byte 8: the header gives a length"):
        load_scene(tmp_path / "cut.glb")


def test_json_nesting_numbers_and_syntax(tmp_path):
    text = CORNELL.read_text()
    deep = text[:-1] + ', "extras": ' + "[" * 5000 + "]" * 5000 + "}"
    (tmp_path / "deep.gltf").write_text(deep)
    with pytest.raises(PipegenError, match=r"deep\.gltf: line \d+, column \d+: the JSON nests "
                                           r"more than 64 levels"):
        load_scene(tmp_path / "deep.gltf")             # json.loads raised RecursionError
    assert _gltf_error(tmp_path, lambda d: d["nodes"][0].update(scale=[float("nan"), 1, 1])
                       ).endswith("invalid JSON: NaN is not a JSON value")
    huge = text.replace('"count": 90', '"count": 1' + "0" * 5000, 1)
    (tmp_path / "huge.gltf").write_text(huge)
    with pytest.raises(PipegenError, match=r"accessors\[0\]\.count: '1000.*is not of type 'integer'"):
        load_scene(tmp_path / "huge.gltf")
    (tmp_path / "syntax.gltf").write_text(text[:100])
    with pytest.raises(PipegenError, match=r"syntax\.gltf: line \d+, column \d+: invalid JSON"):
        load_scene(tmp_path / "syntax.gltf")
    (tmp_path / "fifo.gltf").unlink(missing_ok=True)
    os.mkfifo(tmp_path / "fifo.gltf")
    with pytest.raises(PipegenError, match=r"cannot read glTF file .*fifo\.gltf': not a regular"):
        load_scene(tmp_path / "fifo.gltf")


# -- OBJ / MTL ---------------------------------------------------------------------------------


def _obj_error(tmp_path: Path, obj: str | bytes, mtl: str = "") -> PipegenError:
    path = tmp_path / "m.obj"
    path.write_bytes(obj if isinstance(obj, bytes) else obj.encode())
    if mtl:
        (tmp_path / "m.mtl").write_text(mtl)
    scene = SMALL.split("[[objects]]")[0] + '[[objects]]\nobj = "m.obj"\n'
    (tmp_path / "s.toml").write_text(scene)
    with pytest.raises(PipegenError) as info:
        load_scene(tmp_path / "s.toml")
    assert info.value.span is not None and info.value.span.source_line.startswith("obj =")
    return info.value


QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


@pytest.mark.parametrize("obj, message", [
    (QUAD + "f 1 2 " + "9" * 1_000_000 + "\n", r"m\.obj:5: vertex index \d+ out of range"),
    (QUAD + "f 1/1 2//2 " + "9" * 100_000 + "/3\n",            # mixed corners: parsed one by one
     r"m\.obj:5: cannot read 'f 1/1 2//2 9{41} \.\.\.\d+ more\.\.\. 9+/3': Exceeds the limit"),
    ("v " + "9" * 100_000 + " 0 0\n" + QUAD + "f 2 3 4\n", r"m\.obj:1: vertex 1 is not finite"),
    (QUAD + "f " + " ".join(["1", "2", "3"] * 400_000) + "\n",
     r"m\.obj:5: a face of 1200000 corners: at most 1024"),
    (QUAD + "f 1 2 5\n", r"m\.obj:5: vertex index 5 out of range \(have 4\)"),
    (QUAD + "f -5 1 2\n", r"m\.obj:5: vertex index -5 out of range"),
    ("mtllib ../../../../etc/passwd\n" + QUAD + "f 1 2 3\n",
     r"m\.obj:1: mtllib '\.\./\.\./\.\./\.\./etc/passwd' leads outside the folder"),
    ("mtllib /dev/zero\n" + QUAD + "f 1 2 3\n", r"m\.obj:1: mtllib '/dev/zero' leads outside"),
    (bytes(range(256)) * 100, r"m\.obj: no faces"),
], ids=["huge index", "huge index, mixed corners", "huge coordinate", "1.2M corners",
        "index past the end", "relative index", "mtllib leaving", "mtllib device", "garbage"])
def test_obj_errors_are_located(tmp_path, obj, message):  # ids: the messages
    assert re.search(r"bad OBJ file: .*" + message, _obj_error(tmp_path, obj).message)


def test_obj_sizes_past_the_limits(tmp_path, monkeypatch):
    monkeypatch.setenv("PIPEGEN_SCENE_MAX_BYTES", "100")
    err = _obj_error(tmp_path, QUAD * 10 + "f 1 2 3\n")
    assert re.search(r"cannot read OBJ file .*m\.obj': 328 bytes, more than the limit of 100 "
                     r"bytes \(PIPEGEN_SCENE_MAX_BYTES raises it\)", err.message)
    monkeypatch.delenv("PIPEGEN_SCENE_MAX_BYTES")
    monkeypatch.setenv("PIPEGEN_SCENE_MAX_ELEMENTS", "8")
    err = _obj_error(tmp_path, QUAD * 3 + "f 1 2 3\n")
    assert re.search(r"m\.obj:9: 12 'v' records, more than the limit of 8", err.message)
    err = _obj_error(tmp_path, QUAD + "f 1 2 3 4 1 2 3 4 1 2 3 4\n")
    assert re.search(r"m\.obj: 10 triangles, more than the limit of 8", err.message)


def test_a_hostile_fan_is_refused_and_batching_changes_nothing(tmp_path, monkeypatch):
    n = 3000                            # one vertex shared by 3000 faces folded along a crease
    ring = [f"v {np.cos(2 * np.pi * k / n):.6f} {np.sin(2 * np.pi * k / n):.6f} {k % 2 * 0.5}"
            for k in range(n)]
    fan = "v 0 0 0\n" + "\n".join(ring) + "\n" + "\n".join(
        f"f 1 {k + 2} {(k + 1) % n + 2}" for k in range(n)) + "\n"
    assert re.search(r"smoothing the normals needs \d+ comparisons .* \(vertex 1 is shared by "
                     r"3000 faces, at most 2048 may meet at a crease\)",
                     _obj_error(tmp_path, fan).message)
    # many small creased vertices, in one batch and in batches of a few vertices
    rng = np.random.default_rng(3)
    faces = rng.integers(0, 400, size=(3000, 3))
    fn_raw = rng.normal(size=(3000, 3))
    whole = meshes.smooth_normals(faces, fn_raw, 45.0)
    valence = np.bincount(faces.reshape(-1)).max()               # about 40: 20 batches or so
    monkeypatch.setattr(limits, "SMOOTHING_BATCH_PAIRS", int(valence) ** 2 * 10)
    np.testing.assert_array_equal(meshes.smooth_normals(faces, fn_raw, 45.0), whole)


# -- TOML --------------------------------------------------------------------------------------


@pytest.mark.parametrize("line, message, column", [                # column: the 65th bracket
    ("ambient = " + "[" * 400 + "1" + "]" * 400, "arrays and inline tables nest more than 64", 75),
    ("width = " + "{a = " * 400 + "1" + "}" * 400, "arrays and inline tables nest more than 64", 329),
    ("width = 1" + "0" * 5000, "invalid TOML: a number too long to read", 9),
    ("width.a" + ".b" * 3000 + " = 1", "'width' must be an integer in [1, 16384], got {'a': {'b': "
                                        "{'b': {...}}}}", 1),
    ("width = 1e999", "'width' must be an integer in [1, 16384], got inf", 1),
    ("ambient = [1" + "0" * 400 + ", 0, 0]", "'ambient' must be a list of three numbers", 1),
], ids=["arrays", "inline tables", "5001 digits", "dotted keys", "1e999", "10**400"])
def test_toml_nesting_numbers_and_types_are_located(line, message, column):
    key = re.match(r"\w+", line).group()
    text = line + "\n" + SMALL.replace(key + " =", "# =", 1)
    with pytest.raises(PipegenError) as info:
        parse_scene(text, "s.toml")
    assert info.value.message.startswith(message)
    assert (info.value.span.file, info.value.span.line, info.value.span.column) == ("s.toml", 1, column)


def test_a_toml_file_past_its_size_is_refused(tmp_path):
    (tmp_path / "big.toml").write_text(SMALL + "#" * limits.MAX_TOML_BYTES)
    with pytest.raises(PipegenError, match="cannot read scene file .*larger than 1 MiB"):
        load_scene(tmp_path / "big.toml")
