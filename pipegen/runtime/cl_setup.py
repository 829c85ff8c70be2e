"""Primitive setup and binning for the OpenCL reference (host side, numpy, vectorised).

Between the vertex kernel (clip positions + varyings) and the raster kernel:

1. **clipping** in homogeneous space against z >= -w and z <= w (skipped with depth clamp, which
   clips against w >= 1e-6 instead) and a guard band |x|, |y| <= 4w (so window coordinates stay
   small enough for exact int64 edge functions).  Triangles crossing a plane are re-triangulated
   as fans; new vertices interpolate clip position and varyings with the same parameter (exact
   for perspective-correct interpolation); fans stay in the submission slot of their triangle.
2. **viewport** in float32 like llvmpipe (``x * (1/w) * W/2 + W/2``), window z = ndc z / 2 + 1/2,
   and **snapping** to 8 sub-pixel bits (``rint(x * 256)``, GL_SUBPIXEL_BITS = 8).
3. **facing and culling** from the sign of the fixed-point area (counter-clockwise in GL window
   space = front); zero-area triangles produce no fragments.
4. **interpolation planes** from the *unsnapped* window positions (llvmpipe computes its
   attribute planes from the float positions; only coverage uses the snapped ones): the
   barycentric weights of vertices 1 and 2 are linear in (x - x0, y - y0) (float32), the
   varyings are weighted by ``l_k / w_k`` renormalised (perspective-correct).  Window z is a
   plane in float64 (``zp``/``zq``), evaluated in double by the raster kernel and rounded once:
   llvmpipe's own float plane is up to ~2-3 d24 codes off the exact depth on thin triangles,
   a float32 evaluation here would add as much again.
5. **edge functions** ``E_k = A_k x + B_k y + C_k`` (edge k opposite vertex k, positive inside)
   in 1/256-pixel units, and the **top-left rule**: a pixel centre exactly on an edge belongs to
   the triangle when the edge's inward normal has A > 0, or A == 0 and B > 0 ("left" and, in GL
   window space with y up, "bottom" edges; measured on llvmpipe: it is the top-left rule of image
   space with row 0 on top).
6. **polygon offset**: ``factor * max(|dz/dx|, |dz/dy|) + units * r`` with r = 2^-23 for d24
   (llvmpipe's minimum resolvable difference times two: one unit moves d24 depth by two codes,
   measured) and 2^(e - 23) for d32f (e = exponent of the triangle's largest |z|), added to
   every fragment's z.
7. **binning**: tiles of ``tile`` x ``tile`` pixels; per tile the triangles whose bounding box
   (and, for large boxes, whose edge functions) reach it, in submission order (a stable sort),
   as CSR arrays ``tile_start`` / ``tile_tris``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

SUBPIXEL = 256
GUARD_BAND = 4.0


@dataclass
class Triangles:
    """Set-up triangles in submission order (N of them), device-ready SoA arrays."""

    a: np.ndarray        # (N, 4) int32: A0, A1, A2, inclusive-edge bits
    b: np.ndarray        # (N, 4) int32: B0, B1, B2, 0
    c: np.ndarray        # (N, 4) int64: C0, C1, C2, 0
    z: np.ndarray        # (N, 4) float32: z0, z1 - z0, z2 - z0, polygon offset
    iw: np.ndarray       # (N, 4) float32: 1/w of vertices 0..2, 0
    p: np.ndarray        # (N, 4) float32: window x, y of vertex 0 (unsnapped), 0, 0
    l: np.ndarray        # (N, 4) float32: l1 = l.x dx + l.y dy, l2 = l.z dx + l.w dy
    zp: np.ndarray       # (N, 4) float64: window z plane x0, y0, z0 + offset, dz/dx
    zq: np.ndarray       # (N, 4) float64: dz/dy, 0, 0, 0
    flat: np.ndarray     # (N, 4) uint32: front bit, object id, normal group, light
    vtx: np.ndarray      # (N, 4) int32: vertex indices into the (extended) varyings
    scissor: np.ndarray  # (N, 4) int32: x0, y0, x1, y1 (exclusive); whole viewport if none
    bbox: np.ndarray     # (N, 4) int32: inclusive pixel range x0, y0, x1, y1
    vary: Optional[np.ndarray]   # (S, V', 4) float32 varyings incl. clipping's new vertices
    nverts: int

    @property
    def count(self) -> int:
        return len(self.a)


def _planes(depth_clamp: bool) -> np.ndarray:
    g = GUARD_BAND
    planes = [[1, 0, 0, g], [-1, 0, 0, g], [0, 1, 0, g], [0, -1, 0, g]]
    if depth_clamp:
        planes.append([0, 0, 0, 1])
    else:
        planes += [[0, 0, 1, 1], [0, 0, -1, 1]]
    return np.array(planes, dtype=np.float64)


def clip_triangles(clip: np.ndarray, vary: Optional[np.ndarray], depth_clamp: bool = False):
    """Clip (T*3, 4) clip-space vertices.  Returns (clip (V', 4) float32, vary (S, V', 4),
    tri (N, 3) vertex indices, parent (N,) input triangle of each output triangle)."""
    clip = np.asarray(clip, np.float32)
    T = len(clip) // 3
    tri = np.arange(T * 3, dtype=np.int64).reshape(T, 3)
    if T == 0:
        return clip, vary, tri, np.zeros(0, np.int64)
    planes = _planes(depth_clamp)
    eps = np.zeros(len(planes))
    if depth_clamp:
        eps[-1] = 1e-6
    dist = clip.astype(np.float64) @ planes.T - eps           # (V, P), inside >= 0
    out = (dist < 0).reshape(T, 3, -1)
    outside_all = out.all(axis=1).any(axis=1)
    crosses = out.any(axis=(1, 2)) & ~outside_all
    keep = ~outside_all & ~crosses
    if not crosses.any():
        idx = np.flatnonzero(keep)
        return clip, vary, tri[idx], idx
    S = 0 if vary is None else vary.shape[0]
    new_clip, new_vary, new_tri, new_parent = [], [], [], []
    next_v = len(clip)
    for t in np.flatnonzero(crosses):
        verts = [np.concatenate([clip[3 * t + k].astype(np.float64),
                                 (vary[:, 3 * t + k].reshape(-1).astype(np.float64) if S else np.zeros(0))])
                 for k in range(3)]
        poly = verts
        for p, plane in enumerate(planes):
            if not poly:
                break
            d = [float(v[:4] @ plane) - eps[p] for v in poly]
            res = []
            for k in range(len(poly)):
                a, b, da, db = poly[k], poly[(k + 1) % len(poly)], d[k], d[(k + 1) % len(poly)]
                if da >= 0:
                    res.append(a)
                if (da >= 0) != (db >= 0):
                    res.append(a + (b - a) * (da / (da - db)))
            poly = res
        if len(poly) < 3:
            continue
        base = next_v
        for v in poly:
            new_clip.append(v[:4])
            if S:
                new_vary.append(v[4:].reshape(S, 4))
        next_v += len(poly)
        for k in range(1, len(poly) - 1):
            new_tri.append((base, base + k, base + k + 1))
            new_parent.append(t)
    # merge kept and clipped triangles in submission order (fans stay in their slot)
    kept = np.flatnonzero(keep)
    all_tri = np.concatenate([tri[kept], np.array(new_tri, np.int64).reshape(-1, 3)])
    parent = np.concatenate([kept, np.array(new_parent, np.int64)])
    order = np.argsort(parent, kind="stable")
    clip_out = np.concatenate([clip, np.array(new_clip, np.float32).reshape(-1, 4)])
    vary_out = vary
    if S:
        extra = np.stack(new_vary, axis=1).astype(np.float32) if new_vary else np.zeros((S, 0, 4), np.float32)
        vary_out = np.concatenate([vary, extra], axis=1)
    return clip_out, vary_out, all_tri[order], parent[order]


def setup_triangles(clip: np.ndarray, width: int, height: int, *, cull: str = "none",
                    polygon_offset=None, depth_clamp: bool = False,
                    depth_format: Optional[str] = None, flat: Optional[np.ndarray] = None,
                    vary: Optional[np.ndarray] = None,
                    scissor: Optional[np.ndarray] = None) -> Triangles:
    """Clip, project, snap, cull and build edge equations for a non-indexed triangle list.

    ``clip``: (3T, 4) clip-space positions; ``flat``: (T, 4) uint32 per input triangle (y, z,
    w are kept; x is replaced by the facing bit); ``vary``: (S, 3T, 4); ``scissor``: (T, 4)
    int32 x0, y0, x1, y1 (exclusive) per input triangle, clamped to the viewport.
    """
    clip_v, vary_v, tri, parent = clip_triangles(clip, vary, depth_clamp)
    N = len(tri)
    W, H = int(width), int(height)
    f32 = np.float32
    c = clip_v[tri.reshape(-1)].reshape(N, 3, 4)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        iw = f32(1.0) / c[..., 3]
        xw = (c[..., 0] * iw) * f32(W * 0.5) + f32(W * 0.5)
        yw = (c[..., 1] * iw) * f32(H * 0.5) + f32(H * 0.5)
        zw = (c[..., 2] * iw) * f32(0.5) + f32(0.5)
    X = np.rint(xw.astype(np.float64) * SUBPIXEL).astype(np.int64)
    Y = np.rint(yw.astype(np.float64) * SUBPIXEL).astype(np.int64)
    area = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0])
    keep = area != 0
    if cull == "back":
        keep &= area > 0
    elif cull == "front":
        keep &= area < 0
    # bounding boxes: pixels whose centres (p + 0.5) may be inside
    half = SUBPIXEL // 2
    x0 = -((-(X.min(1) - half)) // SUBPIXEL)
    x1 = (X.max(1) - half) // SUBPIXEL
    y0 = -((-(Y.min(1) - half)) // SUBPIXEL)
    y1 = (Y.max(1) - half) // SUBPIXEL
    sc = np.tile(np.array([0, 0, W, H], np.int64), (N, 1))
    if scissor is not None:
        s = np.asarray(scissor, np.int64)[parent]
        sc = np.stack([np.maximum(s[:, 0], 0), np.maximum(s[:, 1], 0),
                       np.minimum(s[:, 2], W), np.minimum(s[:, 3], H)], axis=1)
    x0 = np.maximum(x0, sc[:, 0])
    y0 = np.maximum(y0, sc[:, 1])
    x1 = np.minimum(x1, sc[:, 2] - 1)
    y1 = np.minimum(y1, sc[:, 3] - 1)
    keep &= (x0 <= x1) & (y0 <= y1)
    idx = np.flatnonzero(keep)
    X, Y, area, iw, zw, tri, parent = X[idx], Y[idx], area[idx], iw[idx], zw[idx], tri[idx], parent[idx]
    xw, yw = xw[idx].astype(np.float64), yw[idx].astype(np.float64)
    x0, y0, x1, y1, sc = x0[idx], y0[idx], x1[idx], y1[idx], sc[idx]
    n = len(idx)
    s = np.sign(area)
    i1, i2 = [1, 2, 0], [2, 0, 1]
    A = -(Y[:, i2] - Y[:, i1]) * s[:, None]
    B = (X[:, i2] - X[:, i1]) * s[:, None]
    C = -(A * X[:, i1] + B * Y[:, i1])
    inclusive = (A > 0) | ((A == 0) & (B > 0))
    bits = (inclusive * np.array([1, 2, 4])).sum(axis=1)

    tri_a = np.zeros((n, 4), np.int32)
    tri_a[:, :3], tri_a[:, 3] = A, bits
    tri_b = np.zeros((n, 4), np.int32)
    tri_b[:, :3] = B
    tri_c = np.zeros((n, 4), np.int64)
    tri_c[:, :3] = C
    z64 = zw.astype(np.float64)
    tri_z = np.zeros((n, 4), np.float32)
    tri_z[:, 0] = zw[:, 0]
    tri_z[:, 1] = z64[:, 1] - z64[:, 0]
    tri_z[:, 2] = z64[:, 2] - z64[:, 0]
    tri_iw = np.zeros((n, 4), np.float32)
    tri_iw[:, :3] = iw
    tri_p = np.zeros((n, 4), np.float32)
    tri_p[:, 0], tri_p[:, 1] = xw[:, 0], yw[:, 0]
    ex, ey = xw[:, 1] - xw[:, 0], yw[:, 1] - yw[:, 0]
    fx, fy = xw[:, 2] - xw[:, 0], yw[:, 2] - yw[:, 0]
    det = ex * fy - ey * fx
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(det != 0, 1.0 / det, 0.0)
    tri_l = np.stack([fy * inv, -fx * inv, -ey * inv, ex * inv], axis=1).astype(np.float32)
    # window z in float64 (the raster kernel evaluates it in double and rounds once: half the
    # error llvmpipe's float plane has, so the two stay within the d24 tolerance)
    dz1, dz2 = z64[:, 1] - z64[:, 0], z64[:, 2] - z64[:, 0]
    tri_zp = np.zeros((n, 4), np.float64)
    tri_zq = np.zeros((n, 4), np.float64)
    tri_zp[:, 0], tri_zp[:, 1], tri_zp[:, 2] = xw[:, 0], yw[:, 0], z64[:, 0]
    tri_zp[:, 3] = dz1 * (fy * inv) + dz2 * (-ey * inv)
    tri_zq[:, 0] = dz1 * (-fx * inv) + dz2 * (ex * inv)
    if polygon_offset is not None and n:
        factor, units = float(polygon_offset[0]), float(polygon_offset[1])
        xs, ys, zs = X / SUBPIXEL, Y / SUBPIXEL, zw.astype(np.float64)
        ex, ey, ez = xs[:, 1] - xs[:, 0], ys[:, 1] - ys[:, 0], zs[:, 1] - zs[:, 0]
        fx, fy, fz = xs[:, 2] - xs[:, 0], ys[:, 2] - ys[:, 0], zs[:, 2] - zs[:, 0]
        det = ex * fy - ey * fx
        dzdx = (ez * fy - ey * fz) / det
        dzdy = (ex * fz - ez * fx) / det
        if depth_format == "d32f":
            zmax = np.abs(zs).max(axis=1)
            e = np.floor(np.log2(np.maximum(zmax, 2.0 ** -126)))
            r = 2.0 ** (e - 23)
        else:
            r = 2.0 ** -23      # llvmpipe: units count two d24 codes each (measured)
        tri_z[:, 3] = (factor * np.maximum(np.abs(dzdx), np.abs(dzdy)) + units * r).astype(np.float32)
        tri_zq[:, 1] = tri_z[:, 3]
    tri_flat = np.zeros((n, 4), np.uint32)
    if flat is not None:
        tri_flat[:] = np.asarray(flat, np.uint32)[parent]
    tri_flat[:, 0] = (area > 0).astype(np.uint32)
    tri_vtx = np.zeros((n, 4), np.int32)
    tri_vtx[:, :3] = tri
    return Triangles(tri_a, tri_b, tri_c, tri_z, tri_iw, tri_p, tri_l, tri_zp, tri_zq, tri_flat,
                     tri_vtx,
                     sc.astype(np.int32), np.stack([x0, y0, x1, y1], axis=1).astype(np.int32),
                     vary_v, len(clip_v))


def bin_triangles(tris: Triangles, width: int, height: int, tile: int = 16,
                  edge_test_tiles: int = 4):
    """Per-tile triangle lists in submission order: (tile_start (ntiles+1,) int32,
    tile_tris (M,) int32, tiles_x, tiles_y).  Triangles whose bounding box spans more than
    ``edge_test_tiles`` tiles are additionally tested per tile against their edge functions
    (a tile is skipped when one edge is negative at all four corners)."""
    tx_n = (width + tile - 1) // tile
    ty_n = (height + tile - 1) // tile
    n = tris.count
    if n == 0:
        return np.zeros(tx_n * ty_n + 1, np.int32), np.zeros(1, np.int32), tx_n, ty_n
    bb = tris.bbox.astype(np.int64)
    tx0, ty0 = bb[:, 0] // tile, bb[:, 1] // tile
    tx1, ty1 = bb[:, 2] // tile, bb[:, 3] // tile
    wx = tx1 - tx0 + 1
    counts = wx * (ty1 - ty0 + 1)
    total = int(counts.sum())
    rep = np.repeat(np.arange(n, dtype=np.int64), counts)
    starts = np.cumsum(counts) - counts
    off = np.arange(total, dtype=np.int64) - np.repeat(starts, counts)
    tx = tx0[rep] + off % wx[rep]
    ty = ty0[rep] + off // wx[rep]
    big = counts[rep] > edge_test_tiles
    if big.any():
        sel = np.flatnonzero(big)
        t = rep[sel]
        # the tile corner that maximises each edge function (pixel-centre positions)
        xa = (tx[sel] * tile) * SUBPIXEL + SUBPIXEL // 2
        xb = (np.minimum(tx[sel] * tile + tile, width) - 1) * SUBPIXEL + SUBPIXEL // 2
        ya = (ty[sel] * tile) * SUBPIXEL + SUBPIXEL // 2
        yb = (np.minimum(ty[sel] * tile + tile, height) - 1) * SUBPIXEL + SUBPIXEL // 2
        ok = np.ones(len(sel), bool)
        for k in range(3):
            A = tris.a[t, k].astype(np.int64)
            B = tris.b[t, k].astype(np.int64)
            C = tris.c[t, k]
            e = A * np.where(A > 0, xb, xa) + B * np.where(B > 0, yb, ya) + C
            ok &= e >= 0
        keep = np.ones(total, bool)
        keep[sel] = ok
        rep, tx, ty = rep[keep], tx[keep], ty[keep]
    tile_id = ty * tx_n + tx
    order = np.argsort(tile_id, kind="stable")
    tile_tris = rep[order].astype(np.int32)
    cnt = np.bincount(tile_id, minlength=tx_n * ty_n)
    tile_start = np.zeros(tx_n * ty_n + 1, np.int32)
    np.cumsum(cnt, out=tile_start[1:])
    if len(tile_tris) == 0:
        tile_tris = np.zeros(1, np.int32)
    return tile_start, tile_tris, tx_n, ty_n
