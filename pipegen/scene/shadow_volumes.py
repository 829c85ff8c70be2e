"""Stencil shadow volumes, built on the host: the triangles ``draw scene… shadow_volumes`` draws
for one light (Trebilco, "Shadows": "Once the shadow volume has marked the stencil buffer to
indicate where the shadowed areas are, the light volumes can be rendered to ignore these
areas").  Both runtimes upload ``shadow_volume(scene, light).positions`` as they are, so GL
and OpenCL draw the same float32 triangles.

Per object of the draw's material filter that may hide something the light reaches (a point
or spot light: its bounding box meets the light's radius, ``may_shadow``), from its
world-space positions welded (corners within ``WELD_TOLERANCE`` of the object's size are one
vertex), the volume is a closed, outward-facing triangle surface around the region the object
hides from the light:

- a **closed** object (every edge a -> b matched by an edge b -> a; the shipped box, sphere and
  cylinder meshes are): near cap = its triangles facing the light, far cap = the others
  extruded away from the light, sides = one quad per silhouette edge (between a light-facing
  and a back-facing triangle), extruded.  The region is the object's shadow.  With the light
  inside a closed object no face is light-facing and the far cap alone (every face extruded)
  encloses the light: all that lies outside the object is shadowed, as it should be, but its
  inside reads shadowed too, where exact visibility says lit (seen only from inside);
- an **open** object (the ``plane`` mesh, or any mesh with an edge of one triangle): both sides
  of every triangle occlude, so each triangle, turned to face the light, casts its own prism
  (near cap it, far cap it extruded and reversed, three sides); sides shared by two such
  prisms cancel and only the net edges are drawn: an edge of one triangle is a silhouette
  always, an edge between a light-facing and a back-facing triangle carries two sides.
  Triangles edge-on to the light (facing neither way) hide nothing and cast nothing.

Near caps: a near cap triangle is one of its object's lit faces, which the camera sees; for
its pixels to count it as behind the surface, the volumes' near vertices (near caps and the
sides' near edges) are moved ``NEAR_CAP_SHIFT`` of the scene's diagonal away from the light
along the light's rays: then the cap lies just behind the lit face (and, for an open object,
behind its own lit triangle), whatever the depth precision or the clipping of the depth
pre-pass, which a depth offset would have to cover and which would also move every place
where a side crosses a receiver.  The shadows move by that distance, far below a pixel when
the scene is in view; a small object seen from very close in a large scene would show a gap of
it at its contact shadow.  (Measured: 1e-4 of each object's own diagonal instead leaves a
near cap in front of its face at 1 pixel of overlapping_spot_shadows at 320x180, 9 codes, and
twice the shadow-edge pixels over 2 codes; the scene's diagonal, none.)

Counting: the pass draws every triangle with depth clamping (no near or far clipping) and,
where the depth test fails, back faces increment and front faces decrement the stencil (depth
fail, "Carmack's reverse"): each pixel ends with the number of volumes around its surface
point, correct with the camera inside a volume since the caps close every volume.  Zero: lit.

Extrusion: a point or spot light's vertex ``v`` moves to ``L + (v - L) / |v - L| * D``; ``D``
is chosen per light so that the far cap and the sides' far edges stay beyond the light's
radius (nothing farther is lit; ``extrusion_distance``).  A directional light's vertex moves
``D`` along the light's direction, ``D`` twice the diagonal of the scene's bounding box (every
receiver lies within it).  Points beyond ``D`` are never in a volume.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

WELD_TOLERANCE = 1e-6    # corners closer than this times the object's largest coordinate: one
EXTRUSION_MARGIN = 1.01  # the far cap's nearest point lies this factor beyond the light radius
MIN_COSINE = 1e-3        # a caster spanning more than ~179.9 degrees seen from the light: D is
#                          capped at radius / MIN_COSINE (its far cap may then cut the radius)
NEAR_CAP_SHIFT = 1e-4    # near caps and sides start this fraction of the scene's diagonal
#                          farther from the light than the object's surface (``shadow_volume``)


@dataclass(frozen=True)
class ShadowVolume:
    """The triangles of one light's shadow volumes (``positions``: (3T, 3) float32, counter-
    clockwise seen from outside the volume) and what they are made of, in that order: near-cap,
    far-cap and side triangles (two per side quad)."""

    positions: np.ndarray
    near: int
    far: int
    sides: int

    @property
    def triangle_count(self) -> int:
        return self.near + self.far + self.sides


def weld(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(vertex id per corner (V,), one position per id (N, 3) float64): corners equal after
    rounding to ``WELD_TOLERANCE`` of the largest coordinate share an id, and its position
    (that of the first such corner), so that shared edges have bit-identical ends."""
    p = np.asarray(positions, np.float64)
    if not len(p):
        return np.zeros(0, np.int64), np.zeros((0, 3))
    scale = max(float(np.abs(p).max()), 1e-30) * WELD_TOLERANCE
    keys = np.round(p / scale).astype(np.int64)
    _, first, ids = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    return ids.reshape(-1), p[first]


