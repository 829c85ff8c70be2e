"""The measurement of the normal encodings' angular error (docs/encodings.md): encode, store in
a format, decode, compared with the input over a Fibonacci grid, the encodings' hard spots and
a local search around the worst normals (``measure_normal_error``), reproducible bit for bit
on every machine.  ``error_tables.NORMAL_ERRORS`` holds its results; ``normal_error_figures``
and ``normal_error`` read them, measuring only what the table lacks."""

from __future__ import annotations

import functools
import math
from typing import Callable, Optional

from pipegen.core import formats
from pipegen.core.formats import Format
from pipegen.core.records import record
from pipegen.packing.error_tables import NORMAL_ERRORS, normal_storage, round_significant
from pipegen.packing.schemes import numpy_impl


# ---- the normals measured, and their angles: the same bits on every machine -----------------


def _libm(fn: Callable[[float], float], x) -> np.ndarray:
    """``fn`` (a ``math`` function) applied to every element of ``x`` (float64 array).

    The measured tables must come out the same on every machine of a kind: numpy's own
    sin/cos/log are SIMD kernels chosen by CPU features and rewritten between numpy versions,
    so their last bits differ (tests/test_packing_exhaustive.py, docs/internals.md); Python's
    ``math`` calls the C library's, one per system image."""
    import numpy as np
    x = np.asarray(x, np.float64)
    return np.fromiter(map(fn, x.ravel().tolist()), np.float64, x.size).reshape(x.shape)


def fibonacci_sphere(count: int, hemisphere: bool = False) -> np.ndarray:
    """``count`` nearly evenly spread unit vectors (float64), on z >= 0 if ``hemisphere``
    (the same bits on every machine: correctly rounded arithmetic and libm's cos/sin)."""
    import numpy as np
    i = np.arange(count, dtype=np.float64) + 0.5
    z = 1.0 - i / count if hemisphere else 1.0 - 2.0 * i / count
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = i * (math.pi * (3.0 - math.sqrt(5.0)))
    return np.stack([r * _libm(math.cos, phi), r * _libm(math.sin, phi), z], axis=-1)


def _unit_rows(p: np.ndarray) -> np.ndarray:
    """Rows of ``p`` (..., 3) scaled to unit length, in correctly rounded operations only (a
    fixed order, no reduction kernel): the same bits on every machine."""
    import numpy as np
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    return p / np.sqrt(x * x + y * y + z * z)[..., None]


def special_normals(hemisphere: bool) -> np.ndarray:
    """The hard spots of the normal encodings, added to the Fibonacci grid.

    Both domains: the axes, the equator's diagonals, (1,1,1)-style octant centres.  Whole
    sphere: (0,0,-1) (the singular point of Kircher and spheremap) and the normals around it
    down to 1e-5 degrees, on rings (the error of spheremap peaks at a distance from -z that
    depends on the format's step, too close to the pole for an even grid to find), and both
    sides of the octahedral seams (x = 0 or y = 0 below the equator, which map to the edges of
    the square) at offsets 1e-7 .. 1e-2."""
    import numpy as np
    pts = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (1, 1, 0), (-1, 1, 0),
           (1, -1, 0), (-1, -1, 0), (1, 1, 1), (-1, -1, 1), (1e-7, 0, 1), (1, 1e-7, 1e-7)]
    if not hemisphere:
        pts += [(0, 0, -1), (1, 1, -1), (-1, 1, -1), (1e-6, 0, -1), (0, -1e-6, -1),
                (0, 1, -1), (0, -1, -1), (1, 0, -1), (-1, 0, -1), (-1e-7, 1, -1), (1e-7, 1, -1)]
    p = _unit_rows(np.array(pts, dtype=np.float64))
    if hemisphere:
        return p
    golden = math.pi * (3.0 - math.sqrt(5.0))
    lo, hi = math.log(1e-5), math.log(30.0)                  # 2000 radii, 1e-5 .. 30 degrees
    t = _libm(math.radians, _libm(math.exp, lo + np.arange(2000) * ((hi - lo) / 1999)))
    t = t[:, None]
    a = (np.arange(256)[None, :] * (2 * math.pi / 256) + np.arange(2000)[:, None] * golden)
    sin_t, cos_a, sin_a = _libm(math.sin, t), _libm(math.cos, a), _libm(math.sin, a)
    ring = np.stack([sin_t * cos_a, sin_t * sin_a,
                     np.broadcast_to(-_libm(math.cos, t), a.shape)], -1).reshape(-1, 3)
    # Octahedral seams: the great half-circles x = 0 and y = 0 below the equator, nudged off
    # them to both sides.
    u = np.linspace(-math.pi / 2, math.pi / 2, 1001)[:, None]          # along the seam
    off = np.array([0.0, 1e-7, -1e-7, 1e-5, -1e-5, 1e-3, -1e-3, 1e-2, -1e-2])[None, :]
    s, c = np.broadcast_arrays(_libm(math.sin, u), -_libm(math.cos, u))  # z = -cos(u) <= 0
    along = np.broadcast_to(s, (1001, off.shape[1]))
    down = np.broadcast_to(c, (1001, off.shape[1]))
    side = np.broadcast_to(off, (1001, off.shape[1]))
    seams = np.concatenate([np.stack([side, along, down], -1).reshape(-1, 3),
                            np.stack([along, side, down], -1).reshape(-1, 3)])
    return np.concatenate([p, ring, _unit_rows(seams)])


