"""Triangle meshes: the procedural primitives, an OBJ loader, normal groups and light volumes.

Every mesh here is a *non-indexed* triangle list (three consecutive vertices per triangle),
counter-clockwise when seen from outside, in float64.  Procedural primitives fit in the unit
cube centred at the origin (the scene's per-object transform sizes and places them):

- ``plane``:    1 x 1 in the xz plane at y = 0, facing +y;
- ``box``:      1 x 1 x 1, flat face normals;
- ``sphere``:   radius 0.5, a uv sphere with smooth normals;
- ``cylinder``: radius 0.5, height 1 along y, smooth sides and flat caps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np


@dataclass(frozen=True)
class Mesh:
    """A non-indexed triangle list: ``positions``/``normals`` (3T, 3), ``groups`` (T,)."""

    positions: np.ndarray
    normals: np.ndarray
    groups: np.ndarray

    @property
    def triangle_count(self) -> int:
        return len(self.groups)


# -- helpers ---------------------------------------------------------------------------------


def row_norms(v: np.ndarray) -> np.ndarray:
    """Length of each row (last axis) of an (..., 3) array, summed as
    ``np.linalg.norm(v, axis=-1)`` sums (x² + y²) + z² (numpy's reduction along a 3-long
    axis; the loaders' tests check the two agree bit for bit) but in three whole-column
    operations: about 15 times faster than the reduction's per-row loop."""
    if v.shape[-1] != 3:
        return np.linalg.norm(v, axis=-1)
    sq = v * v
    return np.sqrt((sq[..., 0] + sq[..., 1]) + sq[..., 2])


def normalize_rows(v: np.ndarray) -> np.ndarray:
    n = row_norms(v)[..., None]
    return v / np.where(n > 0, n, 1.0)


def take_rows(a: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``a[index]`` for an array of rows: ``np.take`` along axis 0 copies (N, 3) rows several
    times faster than fancy indexing does (numpy 2.x), with the same result."""
    return np.take(a, index, axis=0)


def face_normals(positions: np.ndarray) -> np.ndarray:
    """Unit geometric normals (T, 3) of a non-indexed triangle list (ccw = front)."""
    tri = positions.reshape(-1, 3, 3)
    return normalize_rows(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))


def _expand(vertices, normals, faces, orient: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Indexed -> non-indexed.  With ``orient``, each triangle is flipped where needed so that
    its winding agrees with its vertex normals: the generators below then only have to get the
    normals right, and ccw-from-outside follows for every primitive."""
    vertices = np.asarray(vertices, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if orient:
        p = vertices[faces]
        geo = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        flip = np.einsum("ij,ij->i", geo, normals[faces].sum(axis=1)) < 0
        faces = faces.copy()
        faces[flip] = faces[flip][:, [0, 2, 1]]
    idx = faces.reshape(-1)
    return vertices[idx], normals[idx]


def finish_mesh(positions: np.ndarray, normals: np.ndarray,
                vertex: Optional[np.ndarray] = None) -> Mesh:
    """The mesh of a triangle list without its degenerate triangles, with normal groups.
    ``vertex`` (optional, one index per corner) says which corners share a position (an
    indexed file's vertex indices): it only makes the welding of :func:`normal_groups`
    cheaper."""
    keep = _non_degenerate(positions)
    positions = positions.reshape(-1, 3, 3)[keep].reshape(-1, 3)
    normals = normals.reshape(-1, 3, 3)[keep].reshape(-1, 3)
    if vertex is not None:
        vertex = vertex.reshape(-1, 3)[keep].reshape(-1)
    return Mesh(positions, normals, normal_groups(positions, normals, vertex=vertex))


def _non_degenerate(positions: np.ndarray) -> np.ndarray:
    tri = positions.reshape(-1, 3, 3)
    area2 = row_norms(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    scale = np.abs(tri).max(initial=1.0)
    return area2 > 1e-12 * scale * scale


# -- procedural primitives ---------------------------------------------------------------------


def plane(divisions: int = 1) -> Mesh:
    """1 x 1 square in the xz plane at y = 0, facing +y, split into ``divisions``² quads."""
    n = divisions
    t = np.linspace(-0.5, 0.5, n + 1)
    x, z = np.meshgrid(t, t, indexing="ij")
    verts = np.stack([x.ravel(), np.zeros(x.size), z.ravel()], axis=1)
    normals = np.tile([0.0, 1.0, 0.0], (len(verts), 1))
    faces = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = i * (n + 1) + j, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1, i * (n + 1) + j + 1
            faces += [(a, b, c), (a, c, d)]
    return finish_mesh(*_expand(verts, normals, faces))


def box() -> Mesh:
    """Unit cube centred at the origin with one flat normal per face."""
    verts, normals, faces = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.zeros(3), np.zeros(3)
            u[(axis + 1) % 3] = 0.5
            v[(axis + 2) % 3] = 0.5
            c = n * 0.5
            base = len(verts)
            verts += [c - u - v, c + u - v, c + u + v, c - u + v]
            normals += [n] * 4
            faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return finish_mesh(*_expand(verts, normals, faces))


def sphere(segments: int = 24, rings: int = 12) -> Mesh:
    """UV sphere of radius 0.5 with smooth normals; fans (not slivers) at the poles."""
    verts, faces = [], []
    for r in range(rings + 1):
        theta = math.pi * r / rings
        for s in range(segments + 1):
            phi = 2.0 * math.pi * s / segments
            verts.append((math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi)))
    verts = np.array(verts)
    for r in range(rings):
        for s in range(segments):
            a = r * (segments + 1) + s
            b, c, d = a + segments + 1, a + segments + 2, a + 1
            if r != 0:
                faces.append((a, b, d))
            if r != rings - 1:
                faces.append((d, b, c))
    normals = normalize_rows(verts)
    return finish_mesh(*_expand(verts * 0.5, normals, faces))


def cylinder(segments: int = 24) -> Mesh:
    """Cylinder of radius 0.5 along y from -0.5 to 0.5: smooth side, flat caps."""
    verts, normals, faces = [], [], []
    ang = [2.0 * math.pi * s / segments for s in range(segments + 1)]
    ring = [(0.5 * math.cos(a), 0.5 * math.sin(a)) for a in ang]
    for (x, z), a in zip(ring, ang):  # side: two rings sharing radial normals
        radial = (math.cos(a), 0.0, math.sin(a))
        verts += [(x, -0.5, z), (x, 0.5, z)]
        normals += [radial, radial]
    for s in range(segments):
        a, b, c, d = 2 * s, 2 * s + 1, 2 * s + 3, 2 * s + 2
        faces += [(a, b, c), (a, c, d)]
    for y in (-0.5, 0.5):  # caps: a centre vertex and their own ring with the flat normal
        n = (0.0, 1.0 if y > 0 else -1.0, 0.0)
        centre = len(verts)
        verts.append((0.0, y, 0.0))
        verts += [(x, y, z) for x, z in ring[:-1]]
        normals += [n] * (segments + 1)
        for s in range(segments):
            faces.append((centre, centre + 1 + s, centre + 1 + (s + 1) % segments))
    return finish_mesh(*_expand(verts, normals, faces))


PRIMITIVES = {"plane": plane, "box": box, "sphere": sphere, "cylinder": cylinder}


# -- OBJ ---------------------------------------------------------------------------------------


class ObjError(ValueError):
    """A malformed OBJ file; ``line`` is 1-based (0 when not tied to a line)."""

    def __init__(self, message: str, line: int = 0):
        super().__init__(message)
        self.line = line


def smooth_normals(faces: np.ndarray, fn_raw: np.ndarray, crease_deg: float) -> np.ndarray:
    """Per-corner normals: at each corner, the sum of the raw (area-weighted) normals of the
    faces around the corner's vertex whose unit normal is within ``crease_deg`` of the corner's
    own face's, normalised.

    Vectorised.  At a vertex whose face normals all lie within ``crease_deg / 2`` of their
    mean, every pair is within the crease (triangle inequality on the sphere), so each corner
    gets the vertex's whole sum; only the other vertices (creases, zero-area faces) list every
    (corner, face) pair around them, a work of valence² each."""
    unit = normalize_rows(fn_raw)
    cos_crease = math.cos(math.radians(crease_deg))
    corners = faces.reshape(-1)
    n = len(corners)
    if n == 0:
        return np.zeros((0, 3))
    nv = int(corners.max()) + 1

    def per_vertex_sum(per_face):
        """Sum over each vertex's corners of their face's row (in corner order)."""
        return np.stack([np.bincount(corners, weights=np.repeat(per_face[:, k], 3), minlength=nv)
                         for k in range(3)], axis=1)

    mean = normalize_rows(per_vertex_sum(unit))
    dev = np.einsum("ij,ij->i", np.repeat(unit, 3, axis=0), take_rows(mean, corners))
    min_cos = np.full(nv, 2.0)
    np.minimum.at(min_cos, corners, dev)
    zero = np.zeros(nv, dtype=bool)
    zero[corners.reshape(-1, 3)[(unit[:, 0] == 0) & (unit[:, 1] == 0) & (unit[:, 2] == 0)]] = True
    half = math.radians(crease_deg) / 2.0 - 1e-9
    easy = (min_cos >= math.cos(half)) & ~zero & (half > 0)
    out = take_rows(normalize_rows(per_vertex_sum(fn_raw)), corners)

    hard = np.flatnonzero(~easy[corners])        # corners at vertices needing every pair
    if len(hard):
        hv = corners[hard]
        order = hard[np.argsort(hv, kind="stable")]
        sorted_v = corners[order]
        starts = np.flatnonzero(np.r_[True, sorted_v[1:] != sorted_v[:-1]])
        sizes = np.diff(np.r_[starts, len(order)])
        for a, b in _pair_batches(starts, sizes, sorted_v):
            out[order[a:b]] = _crease_sums(order[a:b], corners, unit, fn_raw, cos_crease)
    return out


def _pair_batches(starts: np.ndarray, sizes: np.ndarray, vertex: np.ndarray):
    """Slices [a, b) of the sorted hard corners, whole vertices each, of at most
    ``limits.SMOOTHING_BATCH_PAIRS`` (corner, face) pairs (about 100 bytes of memory a pair),
    after checking the work is bounded: a vertex on a crease shared by thousands of faces (a
    file's hostile fan) would need valence² pairs."""
    from pipegen.scene import limits
    pairs = sizes.astype(np.int64) ** 2
    worst = int(np.argmax(pairs))
    if pairs[worst] > limits.SMOOTHING_BATCH_PAIRS or pairs.sum() > limits.MAX_SMOOTHING_PAIRS:
        raise ObjError(f"smoothing the normals needs {int(pairs.sum())} comparisons of faces "
                       f"around creased vertices, more than the limit of "
                       f"{limits.MAX_SMOOTHING_PAIRS} (vertex {int(vertex[starts[worst]]) + 1} "
                       f"is shared by {int(sizes[worst])} faces, at most "
                       f"{math.isqrt(limits.SMOOTHING_BATCH_PAIRS)} may meet at a crease)")
    total = np.cumsum(pairs)
    ends = np.r_[starts[1:], starts[-1] + sizes[-1]]
    run = 0
    while run < len(sizes):
        done = total[run - 1] if run else 0
        last = max(run, int(np.searchsorted(total, done + limits.SMOOTHING_BATCH_PAIRS,
                                            side="right")) - 1)
        yield int(starts[run]), int(ends[last])
        run = last + 1


def _crease_sums(order: np.ndarray, corners: np.ndarray, unit: np.ndarray, fn_raw: np.ndarray,
                 cos_crease: float) -> np.ndarray:
    """Normals of hard corners ``order`` (sorted by vertex, whole vertices): each the sum of
    the raw normals of the faces around its vertex within the crease of its own, normalised;
    the pairs (corner, face) of each vertex are listed, valence² of them."""
    sorted_v = corners[order]
    m = len(order)
    starts = np.flatnonzero(np.r_[True, sorted_v[1:] != sorted_v[:-1]])
    sizes = np.diff(np.r_[starts, m])
    r_size = np.repeat(sizes, sizes)             # run size of every sorted corner
    r_start = np.repeat(starts, sizes)
    i = np.repeat(np.arange(m), r_size)          # pairs (i, j), j over i's run (i too)
    offset = np.arange(len(i)) - np.repeat(np.cumsum(r_size) - r_size, r_size)
    j = np.repeat(r_start, r_size) + offset
    unit_s, raw_s = take_rows(unit, order // 3), take_rows(fn_raw, order // 3)
    close = np.einsum("ij,ij->i", np.repeat(unit_s, r_size, axis=0),
                      take_rows(unit_s, j)) >= cos_crease
    add = take_rows(raw_s, j[close])
    acc = np.stack([np.bincount(i[close], weights=add[:, k], minlength=m) for k in range(3)],
                   axis=1)
    return normalize_rows(acc)


# -- normal groups -----------------------------------------------------------------------------


def _weld(positions: np.ndarray, tol: float, vertex: Optional[np.ndarray] = None) -> np.ndarray:
    """Position id per vertex: positions equal after rounding to ``tol`` times the largest
    coordinate share an id (ids ordered like ``np.unique(keys, axis=0)``).  With ``vertex``
    (corners of one index share a position), each distinct index is welded once: the same
    points, so the same ids, for a fraction of the sorting."""
    if vertex is not None and len(vertex):
        used = np.zeros(int(vertex.max()) + 1, dtype=bool)
        used[vertex] = True
        rank = np.cumsum(used) - 1                   # index -> its place among the used ones
        local = rank[vertex]
        some_corner = np.empty(int(rank[-1]) + 1, dtype=np.int64)
        some_corner[local] = np.arange(len(vertex))
        return _weld(take_rows(positions, some_corner), tol)[local]
    scale = max(float(np.abs(positions).max()), 1e-30)
    keys = np.round(positions / (scale * tol)).astype(np.int64)
    # per column: a reduction along axis 0 of an (N, 3) array is many times slower
    lo = np.array([keys[:, k].min() for k in range(3)])
    span = np.array([keys[:, k].max() for k in range(3)]) - lo + 1
    if float(span[0]) * float(span[1]) * float(span[2]) < 2.0 ** 62:
        flat = ((keys[:, 0] - lo[0]) * span[1] + (keys[:, 1] - lo[1])) * span[2] + (keys[:, 2] - lo[2])
        _, pid = np.unique(flat, return_inverse=True)
    else:
        _, pid = np.unique(keys, axis=0, return_inverse=True)
    return pid.reshape(-1)


def connected_components(count: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Component label per node of the undirected graph with edges ``a[k] -- b[k]``: the
    smallest node index in the component.  Vectorised hook-and-shortcut (every tree's root is
    its smallest node, so the label of a component is its first node)."""
    parent = np.arange(count)
    a, b = np.asarray(a, dtype=np.int64), np.asarray(b, dtype=np.int64)
    while len(a):
        pa, pb = parent[a], parent[b]
        differ = pa != pb
        if not differ.any():
            break
        pa, pb = pa[differ], pb[differ]
        np.minimum.at(parent, np.maximum(pa, pb), np.minimum(pa, pb))
        while True:                                  # shortcut: every node points at its root
            pp = parent[parent]
            if np.array_equal(pp, parent):
                break
            parent = pp
        a, b = a[differ], b[differ]
    return parent


def normal_groups(positions: np.ndarray, normals: np.ndarray, tol: float = 1e-5,
                  vertex: Optional[np.ndarray] = None) -> np.ndarray:
    """Group id (0..255) per triangle: connected components of the mesh's dual graph where
    two triangles are adjacent when they share an edge *and* agree on the vertex normals at
    both of its ends, so every normal discontinuity (a crease) separates groups.

    Components are numbered in order of their first triangle; past 256 the numbers wrap
    (``% 256``), which keeps the id in 8 bits at the cost of reusing ids far apart in the mesh.
    ``vertex``: as for :func:`finish_mesh` (the same groups, found faster).
    """
    tri_count = len(positions) // 3
    if tri_count == 0:
        return np.zeros(0, dtype=np.int64)
    # Weld positions so shared edges are found although the list is non-indexed.
    pid = _weld(positions, tol, vertex)

    corner = np.arange(3 * tri_count).reshape(-1, 3)
    a = corner.reshape(-1)                       # edge k of triangle t: corner k -> corner k+1
    b = corner[:, [1, 2, 0]].reshape(-1)
    swap = pid[a] > pid[b]                       # orient each edge by position id
    lo, hi = np.where(swap, b, a), np.where(swap, a, b)
    edge_key = pid[lo] * (pid.max() + 1) + pid[hi]
    order = np.argsort(edge_key)
    sorted_key = edge_key[order]
    same = sorted_key[1:] == sorted_key[:-1]
    e0, e1 = order[:-1][same], order[1:][same]   # pairs of triangle-edges on the same edge
    # A non-manifold edge (3+ triangles) needs every pair, not only neighbours in the sort.
    starts = np.flatnonzero(np.r_[True, ~same])
    runs = np.diff(np.r_[starts, len(order)])
    if np.any(runs > 2):
        x0, x1 = _edge_pairs(starts[runs > 2], runs[runs > 2])
        e0, e1 = np.concatenate([e0, order[x0]]), np.concatenate([e1, order[x1]])

    unit = normalize_rows(np.asarray(normals, dtype=np.float64))

    def agree(c0, c1):
        return np.einsum("ij,ij->i", take_rows(unit, c0), take_rows(unit, c1)) > 1 - tol

    smooth = agree(lo[e0], lo[e1]) & agree(hi[e0], hi[e1])
    roots = connected_components(tri_count, e0[smooth] // 3, e1[smooth] // 3)
    # roots are first triangles: a component's number is its root's rank among the roots
    rank = np.cumsum(roots == np.arange(tri_count)) - 1
    return (rank[roots] % 256).astype(np.int64)


def _edge_pairs(run_starts: np.ndarray, run_sizes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Within each run [s, s + n) of sorted edge-instances, the pairs (i, j), j >= i + 2, in
    the order of runs, then i, then j (consecutive pairs are already listed).  Whole arrays,
    not a Python loop: an edge a file repeats 1000 times has 500k pairs, counted first (at
    most ``limits.MAX_SMOOTHING_PAIRS``)."""
    from pipegen.scene import limits
    pairs = int((run_sizes.astype(np.int64) ** 2).sum())
    if pairs > limits.MAX_SMOOTHING_PAIRS:
        raise ObjError(f"edges shared by many triangles (up to {int(run_sizes.max())}) need "
                       f"{pairs} comparisons of their normals, more than the limit of "
                       f"{limits.MAX_SMOOTHING_PAIRS}")
    first = np.cumsum(run_sizes) - run_sizes
    members = np.repeat(run_starts, run_sizes) + np.arange(int(run_sizes.sum())) - np.repeat(first, run_sizes)
    size = np.repeat(run_sizes, run_sizes)               # run size of every member
    i = np.repeat(members, size)
    offset = np.arange(len(i)) - np.repeat(np.cumsum(size) - size, size)
    j = np.repeat(np.repeat(run_starts, run_sizes), size) + offset
    keep = j >= i + 2
    return i[keep], j[keep]


# -- light volumes -----------------------------------------------------------------------------


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere (vertices on the unit sphere): (vertices, faces), faces ccw outside."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, dtype=np.float64) / np.linalg.norm(p) for p in v]
    faces = list(f)
    for _ in range(subdivisions):
        midpoint: dict[tuple[int, int], int] = {}

        def mid(i: int, j: int) -> int:
            key = (min(i, j), max(i, j))
            if key not in midpoint:
                m = verts[i] + verts[j]
                verts.append(m / np.linalg.norm(m))
                midpoint[key] = len(verts) - 1
            return midpoint[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(verts), np.array(faces, dtype=np.int64)


SPHERE_SUBDIVISIONS = 2
CONE_SEGMENTS = 16


def light_volume(volume: str) -> np.ndarray:
    """Unit light volume as a non-indexed float32 triangle list (V, 3), ccw seen from outside.

    - ``"sphere"``: an icosphere (subdivision 2, 320 faces) scaled by 1/inradius, so that every
      face lies *outside* the unit sphere: the mesh circumscribes it, and scaled by a light's
      radius it covers the light's whole sphere of influence.  Its vertices lie at distance
      ``1/inradius`` (about 1.02) from the centre.
    - ``"cone"``: a spot-light cone in its local frame: apex at the origin, axis along -z,
      length 1 (a flat base at z = -1), circumscribing the circular cone of half-angle 45°
      (base circle of radius 1).  The vertex stage scales x and y by ``tan(outer) * radius``
      and z by ``radius``, then rotates -z onto the light direction: the result contains the
      spot's region of influence (the sphere of radius ``radius`` intersected with the cone of
      half-angle ``outer``, for ``outer`` < 90°).
    - ``"quad"``: two triangles covering [-1, 1]² at z = 0, ccw seen from +z (screen quads are
      placed in clip space by the vertex stage).
    """
    if volume == "sphere":
        verts, faces = icosphere(SPHERE_SUBDIVISIONS)
        p = verts[faces]
        plane_dist = np.einsum("ij,ij->i", face_normals(p.reshape(-1, 3)), p[:, 0])
        # The 1e-6 margin keeps the faces outside after rounding to float32.
        positions = (verts * ((1.0 + 1e-6) / plane_dist.min()))[faces].reshape(-1, 3)
    elif volume == "cone":
        n = CONE_SEGMENTS
        r = 1.0 / math.cos(math.pi / n)  # polygon circumscribing the unit circle
        rim = [np.array([r * math.cos(2 * math.pi * k / n), r * math.sin(2 * math.pi * k / n), -1.0])
               for k in range(n)]
        apex, centre = np.zeros(3), np.array([0.0, 0.0, -1.0])
        tris = []
        for k in range(n):
            a, b = rim[k], rim[(k + 1) % n]
            tris += [apex, a, b]       # side (ccw seen from outside)
            tris += [centre, b, a]     # base, facing -z
        positions = np.array(tris)
    elif volume == "quad":
        positions = np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, -1, 0), (1, 1, 0), (-1, 1, 0)],
                             dtype=np.float64)
    else:
        raise ValueError(f"unknown light volume '{volume}' (sphere, cone, quad)")
    return positions.astype(np.float32)