def net_edges(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The edges of triangles ``tris`` (T, 3) vertex ids that do not cancel: (directed edges
    (E, 2), multiplicity (E,)).  Each triangle contributes a -> b, b -> c, c -> a; an edge
    a -> b cancels a b -> a.  Empty for a closed, consistently oriented surface."""
    if not len(tris):
        return np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    lo, hi = e.min(axis=1), e.max(axis=1)
    sign = np.where(e[:, 0] == lo, 1, -1)
    keys, inverse = np.unique(np.stack([lo, hi], axis=1), axis=0, return_inverse=True)
    net = np.zeros(len(keys), np.int64)
    np.add.at(net, inverse.reshape(-1), sign)
    keep = net != 0
    keys, net = keys[keep], net[keep]
    directed = np.where((net > 0)[:, None], keys, keys[:, ::-1])
    return directed, np.abs(net)


def facing(verts: np.ndarray, light) -> np.ndarray:
    """(T,) float64: the triangles' (T, 3, 3) counter-clockwise normal dotted with the direction
    to the light (from the first corner; a directional light: against its direction).
    Positive: facing the light."""
    n = np.cross(verts[:, 1] - verts[:, 0], verts[:, 2] - verts[:, 0])
    if light.type == "directional":
        to_light = -np.asarray(light.direction, np.float64)[None]
    else:
        to_light = np.asarray(light.position, np.float64)[None] - verts[:, 0]
    return np.einsum("tk,tk->t", n, to_light)


_WELDED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def welded_mesh(obj) -> tuple[np.ndarray, np.ndarray, bool]:
    """An object's (welded positions (N, 3), its non-degenerate triangles (T, 3) as vertex
    ids, whether they are closed): what does not depend on the light, kept per object (the
    runtimes ask for every light's volumes; welding was most of the time)."""
    got = _WELDED.get(obj)
    if got is None:
        ids, points = weld(obj.positions)
        tris = ids.reshape(-1, 3)
        tris = tris[(tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2])
                    & (tris[:, 2] != tris[:, 0])]
        got = _WELDED[obj] = (points, tris, len(net_edges(tris)[0]) == 0)
    return got


def casters(obj, light) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One object's welded positions (N, 3), near-cap triangles (T, 3) (vertex ids, facing the
    light) and far-cap triangles (F, 3) (to be extruded as they are): a closed object's
    back-facing triangles, an open object's near caps reversed (the module docstring)."""
    points, tris, closed = welded_mesh(obj)
    f = facing(points[tris], light)
    if closed:
        return points, tris[f > 0], tris[f <= 0]
    near = np.concatenate([tris[f > 0], tris[f < 0][:, ::-1]])     # turned to face the light
    return points, near, near[:, ::-1]


def _directions(points: np.ndarray, light) -> np.ndarray:
    """Unit directions (N, 3) along which each point is extruded."""
    if light.type == "directional":
        d = np.asarray(light.direction, np.float64)
        return np.broadcast_to(d / np.linalg.norm(d), points.shape)
    v = points - np.asarray(light.position, np.float64)
    n = np.linalg.norm(v, axis=1)
    return v / np.where(n > 0, n, 1.0)[:, None]


def extruded(points: np.ndarray, light, distance: float) -> np.ndarray:
    """``points`` (N, 3) extruded: a point or spot light's to ``distance`` from the light along
    the ray through each, a directional light's ``distance`` along its direction."""
    u = _directions(points, light)
    if light.type == "directional":
        return points + u * distance
    return np.asarray(light.position, np.float64)[None] + u * distance