def angular_error_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between vectors (need not be unit), in degrees; exact near 0 (atan2 form)."""
    import numpy as np
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1),
                                 np.sum(a * b, axis=-1)))


def _chord_sq(n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """|n - d/|d||^2 for unit ``n`` (float64): the squared chord between ``n`` and the
    direction of ``d``, increasing with their angle.  Correctly rounded operations in a fixed
    order only, so every machine gets the same bits: the measurement's search decides on it."""
    import numpy as np
    d = np.asarray(d, np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    inv = 1.0 / np.sqrt(x * x + y * y + z * z)
    dx, dy, dz = n[..., 0] - x * inv, n[..., 1] - y * inv, n[..., 2] - z * inv
    return dx * dx + dy * dy + dz * dz


def _chord_to_deg(c2: np.ndarray) -> np.ndarray:
    """The angle (degrees) of a squared chord: 2 asin(|chord| / 2), as accurate near 0 and
    exact to float64 rounding up to 180 degrees."""
    import numpy as np
    return np.degrees(2.0 * np.arcsin(np.minimum(np.sqrt(c2) * 0.5, 1.0)))


# ---- measured error of the normal encodings --------------------------------------------------

NORMAL_GRID = 1 << 20            # Fibonacci normals per domain (whole sphere or hemisphere)
_REFINE_WORST, _REFINE_ROUNDS, _REFINE_CANDIDATES = 48, 14, 192
NORMAL_SEED = 20140417           # the local search's random steps (the table's measurement)


@record(frozen=True)
class NormalError:
    """Angular error (degrees) of encode → store in ``storage`` → decode over one domain."""
    scheme: str
    storage: str
    domain: str                  # "sphere" or "hemisphere" (z >= 0)
    max: float                   # over the grid, the hard spots and the local search
    mean: float                  # over the (equal-area) Fibonacci grid only
    worst: tuple[float, float, float]   # the normal where the maximum was found
    points: int                  # normals evaluated (grid + hard spots + search)


@functools.lru_cache(maxsize=4)
def normal_grid(hemisphere: bool, samples: int) -> np.ndarray:
    """The normals a measurement starts from: ``samples`` Fibonacci points, then the hard
    spots (``special_normals``)."""
    import numpy as np
    return np.concatenate([fibonacci_sphere(samples, hemisphere), special_normals(hemisphere)])


def _store_normals(e: np.ndarray, fmt: Format) -> np.ndarray:
    """What a shader reads back after writing encoded normals ``e`` (..., 2) into ``fmt``."""
    import numpy as np
    F32 = np.float32
    pad = np.zeros(e.shape[:-1] + (fmt.channels,), np.float32)
    pad[..., :2] = e
    return fmt.dequantize(fmt.quantize(pad))[..., :2].astype(F32)


@functools.lru_cache(maxsize=None)
def measure_normal_error(scheme: str, storage: str, hemisphere: bool,
                         samples: int = NORMAL_GRID, seed: int = NORMAL_SEED) -> NormalError:
    """Measure the angular error of encode → quantise to ``storage`` → decode (the float32
    arithmetic of the mirrors, the stores of ``formats``), in degrees.

    The normals: ``samples`` Fibonacci points on the domain, the hard spots of
    ``special_normals`` and a deterministic local search: from each of the 48 worst
    normals (on the whole sphere, one of them replaced by the hemisphere's worst), 14 rounds
    of 192 random steps with a radius that starts at twice the grid spacing and shrinks by 0.6
    per round, keeping the worst.  The maximum is a lower bound of the supremum; the search
    adds up to ~3 % to the grid's maximum (it finishes the climb into the worst quantisation
    cell).  Where it ends depends on its path: six other seeds find maxima within 0.6 % of
    the table's for every storage but rg32f, whose errors (~3e-5 degrees) are float32 rounding
    noise with many near-equal peaks (-9 % .. +5 %; ``python benchmarks/encoding_errors.py
    --path-spread 6``); fresh random normals stay below it
    (tests/test_packing_exhaustive.py).  The mean is over the Fibonacci points alone (they
    are equal-area, so it is the mean over the domain).

    Reproducible by construction: everything that decides which normals are measured and
    which one is the worst (the grid, the mirrors, the squared chords compared, the ranking
    with ties broken by position, the random steps) is correctly rounded arithmetic, libm or
    numpy's seeded bit stream, never a numpy transcendental kernel (those differ by CPU and
    numpy version); only the conversion of chords to degrees uses one, after the search, and
    changes the figures in their last bits at most."""
    import numpy as np
    F32 = np.float32
    fmt = formats.get(storage)
    impl = numpy_impl(scheme, {})

    def chords(n):
        return _chord_sq(n, impl["decode"](_store_normals(impl["encode"](n.astype(F32)), fmt)))

    n = normal_grid(hemisphere, samples)
    err = chords(n)
    mean = float(np.mean(_chord_to_deg(err[:samples])))
    k = _REFINE_WORST
    idx = np.lexsort((np.arange(len(err)), -err))[:k]     # the k worst, ties by position
    best, best_err = n[idx].copy(), err[idx].copy()
    if not hemisphere:
        # The hemisphere is part of the sphere: start one search where its measurement found
        # its maximum, so that the sphere's figure is never below the hemisphere's.
        half = measure_normal_error(scheme, storage, True, samples, seed)
        j = int(np.argmin(best_err))
        best[j] = half.worst
        best_err[j] = chords(np.array([half.worst]))[0]
    rng = np.random.default_rng(seed)
    radius = 2.0 * math.sqrt((2 if hemisphere else 4) * math.pi / samples)
    for _ in range(_REFINE_ROUNDS):
        cand = _unit_rows(best[:, None, :] + rng.normal(size=(k, _REFINE_CANDIDATES, 3)) * radius)
        if hemisphere:
            cand[..., 2] = np.abs(cand[..., 2])
        e = chords(cand.reshape(-1, 3)).reshape(k, _REFINE_CANDIDATES)
        j = np.argmax(e, axis=1)
        top = e[np.arange(k), j]
        better = top > best_err
        best[better] = cand[np.arange(k), j][better]
        best_err[better] = top[better]
        radius *= 0.6
    i = int(np.argmax(best_err))
    worst = float(best_err[i])
    if err.max() > worst:                     # cannot happen (the search keeps the start)
        i, worst, best = int(np.argmax(err)), float(err.max()), n
    return NormalError(scheme, storage, "hemisphere" if hemisphere else "sphere",
                       math.degrees(2.0 * math.asin(min(math.sqrt(worst) * 0.5, 1.0))), mean,
                       tuple(float(x) for x in best[i]),
                       len(n) + _REFINE_ROUNDS * k * _REFINE_CANDIDATES)


def normal_error_figures(scheme: str, format_name: str,
                         hemisphere: Optional[bool] = None) -> tuple[float, float]:
    """(max, mean) angular error in degrees of ``scheme`` through ``format_name``: the
    tabulated measurement (``NORMAL_ERRORS``), measured now if the table lacks it.  The
    domain is the whole sphere, except for ``kircher`` (and when ``hemisphere`` is true): the
    hemisphere z >= 0 of camera-facing view-space normals, all Kircher's mapping is meant
    for."""
    if hemisphere is None:
        hemisphere = scheme == "kircher"
    key = (scheme, normal_storage(format_name), "hemisphere" if hemisphere else "sphere")
    if key not in NORMAL_ERRORS:
        m = measure_normal_error(key[0], key[1], hemisphere)
        return round_significant(m.max), round_significant(m.mean)
    return NORMAL_ERRORS[key]


def normal_error(scheme: str, format_name: str, samples: Optional[int] = None,
                 hemisphere: Optional[bool] = None) -> float:
    """Max angular error (degrees) of encode → quantise to ``format_name`` → decode: the
    tabulated figure (``normal_error_figures``), or with ``samples`` a fresh measurement on a
    grid of that many normals."""
    if samples is None:
        return normal_error_figures(scheme, format_name, hemisphere)[0]
    if hemisphere is None:
        hemisphere = scheme == "kircher"
    return measure_normal_error(scheme, normal_storage(format_name), bool(hemisphere),
                                samples).max
