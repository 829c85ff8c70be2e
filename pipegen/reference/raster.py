"""A float64 numpy rasteriser that produces the reference G-buffer of a scene.

It follows the GL rules the two backends follow, so its coverage agrees with theirs away from
primitive edges:

- clip space ``P @ V @ p``; triangles are clipped against the near and far planes (z = ±w) and a
  guard band (|x|, |y| <= 4w) in homogeneous space, so every vertex has w > 0 and window
  coordinates stay small enough for exact edge functions;
- window coordinates are snapped to 8 sub-pixel bits (1/256 pixel), which makes the edge
  functions exact in float64 (every product is an integer below 2^53);
- pixel centres at +0.5; a centre exactly on an edge is covered only by a *top* or *left* edge
  (top-left fill rule, in image space: row 0 is the top row, y grows downwards), so two
  triangles sharing an edge cover each pixel on it exactly once;
- counter-clockwise front faces (in GL window space, y up); optional back/front culling;
- depth = z_ndc / 2 + 1/2 interpolated linearly in screen space; depth test ``less`` against a
  buffer cleared to 1.0, primitive order breaking ties (the earlier triangle wins);
- attributes interpolated perspective-correctly.

Arrays are indexed ``[row, column]`` with row 0 at the *top* of the image (as in a PNG); GL
window row ``y`` is ``height - 1 - row``.

Vectorisation: triangles are bucketed by the power-of-two size of their screen bounding box, and
each bucket is evaluated as one (n, h, w) block; the surviving fragments of all triangles are
then resolved per pixel with one lexicographic sort on (pixel, depth, triangle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SUBPIXEL = 256.0       # 8 sub-pixel bits
GUARD_BAND = 4.0       # clip |x|, |y| to GUARD_BAND * w
CHUNK_CELLS = 1 << 22  # bounding-box cells evaluated at once


@dataclass
class GBuffer:
    """Per-pixel surface data of the nearest fragment, (H, W[, C]) arrays, row 0 on top.

    Uncovered (sky) pixels: coverage False, depth 1.0, ids and triangle -1, the rest zero.
    """

    width: int
    height: int
    coverage: np.ndarray      # bool
    position: np.ndarray      # float64 (H, W, 3) world space, perspective-correct
    normal: np.ndarray        # float64 (H, W, 3) interpolated, *not* renormalised
    albedo: np.ndarray        # float64 (H, W, 3)
    specular: np.ndarray      # float64
    shininess: np.ndarray     # float64
    alpha: np.ndarray         # float64
    object_id: np.ndarray     # int64, -1 on sky
    normal_group: np.ndarray  # int64, -1 on sky
    depth: np.ndarray         # float64 window depth in [0, 1]
    triangle: np.ndarray      # int64 index into the drawn triangle list, -1 on sky
    edge: np.ndarray          # bool: the 3x3 neighbourhood sees another triangle or the sky

    @property
    def silhouette(self) -> np.ndarray:
        """Pixels whose 3x3 neighbourhood sees another object, another normal group (a crease)
        or the sky: where a one-pixel coverage difference changes the shaded value.  Edges
        between triangles of one smooth surface are not included: the interpolated
        attributes are continuous across them."""
        surface = np.where(self.object_id < 0, -1, self.object_id * 256 + self.normal_group)
        return edge_mask(surface)


def rasterize(scene, material: tuple[str, ...] = (), cull: str = "back") -> GBuffer:
    """Rasterise the scene's geometry (filtered by ``material``) into a reference G-buffer.

    The inputs are the float32 vertex data every backend receives (``Scene.geometry``), widened
    to float64, so the reference sees exactly the same scene.
    """
    return rasterize_geometry(scene, scene.geometry(tuple(material)), cull)


def rasterize_geometry(scene, geo, cull: str = "back") -> GBuffer:
    """Rasterise a ``Geometry`` (float32 vertex data, widened to float64) with the scene's
    camera and output size."""
    mvp = scene.camera.projection(scene.aspect) @ scene.camera.view_matrix()
    tri_attr = np.concatenate([geo.albedo, geo.material, geo.ids], axis=1).astype(np.float64)[::3]
    frags = rasterize_triangles(
        geo.positions.astype(np.float64).reshape(-1, 3, 3),
        geo.normals.astype(np.float64).reshape(-1, 3, 3),
        mvp, scene.width, scene.height, cull)
    return _gbuffer(frags, tri_attr, scene.width, scene.height)


def rasterize_each(scene, material: tuple[str, ...] = ("translucent",),
                   cull: str = "back") -> list[tuple[object, GBuffer]]:
    """Rasterise every object passing ``material`` *on its own*: ``[(SceneObject, GBuffer)]``
    in scene order, each G-buffer holding that object's nearest (unculled) surface only.
    This gives the per-pixel lists of fragments that a single depth-tested G-buffer hides,
    e.g. the stacked translucent layers.  The vertex data is the same float32
    ``Scene.geometry`` the backends draw (object ids are unique, so the slices are exact)."""
    geo = scene.geometry(tuple(material))
    out = []
    for obj in scene.select(tuple(material)):
        keep = geo.ids[:, 0] == obj.id
        part = type(geo)(geo.positions[keep], geo.normals[keep], geo.albedo[keep],
                         geo.material[keep], geo.ids[keep], geo.layer[keep])
        out.append((obj, rasterize_geometry(scene, part, cull)))
    return out


# -- triangles to fragments ----------------------------------------------------------------------


@dataclass
class Fragments:
    """The winning fragment per covered pixel (flat arrays, one entry per covered pixel)."""

    pixel: np.ndarray      # row * width + column
    triangle: np.ndarray   # index of the input triangle
    depth: np.ndarray
    position: np.ndarray   # (n, 3) interpolated attribute 0
    normal: np.ndarray     # (n, 3) interpolated attribute 1


def rasterize_triangles(positions: np.ndarray, normals: np.ndarray, mvp: np.ndarray,
                        width: int, height: int, cull: str = "back") -> Fragments:
    """positions, normals: (T, 3, 3) world space.  Returns the depth-test winners."""
    assert cull in ("back", "front", "none"), cull
    T = len(positions)
    clip = np.concatenate([positions, np.ones((T, 3, 1))], axis=2) @ mvp.T   # (T, 3, 4)
    attrs = np.concatenate([positions, normals], axis=2)                     # (T, 3, 6)
    clip, attrs, source = _clip(clip, attrs, np.arange(T))

    # Window coordinates in image space (y down), snapped to the sub-pixel grid.
    w = clip[..., 3]
    ndc = clip[..., :3] / w[..., None]
    sx = np.round((ndc[..., 0] + 1.0) * 0.5 * width * SUBPIXEL)
    sy = np.round((1.0 - ndc[..., 1]) * 0.5 * height * SUBPIXEL)
    depth = ndc[..., 2] * 0.5 + 0.5

    # Twice the signed area in image space; ccw in GL window space (y up) is negative here.
    area = (sx[:, 1] - sx[:, 0]) * (sy[:, 2] - sy[:, 0]) - (sx[:, 2] - sx[:, 0]) * (sy[:, 1] - sy[:, 0])
    keep = area != 0
    if cull == "back":
        keep &= area < 0
    elif cull == "front":
        keep &= area > 0
    idx = np.flatnonzero(keep)
    sx, sy, depth, w, attrs, source, area = sx[idx], sy[idx], depth[idx], w[idx], attrs[idx], source[idx], area[idx]

    # Covered pixel range of each bounding box: centres (c + 0.5) inside [min, max].
    half = SUBPIXEL / 2
    c0 = np.clip(np.ceil((sx.min(1) - half) / SUBPIXEL), 0, width).astype(np.int64)
    c1 = np.clip(np.floor((sx.max(1) - half) / SUBPIXEL), -1, width - 1).astype(np.int64)
    r0 = np.clip(np.ceil((sy.min(1) - half) / SUBPIXEL), 0, height).astype(np.int64)
    r1 = np.clip(np.floor((sy.max(1) - half) / SUBPIXEL), -1, height - 1).astype(np.int64)
    bw, bh = c1 - c0 + 1, r1 - r0 + 1
    visible = (bw > 0) & (bh > 0)

    # Edge k runs from vertex k to vertex k+1; its function is positive inside (orientation
    # normalised by the sign of the area).  A centre exactly on an edge belongs to the
    # triangle when the edge is a left edge (interior to its right) or a top edge (horizontal,
    # interior below).
    sign = np.sign(area)
    ax, ay = sx, sy
    bx, by = sx[:, [1, 2, 0]], sy[:, [1, 2, 0]]
    nx = -(by - ay) * sign[:, None]
    ny = (bx - ax) * sign[:, None]
    # E is an integer (in sub-pixel units squared), so "E > 0" is "E - 1 >= 0".
    bias = np.where((nx > 0) | ((nx == 0) & (ny > 0)), 0.0, -1.0)

    out_pix, out_tri, out_b = [], [], []
    pw = np.maximum(1, 2 ** np.ceil(np.log2(np.maximum(bw, 1)))).astype(np.int64)
    ph = np.maximum(1, 2 ** np.ceil(np.log2(np.maximum(bh, 1)))).astype(np.int64)
    vis = np.flatnonzero(visible)
    keys, which = np.unique(np.stack([pw[vis], ph[vis]], axis=1), axis=0, return_inverse=True)
    for b, (bucket_w, bucket_h) in enumerate(keys):
        members = vis[which.reshape(-1) == b]
        per_chunk = max(1, CHUNK_CELLS // (bucket_w * bucket_h))
        for start in range(0, len(members), per_chunk):
            t = members[start:start + per_chunk]
            cols = c0[t, None, None] + np.arange(bucket_w)[None, None, :]
            rows = r0[t, None, None] + np.arange(bucket_h)[None, :, None]
            px = cols * SUBPIXEL + half
            py = rows * SUBPIXEL + half
            inside = (cols <= c1[t, None, None]) & (rows <= r1[t, None, None])
            e = []
            for k in range(3):
                ek = ((bx[t, k, None, None] - ax[t, k, None, None]) * (py - ay[t, k, None, None])
                      - (by[t, k, None, None] - ay[t, k, None, None]) * (px - ax[t, k, None, None]))
                ek = ek * sign[t, None, None]
                inside &= ek + bias[t, k, None, None] >= 0
                e.append(ek)
            n, i, j = np.nonzero(inside)
            out_tri.append(t[n])
            out_pix.append((r0[t[n]] + i) * width + (c0[t[n]] + j))
            # Edge k is opposite vertex k+2: barycentric weights (w0, w1, w2) = (E1, E2, E0) / A.
            out_b.append(np.stack([e[1][n, i, j], e[2][n, i, j], e[0][n, i, j]], axis=1))

    if not out_tri:
        z = np.zeros(0, np.int64)
        return Fragments(z, z, np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    tri = np.concatenate(out_tri)
    pix = np.concatenate(out_pix)
    bary = np.concatenate(out_b) / np.abs(area[tri])[:, None]
    z = np.einsum("ij,ij->i", bary, depth[tri])

    # Depth test "less" against a buffer cleared to 1.0, in primitive order: per pixel the
    # smallest depth wins, and among equal depths the earliest triangle.
    ok = z < 1.0
    tri, pix, bary, z = tri[ok], pix[ok], bary[ok], z[ok]
    order = np.lexsort((source[tri], z, pix))
    first = np.ones(len(order), dtype=bool)
    first[1:] = pix[order][1:] != pix[order][:-1]
    win = order[first]
    tri, pix, bary, z = tri[win], pix[win], bary[win], z[win]

    # Perspective-correct weights: screen-space weights divided by w, renormalised.
    pc = bary / w[tri]
    pc /= pc.sum(axis=1, keepdims=True)
    values = np.einsum("ik,ikc->ic", pc, attrs[tri])
    return Fragments(pix, source[tri], z, values[:, :3], values[:, 3:6])


def _clip(clip: np.ndarray, attrs: np.ndarray, source: np.ndarray):
    """Clip triangles in homogeneous space against z >= -w, z <= w and the guard band.
    Triangles fully outside one plane are dropped; ones crossing a plane are re-triangulated
    as fans (attributes interpolated with the same parameter as the clip coordinates, which is
    exact since both are affine in the original vertex)."""
    planes = np.array([[0, 0, 1, 1], [0, 0, -1, 1],
                       [1, 0, 0, GUARD_BAND], [-1, 0, 0, GUARD_BAND],
                       [0, 1, 0, GUARD_BAND], [0, -1, 0, GUARD_BAND]], dtype=np.float64)
    dist = clip @ planes.T                                        # (T, 3, 6), inside >= 0
    outside_all = (dist < 0).all(axis=1).any(axis=1)
    crosses = (dist < 0).any(axis=(1, 2)) & ~outside_all
    keep = ~outside_all & ~crosses
    new_clip, new_attr, new_src = [clip[keep]], [attrs[keep]], [source[keep]]
    for t in np.flatnonzero(crosses):
        poly = [np.concatenate([clip[t, k], attrs[t, k]]) for k in range(3)]
        for plane in planes:
            if not poly:
                break
            d = [float(v[:4] @ plane) for v in poly]
            out = []
            for k in range(len(poly)):
                a, b, da, db = poly[k], poly[(k + 1) % len(poly)], d[k], d[(k + 1) % len(poly)]
                if da >= 0:
                    out.append(a)
                if (da >= 0) != (db >= 0):
                    out.append(a + (b - a) * (da / (da - db)))
            poly = out
        for k in range(1, len(poly) - 1):
            tri = np.stack([poly[0], poly[k], poly[k + 1]])
            new_clip.append(tri[None, :, :4])
            new_attr.append(tri[None, :, 4:])
            new_src.append(np.array([source[t]]))
    return np.concatenate(new_clip), np.concatenate(new_attr), np.concatenate(new_src)


# -- fragments to the G-buffer -------------------------------------------------------------------


def _gbuffer(frags: Fragments, tri_attr: np.ndarray, width: int, height: int) -> GBuffer:
    n = width * height

    def plane(fill, values, dtype, channels=0):
        shape = (n, channels) if channels else (n,)
        a = np.full(shape, fill, dtype=dtype)
        a[frags.pixel] = values
        return a.reshape((height, width, channels) if channels else (height, width))

    attr = tri_attr[frags.triangle]   # albedo(3), specular, shininess, alpha, object id, group
    triangle = plane(-1, frags.triangle, np.int64)
    return GBuffer(
        width=width, height=height,
        coverage=plane(False, True, bool),
        position=plane(0.0, frags.position, np.float64, 3),
        normal=plane(0.0, frags.normal, np.float64, 3),
        albedo=plane(0.0, attr[:, 0:3], np.float64, 3),
        specular=plane(0.0, attr[:, 3], np.float64),
        shininess=plane(0.0, attr[:, 4], np.float64),
        alpha=plane(0.0, attr[:, 5], np.float64),
        object_id=plane(-1, np.rint(attr[:, 6]), np.int64),
        normal_group=plane(-1, np.rint(attr[:, 7]), np.int64),
        depth=plane(1.0, frags.depth, np.float64),
        triangle=triangle,
        edge=edge_mask(triangle),
    )


def edge_mask(ids: np.ndarray) -> np.ndarray:
    """True where the 3x3 neighbourhood holds more than one value of ``ids`` (a triangle index
    with -1 for sky): the pixels where coverage may legitimately differ between rasterisers."""
    p = np.pad(ids, 1, mode="edge")
    h, w = ids.shape
    views = [p[i:i + h, j:j + w] for i in range(3) for j in range(3)]
    return np.maximum.reduce(views) != np.minimum.reduce(views)