def scene_diagonal(scene) -> float:
    """The length of the diagonal of the bounding box of every object of ``scene``."""
    lo = np.min([o.positions.min(axis=0) for o in scene.objects], axis=0)
    hi = np.max([o.positions.max(axis=0) for o in scene.objects], axis=0)
    return float(np.linalg.norm(hi - lo))


def extrusion_distance(scene, light, pieces: list) -> float:
    """How far a light's volumes extrude (see the module docstring).  Point or spot: over
    every far-cap triangle and side far edge (``pieces``: (positions, far (F, 3), sides (S, 2))
    per object), with ``u`` its corners' unit directions from the light and ``c`` their mean
    direction, a far point is at least ``D * min(u . c)`` from the light; ``D = radius *
    EXTRUSION_MARGIN / min(u . c)`` (at least ``EXTRUSION_MARGIN`` times the farthest caster
    corner, so every corner moves outwards).  Directional: twice the scene's diagonal."""
    if light.type == "directional":
        return 2.0 * scene_diagonal(scene) + 1.0
    cos_min, far_corner = 1.0, 0.0
    L = np.asarray(light.position, np.float64)
    for points, far, sides in pieces:
        u = _directions(points, light)
        far_corner = max(far_corner, float(np.linalg.norm(points - L, axis=1).max(initial=0.0)))
        for group in (far, sides):
            if not len(group):
                continue
            g = u[group]                                         # (K, corners, 3)
            c = g.sum(axis=1)
            c /= np.maximum(np.linalg.norm(c, axis=1), 1e-300)[:, None]
            cos_min = min(cos_min, float(np.einsum("kjd,kd->kj", g, c).min()))
    cos_min = max(cos_min, MIN_COSINE)
    return max(float(light.radius) * EXTRUSION_MARGIN / cos_min,
               far_corner * EXTRUSION_MARGIN)


def may_shadow(obj, light) -> bool:
    """Whether ``obj`` can hide a point the light reaches from it: a point or spot light
    reaches points within its radius, and the segment from such a point to the light stays in
    that ball, so an object whose bounding box lies wholly outside it hides nothing (exact: no
    volume is left out that could count).  Directional lights: every object."""
    if light.type == "directional":
        return True
    lo, hi = obj.positions.min(axis=0), obj.positions.max(axis=0)
    L = np.asarray(light.position, np.float64)
    gap = np.maximum(np.maximum(lo - L, L - hi), 0.0)
    return float(np.sqrt((gap * gap).sum())) < float(light.radius)


def shadow_volume(scene, light, material: tuple[str, ...] = ("opaque",)) -> ShadowVolume:
    """The shadow volumes of ``scene``'s objects of ``material`` for ``light`` (a scene light
    of any type), float32 positions; no triangles for a light that casts no shadows."""
    empty = ShadowVolume(np.zeros((0, 3), np.float32), 0, 0, 0)
    if not getattr(light, "shadows", False):
        return empty
    pieces, caps = [], []
    for obj in scene.select(tuple(material)):
        if not may_shadow(obj, light):
            continue
        points, near, far = casters(obj, light)
        sides, count = net_edges(near)
        sides = np.repeat(sides, count, axis=0)
        pieces.append((points, far, sides))
        caps.append(near)
    if not pieces:
        return empty
    D = extrusion_distance(scene, light, pieces)
    shift = NEAR_CAP_SHIFT * scene_diagonal(scene)
    near_out, far_out, side_out = [], [], []
    for (points, far, sides), near in zip(pieces, caps):
        out = extruded(points, light, D)
        start = points + _directions(points, light) * shift      # just behind the lit faces
        near_out.append(start[near])
        far_out.append(out[far])
        a, b = sides[:, 0], sides[:, 1]
        # the quad a, b, b', a' seen from outside: (a, a', b') and (a, b', b)
        quads = np.stack([start[a], out[a], out[b], start[a], out[b], start[b]], axis=1)
        side_out.append(quads.reshape(-1, 3, 3))
    near_t = np.concatenate(near_out).reshape(-1, 3, 3)
    far_t = np.concatenate(far_out).reshape(-1, 3, 3)
    side_t = np.concatenate(side_out).reshape(-1, 3, 3)
    tris = np.concatenate([near_t, far_t, side_t]).reshape(-1, 3)
    return ShadowVolume(np.ascontiguousarray(tris, np.float32), len(near_t), len(far_t),
                        len(side_t))
