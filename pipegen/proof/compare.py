"""Compare one target rendered by two backends, with tolerances from ``formats.py``.

Errors are measured in the format's own units: integer code distance for fixed-point, integer
and depth-stencil formats, ulps for float formats (after flushing denormals; NaN matches only
NaN, infinities only themselves).  A pixel over tolerance whose value is matched by some pixel
of the other image in its 3x3 neighbourhood (and vice versa) is taken as a coverage difference
on a primitive edge, if it sits next to a discontinuity: admitted, counted, and bounded.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Union

import numpy as np

from pipegen.core.formats import Format, Tolerance, flush_denormals

# Edge pixels admitted before a comparison fails: a fraction of the image, at least a few.
EDGE_FRACTION = 0.005
EDGE_MIN = 4


@dataclass
class TargetComparison:
    name: str
    format: Format
    tolerance: Tolerance
    max_error: float          # in tolerance.units (codes / ulp / differing values)
    rmse: float               # in the same units
    over: int                 # pixels over tolerance and not admitted as edges
    edge_admitted: int
    edge_bound: int
    error_map: np.ndarray     # (H, W) float: per-pixel error in units (for the error PNG)
    limit_map: Optional[np.ndarray] = None   # (H, W) per-pixel limit (per-pixel P), else None
    over_mask: Optional[np.ndarray] = None   # (H, W) the pixels counted in ``over``
    discontinuities: list = field(default_factory=list)   # discontinuity.Discontinuity
    discontinuity_mask: Optional[np.ndarray] = None       # (H, W) their pixels

    @property
    def passed(self) -> bool:
        """Within tolerance away from coverage edges; discontinuities are counted apart
        (``discontinuity_count``), their tolerance is the caller's."""
        return self.over == 0 and self.edge_admitted <= self.edge_bound

    @property
    def discontinuity_count(self) -> int:
        return sum(d.count for d in self.discontinuities)

    def worst_pixel(self) -> tuple[int, int]:
        """(x, y), y from the top: the pixel counted in ``over`` (else anywhere) with the
        largest error over its limit."""
        limit = self.tolerance.limit if self.limit_map is None else self.limit_map
        score = self.error_map - limit
        if self.over_mask is not None and self.over_mask.any():
            score = np.where(self.over_mask, score, -np.inf)
        y, x = np.unravel_index(int(np.argmax(score)), score.shape)
        return int(x), int(score.shape[0] - 1 - y)

    def row(self) -> tuple[str, ...]:
        units = {"code": "codes", "ulp": "ulp", "exact": "exact"}[self.tolerance.units]
        limit = f"≤{self.tolerance.limit}"
        if self.limit_map is not None and self.limit_map.size:
            lo, hi = int(self.limit_map.min()), int(self.limit_map.max())
            limit = f"≤{lo}..{hi}" if lo != hi else f"≤{hi}"
        return (self.name, self.format.name, f"{_num(self.max_error)} {units}",
                f"{self.rmse:.3g}", limit, str(self.over),
                f"{self.edge_admitted}/{self.edge_bound}", str(self.discontinuity_count),
                "ok" if self.passed else "FAIL")


def compare_target(name: str, fmt: Format, a: np.ndarray, b: np.ndarray,
                   blended_passes: Union[int, np.ndarray] = 0,
                   tolerance: Tolerance | None = None,
                   stencil: bool = False, exact_channels: tuple[bool, ...] = (),
                   exclude: Optional[np.ndarray] = None) -> TargetComparison:
    """Compare codes ``a`` and ``b`` (same shape) of target ``name`` in format ``fmt``.

    ``blended_passes``: P of docs/tolerances.md, one number for the whole target or an (H, W)
    array of per-pixel counts (how many fragments were blended into each pixel); each pixel
    is then held to ``fmt.tolerance(P[y, x])`` (the reported tolerance is the largest).
    ``exact_channels`` flags channels that must match exactly (packed integers sharing a
    target with ordinary values): any difference there counts as over tolerance.
    ``exclude``: (H, W) pixels not counted (the discontinuities found among those over).
    """
    assert a.shape == b.shape, (name, a.shape, b.shape)
    p = np.asarray(blended_passes)
    limit_map = None
    if p.ndim:
        assert p.shape == a.shape[:2], (name, p.shape, a.shape)
        values = np.unique(p.astype(np.int64)) if p.size else np.zeros(1, np.int64)
        tol = tolerance or (Tolerance("exact", 0) if stencil else fmt.tolerance(int(values[-1])))
        if tolerance is None and not stencil:
            limits = np.array([fmt.tolerance(int(v)).limit for v in values])
            limit_map = limits[np.searchsorted(values, p.astype(np.int64))]
    else:
        tol = tolerance or (Tolerance("exact", 0) if stencil else fmt.tolerance(int(p)))
    limit = tol.limit if limit_map is None else limit_map
    err = channel_error(a, b, tol)
    if any(exact_channels) and err.ndim == 3:
        exact = np.array(exact_channels + (False,) * (err.shape[2] - len(exact_channels)))
        over = (limit if limit_map is None else limit_map[..., None]) + 1
        err[..., exact] = np.where(err[..., exact] > 0, np.maximum(err[..., exact], over), 0.0)
    per_pixel = err.max(axis=-1) if err.ndim == 3 else err
    bad = per_pixel > limit
    if exclude is not None:
        bad &= ~exclude
    admitted = np.zeros_like(bad)
    if bad.any():          # the neighbourhood tests decide only for pixels over tolerance
        on_edge = _discontinuity(a, tol, limit) | _discontinuity(b, tol, limit)
        admitted = bad & on_edge & _neighbourhood_match(a, b, tol, limit) \
            & _neighbourhood_match(b, a, tol, limit)
    finite = per_pixel[np.isfinite(per_pixel)]
    rmse = float(np.sqrt(np.mean(finite.astype(np.float64) ** 2))) if finite.size else 0.0
    bound = max(EDGE_MIN, int(EDGE_FRACTION * per_pixel.size))
    counted = per_pixel if exclude is None else np.where(exclude, 0.0, per_pixel)
    return TargetComparison(name, fmt, tol, float(counted.max()) if counted.size else 0.0,
                            rmse, int((bad & ~admitted).sum()), int(admitted.sum()), bound,
                            per_pixel.astype(np.float64), limit_map, bad & ~admitted)


