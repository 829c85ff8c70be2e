"""The vectorised normals and normal groups (issue 13) give what the loop-based code before
them gave, on every shipped mesh: the procedural primitives, the OBJ files in
examples/models/, the OBJ meshes the scene tests write, and a Sponza-shaped generated file.

``_reference_*`` below are the functions of pipegen/scene/meshes.py at commit caa375c, verbatim but
for names: a Python loop over vertices for smoothing and a union-find loop for groups; they
normalise with ``np.linalg.norm`` (``_unit``), independent of the loader's ``row_norms``."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from pipegen.scene import meshes, obj as objfile
from pipegen.scene.obj import read_obj

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "examples" / "models"


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _reference_non_degenerate(positions):
    tri = positions.reshape(-1, 3, 3)
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    scale = np.abs(tri).max(initial=1.0)
    return area2 > 1e-12 * scale * scale


def _reference_smooth_normals(faces, fn_raw, crease_deg):
    unit = _unit(fn_raw)
    cos_crease = math.cos(math.radians(crease_deg))
    corners = faces.reshape(-1)
    out = np.repeat(unit, 3, axis=0)
    order = np.argsort(corners, kind="stable")
    bounds = np.flatnonzero(np.diff(corners[order])) + 1
    for group in np.split(order, bounds):
        tris = group // 3
        close = unit[tris] @ unit[tris].T >= cos_crease
        out[group] = _unit(close.astype(np.float64) @ fn_raw[tris])
    return out


def _reference_normal_groups(positions, normals, tol=1e-5):
    tri_count = len(positions) // 3
    if tri_count == 0:
        return np.zeros(0, dtype=np.int64)
    scale = max(float(np.abs(positions).max()), 1e-30)
    keys = np.round(positions / (scale * tol)).astype(np.int64)
    _, pid = np.unique(keys, axis=0, return_inverse=True)
    pid = pid.reshape(-1)
    corner = np.arange(3 * tri_count).reshape(-1, 3)
    a = corner.reshape(-1)
    b = corner[:, [1, 2, 0]].reshape(-1)
    swap = pid[a] > pid[b]
    lo, hi = np.where(swap, b, a), np.where(swap, a, b)
    edge_key = pid[lo] * (pid.max() + 1) + pid[hi]
    order = np.argsort(edge_key, kind="stable")
    same = edge_key[order][1:] == edge_key[order][:-1]
    e0, e1 = order[:-1][same], order[1:][same]
    starts = np.flatnonzero(np.r_[True, ~same])
    runs = np.diff(np.r_[starts, len(order)])
    extra = [(order[s + i], order[s + j]) for s, n in zip(starts[runs > 2], runs[runs > 2])
             for i in range(n) for j in range(i + 2, n)]
    if extra:
        e0 = np.concatenate([e0, [p[0] for p in extra]])
        e1 = np.concatenate([e1, [p[1] for p in extra]])

    def agree(c0, c1):
        return np.einsum("ij,ij->i", _unit(normals[c0]), _unit(normals[c1])) > 1 - tol

    smooth = agree(lo[e0], lo[e1]) & agree(hi[e0], hi[e1])
    parent = np.arange(tri_count)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for t0, t1 in zip(e0[smooth] // 3, e1[smooth] // 3):
        r0, r1 = find(int(t0)), find(int(t1))
        if r0 != r1:
            parent[max(r0, r1)] = min(r0, r1)
    roots = np.array([find(t) for t in range(tri_count)])
    _, first, inverse = np.unique(roots, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))
    return (rank[inverse] % 256).astype(np.int64)


def _reference_obj(path, crease_deg=45.0):
    """The loader before issue 13 (v, vn, f; fans; smoothing over OBJ vertex indices)."""
    verts, vnormals, tri_v, tri_n = [], [], [], []
    for line in Path(path).read_text().splitlines():
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append(tuple(float(x) for x in parts[1:4]))
        elif parts[0] == "vn":
            vnormals.append(tuple(float(x) for x in parts[1:4]))
        elif parts[0] == "f":
            corners = [c.split("/") for c in parts[1:]]

            def index(tok, count):
                i = int(tok)
                return i - 1 if i > 0 else count + i
            vi = [index(c[0], len(verts)) for c in corners]
            has_n = all(len(c) >= 3 and c[2] for c in corners)
            ni = [index(c[2], len(vnormals)) for c in corners] if has_n else None
            for k in range(1, len(vi) - 1):
                tri_v.append((vi[0], vi[k], vi[k + 1]))
                tri_n.append((ni[0], ni[k], ni[k + 1]) if ni else None)
    V = np.array(verts, dtype=np.float64)
    F = np.array(tri_v, dtype=np.int64)
    positions = V[F].reshape(-1, 3)
    fn_raw = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    normals = _reference_smooth_normals(F, fn_raw, crease_deg)
    N = np.array(vnormals, dtype=np.float64) if vnormals else np.zeros((0, 3))
    for t, ni in enumerate(tri_n):
        if ni is not None:
            normals[3 * t: 3 * t + 3] = _unit(N[list(ni)])
    keep = _reference_non_degenerate(positions)
    positions = positions.reshape(-1, 3, 3)[keep].reshape(-1, 3)
    normals = normals.reshape(-1, 3, 3)[keep].reshape(-1, 3)
    return positions, normals, _reference_normal_groups(positions, normals)


PRIMITIVE_CASES = [("box", {}), ("plane", {}), ("plane", {"divisions": 7}), ("sphere", {}),
                   ("sphere", {"segments": 7, "rings": 5}), ("sphere", {"segments": 64, "rings": 32}),
                   ("cylinder", {}), ("cylinder", {"segments": 5}), ("cylinder", {"segments": 100})]


@pytest.mark.parametrize("name,kwargs", PRIMITIVE_CASES)
def test_primitive_groups_as_before(name, kwargs):
    m = meshes.PRIMITIVES[name](**kwargs)
    np.testing.assert_array_equal(m.groups, _reference_normal_groups(m.positions, m.normals))


def _sponza_like(tmp_path):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        spec = importlib.util.spec_from_file_location("bench_load_scene",
                                                      ROOT / "benchmarks" / "load_scene.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    path = tmp_path / "sponza_like.obj"
    mod.sponza_like(path, 1)
    return path


def _obj_files(tmp_path):
    from test_scene import _CUBE_OBJ, _ridge_obj
    files = sorted(MODELS.rglob("*.obj"))
    (tmp_path / "cube.obj").write_text(_CUBE_OBJ)
    files.append(tmp_path / "cube.obj")
    for kind in ("smooth", "explicit", "shared"):
        _ridge_obj(tmp_path / f"ridge_{kind}.obj", kind)
        files.append(tmp_path / f"ridge_{kind}.obj")
    # a smooth torus without normals, and a bumpy one with sharp and smooth vertices mixed
    for bumpy in (False, True):
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 41)[:-1], np.linspace(0, 2 * np.pi, 25)[:-1],
                           indexing="ij")
        r = 1 + (0.3 * (np.sin(5 * u) > 0) if bumpy else 0)
        x, y, z = (2 + r * 0.5 * np.cos(v)) * np.cos(u), r * 0.5 * np.sin(v), (2 + r * 0.5 * np.cos(v)) * np.sin(u)
        lines = [f"v {a} {b} {c}" for a, b, c in zip(x.ravel(), y.ravel(), z.ravel())]
        idx = np.arange(40 * 24).reshape(40, 24) + 1
        for i in range(40):
            for j in range(24):
                a, b = idx[i, j], idx[(i + 1) % 40, j]
                c, d = idx[(i + 1) % 40, (j + 1) % 24], idx[i, (j + 1) % 24]
                lines.append(f"f {a} {d} {c} {b}")
        p = tmp_path / f"torus_{'bumpy' if bumpy else 'smooth'}.obj"
        p.write_text("\n".join(lines) + "\n")
        files.append(p)
    files.append(_sponza_like(tmp_path))
    return files


def test_obj_normals_and_groups_as_before(tmp_path):
    files = _obj_files(tmp_path)
    assert any(f.parent == MODELS / "cornell_box" for f in files)
    for path in files:
        pos, nrm, groups = _reference_obj(path)
        m = objfile.load_obj(path)
        np.testing.assert_array_equal(m.positions, pos, err_msg=str(path))
        np.testing.assert_allclose(m.normals, nrm, rtol=0, atol=1e-12, err_msg=str(path))
        np.testing.assert_array_equal(m.groups, groups, err_msg=str(path))
        # per material part: the same normals, and the groups of that part alone
        model = read_obj(path)
        for part in model.parts:
            np.testing.assert_array_equal(part.mesh.groups,
                                          _reference_normal_groups(part.mesh.positions,
                                                                   part.mesh.normals))


def test_smooth_normals_high_valence_and_degenerate():
    # a fan of 300 triangles around one vertex (valence 300), folded along a crease, plus a
    # zero-area triangle at the centre
    k = np.arange(300)
    a0, a1 = 2 * np.pi * k / 300, 2 * np.pi * (k + 1) / 300
    ring = lambda a: np.stack([np.cos(a), np.where(np.cos(a) > 0, np.cos(a), 0.0), np.sin(a)], 1)  # noqa: E731
    V = np.concatenate([[[0.0, 0, 0]], ring(a0)])
    F = np.stack([np.zeros(300, int), 1 + (k + 1) % 300, 1 + k], axis=1)
    F = np.concatenate([F, [[0, 0, 1]]])
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for crease in (1.0, 45.0, 179.0):
        np.testing.assert_allclose(meshes.smooth_normals(F, fn, crease),
                                   _reference_smooth_normals(F, fn, crease), atol=1e-12)


def test_connected_components_labels_are_first_nodes():
    rng = np.random.default_rng(5)
    n = 2000
    a, b = rng.integers(0, n, 1500), rng.integers(0, n, 1500)
    labels = meshes.connected_components(n, a, b)
    # reference: union-find
    parent = list(range(n))

    def find(x):
        while parent[x] != x:
            x = parent[x]
        return x
    for x, y in zip(a, b):
        rx, ry = find(int(x)), find(int(y))
        if rx != ry:
            parent[max(rx, ry)] = min(rx, ry)
    np.testing.assert_array_equal(labels, [find(i) for i in range(n)])
