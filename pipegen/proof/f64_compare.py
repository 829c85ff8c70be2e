"""One target of a float32 render against the technique's float64 evaluation, within the bound
of the tolerance model (``tolerance.py``, ``f64_bound.py``; docs/tolerances.md).

``compare_values`` is the one comparison ``pipegen check --precision f64``, ``pipegen stress``
and ``pipegen.testing.assert_close_to_f64`` make: per pixel the error over the bound, pixels over
it admitted as coverage differences next to a jump of the float64 image (each image's value found
in the other's 3x3 neighbourhood), the rest counted; ``discontinuity.py`` then explains what it
can of the rest as the technique's own discontinuities.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np

from pipegen.core import formats as F

EDGE_FRACTION = 0.005        # as compare.py: coverage differences admitted on edges
EDGE_MIN = 4


@dataclass
class TargetResult:
    key: str
    format: str
    backend: str
    exact: bool
    worst_ratio: float            # max error / bound over pixels not admitted as edges
    worst_error: float            # value units (exact targets: differing codes)
    bound_at_worst: float
    over: int                     # pixels over the bound, not admitted
    edges: int                    # pixels over the bound admitted as coverage differences
    edge_bound: int
    nonfinite_mismatch: int       # NaN/inf on one side only
    ratio_map: np.ndarray = field(repr=False, default=None)   # (H, W) error / bound
    output: bool = False          # the technique's output (or its depth/stencil): pass/fail;
    #                               other targets are reported (warn), not failed
    over_mask: np.ndarray = field(repr=False, default=None)   # (H, W) the pixels of ``over``
    worst_xy: tuple[int, int] = (0, 0)        # the worst pixel, (x, y) with y from the top
    worst_values: tuple = ((), ())            # (float32, float64) channels there
    discontinuities: list = field(default_factory=list)       # discontinuity.Discontinuity
    discontinuity_mask: np.ndarray = field(repr=False, default=None)   # (H, W) their pixels
    bound_map: np.ndarray = field(repr=False, default=None)   # the bound, value units

    @property
    def passed(self) -> bool:
        """Within the bound away from coverage edges; discontinuities are counted apart
        (``discontinuity_count``), their tolerance is the caller's."""
        return self.over == 0 and self.edges <= self.edge_bound and self.nonfinite_mismatch == 0

    @property
    def discontinuity_count(self) -> int:
        return sum(d.count for d in self.discontinuities)

    def units(self, value: float) -> str:
        fmt = F.get(self.format)
        if self.exact:
            return f"{value:.0f} codes"
        if fmt.is_normalized or fmt.kind is F.Kind.DEPTH_STENCIL:
            top = max(fmt.max_codes)
            return f"{value * top:.3g} codes"
        return f"{value:.3g}"


def finite_counts(values: dict, f64: bool) -> tuple[int, int]:
    nan = inf = 0
    for k, v in values.items():
        a = np.asarray(v)
        if a.dtype.kind != "f" or k.endswith(".stencil"):
            continue
        nan += int(np.isnan(a).sum())
        inf += int(np.isinf(a).sum())
    return nan, inf


def neighbour_stack(a: np.ndarray) -> np.ndarray:
    h, w = a.shape[:2]
    pad = [(1, 1), (1, 1)] + [(0, 0)] * (a.ndim - 2)
    p = np.pad(a, pad, mode="edge")
    return np.stack([p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
                     for dy in (-1, 0, 1) for dx in (-1, 0, 1)])


