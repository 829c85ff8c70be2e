"""Primitive setup and binning for the OpenCL reference (host side, numpy, vectorised).

Between the vertex kernel (clip positions + varyings) and the raster kernel.  Positions and
window depth follow llvmpipe (Mesa 22.3) operation for operation, so depth codes agree exactly
(tests/test_cl_depth.py):

1. **clipping** in homogeneous space as draw_pipe_clip.c: llvmpipe clips triangles against the
   viewport planes x <= w, x >= -w, y <= w, y >= -w (no guard band) and, unless depth clamp is
   on, z >= -w and z <= w, in that order, only against the planes some vertex is outside of
   (vertex masks as draw's LLVM path tests them).  float32 throughout: plane distances
   ``w - c`` / ``c + w``, ``t`` measured from the vertex nearer the plane, new vertex (clip
   position and varyings) ``out + t * (in - out)``; a NaN/inf distance drops the triangle.
   The polygon p0..pn-1 becomes the fan (p[i-1], p[i], p0) (emit_poly, last vertex
   provoking), in the submission slot of its triangle.
2. **viewport** in float32 like llvmpipe: shader vertices ``fma(x * (1/w), W/2, W/2)`` (draw's
   LLVM path uses fmuladd, fused on FMA hardware), clipper-made ones ``x * (1/w) * W/2 + W/2``
   rounded step by step (draw_pipe_clip.c interp); window z likewise with scale = translate =
   1/2; **snapping** to 8 sub-pixel bits (``rint(x * 256)``, GL_SUBPIXEL_BITS = 8).
3. **facing and culling** from the sign of the fixed-point area (counter-clockwise in GL window
   space = front); zero-area triangles produce no fragments.
4. **interpolation planes** as llvmpipe's setup (lp_state_setup.c, init_args + calc_coef4)
   from the *unsnapped* window positions (only coverage uses the snapped ones), float32 without
   contraction, in llvmpipe's vertex order (v0, v1 swapped when the GL-window area is
   positive): ``a0`` at the window origin (pixel centre folded in: 0.5, or 0 when the pass
   is multisampled), ``dadx``, ``dady`` per channel.  The ``1/w`` of the vertices is a linear
   plane (``w``: position slot 0, channel 3); smooth varyings are perspective-corrected
   (LP_INTERP_PERSPECTIVE, apply_perspective_corr): premultiplied by their vertex's 1/w before
   the plane is computed (``coef``).  The raster kernel evaluates a plane at the integer pixel
   as ``fma(dady, y, fma(dadx, x, a0))`` (lp_bld_interp.c, interp_attrib_linear) and divides
   a smooth varying by the interpolated 1/w: ``a * (1 / w)`` (attribs_update_simple:
   lp_build_rcp is a correctly rounded division).  Flat varyings take the provoking (last)
   vertex (LP_INTERP_CONSTANT, attribs[2]).  Window z is the same float32 plane
   (``depth_plane``) -- its rounding errors (several d24 codes on steep, thin triangles far
   from the origin) included.
5. **edge functions** ``E_k = A_k x + B_k y + C_k`` (edge k opposite vertex k, positive inside)
   in 1/256-pixel units, and the **top-left rule**: a pixel centre exactly on an edge belongs to
   the triangle when the edge's inward normal has A > 0, or A == 0 and B > 0 ("left" and, in GL
   window space with y up, "bottom" edges; measured on llvmpipe: it is the top-left rule of image
   space with row 0 on top).
6. **polygon offset** as lp_do_offset_tri, in float32 from the same setup values:
   ``factor * max(|dz/dx|, |dz/dy|) + units * r`` with r = (float)(2 / (2^24 - 1)) for d24 (one
   unit is two codes) and 2^(e - 23) for d32f (e = exponent of the triangle's largest |z|),
   added to every fragment's z after the plane.
7. **binning**: tiles of ``tile`` x ``tile`` pixels; per tile the triangles whose bounding box
   (and, for large boxes, whose edge functions) reach it, in submission order (a stable sort),
   as CSR arrays ``tile_start`` / ``tile_tris``.  Boxes and tile tests use the pixel centres
   with one sample per pixel (``samples=1``), any sample position otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

SUBPIXEL = 256


@dataclass
class Triangles:
    """Set-up triangles in submission order (N of them), device-ready SoA arrays."""

    a: np.ndarray        # (N, 4) int32: A0, A1, A2, inclusive-edge bits
    b: np.ndarray        # (N, 4) int32: B0, B1, B2, 0
    c: np.ndarray        # (N, 4) int64: C0, C1, C2, 0
    z: np.ndarray        # (N, 4) float32: window z plane a0, dadx, dady (llvmpipe's), offset
    w: np.ndarray        # (N, 4) float32: plane of 1/w: a0, dadx, dady (llvmpipe's), 0
    coef: np.ndarray     # (N, K, 3, 4) float32: a0, dadx, dady of the K smooth varyings
                         #   premultiplied by 1/w (llvmpipe's perspective planes)
    zp: np.ndarray       # (N, 4) float64: exact plane x0, y0, z0 + offset, dz/dx (reference)
    zq: np.ndarray       # (N, 4) float64: dz/dy, offset, a0 for pixel centre 0 (MSAA), 0
    flat: np.ndarray     # (N, 4) uint32: front bit, object id, normal group, light
    vtx: np.ndarray      # (N, 4) int32: vertex indices into the (extended) varyings
    scissor: np.ndarray  # (N, 4) int32: x0, y0, x1, y1 (exclusive); whole viewport if none
    bbox: np.ndarray     # (N, 4) int32: inclusive pixel range x0, y0, x1, y1
    vary: Optional[np.ndarray]   # (S, V', 4) float32 varyings incl. clipping's new vertices
    nverts: int
    samples: Optional[int] = None    # samples per pixel the boxes are for (None: any)

    @property
    def count(self) -> int:
        return len(self.a)


def fma32(a, b, c) -> np.ndarray:
    """Correctly rounded float32 ``a * b + c`` (vectorised): the product of two float32 is
    exact in float64; the sum is rounded to odd in float64 (TwoSum error term) so that the
    final rounding to float32 is a single correct one."""
    a, b, c = (np.asarray(v, np.float32).astype(np.float64) for v in (a, b, c))
    p = a * b
    with np.errstate(invalid="ignore", over="ignore"):
        s = p + c
        bb = s - p
        err = (p - (s - bb)) + (c - bb)
        bits = s.view(np.int64)
        fix = (err != 0) & np.isfinite(s) & ((bits & 1) == 0)
        toward = np.where(np.signbit(err) == np.signbit(s), 1, -1)
        s = np.where(fix, (bits + toward).view(np.float64), s)
        return s.astype(np.float32)


def depth_plane(xw, yw, zw, area, polygon_offset=None, depth_format=None, center=0.5,
                with_ms_a0=False):
    """Window-z plane of each triangle exactly as llvmpipe (Mesa 22.3) sets it up.

    ``xw``, ``yw``, ``zw``: (N, 3) float32 window positions (unsnapped); ``area``: (N,) the
    fixed-point doubled area (> 0 counter-clockwise in GL window space).  Returns ``(pz, off)``:
    pz (N, 3) float32 ``a0, dadx, dady`` and off (N,) float32 polygon offset, such that the
    fragment at pixel (X, Y) (integers) gets ``fma(dady, Y, fma(dadx, X, a0)) + off``.
    ``center``: the pixel centre folded into a0 (0.5; 0 with multisampling, where llvmpipe
    evaluates the plane at X + sample x, Y + sample y instead: key->pixel_center_half is
    ``half_pixel_center && !multisample``).  ``with_ms_a0``: also return a0 for centre 0.

    llvmpipe: lp_setup_tri.c (triangle_both) hands the setup function the vertices in its
    own counter-clockwise order: (v0, v1, v2) when the GL-window area is negative, (v1, v0, v2)
    when positive (the provoking vertex stays last).  lp_state_setup.c (init_args, calc_coef4)
    then computes, all float32 without contraction:
    ``ooa = 1 / ((x0-x1)(y2-y0) - (y0-y1)(x2-x0))``;
    ``dadx = (z0-z1)((y2-y0) ooa) - (z2-z0)((y0-y1) ooa)``;
    ``dady = (z2-z0)((x0-x1) ooa) - (z0-z1)((x2-x0) ooa)``;
    ``a0 = z0 - (dadx (x0 - .5) + dady (y0 - .5))`` -- the value at the window origin, so the
    float32 error grows with the gradient times the distance from the origin (up to tens of
    d24 codes on steep, thin triangles; llvmpipe's own FIXME).  The fragment shader
    (lp_bld_interp.c, attribs_update_simple) evaluates ``fmuladd(dady, y, fmuladd(dadx, x,
    a0))`` at the integer pixel position (fused on FMA hardware) and adds the polygon offset
    (lp_do_offset_tri, stored in a0.x) after the plane.
    """
    f32 = np.float32
    xw, yw, zw = (np.asarray(v, f32) for v in (xw, yw, zw))
    n = len(xw)
    swap = np.asarray(area) > 0
    order = np.where(swap[:, None], np.array([1, 0, 2]), np.array([0, 1, 2]))
    x = np.take_along_axis(xw, order, 1)
    y = np.take_along_axis(yw, order, 1)
    z = np.take_along_axis(zw, order, 1)
    half = f32(center)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        x0c, y0c = x[:, 0] - half, y[:, 0] - half
        dx01, dy01 = x[:, 0] - x[:, 1], y[:, 0] - y[:, 1]
        dx20, dy20 = x[:, 2] - x[:, 0], y[:, 2] - y[:, 0]
        ooa = f32(1.0) / (dx01 * dy20 - dy01 * dx20)
        dz01, dz20 = z[:, 0] - z[:, 1], z[:, 2] - z[:, 0]
        dadx = dz01 * (dy20 * ooa) - dz20 * (dy01 * ooa)
        dady = dz20 * (dx01 * ooa) - dz01 * (dx20 * ooa)
        a0 = z[:, 0] - (dadx * x0c + dady * y0c)
        off = np.zeros(n, f32)
        if polygon_offset is not None and n:
            factor, units = float(polygon_offset[0]), float(polygon_offset[1])
            # lp_do_offset_tri: cross(e, f).xy * ooa, max of the absolute values, * factor
            zx = np.abs((dy20 * dz01 - dz20 * dy01) * ooa)
            zy = np.abs((dz20 * dx01 - dx20 * dz01) * ooa)
            mult = np.where(zx > zy, zx, zy) * f32(factor)
            if depth_format == "d32f":
                # units * 2^(exponent(max |z|) - 23), the exponent clamped at 2^-126.. 0
                zmax = np.abs(z).max(axis=1)
                e = (zmax.view(np.int32) & np.int32(0xFF << 23)) - np.int32(23 << 23)
                bias = np.maximum(e, 0).astype(np.int32).view(f32) * f32(units)
                off = bias + mult
            else:
                # lp_state_setup.c: pgon_offset_units = (float)(units * mrd * 2), mrd = 1/(2^24-1)
                off = f32(units * (1.0 / 16777215.0) * 2.0) + mult
        pz = np.stack([a0, dadx, dady], axis=1).astype(f32)
        if with_ms_a0:
            a0_ms = z[:, 0] - (dadx * x[:, 0] + dady * y[:, 0])
            return pz, np.asarray(off, f32), a0_ms.astype(f32)
        return pz, np.asarray(off, f32)


def llvmpipe_order(area) -> np.ndarray:
    """(N, 3) the vertex order llvmpipe's setup sees (lp_setup_tri.c, triangle_both): v0 and
    v1 swapped when the GL-window area is positive; the provoking vertex stays last."""
    swap = np.asarray(area) > 0
    return np.where(swap[:, None], np.array([1, 0, 2]), np.array([0, 1, 2]))


def attribute_planes(xw, yw, area, attrs, center=0.5) -> np.ndarray:
    """Plane coefficients of per-vertex attributes exactly as llvmpipe's setup computes them.

    ``xw``, ``yw``: (N, 3) float32 window positions (unsnapped); ``area``: (N,) the fixed-point
    doubled area (its sign picks the vertex order); ``attrs``: (N, 3, C) float32 values at the
    vertices (already multiplied by 1/w for perspective-corrected varyings).  Returns (N, 3, C)
    float32: ``a0`` (at the window origin, ``center`` folded in), ``dadx``, ``dady``; the value
    at pixel (X, Y) is ``fma(dady, Y, fma(dadx, X, a0))``.

    lp_state_setup.c, init_args: ``ooa = 1 / ((x0-x1)(y2-y0) - (y0-y1)(x2-x0))``,
    ``dx01_ooa = (x0-x1) ooa`` etc.; calc_coef4, all float32 unfused:
    ``dadx = (a0-a1) dy20_ooa - (a2-a0) dy01_ooa``,
    ``dady = (a2-a0) dx01_ooa - (a0-a1) dx20_ooa``,
    ``a0' = a0 - (dadx (x0 - c) + dady (y0 - c))``.
    """
    f32 = np.float32
    xw, yw, attrs = (np.asarray(v, f32) for v in (xw, yw, attrs))
    swap = (np.asarray(area) > 0)[:, None]
    # llvmpipe's vertex order (llvmpipe_order): v0 and v1 swapped where the area is positive
    x0, x1 = np.where(swap[:, 0], xw[:, 1], xw[:, 0]), np.where(swap[:, 0], xw[:, 0], xw[:, 1])
    y0, y1 = np.where(swap[:, 0], yw[:, 1], yw[:, 0]), np.where(swap[:, 0], yw[:, 0], yw[:, 1])
    x2, y2 = xw[:, 2], yw[:, 2]
    a0, a1 = np.where(swap, attrs[:, 1], attrs[:, 0]), np.where(swap, attrs[:, 0], attrs[:, 1])
    a2 = attrs[:, 2]
    half = f32(center)
    out = np.empty((len(xw), 3) + attrs.shape[2:], f32)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        dx01, dy01 = x0 - x1, y0 - y1
        dx20, dy20 = x2 - x0, y2 - y0
        ooa = f32(1.0) / (dx01 * dy20 - dy01 * dx20)
        dx01o, dy01o = (dx01 * ooa)[:, None], (dy01 * ooa)[:, None]
        dx20o, dy20o = (dx20 * ooa)[:, None], (dy20 * ooa)[:, None]
        da01 = a0 - a1
        da20 = a2 - a0
        dadx = np.subtract(da01 * dy20o, da20 * dy01o, out=out[:, 1])
        dady = np.subtract(da20 * dx01o, da01 * dx20o, out=out[:, 2])
        np.subtract(a0, dadx * (x0 - half)[:, None] + dady * (y0 - half)[:, None], out=out[:, 0])
    return out


# draw_pipe_clip.c's planes in its order (bit k of the vertex clip mask): x <= w, x >= -w,
# y <= w, y >= -w, z >= -w (near), z <= w (far).  llvmpipe clips triangles without a guard
# band (lp_context.c: draw_set_driver_clipping(draw, FALSE, FALSE, FALSE, TRUE)).
_PLANE_AXIS = (0, 0, 1, 1, 2, 2)
_PLANE_SIGN = (-1, 1, -1, 1, 1, -1)


def _clip_mask(clip: np.ndarray, depth_clamp: bool) -> np.ndarray:
    """Per-vertex outside bits as draw's LLVM vertex path tests them (float32)."""
    x, y, z, w = (clip[:, k] for k in range(4))
    zero = np.float32(0.0)
    with np.errstate(invalid="ignore", over="ignore"):
        bits = [x > w, zero > x + w, y > w, zero > y + w]
        if not depth_clamp:      # depth clamp disables depth clipping (draw->clip_z)
            bits += [zero > z + w, z > w]
    m = np.zeros(len(clip), np.int64)
    for k, b in enumerate(bits):
        m |= b.astype(np.int64) << k
    return m


def _plane_dist(P: np.ndarray, k: int) -> np.ndarray:
    """draw's dot4(clip_pos, plane) for plane k: ``w - c`` or ``c + w`` in float32."""
    c, w = P[..., _PLANE_AXIS[k]], P[..., 3]
    return (w - c) if _PLANE_SIGN[k] < 0 else (c + w)


def _clip_polygons(P, A, n, mask):
    """Sutherland-Hodgman as draw_pipe_clip.c (do_clip_tri, Mesa 22.3) on a batch of
    polygons: P (M, K, 4) float32 clip positions, A (M, K, F) float32 attributes, n (M,)
    vertex counts, mask (M,) the planes to clip against (union of the vertices' bits).
    Returns (P, A, n, src) after clipping; src (M, K) is the input slot a vertex came from
    (its original vertex when >= 0), -1 for vertices made by the clipper; n = 0: dropped."""
    M, K = P.shape[:2]
    src = np.where(np.arange(K)[None, :] < n[:, None], np.arange(K)[None, :], -1)
    alive = np.ones(M, bool)
    f32 = np.float32
    for k in range(6):
        sel = np.flatnonzero(alive & ((mask >> k) & 1 == 1) & (n >= 3))
        if len(sel) == 0:
            continue
        Ps, As, ns, ss = P[sel], A[sel], n[sel], src[sel]
        K = Ps.shape[1]
        j = np.arange(K)[None, :]
        valid = j < ns[:, None]
        with np.errstate(invalid="ignore", over="ignore"):
            dp = _plane_dist(Ps, k)
        bad = (~np.isfinite(dp) & valid).any(axis=1)       # draw discards NaN/inf distances
        cur = np.where(valid, (j + 1) % np.maximum(ns, 1)[:, None], 0)
        dprev = dp
        dcur = np.take_along_axis(dp, cur, 1)
        inside = dprev >= 0
        emit_prev = inside & valid
        cross = np.where(inside, dcur < 0, ~(dcur < 0)) & valid
        # t measured from the vertex nearer the plane: ``interp(new, t, out, in)`` with out
        # the nearer one (measured: the older "t from the outside vertex" form misses
        # llvmpipe 22.3.6 by up to hundreds of d24 codes on steep clipped triangles)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            denom = dcur - dprev
            from_cur = np.where(dcur < 0, -dcur < dprev, ~(-dprev < dcur))
            t = np.where(from_cur, dcur / denom, -dprev / denom).astype(f32)
        Pc = np.take_along_axis(Ps, cur[..., None], 1)
        Ac = np.take_along_axis(As, cur[..., None], 1)
        fc = from_cur[..., None]
        o_P, i_P = np.where(fc, Pc, Ps), np.where(fc, Ps, Pc)
        o_A, i_A = np.where(fc, Ac, As), np.where(fc, As, Ac)
        with np.errstate(invalid="ignore", over="ignore"):
            newP = o_P + t[..., None] * (i_P - o_P)          # LINTERP(t, out, in)
            newA = o_A + t[..., None] * (i_A - o_A)
        # scatter: per edge [prev if inside] then [new if crossing]
        cnt = emit_prev.astype(np.int64) + cross
        pos = np.cumsum(cnt, axis=1) - cnt
        n_out = cnt.sum(axis=1)
        K2 = max(int(n_out.max()), 1)
        oP = np.zeros((len(sel), K2, 4), f32)
        oA = np.zeros((len(sel), K2, As.shape[2]), f32)
        oS = np.full((len(sel), K2), -1, np.int64)
        r, c = np.nonzero(emit_prev)
        oP[r, pos[r, c]], oA[r, pos[r, c]], oS[r, pos[r, c]] = Ps[r, c], As[r, c], ss[r, c]
        r, c = np.nonzero(cross)
        q = pos[r, c] + emit_prev[r, c]
        oP[r, q], oA[r, q] = newP[r, c], newA[r, c]
        # write back (grow the batch arrays when a plane added vertices)
        if K2 > P.shape[1]:
            pad = K2 - P.shape[1]
            P = np.concatenate([P, np.zeros((M, pad, 4), f32)], axis=1)
            A = np.concatenate([A, np.zeros((M, pad, A.shape[2]), f32)], axis=1)
            src = np.concatenate([src, np.full((M, pad), -1, np.int64)], axis=1)
        P[sel, :K2], A[sel, :K2], src[sel, :K2] = oP, oA, oS
        P[sel, K2:], src[sel, K2:] = 0, -1
        n[sel] = n_out
        alive[sel[bad]] = False
    n = np.where(alive & (n >= 3), n, 0)
    return P, A, n, src


def clip_triangles(clip: np.ndarray, vary: Optional[np.ndarray], depth_clamp: bool = False):
    """Clip (T*3, 4) clip-space vertices like llvmpipe's draw module (float32, viewport x/y
    planes, near/far unless ``depth_clamp``).  Returns (clip (V', 4) float32, vary (S, V', 4),
    tri (N, 3) vertex indices, parent (N,) input triangle of each output triangle); vertices
    from index len(clip) on were made by the clipper.  A clipped polygon p0..pn-1 is emitted as the
    fan (p[i-1], p[i], p0), i = 2..n-1 (draw's emit_poly with the last vertex provoking), in
    the submission slot of its triangle."""
    clip = np.asarray(clip, np.float32)
    T = len(clip) // 3
    tri = np.arange(T * 3, dtype=np.int64).reshape(T, 3)
    if T == 0:
        return clip, vary, tri, np.zeros(0, np.int64)
    vm = _clip_mask(clip[:T * 3], depth_clamp).reshape(T, 3)
    union = vm[:, 0] | vm[:, 1] | vm[:, 2]
    inter = vm[:, 0] & vm[:, 1] & vm[:, 2]
    keep = union == 0
    crosses = (union != 0) & (inter == 0)
    if not crosses.any():
        idx = np.flatnonzero(keep)
        return clip, vary, tri[idx], idx
    S = 0 if vary is None else vary.shape[0]
    ct = np.flatnonzero(crosses)
    M = len(ct)
    P = clip[tri[ct]].copy()                                   # (M, 3, 4)
    if S:
        A = np.transpose(np.asarray(vary, np.float32)[:, tri[ct]], (1, 2, 0, 3))
        A = A.reshape(M, 3, S * 4)
    else:
        A = np.zeros((M, 3, 0), np.float32)
    P, A, n, src = _clip_polygons(P, A, np.full(M, 3, np.int64), union[ct])
    # vertex table: original vertices keep their index, clipper-made ones are appended
    K = P.shape[1]
    slot = np.arange(K)[None, :]
    valid = slot < n[:, None]
    made = valid & (src < 0)
    new_id = np.full((M, K), -1, np.int64)
    new_id[made] = len(clip) + np.arange(int(made.sum()))
    orig_id = np.take_along_axis(tri[ct], np.maximum(src, 0), 1)
    vid = np.where(src >= 0, orig_id, new_id)
    # fans (p[i-1], p[i], p0)
    nf = np.maximum(n - 2, 0)
    par = np.repeat(np.arange(M), nf)
    i = np.arange(int(nf.sum())) - np.repeat(np.cumsum(nf) - nf, nf) + 2
    fan = np.stack([vid[par, i - 1], vid[par, i], vid[par, 0]], axis=1)
    kept = np.flatnonzero(keep)
    all_tri = np.concatenate([tri[kept], fan.reshape(-1, 3)])
    parent = np.concatenate([kept, ct[par]])
    order = np.argsort(parent, kind="stable")
    clip_out = np.concatenate([clip, P[made]])
    vary_out = vary
    if S:
        extra = np.transpose(A[made].reshape(-1, S, 4), (1, 0, 2))
        vary_out = np.concatenate([np.asarray(vary, np.float32), extra], axis=1)
    return clip_out, vary_out, all_tri[order], parent[order]


def window_coords(clip: np.ndarray, width: int, height: int, n_orig: int) -> np.ndarray:
    """(V, 4) float32 ``1/w, x, y, z`` in window space, as llvmpipe's draw module computes
    them: vertices ``< n_orig`` (from the vertex shader) in the LLVM path, ``x * (1/w)`` then a
    fused multiply-add with the viewport scale and translation; vertices made by the clipper in
    C (draw_pipe_clip.c interp: ``x * oow * scale + trans``, separately rounded)."""
    f32 = np.float32
    clip = np.asarray(clip, f32)
    out = np.empty((len(clip), 4), f32)
    scale = (f32(width * 0.5), f32(height * 0.5), f32(0.5))
    trans = (f32(width * 0.5), f32(height * 0.5), f32(0.5))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        oow = f32(1.0) / clip[:, 3]
        out[:, 0] = oow
        for k in range(3):
            p = clip[:, k] * oow
            out[:n_orig, k + 1] = fma32(p[:n_orig], scale[k], trans[k])
            out[n_orig:, k + 1] = p[n_orig:] * scale[k] + trans[k]
    return out


def setup_triangles(clip: np.ndarray, width: int, height: int, *, cull: str = "none",
                    polygon_offset=None, depth_clamp: bool = False,
                    depth_format: Optional[str] = None, flat: Optional[np.ndarray] = None,
                    vary: Optional[np.ndarray] = None,
                    scissor: Optional[np.ndarray] = None,
                    samples: Optional[int] = None, smooth: Optional[list] = None,
                    pixel_center: float = 0.5, w_plane: bool = True) -> Triangles:
    """Clip, project, snap, cull and build edge equations for a non-indexed triangle list.

    ``clip``: (3T, 4) clip-space positions; ``flat``: (T, 4) uint32 per input triangle (y, z,
    w are kept; x is replaced by the facing bit); ``vary``: (S, 3T, 4); ``scissor``: (T, 4)
    int32 x0, y0, x1, y1 (exclusive) per input triangle, clamped to the viewport;
    ``samples``: samples per pixel of the pass (1: bounding boxes of pixel centres; None: of
    any sample position, always safe); ``smooth``: the varying slots interpolated with
    perspective correction (``coef``; default all of them); ``pixel_center``: the pixel
    centre folded into the planes' a0 (0.5; 0 for multisampled passes, which evaluate the
    planes at the pixel centre instead, as llvmpipe); ``w_plane``: set up the 1/w plane even
    without smooth varyings (for ``frag_coord.w``; False leaves ``w`` zero).
    """
    clip_v, vary_v, tri, parent = clip_triangles(clip, vary, depth_clamp)
    N = len(tri)
    W, H = int(width), int(height)
    f32 = np.float32
    win = window_coords(clip_v, W, H, len(clip))
    iw, xw, yw, zw = (win[:, k][tri] for k in range(4))
    X = np.rint(xw.astype(np.float64) * SUBPIXEL).astype(np.int64)
    Y = np.rint(yw.astype(np.float64) * SUBPIXEL).astype(np.int64)
    area = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0])
    keep = area != 0
    if cull == "back":
        keep &= area > 0
    elif cull == "front":
        keep &= area < 0
    # bounding boxes: pixels with a sample position (the centre, 128/256, when ``samples`` is
    # 1; any of 1..255/256 otherwise) inside the box.  Clipping makes slivers along the
    # viewport edges that cover samples but no pixel centre.
    lo, hi = (SUBPIXEL // 2, SUBPIXEL // 2) if samples == 1 else (SUBPIXEL - 1, 1)
    x0 = -((-(X.min(1) - lo)) // SUBPIXEL)
    x1 = (X.max(1) - hi) // SUBPIXEL
    y0 = -((-(Y.min(1) - lo)) // SUBPIXEL)
    y1 = (Y.max(1) - hi) // SUBPIXEL
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
    xw_f, yw_f = xw[idx], yw[idx]
    xw, yw = xw_f.astype(np.float64), yw_f.astype(np.float64)
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
    # 1/w plane (linear) and the smooth varyings' planes premultiplied by 1/w (perspective),
    # set up together: (n, 3, 1 + 4K) attributes, 1/w first
    tri_w = np.zeros((n, 4), np.float32)
    S = 0 if vary_v is None else vary_v.shape[0]
    smooth = list(range(S)) if smooth is None else [int(k) for k in smooth]
    tri_coef = np.zeros((n, len(smooth), 3, 4), np.float32)
    if (smooth or w_plane) and n:
        attrs = [iw[:, :, None]]
        if smooth:
            va = np.asarray(vary_v, np.float32)[smooth][:, tri]            # (K, n, 3, 4)
            va = np.transpose(va, (1, 2, 0, 3)).reshape(n, 3, -1)           # (n, 3, K*4)
            with np.errstate(invalid="ignore", over="ignore", under="ignore"):
                attrs.append(va * iw[:, :, None])
        planes = attribute_planes(xw_f, yw_f, area, np.concatenate(attrs, axis=2),
                                  pixel_center)                          # (n, 3, 1 + 4K)
        tri_w[:, :3] = planes[:, :, 0]
        if smooth:
            tri_coef = np.ascontiguousarray(
                np.transpose(planes[:, :, 1:].reshape(n, 3, len(smooth), 4), (0, 2, 1, 3)))
    # window z: llvmpipe's float32 plane (a0 at the window origin, see depth_plane)
    pz, offset, a0_ms = depth_plane(xw_f, yw_f, zw, area, polygon_offset, depth_format,
                                    with_ms_a0=True)
    tri_z = np.zeros((n, 4), np.float32)
    tri_z[:, :3], tri_z[:, 3] = pz, offset
    # zp: the exact plane in float64 (x0, y0, z0 + offset, dz/dx; for reference and tests);
    # zq: dz/dy, the polygon offset, and a0 with pixel centre 0 (multisampling; read by the
    # raster kernel only when PG_SAMPLES > 1)
    ex, ey = xw[:, 1] - xw[:, 0], yw[:, 1] - yw[:, 0]
    fx, fy = xw[:, 2] - xw[:, 0], yw[:, 2] - yw[:, 0]
    det = ex * fy - ey * fx
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(det != 0, 1.0 / det, 0.0)
    z64 = zw.astype(np.float64)
    dz1, dz2 = z64[:, 1] - z64[:, 0], z64[:, 2] - z64[:, 0]
    tri_zp = np.zeros((n, 4), np.float64)
    tri_zq = np.zeros((n, 4), np.float64)
    tri_zp[:, 0], tri_zp[:, 1], tri_zp[:, 2] = xw[:, 0], yw[:, 0], z64[:, 0] + offset
    tri_zp[:, 3] = dz1 * (fy * inv) + dz2 * (-ey * inv)
    tri_zq[:, 0] = dz1 * (-fx * inv) + dz2 * (ex * inv)
    tri_zq[:, 1] = offset
    tri_zq[:, 2] = a0_ms
    tri_flat = np.zeros((n, 4), np.uint32)
    if flat is not None:
        tri_flat[:] = np.asarray(flat, np.uint32)[parent]
    tri_flat[:, 0] = (area > 0).astype(np.uint32)
    tri_vtx = np.zeros((n, 4), np.int32)
    tri_vtx[:, :3] = tri
    return Triangles(tri_a, tri_b, tri_c, tri_z, tri_w, tri_coef, tri_zp, tri_zq, tri_flat,
                     tri_vtx,
                     sc.astype(np.int32), np.stack([x0, y0, x1, y1], axis=1).astype(np.int32),
                     vary_v, len(clip_v), samples)


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
        # the tile corner that maximises each edge function (pixel-centre positions with one
        # sample, else the extreme sample positions any pattern could use)
        lo, hi = (SUBPIXEL // 2, SUBPIXEL // 2) if tris.samples == 1 else (1, SUBPIXEL - 1)
        xa = (tx[sel] * tile) * SUBPIXEL + lo
        xb = (np.minimum(tx[sel] * tile + tile, width) - 1) * SUBPIXEL + hi
        ya = (ty[sel] * tile) * SUBPIXEL + lo
        yb = (np.minimum(ty[sel] * tile + tile, height) - 1) * SUBPIXEL + hi
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
