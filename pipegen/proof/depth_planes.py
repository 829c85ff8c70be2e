"""The error of a depth attachment's float32 plane, per pixel: a term of the float64 bound.

llvmpipe sets a triangle's window-depth plane up in float32 (``calc_coef4``: ``dz/dx`` and
``dz/dy`` as differences of products, ``a0`` at the window origin) and evaluates it at each
pixel; the CL backend does the same, bit for bit (``runtime/cl/setup.py``).  For most triangles
that plane is within a code of the exact plane through the same float32 vertices, which the
constant 2 d24 codes of ``tolerance.store_error`` allow.  For a long, thin triangle the two
products nearly cancel, a coefficient is off by a fraction of a percent, and the error grows
with the distance from the plane's origin: 18 codes on street_lamps' road (docs/tolerances.md).

``plane_error(draws, values)`` is, per pixel of a depth target, the difference
between the float32 plane and the exact plane of the triangle that drew the pixel, both taken
from the float64 evaluation's own set-up (``CLPipeline.depth_draws``: the float32 set-up of
the same vertices, with ``zp``/``zq``, the exact planes through them).  The triangle that drew
a pixel is the covering one whose exact plane is nearest the float64 evaluation's depth there
(a triangle hidden behind it is farther).  Where the vertices themselves are off (the float32
vertex transform), the position term of the bound answers; this term is the set-up's alone.
"""

from __future__ import annotations

import numpy as np

from pipegen.backends.opencl.abi import SUBPIXEL
from pipegen.runtime.cl.setup import fma32     # correctly rounded, as the kernels' fma

F32 = np.float32


def triangle_errors(tris, index, xs: np.ndarray, ys: np.ndarray, centre: float = 0.5) -> tuple:
    """(exact depth, |float32 plane - exact plane|) of triangle ``index`` (one, or an array
    of them matching ``xs``) at integer pixels ``xs``, ``ys`` (window coordinates), where
    the float32 plane is evaluated: its a0 holds the pixel ``centre`` (0.5; 0 in a
    multisampled pass, which evaluates the plane at the pixel's corner plus each sample's
    offset: the error there is the corner's, within the plane error's change over half a
    pixel)."""
    z = np.asarray(tris.z, F32)[index]
    a0, dadx, dady, offset = (z[..., c] for c in range(4))
    z32 = fma32(dady, ys.astype(F32), fma32(dadx, xs.astype(F32), a0))
    z32 = np.where(offset != 0, (z32 + offset).astype(F32), z32)
    zp, zq = np.asarray(tris.zp)[index], np.asarray(tris.zq)[index]
    exact = zp[..., 2] + zp[..., 3] * (xs + centre - zp[..., 0]) \
        + zq[..., 0] * (ys + centre - zp[..., 1])
    return exact, np.abs(z32.astype(np.float64) - exact)


def _covered(tris, index, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Pixel centres inside triangle ``index`` (one, or an array matching ``xs``) or on its
    edges (the edge functions in 1/SUBPIXEL units, positive inside: a superset of what the
    top-left rule keeps)."""
    X = xs.astype(np.int64) * SUBPIXEL + SUBPIXEL // 2
    Y = ys.astype(np.int64) * SUBPIXEL + SUBPIXEL // 2
    a, b, c = (np.asarray(m, np.int64) for m in (tris.a, tris.b, tris.c))
    inside = np.ones(np.shape(xs), bool)
    for k in range(3):       # column by column: gathering whole rows costs 3x more
        e = a[:, k][index] * X
        e += b[:, k][index] * Y
        e += c[:, k][index]
        inside &= e >= 0
    return inside


CHUNK = 1 << 20      # pixels of triangle boxes handled at once


def plane_error(draws: list, values: np.ndarray) -> np.ndarray:
    """Per pixel of a depth target (``values``: the float64 evaluation's window depth, (H, W),
    GL row order), the float32 plane error of the triangle that drew it, in window-depth
    units (0 where no triangle of ``draws`` covers the pixel).  ``draws``: the set-up
    ``(Triangles, centre)`` of every pass execution that wrote the target (with ``zp``,
    ``zq``; ``centre``: the pixel centre their planes hold, ``triangle_errors``).  The
    triangles' boxes are walked a million pixels at a time, all of a chunk's at once."""
    values = np.asarray(values, np.float64)
    h, w = values.shape
    term = np.zeros(h * w)
    nearest = np.full(h * w, np.inf)        # |exact plane - float64 depth| of the one chosen
    for tris, centre in draws:
        if tris.zp is None or tris.zq is None or not tris.count:
            continue
        box = np.asarray(tris.bbox, np.int64)
        x0, y0 = np.maximum(box[:, 0], 0), np.maximum(box[:, 1], 0)
        bw = np.maximum(np.minimum(box[:, 2], w - 1) - x0 + 1, 0)
        bh = np.maximum(np.minimum(box[:, 3], h - 1) - y0 + 1, 0)
        area = bw * bh
        ends = np.cumsum(area)
        first = 0
        while first < tris.count:
            # the next triangles whose boxes hold up to CHUNK pixels (at least one triangle)
            base = ends[first] - area[first]
            last = max(int(np.searchsorted(ends, base + CHUNK, side="right")), first + 1)
            idx = np.arange(first, last)
            n = area[idx]
            tri = np.repeat(idx, n)
            off = np.arange(int(n.sum())) - np.repeat(ends[idx] - n - base, n)
            xs = x0[tri] + off % np.maximum(bw[tri], 1)
            ys = y0[tri] + off // np.maximum(bw[tri], 1)
            keep = _covered(tris, tri, xs, ys)
            tri, xs, ys = tri[keep], xs[keep], ys[keep]
            exact, err = triangle_errors(tris, tri, xs, ys, centre)
            pix = ys * w + xs
            dist = np.abs(exact - values.ravel()[pix])
            # per pixel, the chunk's nearest triangle, then against those before
            order = np.lexsort((dist, pix))
            pix, dist, err = pix[order], dist[order], err[order]
            head = np.ones(len(pix), bool)
            head[1:] = pix[1:] != pix[:-1]
            pix, dist, err = pix[head], dist[head], err[head]
            take = dist < nearest[pix]
            nearest[pix[take]] = dist[take]
            term[pix[take]] = err[take]
            first = last
    return term.reshape(h, w)