def error(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    """|got - want| with NaN matching only NaN, infinities only themselves (inf otherwise)."""
    with np.errstate(invalid="ignore", over="ignore"):
        e = np.abs(got - want)
    both_nan = np.isnan(got) & np.isnan(want)
    same_inf = np.isinf(got) & np.isinf(want) & (np.sign(got) == np.sign(want))
    e = np.where(both_nan | same_inf, 0.0, e)
    return np.where(np.isnan(e), np.inf, e)


def comparable(key: str, fmt: F.Format, got_codes: np.ndarray, f64: np.ndarray,
               exact: bool) -> tuple[np.ndarray, np.ndarray]:
    """A float32 render's target and the float64 evaluation's, in the units they compare in:
    values (the float a shader reads; float formats with denormals flushed, as the float32
    runs do), or codes for exact targets (integers, packed indices, stencil)."""
    if exact:
        want = np.asarray(fmt.quantize(f64) if not key.endswith(".stencil") and
                          not fmt.is_integer else f64).astype(np.float64)
        return np.asarray(got_codes).astype(np.float64), want
    got = F.flush_denormals(np.asarray(got_codes)) if fmt.kind is F.Kind.FLOAT \
        else np.asarray(got_codes)
    return fmt.dequantize(got), np.asarray(f64, np.float64)


def comparison_units(info: dict):
    """``convert(key, float64 values)`` for ``discontinuity.Explainer``: the units
    ``comparable`` gives a target in (``info``: ``tolerance.plan_targets``)."""
    def convert(key: str, v: np.ndarray) -> np.ndarray:
        base, _, aspect = key.partition(".")
        t = info[base]
        if t.exact or aspect:
            return comparable(key, t.format, v, v, True)[1]
        return np.asarray(v, np.float64)
    return convert


def compare_values(key: str, fmt: F.Format, backend: str, got_codes: np.ndarray,
                   f64: np.ndarray, bound: np.ndarray, exact: bool,
                   exclude: np.ndarray | None = None) -> TargetResult:
    """Target ``key`` of a float32 render (codes) against the float64 evaluation (values)
    within ``bound`` (value units, per pixel and channel).  ``exclude``: (H, W) pixels not to
    count (the discontinuities found among the pixels over the bound)."""
    got, want = comparable(key, fmt, got_codes, f64, exact)
    if exact:
        bound = np.zeros(got.shape)
    err = error(got, want)
    nonfinite = int((np.isinf(err) & ~(np.isinf(got) & np.isinf(want))).sum())
    tiny = 1e-12 * np.maximum(np.abs(np.where(np.isfinite(want), want, 0.0)), 1e-30)
    ratio = err / np.maximum(bound, tiny) if not exact else np.where(err > 0, np.inf, 0.0)
    ratio = np.where(err == 0, 0.0, ratio)
    px_ratio = ratio.max(axis=-1) if ratio.ndim == 3 else ratio
    bad = px_ratio > 1.0
    if exclude is not None:
        bad &= ~exclude
    admitted = np.zeros_like(bad)
    if bad.any():
        # a coverage difference: next to a jump of the float64 image much larger than the
        # bound, and each image's value found in the other's 3x3 neighbourhood
        nb_want = neighbour_stack(want)
        nb_got = neighbour_stack(got)
        lim = bound if not exact else np.zeros_like(err)

        def within(e):
            e = np.where(np.isnan(e), np.inf, e)
            ok = e <= lim[None] * (1 + 1e-9)
            return ok.all(axis=-1) if ok.ndim == 4 else ok
        with np.errstate(invalid="ignore"):
            jump = np.abs(nb_want - want[None])
            jump = np.where(np.isnan(jump), np.inf, jump)
            jmax = jump.max(axis=0)
            jmax = jmax.max(axis=-1) if jmax.ndim == 3 else jmax
            lmax = lim.max(axis=-1) if lim.ndim == 3 else lim
            edge = jmax > 0 if exact else jmax > 4 * lmax
            m1 = within(np.abs(nb_want - got[None])).any(axis=0)
            m2 = within(np.abs(nb_got - want[None])).any(axis=0)
        admitted = bad & edge & m1 & m2
    rest = np.where(admitted | (exclude if exclude is not None else False), 0.0, px_ratio)
    worst, e_px, b_px, xy, values = 0.0, 0.0, 0.0, (0, 0), ((), ())
    if rest.size:
        k = np.unravel_index(int(np.argmax(rest)), rest.shape)
        e_px = err.max(axis=-1)[k] if err.ndim == 3 else err[k]
        b_px = bound.max(axis=-1)[k] if bound.ndim == 3 else bound[k]
        if err.ndim == 3:
            c = int(np.argmax(ratio[k]))
            e_px, b_px = err[k][c], bound[k][c]
        worst = float(rest[k])
        xy = (int(k[1]), int(rest.shape[0] - 1 - k[0]))
        values = (tuple(np.atleast_1d(got[k]).tolist()), tuple(np.atleast_1d(want[k]).tolist()))
    edge_bound = max(EDGE_MIN, int(EDGE_FRACTION * bad.size))
    over = bad & ~admitted
    return TargetResult(key, fmt.name, backend, exact, worst, float(e_px), float(b_px),
                        int(over.sum()), int(admitted.sum()), edge_bound,
                        nonfinite, px_ratio, over_mask=over, worst_xy=xy, worst_values=values,
                        bound_map=np.asarray(bound, np.float64))


