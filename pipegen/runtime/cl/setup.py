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
   space with row 0 on top).  A triangle whose box holds at most ``SMALL_BOX`` pixels is
   tested with these at each of their samples, where the pass's sample positions are known
   (``samples``), and dropped where it covers none (``covers_a_sample``; the device set-up
   tests the same way): it would draw nothing.
6. **polygon offset** as lp_do_offset_tri, in float32 from the same setup values:
   ``factor * max(|dz/dx|, |dz/dy|) + units * r`` with r = (float)(2 / (2^24 - 1)) for d24 (one
   unit is two codes) and 2^(e - 23) for d32f (e = exponent of the triangle's largest |z|),
   added to every fragment's z after the plane.
7. **binning**: tiles of ``tile`` x ``tile`` pixels; per tile the triangles whose bounding box
   (and, for large boxes, whose edge functions) reach it, in submission order (a stable sort),
   as CSR arrays ``tile_start`` / ``tile_tris``.  Boxes and tile tests use the pixel centres
   with one sample per pixel (``samples=1``), any sample position otherwise.  The raster
   kernel also reads the boxes (``bbox``): it tests a triangle only at the pixels inside.

Every result is per triangle (per vertex for the window coordinates), whatever else is set
up in the same call: the CL runtime sets up many lights' volumes, or the union of several
passes' varyings, at once and hands each pass its part.  The arithmetic runs on (3, N)
rows (vertex k of every triangle in row k); ``depth_plane``, ``attribute_planes`` and
``window_coords`` give the same values in per-triangle layout.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Optional

import numpy as np

# SUBPIXEL: 1/256 pixel, one place for it; the samples a small triangle's box is tested at
from pipegen.backends.opencl.abi import SAMPLE_POSITIONS, SMALL_BOX, SUBPIXEL, sample_positions


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
    zp: Optional[np.ndarray]   # (N, 4) float64: exact plane x0, y0, z0 + offset, dz/dx
                               #   (reference; None when set up ``with_zp=False``)
    zq: Optional[np.ndarray]   # (N, 4) float64: dz/dy, offset, a0 for pixel centre 0 (MSAA), 0
                               #   (None when set up ``with_zq=False``)
    flat: np.ndarray     # (N, 4) uint32: front bit, object id, normal group, light
    vtx: np.ndarray      # (N, 4) int32: vertex indices into the (extended) varyings
    scissor: np.ndarray  # (N, 4) int32: x0, y0, x1, y1 (exclusive); whole viewport if none
    bbox: np.ndarray     # (N, 4) int32: inclusive pixel range x0, y0, x1, y1
    vary: Optional[np.ndarray]   # (S, V', 4) float32 varyings incl. clipping's new vertices
    nverts: int
    samples: Optional[int] = None    # samples per pixel the boxes are for (None: any)
    parent: Optional[np.ndarray] = None   # (N,) int64: the input triangle each one comes from
    h: Optional[np.ndarray] = None   # (N, 4, 4) float64: the float64 evaluation's planes
                                     #   (cl_geometry.homogeneous_planes), or None

    @property
    def count(self) -> int:
        return len(self.a)


def _fma32_exact(a, b, c) -> np.ndarray:
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


def _flat_at(x: np.ndarray, shape: tuple, idx: np.ndarray) -> np.ndarray:
    """``np.broadcast_to(x, shape).reshape(-1)[idx]`` without materialising the broadcast."""
    if x.shape == shape:
        return x.reshape(-1)[idx]
    if x.size == 1:
        return np.full(len(idx), x.reshape(-1)[0], x.dtype)
    return np.broadcast_to(x, shape)[np.unravel_index(idx, shape)]


_LOW_WORD = 0 if sys.byteorder == "little" else 1


def fma32(a, b, c) -> np.ndarray:
    """Correctly rounded float32 ``a * b + c`` (vectorised).  The product of two float32 is
    exact in float64, so rounding the float64 sum to float32 is correct unless that sum was
    itself rounded and landed exactly on a float32 rounding boundary (a tie, which the
    float64 rounding may have decided), or lies in the float32 subnormal range: those few
    take the exact path (the sum rounded to odd in float64, from its TwoSum error term).
    When ``b`` is a power of two (the depth range's 1/2) the float32 product is already exact
    wherever it is a finite normal number, and then the fma is the float32 sum."""
    a, b, c = (np.asarray(v, np.float32) for v in (a, b, c))
    shape = np.broadcast_shapes(a.shape, b.shape, c.shape)
    if b.size == 1 and a.shape == shape:
        bv = float(b.reshape(-1)[0])
        if bv != 0 and np.isfinite(bv) and np.frexp(bv)[0] in (0.5, -0.5):
            with np.errstate(invalid="ignore", over="ignore", under="ignore"):
                q = a * b.reshape(())
                out = q + c
                # exact product: finite and normal (float32's normal range starts at 2^-126)
                np.abs(q, out=q)
                bad = ~((q >= np.float32(2.0 ** -126)) & (q <= np.finfo(np.float32).max))
            if bad.any():
                idx = np.flatnonzero(bad.reshape(-1))
                out.reshape(-1)[idx] = _fma32_general(
                    a.reshape(-1)[idx], b.reshape(()), _flat_at(c, shape, idx))
            return out
        window = _exact_exponents(bv, float(c.reshape(-1)[0])) if c.size == 1 else None
        if window is not None:
            # the viewport transform's case: the float64 sum is exact for every a whose
            # exponent lies in the window, and then its float32 rounding is the fma
            elo, ehi = window
            with np.errstate(invalid="ignore", over="ignore"):
                s = np.multiply(a, b, dtype=np.float64)
                s += c
                out = s.astype(np.float32)
            u = np.bitwise_and(a.reshape(-1).view(np.uint32), np.uint32(0x7F800000))
            u -= np.uint32(elo << 23)                  # below the window: wraps around
            bad = u > np.uint32((ehi - elo) << 23)
            if bad.any():
                idx = np.flatnonzero(bad)
                out.reshape(-1)[idx] = _fma32_general(a.reshape(-1)[idx], b.reshape(()),
                                                      c.reshape(()))
            return out
    return _fma32_general(a, b, c)


def _exact_exponents(b: float, c: float) -> Optional[tuple]:
    """The biased float32 exponents [lo, hi] of the a for which the float64 ``a * b + c``
    (float32 a, b, c; a normal) is exact, or None when that window is too narrow to be worth
    testing.  The product is exact (48 bits); the sum is when all its bits fit in 53: with
    e() the exponent and l() the lowest set bit, the sum stays below 2^(e(c) + 3) when
    e(a) <= e(c) - e(b), and its lowest bit is at least min(l(a) + l(b), l(c)), l(a) >=
    e(a) - 23; so e(a) >= e(c) - 27 - l(b) suffices (l(c) >= e(c) - 23 always)."""
    def exps(v):                     # (exponent, lowest set bit) of a normal float32
        bits = int(np.float32(v).view(np.uint32)) & 0x7FFFFFFF
        e = (bits >> 23) - 127
        if not 1 <= bits >> 23 <= 254:
            return None
        mant = (bits & 0x7FFFFF) | 0x800000
        return e, e - 23 + ((mant & -mant).bit_length() - 1)
    eb, ec = exps(b), exps(c)
    if eb is None or ec is None:
        return None
    hi = ec[0] - eb[0]
    lo = ec[0] - 27 - eb[1]
    lo, hi = max(lo + 127, 1), min(hi + 127, 254)
    return (lo, hi) if hi - lo >= 4 else None


def _fma32_general(a, b, c) -> np.ndarray:
    """``fma32`` through the float64 sum (see there).  The suspects are found on 32-bit words
    (the low word of the float64 sum holds the 29 bits below float32's; ``|out|``'s bits
    minus those of 2^-125 wrap around below it, and NaN lies above +inf), with as few
    full-size temporaries as possible: their fresh pages cost more than the arithmetic."""
    shape = np.broadcast_shapes(a.shape, b.shape, c.shape)
    with np.errstate(invalid="ignore", over="ignore"):
        s = np.multiply(a, b, dtype=np.float64)            # exact
        if s.shape == shape:
            s += c
        else:
            s = s + c
        out = s.astype(np.float32)
    flat_s, flat_o = s.reshape(-1), out.reshape(-1)
    t = np.bitwise_and(flat_s.view(np.uint32)[_LOW_WORD::2], np.uint32(0x1FFFFFFF))
    suspect = t == np.uint32(0x10000000)
    np.bitwise_and(flat_o.view(np.uint32), np.uint32(0x7FFFFFFF), out=t)
    t -= np.uint32(0x01000000)                             # 2^-125
    suspect |= t > np.uint32(0x7F800000 - 0x01000000)
    if suspect.any():
        idx = np.flatnonzero(suspect)
        a_, b_, c_ = (_flat_at(v, shape, idx) for v in (a, b, c))
        ss = flat_s[idx]
        with np.errstate(invalid="ignore", over="ignore"):
            ps = np.multiply(a_, b_, dtype=np.float64)
            cs = c_.astype(np.float64)
            # Fast2Sum: the rounding error of s is exactly (s - big) - small
            big_p = np.abs(ps) >= np.abs(cs)
            err = np.where(big_p, (ss - ps) - cs, (ss - cs) - ps)
            redo = (err != 0) | ~(np.abs(ss) >= 2.0 ** -125)
        if redo.any():
            flat_o[idx[redo]] = _fma32_exact(a_[redo], b_[redo], c_[redo])
    return out


class _Edges:
    """The vertex-order-dependent terms of llvmpipe's setup (lp_state_setup.c, init_args) for
    triangles given as (3, n) float32 rows of window x and y: the vertex order llvmpipe's
    setup sees (v0 and v1 swapped where the GL-window ``area`` is positive, the provoking
    vertex last), ``ooa = 1 / ((x0-x1)(y2-y0) - (y0-y1)(x2-x0))`` and ``dx01 * ooa`` etc.,
    all float32 without contraction."""

    def __init__(self, xw, yw, area):
        f32 = np.float32
        self.swap = sw = np.asarray(area) > 0
        # (in place where a temporary would do: fewer fresh arrays, the same operations)
        x0, x1 = np.where(sw, xw[1], xw[0]), np.where(sw, xw[0], xw[1])
        y0, y1 = np.where(sw, yw[1], yw[0]), np.where(sw, yw[0], yw[1])
        x2, y2 = xw[2], yw[2]
        self.x0, self.y0 = x0, y0
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            self.dx01, self.dy01 = np.subtract(x0, x1, out=x1), np.subtract(y0, y1, out=y1)
            self.dx20, self.dy20 = x2 - x0, y2 - y0
            ooa = self.dx01 * self.dy20
            ooa -= self.dy01 * self.dx20
            self.ooa = np.divide(f32(1.0), ooa, out=ooa)
            self.dx01o, self.dy01o = self.dx01 * ooa, self.dy01 * ooa
            self.dx20o, self.dy20o = self.dx20 * ooa, self.dy20 * ooa

    def order(self, v):
        """(3, n, ...) per-vertex values -> (v0, v1, v2) in llvmpipe's order."""
        sw = self.swap.reshape(self.swap.shape + (1,) * (v.ndim - 2))
        return np.where(sw, v[1], v[0]), np.where(sw, v[0], v[1]), v[2]

    def planes(self, v, center):
        """(a0, dadx, dady) of (3, n, ...) float32 vertex values (calc_coef4): ``planes_cm``
        with the per-triangle axis last, put back first."""
        a0, a1, a2 = (np.moveaxis(a, 0, -1) for a in self.order(v))
        return tuple(np.moveaxis(p, -1, 0) for p in self.planes_cm(a0, a1, a2, center))

    def planes_cm(self, a0, a1, a2, center):
        """(a0, dadx, dady) of values already in llvmpipe's vertex order, the triangles on the
        last axis (channel-major: (C, n); calc_coef4, float32 unfused): ``dadx = (a0-a1)
        dy20_ooa - (a2-a0) dy01_ooa``, ``dady = (a2-a0) dx01_ooa - (a0-a1) dx20_ooa``,
        ``a0' = a0 - (dadx (x0 - c) + dady (y0 - c))``."""
        half = np.float32(center)
        with np.errstate(invalid="ignore", over="ignore", under="ignore"):
            da01, da20 = a0 - a1, a2 - a0
            dadx = da01 * self.dy20o - da20 * self.dy01o
            dady = da20 * self.dx01o - da01 * self.dx20o
            return a0 - (dadx * (self.x0 - half) + dady * (self.y0 - half)), dadx, dady

    def depth(self, zw, polygon_offset=None, depth_format=None, center=0.5, ms_a0=True):
        """(a0, dadx, dady, offset, a0 for pixel centre 0) of the window-z plane (zw: (3, n));
        the last None unless ``ms_a0``."""
        f32 = np.float32
        z0, z1, z2 = self.order(zw)
        n = len(z0)
        a0, dadx, dady = self.planes_cm(z0, z1, z2, center)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            dz01, dz20 = z0 - z1, z2 - z0
            a0_ms = z0 - (dadx * self.x0 + dady * self.y0) if ms_a0 else None
            off = np.zeros(n, f32)
            if polygon_offset is not None and n:
                factor, units = float(polygon_offset[0]), float(polygon_offset[1])
                # lp_do_offset_tri: cross(e, f).xy * ooa, max of the absolute values, * factor
                zx = np.abs((self.dy20 * dz01 - dz20 * self.dy01) * self.ooa)
                zy = np.abs((dz20 * self.dx01 - self.dx20 * dz01) * self.ooa)
                mult = np.where(zx > zy, zx, zy) * f32(factor)
                if depth_format == "d32f":
                    # units * 2^(exponent(max |z|) - 23), the exponent clamped at 2^-126.. 0
                    zmax = np.maximum(np.maximum(np.abs(z0), np.abs(z1)), np.abs(z2))
                    e = (zmax.view(np.int32) & np.int32(0xFF << 23)) - np.int32(23 << 23)
                    bias = np.maximum(e, 0).astype(np.int32).view(f32) * f32(units)
                    off = bias + mult
                else:
                    # lp_state_setup.c: pgon_offset_units = (float)(units * mrd * 2),
                    # mrd = 1/(2^24-1)
                    off = f32(units * (1.0 / 16777215.0) * 2.0) + mult
        return a0, dadx, dady, np.asarray(off, f32), a0_ms


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
    a0, dadx, dady, off, a0_ms = _Edges(xw.T, yw.T, area).depth(
        zw.T, polygon_offset, depth_format, center)
    pz = np.stack([a0, dadx, dady], axis=1).astype(f32)
    if with_ms_a0:
        return pz, off, a0_ms.astype(f32)
    return pz, off


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
    a0, dadx, dady = _Edges(xw.T, yw.T, area).planes(np.moveaxis(attrs, 1, 0), center)
    return np.stack([a0, dadx, dady], axis=1)


# draw_pipe_clip.c's planes in its order (bit k of the vertex clip mask): x <= w, x >= -w,
# y <= w, y >= -w, z >= -w (near), z <= w (far).  llvmpipe clips triangles without a guard
# band (lp_context.c: draw_set_driver_clipping(draw, FALSE, FALSE, FALSE, TRUE)).
_PLANE_AXIS = (0, 0, 1, 1, 2, 2)
_PLANE_SIGN = (-1, 1, -1, 1, 1, -1)


def _clip_mask(clip: Optional[np.ndarray], depth_clamp: bool,
               cols: Optional[np.ndarray] = None) -> np.ndarray:
    """Per-vertex outside bits (uint8) as draw's LLVM vertex path tests them (float32), of
    ``clip`` (V, 4) or, given instead, its transpose ``cols`` (4, V)."""
    x, y, z, w = np.ascontiguousarray(np.asarray(clip, np.float32).T) if cols is None else cols
    zero = np.float32(0.0)
    m = np.greater(x, w).view(np.uint8)
    # the other planes into one scratch sum and flag array (fewer fresh pages)
    s = np.empty_like(x)
    flag = np.empty(len(x), bool)
    f8 = flag.view(np.uint8)
    tests = [(x, None, 1), (y, w, 2), (y, None, 3)]       # (coordinate, w or None, bit)
    if not depth_clamp:      # depth clamp disables depth clipping (draw->clip_z)
        tests += [(z, None, 4), (z, w, 5)]
    with np.errstate(invalid="ignore", over="ignore"):
        for c, w_or_none, k in tests:
            if w_or_none is None:        # zero > c + w
                np.add(c, w, out=s)
                np.less(s, zero, out=flag)
            else:                        # c > w
                np.greater(c, w, out=flag)
            np.left_shift(f8, np.uint8(k), out=f8)
            m |= f8
    return m


def _outside(cols: np.ndarray, depth_clamp: bool) -> np.ndarray:
    """Per vertex: is any bit of ``_clip_mask`` set?  ``c > w`` or ``0 > c + w`` is exactly
    ``|c| > w`` (the float32 sum has the sign of the exact one and is 0 only when that is;
    NaN fails both), so three comparisons instead of six plus the sums."""
    x, y, z, w = cols
    s = np.abs(x)
    out = np.greater(s, w)
    flag = np.empty(len(w), bool)
    for c in (y,) if depth_clamp else (y, z):
        np.abs(c, out=s)
        np.greater(s, w, out=flag)
        out |= flag
    return out


def _plane_dist(P: np.ndarray, k: int) -> np.ndarray:
    """draw's dot4(clip_pos, plane) for plane k: ``w - c`` or ``c + w`` in float32."""
    c, w = P[..., _PLANE_AXIS[k]], P[..., 3]
    return (w - c) if _PLANE_SIGN[k] < 0 else (c + w)


def _clip_polygons(P, A, n, mask):
    """Sutherland-Hodgman as draw_pipe_clip.c (do_clip_tri, Mesa 22.3) on a batch of
    polygons: P (M, K, 4) float32 clip positions, A (M, K, F) float32 attributes, n (M,)
    vertex counts, mask (M,) the planes to clip against (union of the vertices' bits).
    Returns (P, A, n, src) after clipping; src (M, K) is the input slot a vertex came from
    (its original vertex when >= 0), -1 for vertices made by the clipper; n = 0: dropped.
    Positions and attributes travel together as (M, K, 4 + F) rows (the same interpolation
    of every channel; a batch is usually a handful of polygons, so the cost is numpy calls
    per plane, not arithmetic)."""
    M, K = P.shape[:2]
    V = np.concatenate([np.asarray(P, np.float32), np.asarray(A, np.float32)], axis=2)
    src = np.where(np.arange(K)[None, :] < n[:, None], np.arange(K)[None, :], -1)
    alive = np.ones(M, bool)
    f32 = np.float32
    for k in range(6):
        sel = np.flatnonzero(alive & ((mask >> k) & 1 == 1) & (n >= 3))
        if len(sel) == 0:
            continue
        Vs, ns, ss = V[sel], n[sel], src[sel]
        m, K = Vs.shape[:2]
        j = np.arange(K)[None, :]
        rows = np.arange(m)[:, None]
        valid = j < ns[:, None]
        with np.errstate(invalid="ignore", over="ignore"):
            dp = _plane_dist(Vs, k)
        bad = (~np.isfinite(dp) & valid).any(axis=1)       # draw discards NaN/inf distances
        cur = np.where(valid, (j + 1) % np.maximum(ns, 1)[:, None], 0)
        dprev = dp
        dcur = dp[rows, cur]
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
        Vc = Vs[rows, cur]
        fc = from_cur[..., None]
        o_V, i_V = np.where(fc, Vc, Vs), np.where(fc, Vs, Vc)
        with np.errstate(invalid="ignore", over="ignore"):
            newV = o_V + t[..., None] * (i_V - o_V)          # LINTERP(t, out, in)
        # scatter: per edge [prev if inside] then [new if crossing]
        cnt = emit_prev.astype(np.int64) + cross
        pos = np.cumsum(cnt, axis=1) - cnt
        n_out = cnt.sum(axis=1)
        K2 = max(int(n_out.max()), 1)
        oV = np.zeros((m, K2, V.shape[2]), f32)
        oS = np.full((m, K2), -1, np.int64)
        r, c = np.nonzero(emit_prev)
        oV[r, pos[r, c]], oS[r, pos[r, c]] = Vs[r, c], ss[r, c]
        r, c = np.nonzero(cross)
        oV[r, pos[r, c] + emit_prev[r, c]] = newV[r, c]
        # write back (grow the batch arrays when a plane added vertices)
        if K2 > V.shape[1]:
            pad = K2 - V.shape[1]
            V = np.concatenate([V, np.zeros((M, pad, V.shape[2]), f32)], axis=1)
            src = np.concatenate([src, np.full((M, pad), -1, np.int64)], axis=1)
        V[sel, :K2], src[sel, :K2] = oV, oS
        V[sel, K2:], src[sel, K2:] = 0, -1
        n[sel] = n_out
        alive[sel[bad]] = False
    n = np.where(alive & (n >= 3), n, 0)
    return V[..., :4], V[..., 4:], n, src


def clip_triangles(clip: np.ndarray, vary: Optional[np.ndarray], depth_clamp: bool = False):
    """Clip (T*3, 4) clip-space vertices like llvmpipe's draw module (float32, viewport x/y
    planes, near/far unless ``depth_clamp``).  Returns (clip (V', 4) float32, vary (S, V', 4),
    tri (N, 3) vertex indices, parent (N,) input triangle of each output triangle); vertices
    from index len(clip) on were made by the clipper.  A clipped polygon p0..pn-1 is emitted as the
    fan (p[i-1], p[i], p0), i = 2..n-1 (draw's emit_poly with the last vertex provoking), in
    the submission slot of its triangle."""
    clip_v, vary_v, vid, parent = _clip_triangles(clip, vary, depth_clamp)
    return clip_v, vary_v, np.ascontiguousarray(vid.T), parent


def _clip_triangles(clip: np.ndarray, vary: Optional[np.ndarray], depth_clamp: bool,
                    cols: Optional[np.ndarray] = None):
    """``clip_triangles`` with the vertex indices as (3, N) rows (vertex k of every triangle
    in row k); ``cols``: ``clip`` transposed, (4, V), if the caller has it."""
    clip = np.asarray(clip, np.float32)
    T = len(clip) // 3
    if T == 0:
        return clip, vary, np.zeros((3, 0), np.int64), np.zeros(0, np.int64)
    cols = np.ascontiguousarray(clip[:T * 3].T) if cols is None else cols[:, :T * 3]
    corner = np.arange(3, dtype=np.int64)[:, None]
    # the clip mask of the vertices of triangles with a vertex outside some plane (the
    # others have none: all inside, kept as they are)
    out = _outside(cols, depth_clamp).reshape(T, 3)
    cand = np.flatnonzero(out[:, 0] | out[:, 1] | out[:, 2])
    keep = np.ones(T, bool)
    keep[cand] = False
    union = np.zeros(T, np.uint8)
    crosses = np.zeros(T, bool)
    if len(cand):
        vm = _clip_mask(None, depth_clamp, cols[:, (cand * 3 + corner).T.reshape(-1)])
        vm = vm.reshape(-1, 3)
        union[cand] = vm[:, 0] | vm[:, 1] | vm[:, 2]
        crosses[cand] = (vm[:, 0] & vm[:, 1] & vm[:, 2]) == 0
    if not crosses.any():
        idx = np.flatnonzero(keep)
        return clip, vary, idx * 3 + corner, idx
    S = 0 if vary is None else vary.shape[0]
    ct = np.flatnonzero(crosses)
    M = len(ct)
    tri_ct = ct[:, None] * 3 + corner.T                        # (M, 3) their vertices
    P = clip[tri_ct]                                           # (M, 3, 4)
    if S:
        A = np.transpose(np.asarray(vary, np.float32)[:, tri_ct], (1, 2, 0, 3))
        A = A.reshape(M, 3, S * 4)
    else:
        A = np.zeros((M, 3, 0), np.float32)
    P, A, n, src = _clip_polygons(P, A, np.full(M, 3, np.int64), union[ct].astype(np.int64))
    # vertex table: original vertices keep their index, clipper-made ones are appended
    K = P.shape[1]
    slot = np.arange(K)[None, :]
    valid = slot < n[:, None]
    made = valid & (src < 0)
    new_id = np.full((M, K), -1, np.int64)
    new_id[made] = len(clip) + np.arange(int(made.sum()))
    orig_id = np.take_along_axis(tri_ct, np.maximum(src, 0), 1)
    pvid = np.where(src >= 0, orig_id, new_id)
    # fans (p[i-1], p[i], p0)
    nf = np.maximum(n - 2, 0)
    par = np.repeat(np.arange(M), nf)
    i = np.arange(int(nf.sum())) - np.repeat(np.cumsum(nf) - nf, nf) + 2
    # submission order: each input triangle's output (itself, or its fan) in its slot, placed
    # directly (what a stable sort of the outputs by parent gives)
    per = keep.astype(np.int64)
    per[ct] = nf
    parent = np.repeat(np.arange(T, dtype=np.int64), per)
    vid = parent * 3 + corner                       # right for the kept ones
    at = (np.cumsum(per) - per)[ct[par]] + (i - 2)
    vid[0, at], vid[1, at], vid[2, at] = pvid[par, i - 1], pvid[par, i], pvid[par, 0]
    clip_out = np.concatenate([clip, P[made]])
    vary_out = vary
    if S:
        extra = np.transpose(A[made].reshape(-1, S, 4), (1, 0, 2))
        vary_out = np.concatenate([np.asarray(vary, np.float32), extra], axis=1)
    return clip_out, vary_out, vid, parent


def _window_rows(clip: np.ndarray, width: int, height: int, n_orig: int,
                 viewport=None) -> np.ndarray:
    """``window_coords`` as (4, V) rows; ``viewport`` (x, y, w, h): a viewport other than the
    whole ``width x height`` target (llvmpipe: scale w/2, translate x + w/2)."""
    f32 = np.float32
    cols = np.ascontiguousarray(np.asarray(clip, f32).T)
    out = np.empty((4, cols.shape[1]), f32)
    vx, vy, vw, vh = viewport if viewport is not None else (0, 0, width, height)
    scale = (f32(vw * 0.5), f32(vh * 0.5), f32(0.5))
    trans = (f32(vx + vw * 0.5), f32(vy + vh * 0.5), f32(0.5))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        oow = np.divide(f32(1.0), cols[3], out=out[0])
        for k in range(3):
            p = cols[k] * oow
            out[k + 1, :n_orig] = fma32(p[:n_orig], scale[k], trans[k])
            out[k + 1, n_orig:] = p[n_orig:] * scale[k] + trans[k]
    return out


def window_coords(clip: np.ndarray, width: int, height: int, n_orig: int) -> np.ndarray:
    """(V, 4) float32 ``1/w, x, y, z`` in window space, as llvmpipe's draw module computes
    them: vertices ``< n_orig`` (from the vertex shader) in the LLVM path, ``x * (1/w)`` then a
    fused multiply-add with the viewport scale and translation; vertices made by the clipper in
    C (draw_pipe_clip.c interp: ``x * oow * scale + trans``, separately rounded)."""
    return np.ascontiguousarray(_window_rows(clip, width, height, n_orig).T)


def _exact_z_planes(xw, yw, zw, offset, a0_ms, with_zp: bool, with_zq: bool):
    """``Triangles.zp`` and ``zq`` (each None unless asked for) from the per-vertex rows (3, n)
    of the unsnapped window positions, the polygon offset and a0 for pixel centre 0."""
    if not (with_zp or with_zq):
        return None, None
    n, f64 = len(offset), np.float64
    # float64 differences of the float32 positions (cast exactly first), and the products in
    # the operand order of ``dz1 * (fy * inv) + dz2 * (-ey * inv)`` (dz/dx) and
    # ``dz1 * (-fx * inv) + dz2 * (ex * inv)`` (dz/dy), in place
    ex, ey = np.subtract(xw[1], xw[0], dtype=f64), np.subtract(yw[1], yw[0], dtype=f64)
    fx, fy = np.subtract(xw[2], xw[0], dtype=f64), np.subtract(yw[2], yw[0], dtype=f64)
    dz1, dz2 = np.subtract(zw[1], zw[0], dtype=f64), np.subtract(zw[2], zw[0], dtype=f64)
    inv = np.multiply(ex, fy)
    inv -= np.multiply(ey, fx)                      # det
    zero = inv == 0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        np.divide(1.0, inv, out=inv)
        inv[zero] = 0.0
        t, u = np.empty(n, f64), np.empty(n, f64)
        tri_zp = tri_zq = None
        if with_zp:
            tri_zp = np.empty((n, 4), f64)
            tri_zp[:, 0], tri_zp[:, 1] = xw[0], yw[0]
            np.add(zw[0], offset, out=tri_zp[:, 2], dtype=f64)
            np.multiply(fy, inv, out=t)
            np.multiply(dz1, t, out=t)
            np.negative(ey, out=u)
            np.multiply(u, inv, out=u)
            np.multiply(dz2, u, out=u)
            np.add(t, u, out=tri_zp[:, 3])
        if with_zq:
            tri_zq = np.zeros((n, 4), f64)
            np.negative(fx, out=t)
            np.multiply(t, inv, out=t)
            np.multiply(dz1, t, out=t)
            np.multiply(ex, inv, out=u)
            np.multiply(dz2, u, out=u)
            np.add(t, u, out=tri_zq[:, 0])
            tri_zq[:, 1] = offset
            tri_zq[:, 2] = a0_ms
    return tri_zp, tri_zq


def _snap(v: np.ndarray) -> np.ndarray:
    """Window coordinates to 1/SUBPIXEL units: ``rint(v * SUBPIXEL)`` in float64 (exact)."""
    t = np.multiply(v, SUBPIXEL, dtype=np.float64)
    return np.rint(t, out=t).astype(np.int64)


def covers_a_sample(X: np.ndarray, Y: np.ndarray, area: np.ndarray, x0, y0, x1, y1,
                    samples: int) -> np.ndarray:
    """Whether each triangle (snapped vertices ``X``, ``Y``: (3, n) in 1/256 pixel; nonzero
    ``area``) covers a sample of a pixel of its box ``x0..x1``, ``y0..y1`` (at most
    ``SMALL_BOX`` pixels), by the raster kernel's own test: its edge functions, with the
    int32 coefficients it reads, at ``sample_positions(samples)``, top-left edges inclusive
    (cl_setup.cl.j2's setup_tri tests the same way)."""
    s = np.sign(area)
    E = []
    for i1, i2 in ((1, 2), (2, 0), (0, 1)):
        a = ((Y[i1] - Y[i2]) * s).astype(np.int32).astype(np.int64)
        b = ((X[i2] - X[i1]) * s).astype(np.int32).astype(np.int64)
        c = -((Y[i1] - Y[i2]) * s * X[i1] + (X[i2] - X[i1]) * s * Y[i1])
        E.append((a, b, c, ((a > 0) | ((a == 0) & (b > 0))).astype(np.int64)))
    w = x1 - x0 + 1
    n_px = w * (y1 - y0 + 1)
    got = np.zeros(len(area), bool)
    sx, sy = sample_positions(samples)
    for j in range(int(n_px.max()) if len(n_px) else 0):
        inside = j < n_px
        px, py = x0 + j % w, y0 + j // w
        for dx, dy in zip(sx, sy):
            xs, ys = px * SUBPIXEL + dx, py * SUBPIXEL + dy
            hit = inside.copy()
            for a, b, c, inclusive in E:
                hit &= a * xs + b * ys + c >= 1 - inclusive
            got |= hit
    return got


def setup_triangles(clip: np.ndarray, width: int, height: int, *, cull: str = "none",
                    polygon_offset=None, depth_clamp: bool = False,
                    depth_format: Optional[str] = None, flat: Optional[np.ndarray] = None,
                    vary: Optional[np.ndarray] = None,
                    scissor: Optional[np.ndarray] = None,
                    samples: Optional[int] = None, smooth: Optional[list] = None,
                    pixel_center: float = 0.5, w_plane: bool = True,
                    viewport=None, with_zp: bool = True, with_zq: bool = True) -> Triangles:
    """Clip, project, snap, cull and build edge equations for a non-indexed triangle list.

    ``clip``: (3T, 4) clip-space positions; ``cull``: "none", "back", "front" or "auto" (per
    input triangle: bit 2 of its ``flat.x`` set, its back faces are kept and marked with
    bit 1, else its front faces); ``flat``: (T, 4) uint32 per input triangle (y, z, w are
    kept; x is replaced by the facing bit); ``vary``: (S, 3T, 4); ``scissor``: (T, 4)
    int32 x0, y0, x1, y1 (exclusive) per input triangle, clamped to the viewport;
    ``samples``: samples per pixel of the pass (1: bounding boxes of pixel centres; None: of
    any sample position, always safe); ``smooth``: the varying slots interpolated with
    perspective correction (``coef``; default all of them); ``pixel_center``: the pixel
    centre folded into the planes' a0 (0.5; 0 for multisampled passes, which evaluate the
    planes at the pixel centre instead, as llvmpipe); ``w_plane``: set up the 1/w plane even
    without smooth varyings (for ``frag_coord.w``; False leaves ``w`` zero); ``viewport``:
    (x, y, w, h) inside the target, default the whole target (shadow-map tiles);
    ``with_zp``, ``with_zq``: compute ``zp`` and ``zq`` (else None; the raster kernel never
    reads ``zp`` and reads ``zq`` only when multisampled).
    """
    f32 = np.float32
    clip = np.asarray(clip, f32)
    n_orig = len(clip)
    # x, y, z, w rows (strided views: a transposed copy costs more than it saves)
    clip_v, vary_v, vid, parent = _clip_triangles(clip, vary, depth_clamp, clip.T)
    cols = clip_v.T
    W, H = int(width), int(height)
    vx, vy, vw, vh = viewport if viewport is not None else (0, 0, W, H)
    scale = (f32(vw * 0.5), f32(vh * 0.5), f32(0.5))
    trans = (f32(vx + vw * 0.5), f32(vy + vh * 0.5), f32(0.5))
    # The values of _window_rows, computed where needed: window x and y of every vertex
    # (culling needs them all), gathered per triangle as (3, N) rows (vertex k of every
    # triangle in row k); 1/w and z only for the triangles culling keeps.  Every step is
    # elementwise, so computing a value per triangle corner instead of per vertex, or for a
    # subset, gives the same bits.  (np.take: fancy indexing along axis 1 is several times
    # slower.)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        oow = f32(1.0) / cols[3]
        xy = np.empty((2, len(oow)), f32)
        for k in range(2):
            p = cols[k] * oow
            xy[k, :n_orig] = fma32(p[:n_orig], scale[k], trans[k])
            xy[k, n_orig:] = p[n_orig:] * scale[k] + trans[k]
    xw, yw = np.take(xy, vid, axis=1)
    X, Y = (_snap(r) for r in (xw, yw))
    area = (X[1] - X[0]) * (Y[2] - Y[0]) - (X[2] - X[0]) * (Y[1] - Y[0])
    keep = area != 0
    if cull == "back":
        keep &= area > 0
    elif cull == "front":
        keep &= area < 0
    elif cull == "auto":     # per input triangle: flat.x bit 2, drawn with its back faces
        inside = (np.take(np.asarray(flat, np.uint32)[:, 0], parent) >> 2) & 1
        keep &= np.where(inside == 1, area < 0, area > 0)
    # bounding boxes: pixels with a sample position (the centre, 128/256, when ``samples`` is
    # 1; any of 1..255/256 otherwise) inside the box.  Clipping makes slivers along the
    # viewport edges that cover samples but no pixel centre.  (>> 8: floor division by
    # SUBPIXEL)
    lo, hi = (SUBPIXEL // 2, SUBPIXEL // 2) if samples == 1 else (SUBPIXEL - 1, 1)
    x0 = -((lo - np.minimum(np.minimum(X[0], X[1]), X[2])) >> 8)
    x1 = (np.maximum(np.maximum(X[0], X[1]), X[2]) - hi) >> 8
    y0 = -((lo - np.minimum(np.minimum(Y[0], Y[1]), Y[2])) >> 8)
    y1 = (np.maximum(np.maximum(Y[0], Y[1]), Y[2]) - hi) >> 8
    if scissor is not None:
        s = np.take(np.asarray(scissor, np.int64), parent, axis=0)
        sc = np.stack([np.maximum(s[:, 0], 0), np.maximum(s[:, 1], 0),
                       np.minimum(s[:, 2], W), np.minimum(s[:, 3], H)], axis=1)
        np.maximum(x0, sc[:, 0], out=x0)
        np.maximum(y0, sc[:, 1], out=y0)
        np.minimum(x1, sc[:, 2] - 1, out=x1)
        np.minimum(y1, sc[:, 3] - 1, out=y1)
    else:
        sc = None
        np.maximum(x0, 0, out=x0)
        np.maximum(y0, 0, out=y0)
        np.minimum(x1, W - 1, out=x1)
        np.minimum(y1, H - 1, out=y1)
    keep &= (x0 <= x1) & (y0 <= y1)
    if samples in SAMPLE_POSITIONS:
        small = np.flatnonzero(keep & ((x1 - x0 + 1) * (y1 - y0 + 1) <= SMALL_BOX))
        if len(small):
            keep[small] = covers_a_sample(X[:, small], Y[:, small], area[small], x0[small],
                                          y0[small], x1[small], y1[small], samples)
    if not keep.all():
        idx = np.flatnonzero(keep)
        X, Y, xw, yw, vid = (np.take(v, idx, axis=1) for v in (X, Y, xw, yw, vid))
        area, parent, x0, y0, x1, y1 = (np.take(v, idx) for v in (area, parent, x0, y0, x1, y1))
        if sc is not None:
            sc = np.take(sc, idx, axis=0)
    n = len(area)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        iw = np.take(oow, vid)
        pz = np.take(cols[2], vid) * iw
        zw = fma32(pz, scale[2], trans[2])
        if len(oow) > n_orig:          # clipper-made vertices: rounded step by step
            made = vid >= n_orig
            zw[made] = pz[made] * scale[2] + trans[2]
    s = np.sign(area)
    tri_a = np.empty((n, 4), np.int32)
    tri_b = np.zeros((n, 4), np.int32)
    tri_c = np.zeros((n, 4), np.int64)
    bits = np.zeros(n, np.uint8)
    A, B, t = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.int64)
    flag, f2 = np.empty(n, bool), np.empty(n, bool)
    # edge k opposite vertex k, from vertex i1 = k+1 to i2 = k+2 (mod 3): A = -(Y2 - Y1) s,
    # B = (X2 - X1) s, C = -(A X1 + B Y1) (in place; int64 wraps the same either way)
    for k, (i1, i2) in enumerate(((1, 2), (2, 0), (0, 1))):
        np.multiply(np.subtract(Y[i1], Y[i2], out=A), s, out=A)
        np.multiply(np.subtract(X[i2], X[i1], out=B), s, out=B)
        tri_a[:, k] = A
        tri_b[:, k] = B
        np.multiply(A, X[i1], out=t)
        t += np.multiply(B, Y[i1], out=tri_c[:, k])
        np.negative(t, out=tri_c[:, k])
        # inclusive edge: A > 0, or A == 0 and B > 0
        np.greater(A, 0, out=flag)
        flag |= np.logical_and(np.equal(A, 0, out=f2), np.greater(B, 0), out=f2)
        bits |= flag.view(np.uint8) << np.uint8(k)
    tri_a[:, 3] = bits
    edges = _Edges(xw, yw, area)
    # 1/w plane (linear) and the smooth varyings' planes premultiplied by 1/w (perspective),
    # set up together: (1 + 4K, 3, n) attributes, 1/w first, gathered straight in llvmpipe's
    # vertex order (the values _Edges.order would pick)
    tri_w = np.zeros((n, 4), np.float32)
    S = 0 if vary_v is None else vary_v.shape[0]
    smooth = list(range(S)) if smooth is None else [int(k) for k in smooth]
    K = len(smooth)
    tri_coef = np.zeros((n, K, 3, 4), np.float32)
    if (smooth or w_plane) and n:
        sw = edges.swap
        # channel-major: numpy's inner loops then run over the triangles, not over 1 + 4K
        # channels (the same elementwise arithmetic as _Edges.planes, several times faster)
        attrs = np.empty((1 + 4 * K, 3, n), f32)
        iwl = attrs[0]
        iwl[0], iwl[1], iwl[2] = np.where(sw, iw[1], iw[0]), np.where(sw, iw[0], iw[1]), iw[2]
        if smooth:
            vidl = np.stack([np.where(sw, vid[1], vid[0]), np.where(sw, vid[0], vid[1]),
                             vid[2]])
            vary32 = np.asarray(vary_v, np.float32)
            with np.errstate(invalid="ignore", over="ignore", under="ignore"):
                for j, slot in enumerate(smooth):
                    np.multiply(np.take(vary32[slot], vidl, axis=0).transpose(2, 0, 1), iwl,
                                out=attrs[1 + 4 * j:5 + 4 * j])
        planes = edges.planes_cm(attrs[:, 0], attrs[:, 1], attrs[:, 2], pixel_center)
        for r, plane in enumerate(planes):                       # 3 x (1 + 4K, n)
            tri_w[:, r] = plane[0]
            if smooth:
                tri_coef[:, :, r, :] = plane[1:].reshape(K, 4, n).transpose(2, 0, 1)
    # window z: llvmpipe's float32 plane (a0 at the window origin, see depth_plane)
    za0, zdx, zdy, offset, a0_ms = edges.depth(zw, polygon_offset, depth_format,
                                               ms_a0=with_zq)
    tri_z = np.empty((n, 4), np.float32)
    tri_z[:, 0], tri_z[:, 1], tri_z[:, 2], tri_z[:, 3] = za0, zdx, zdy, offset
    # zp: the exact plane in float64 (x0, y0, z0 + offset, dz/dx; for reference and tests);
    # zq: dz/dy, the polygon offset, and a0 with pixel centre 0 (multisampling; read by the
    # raster kernel only when PG_SAMPLES > 1)
    tri_zp, tri_zq = _exact_z_planes(xw, yw, zw, offset, a0_ms, with_zp, with_zq)
    if flat is not None:
        tri_flat = np.take(np.asarray(flat, np.uint32), parent, axis=0)
    else:
        tri_flat = np.zeros((n, 4), np.uint32)
    inside = (tri_flat[:, 0] >> 2) & 1 if cull == "auto" else 0
    tri_flat[:, 0] = area > 0
    tri_flat[:, 0] |= inside << 1       # cull auto: a back-face light's triangle (pg_inside)
    tri_vtx = np.zeros((n, 4), np.int32)
    tri_vtx[:, :3] = vid.T
    tri_sc = np.empty((n, 4), np.int32)
    if sc is None:
        tri_sc[:] = (0, 0, W, H)
    else:
        tri_sc[:] = sc
    bbox = np.empty((n, 4), np.int32)
    bbox[:, 0], bbox[:, 1], bbox[:, 2], bbox[:, 3] = x0, y0, x1, y1
    return Triangles(tri_a, tri_b, tri_c, tri_z, tri_w, tri_coef, tri_zp, tri_zq, tri_flat,
                     tri_vtx, tri_sc, bbox, vary_v, len(clip_v), samples,
                     np.asarray(parent, np.int64))


def edge_test_lists(edge_test_tiles: int, tile: int, tile_h: int) -> int:
    """How many of a box's lists (``tile`` wide, ``tile_h`` tall) make binning test each
    against the triangle's edges: ``edge_test_tiles`` tiles' worth.  A small triangle's box
    rarely holds a band its edges miss, and testing every band of a box over four rows cost a
    quarter of binning deferred's light volumes at 160x90 in lists a row tall
    (0.39 -> 0.29 ms)."""
    return edge_test_tiles * max(1, tile // tile_h)


def bin_pairs(tris: Triangles, width: int, height: int, tile: int = 16,
              edge_test_tiles: int = 4, subset: Optional[np.ndarray] = None,
              tile_h: Optional[int] = None):
    """The (triangle, tile) pairs of binning, in triangle order: (tri (M,) int64 indices
    into ``tris``, tile_id (M,) int64, tiles_x, tiles_y).  A triangle reaches the tiles its
    bounding box covers; when that is more than ``edge_test_tiles`` tiles' worth
    (``edge_test_lists``), only those where
    no edge function is negative at all four corners.  ``subset``: only these triangles
    (increasing indices).  ``tile_h``: the tiles' height in rows where it is not ``tile``
    (a band of a tile's rows: ``geometry``'s ``band``)."""
    th = tile if tile_h is None else tile_h
    tx_n = (width + tile - 1) // tile
    ty_n = (height + th - 1) // th
    idx = None if subset is None else np.asarray(subset, np.int64)
    n = tris.count if idx is None else len(idx)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), tx_n, ty_n
    bb = (tris.bbox if idx is None else tris.bbox[idx]).astype(np.int64)
    tx0, ty0 = bb[:, 0] // tile, bb[:, 1] // th
    tx1, ty1 = bb[:, 2] // tile, bb[:, 3] // th
    wx = tx1 - tx0 + 1
    counts = wx * (ty1 - ty0 + 1)
    total = int(counts.sum())
    if total == n:                        # every box in one tile (common for small triangles)
        rep = np.arange(n, dtype=np.int64)
        tx, ty = tx0, ty0
    else:
        # each box's tile rows, then each row's tiles (row-major per triangle); two repeats
        # instead of dividing every pair's offset by its box width
        def runs(lengths):      # (run index, position within the run) of consecutive runs
            m = int(lengths.sum())
            run = np.repeat(np.arange(len(lengths), dtype=np.int64), lengths)
            return run, np.arange(m, dtype=np.int64) - np.repeat(np.cumsum(lengths) - lengths,
                                                                 lengths)
        row_tri, dy = runs(ty1 - ty0 + 1)
        row_of, dx = runs(wx[row_tri])
        rep = row_tri[row_of]
        tx = tx0[rep] + dx
        ty = (ty0[row_tri] + dy)[row_of]
        big = counts[rep] > edge_test_lists(edge_test_tiles, tile, th)
        if big.any():
            sel = np.flatnonzero(big)
            t = rep[sel] if idx is None else idx[rep[sel]]
            # the tile corner that maximises each edge function (pixel-centre positions with
            # one sample, else the extreme sample positions any pattern could use)
            lo, hi = (SUBPIXEL // 2, SUBPIXEL // 2) if tris.samples == 1 else (1, SUBPIXEL - 1)
            xa = (tx[sel] * tile) * SUBPIXEL + lo
            xb = (np.minimum(tx[sel] * tile + tile, width) - 1) * SUBPIXEL + hi
            ya = (ty[sel] * th) * SUBPIXEL + lo
            yb = (np.minimum(ty[sel] * th + th, height) - 1) * SUBPIXEL + hi
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
    return (rep if idx is None else idx[rep]), ty * tx_n + tx, tx_n, ty_n


def bins_from_pairs(tri: np.ndarray, tile_id: np.ndarray, ntiles: int):
    """CSR tile lists (tile_start (ntiles+1,) int32, tile_tris (M,) int32) from (triangle,
    tile) pairs in triangle order: per tile, its triangles in submission order."""
    # stable sort by tile; on 16-bit keys numpy's stable sort is a radix sort
    key = tile_id.astype(np.uint16) if ntiles <= 1 << 16 else tile_id
    order = np.argsort(key, kind="stable")
    tile_tris = tri[order].astype(np.int32)
    tile_start = np.zeros(ntiles + 1, np.int32)
    np.cumsum(np.bincount(tile_id, minlength=ntiles), out=tile_start[1:])
    if len(tile_tris) == 0:
        tile_tris = np.zeros(1, np.int32)
    return tile_start, tile_tris


def bin_triangles(tris: Triangles, width: int, height: int, tile: int = 16,
                  edge_test_tiles: int = 4, subset: Optional[np.ndarray] = None,
                  tile_h: Optional[int] = None):
    """Per-tile triangle lists in submission order: (tile_start (ntiles+1,) int32,
    tile_tris (M,) int32, tiles_x, tiles_y).  Triangles whose bounding box spans more than
    ``edge_test_tiles`` tiles are additionally tested per tile against their edge functions
    (a tile is skipped when one edge is negative at all four corners).  ``subset``: bin only
    these triangles (indices into ``tris``, increasing); ``tile_tris`` still holds indices into
    ``tris``.  ``tile_h``: the tiles' height (default ``tile``)."""
    tri, tile_id, tx_n, ty_n = bin_pairs(tris, width, height, tile, edge_test_tiles, subset,
                                         tile_h)
    tile_start, tile_tris = bins_from_pairs(tri, tile_id, tx_n * ty_n)
    return tile_start, tile_tris, tx_n, ty_n
