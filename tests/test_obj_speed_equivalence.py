"""The fast OBJ reader (issue 26 item 5) reads what the slow, line-by-line one reads.

- ``decimals.parse_floats`` gives ``np.fromstring``'s float64 bit for bit, or ``None``;
- ``read_obj`` on files that take every path of the scanner (runs of records broken by
  other statements, comments, blank lines, CRLF, tabs, leading spaces, ``vt``, ``v//vn`` and
  ``v/vt/vn`` corners, negative indices, polygons, exponents that take the fallback parser)
  gives the positions, normals and normal groups of ``_reference_obj`` (the loader before
  issue 13, in tests/test_loaders_reference.py, normalising with ``np.linalg.norm``);
- welding per OBJ vertex index finds the groups welding every corner finds;
- ``row_norms`` is ``np.linalg.norm`` bit for bit;
- and the values themselves on a crease and a smooth surface: a box's corners carry its
  face normals, a smooth ring's the radial direction.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipegen.scene import decimals, meshes
from pipegen.scene.meshes import ObjError
from pipegen.scene.obj import read_obj
from test_loaders_reference import _reference_normal_groups, _reference_obj


def _random_decimals(rng, count: int) -> list[str]:
    out = []
    for _ in range(count):
        digits = "".join(map(str, rng.integers(0, 10, rng.integers(1, 16))))
        point = rng.integers(0, len(digits) + 1)        # also "5." and ".5"
        text = digits[:point] + ("." if rng.random() < 0.8 else "") + digits[point:]
        out.append(rng.choice(["", "-", "+"], p=[0.5, 0.4, 0.1]) + text)
    return out


def test_parse_floats_is_strtod_bit_for_bit():
    rng = np.random.default_rng(26)
    tokens = _random_decimals(rng, 50_000) + ["-0.000", "-0", "+0", "007.50", "123456789012345",
                                              "0.00000000000001", "999999999999999", "-.5", "5."]
    text = (" ".join(tokens[:100]) + "\n  " + "\n".join(tokens[100:]) + " \n").encode()
    got = decimals.parse_floats(text)
    want = np.fromstring(text, dtype=np.float64, sep=" ")
    assert got is not None and len(got) == len(tokens)
    np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))   # -0.0 too
    assert np.signbit(got[len(tokens) - 9: len(tokens) - 6]).tolist() == [True, True, False]


@pytest.mark.parametrize("text", [b"1e5", b"1.5E-3", b"nan", b"inf", b"1.2.3", b"1..2", b"+-1",
                                  b"1-2", b"-", b".", b"1234567890123456",
                                  b"0.000000000000001", b"1,5", b"0x10"])
def test_parse_floats_leaves_other_tokens_to_strtod(text):
    assert decimals.parse_floats(b"1.25 " + text + b" 2") is None


@pytest.mark.parametrize("shape", [(200_000, 3), (3,), (1, 3), (500, 4, 3), (100, 4)])
def test_row_norms_are_linalg_norm_bit_for_bit(shape):
    rng = np.random.default_rng(5)
    v = rng.standard_normal(shape) * np.exp(rng.uniform(-30, 30, shape[:-1] + (1,)))
    v.reshape(-1, shape[-1])[:10] = 0.0
    np.testing.assert_array_equal(meshes.row_norms(v), np.linalg.norm(v, axis=-1))
    unit = meshes.normalize_rows(v)
    assert unit.shape == v.shape
    np.testing.assert_allclose(np.linalg.norm(unit.reshape(-1, shape[-1])[10:], axis=-1), 1.0,
                               rtol=0, atol=4e-16)


def _ring_and_box(crlf: bool = False, exponents: bool = False) -> str:
    """A smooth ring (a 24-sided tube, no normals) and a box with its own normals, in one
    file written the untidy ways real files are; with ``exponents`` the box's coordinates
    are written as ``2e0`` (so every ``v`` record takes the ``strtod`` fallback)."""
    lines = ["# test model", "mtllib none.mtl", "o ring", "\tv 0 0 0  # unused vertex"]
    ring, segments = [], 24
    for k in range(segments):
        a = 2 * math.pi * k / segments
        for y in (0.0, 1.0):
            ring.append(f"v {math.cos(a):.6f} {y:.1f} {math.sin(a):.6f}")
    lines += ring[:20] + ["vt 0.5 0.5", "", "  " + ring[20]] + ring[21:]
    lines += ["usemtl ring", "s 1"]
    for k in range(segments):
        a, b = 2 + 2 * k, 2 + 2 * ((k + 1) % segments)   # 1-based: vertex 1 is the unused one
        quad, pair = f"f {a} {a + 1} {b + 1} {b}", f"f {a} {a + 1} {b + 1}\nf {a} {b + 1} {b}"
        lines.append(quad if k % 2 else pair)
    lines += ["o box", "usemtl box"]
    box = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1),
           (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
    lines += [f"v {3 + x}{'e0' if exponents else '.0'} {y} {z}" for x, y, z in box]
    lines += ["vn 0 0 -1", "vn 0 0 1", "vn 0 -1 0", "vn 0 1 0", "vn -1 0 0", "vn 1 0 0"]
    quads = [((1, 4, 3, 2), 1), ((5, 6, 7, 8), 2), ((1, 2, 6, 5), 3), ((4, 8, 7, 3), 4),
             ((1, 5, 8, 4), 5), ((2, 3, 7, 6), 6)]
    for k, (quad, n) in enumerate(quads):       # negative indices, v//vn and v/vt/vn mixed
        if k < 3:
            lines.append("f " + " ".join(f"{i - 9}//{n - 7}" for i in quad))
        else:
            lines.append("f " + " ".join(f"{i - 9}/1/{n - 7}" for i in quad))
    # a pentagon fan on the box's top, smoothed (no normals)
    lines.append("f -4 -3 -2 -1 -4")
    text = "\n".join(lines) + "\n"
    return text.replace("\n", "\r\n") if crlf else text


@pytest.mark.parametrize("crlf,exponents", [(False, False), (True, False), (False, True)])
def test_read_obj_matches_the_line_by_line_loader(tmp_path, crlf, exponents):
    path = tmp_path / "ring_box.obj"
    path.write_bytes(_ring_and_box(crlf, exponents).encode())
    model = read_obj(path)
    pos, nrm, groups = _reference_obj(path)
    mesh = model.mesh
    np.testing.assert_array_equal(mesh.positions, pos)
    np.testing.assert_allclose(mesh.normals, nrm, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(mesh.groups, groups)
    assert [p.material.name for p in model.parts] == ["ring", "box"]
    for part in model.parts:
        np.testing.assert_array_equal(
            part.mesh.groups, _reference_normal_groups(part.mesh.positions, part.mesh.normals))
    assert any("'vt' x1" in n and "'s' x1" in n and "'o' x2" in n for n in model.notes)


def test_values_on_a_crease_and_a_smooth_surface(tmp_path):
    path = tmp_path / "ring_box.obj"
    path.write_text(_ring_and_box())
    ring, box = read_obj(path).parts
    # 24 segments: 12 written as two triangles, 12 as quads
    assert ring.mesh.triangle_count == 48 and box.mesh.triangle_count == 12 + 2
    # the smooth tube: each vertex joins the faces of its two segments (15° apart), one
    # triangle of one and two of the other (equal areas): the area-weighted mean lies
    # atan(sin 15° / (2 + cos 15°)) from the heavier face normal, 2.51° from the radial
    p, n = ring.mesh.positions, ring.mesh.normals
    radial = p * [1, 0, 1]
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    s15 = math.radians(15)
    off = math.radians(7.5) - math.atan2(math.sin(s15), 2 + math.cos(s15))
    np.testing.assert_allclose(np.einsum("ij,ij->i", n, radial), math.cos(off), rtol=0, atol=1e-6)
    assert n[:, 1].tolist() == [0.0] * len(n)
    assert len(set(ring.mesh.groups.tolist())) == 1
    # the box: the given normals, one group per face; the pentagon fan on the z = 1 face
    # (its last triangle degenerate, dropped) is smoothed within 45°: the face's normal
    expect = np.repeat([[0, 0, -1], [0, 0, -1], [0, 0, 1], [0, 0, 1], [0, -1, 0], [0, -1, 0],
                        [0, 1, 0], [0, 1, 0], [-1, 0, 0], [-1, 0, 0], [1, 0, 0], [1, 0, 0],
                        [0, 0, 1], [0, 0, 1]], 3, axis=0)
    np.testing.assert_array_equal(box.mesh.normals, expect)
    assert box.dropped == 1
    groups = box.mesh.groups.tolist()
    assert len(set(groups)) == 6 and groups[12] == groups[13] == groups[2] != groups[0]


def test_welding_per_vertex_index_finds_the_same_groups():
    # a folded grid (a crease along x = 0) whose vertices are written twice under two
    # indices (and a third time 1e-9 away): welding by index must still join them
    rng = np.random.default_rng(3)
    xs, zs = np.linspace(-1, 1, 7), np.linspace(0, 1, 4)
    grid = np.array([[x, abs(x), z] for x in xs for z in zs])
    V = np.concatenate([grid, grid, grid + 1e-9])
    quads = [(i * 4 + j, i * 4 + j + 1, (i + 1) * 4 + j + 1, (i + 1) * 4 + j)
             for i in range(6) for j in range(3)]
    F = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    F = F + len(grid) * rng.integers(0, 3, F.shape)      # each corner picks one copy
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    normals = np.repeat(meshes.normalize_rows(fn), 3, axis=0)
    positions = V[F].reshape(-1, 3)
    by_index = meshes.normal_groups(positions, normals, vertex=F.reshape(-1))
    np.testing.assert_array_equal(by_index, meshes.normal_groups(positions, normals))
    np.testing.assert_array_equal(by_index, _reference_normal_groups(positions, normals))
    assert len(set(by_index.tolist())) == 2


def test_errors_keep_their_lines(tmp_path):
    path = tmp_path / "e.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf\nf 1 2 3\n")
    with pytest.raises(ObjError, match="at least three vertices") as e:
        read_obj(path)
    assert e.value.line == 5
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 99999999999999999999\n")
    with pytest.raises(ObjError, match="vertex index .* out of range") as e:
        read_obj(path)
    assert e.value.line == 5
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nv 1 1x 0\nf 1 2 3\n")
    with pytest.raises(ObjError, match="a 'v' record needs three coordinates") as e:
        read_obj(path)
    assert e.value.line == 5