def channel_error(a: np.ndarray, b: np.ndarray, tol: Tolerance) -> np.ndarray:
    """Per-channel error in the tolerance's units (inf where NaN meets a number)."""
    if tol.units == "ulp":
        return ulp_distance(a, b, tol.abs_floor)
    if tol.units == "exact":
        return (a != b).astype(np.float64)
    return np.abs(a.astype(np.int64) - b.astype(np.int64)).astype(np.float64)


def ulp_distance(a: np.ndarray, b: np.ndarray, abs_floor: float = 0.0) -> np.ndarray:
    a, b = flush_denormals(a), flush_denormals(b)
    int_t = {2: np.int16, 4: np.int32}[a.dtype.itemsize]
    ia = _ordered(np.ascontiguousarray(a).view(int_t))
    ib = _ordered(np.ascontiguousarray(b).view(int_t))
    d = np.abs(ia - ib).astype(np.float64)
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    d[nan_a & nan_b] = 0.0
    d[nan_a ^ nan_b] = np.inf
    with np.errstate(invalid="ignore"):
        close = np.abs(a.astype(np.float64) - b.astype(np.float64)) <= abs_floor
    d[close & ~(nan_a | nan_b)] = 0.0
    return d


def _ordered(i: np.ndarray) -> np.ndarray:
    """Map IEEE bit patterns (viewed as signed ints) to integers that order like the floats;
    -0 and +0 both map to 0."""
    magnitude_mask = np.int64((1 << (8 * i.dtype.itemsize - 1)) - 1)
    wide = i.astype(np.int64)
    return np.where(wide < 0, -(wide & magnitude_mask), wide)


def _discontinuity(a: np.ndarray, tol: Tolerance, limit=None) -> np.ndarray:
    """Pixels next to a jump in value much larger than the tolerance: where primitive edges
    are.  In smooth regions (gradients) no pixel qualifies, so a value that is off there
    cannot hide behind a similar neighbour.  ``limit``: the tolerance's limit, or a per-pixel
    (H, W) array of limits."""
    jump = _neighbourhood_extreme(a, a, tol)
    return jump > 4 * ((tol.limit if limit is None else limit) + 1)


def _neighbourhood_extreme(a: np.ndarray, b: np.ndarray, tol: Tolerance) -> np.ndarray:
    h, w = a.shape[:2]
    pad = [(1, 1), (1, 1)] + [(0, 0)] * (b.ndim - 2)
    bp = np.pad(b, pad, mode="edge")
    worst = np.zeros((h, w))
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            e = channel_error(a, bp[1 + dy:1 + dy + h, 1 + dx:1 + dx + w], tol)
            worst = np.maximum(worst, e.max(axis=-1) if e.ndim == 3 else e)
    return worst


def _neighbourhood_match(a: np.ndarray, b: np.ndarray, tol: Tolerance, limit=None
                         ) -> np.ndarray:
    """For each pixel: does a's value match b's value at some pixel of the 3x3 neighbourhood?
    (within ``limit``: the tolerance's, or a per-pixel (H, W) array)"""
    limit = tol.limit if limit is None else limit
    h, w = a.shape[:2]
    pad = [(1, 1), (1, 1)] + [(0, 0)] * (b.ndim - 2)
    bp = np.pad(b, pad, mode="edge")
    match = np.zeros((h, w), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted = bp[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            e = channel_error(a, shifted, tol)
            e = e.max(axis=-1) if e.ndim == 3 else e
            match |= e <= limit
    return match


def _num(x: float) -> str:
    if not np.isfinite(x):
        return "inf"
    return f"{x:.0f}" if float(x).is_integer() else f"{x:.3g}"
