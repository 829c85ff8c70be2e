"""Why a float32 target broke its bound against the float64 evaluation, in one line (issue 25
item 2): where (the worst pixel), by how much, and what the bound was made of there: the
target's own store and arithmetic (``local``), the sensitivity of the image to a one-ulp move
of the geometry (``position``: grazing and distant surfaces magnify it), or errors read from
other targets and magnified by the pass that reads them (``reads``: the factor is the reads
term over the largest bound of the targets read, at that pixel).  A pixel the discontinuity
search explained (``discontinuity.py``) is said to be one instead.

Used by ``pipegen stress`` (its notes and labelled pictures) and ``pipegen check --precision
f64``."""

from __future__ import annotations

from typing import Optional

import numpy as np

from pipegen.proof.f64_compare import TargetResult

# what exceeding a bound made mostly of each term says about where the error came from
CAUSES = {
    "local": "the bound there is the rounding of the stored result; an error {ratio} came "
             "from pass {writers}'s float32 arithmetic magnifying rounding (a cancellation, "
             "or a large intermediate such as |p|^2 far from the origin)",
    # a depth attachment's values come from the rasteriser's depth plane, not from code
    "local_depth": "the bound there is the error of the float32 depth plane of the triangle "
                   "that drew the pixel (its set-up from the triangle's vertices) and its "
                   "rounding; an error {ratio} means the depth is not that plane's: another "
                   "triangle's, or a plane set up otherwise (docs/tolerances.md, \"The bound\")",
    "position": "the bound there is mostly the image's sensitivity to a one-ulp move of the "
                "geometry (a grazing or distant surface magnifies it); the error exceeds even "
                "that",
    "reads": "the bound there is mostly errors read from {reads}{magnified}; the error exceeds "
             "even that: pass {writers} magnifies what it reads more than the bound measured",
}

def _at(a, row: int, col: int) -> float:
    a = np.asarray(a, np.float64)
    if a.ndim == 0:
        return float(a)
    v = a[row, col] if a.shape[:2] != () and a.ndim >= 2 else a
    return float(np.max(v))


def magnification(key: str, row: int, col: int, part_maps: dict, info: dict) -> tuple:
    """(factor, target read) at a pixel: the reads term of ``key`` over the largest bound of
    a target its writers read, where that target has the same size (else (None, None))."""
    base = key.partition(".")[0]
    reads = part_maps.get(key, {}).get("reads")
    if reads is None or base not in info:
        return None, None
    best, which = 0.0, None
    for r in info[base].reads:
        total = part_maps.get(r, {}).get("total")
        if total is None or np.shape(total)[:2] != np.shape(reads)[:2]:
            continue
        v = _at(total, row, col)
        if v > best:
            best, which = v, r
    if which is None or best <= 0:
        return None, None
    return _at(reads, row, col) / best, which


def why_over(t: TargetResult, part_maps: dict, info: dict, case: str = "") -> Optional[str]:
    """One line for a target over its bound (None when it is within it): ``case: target
    (backend) over its bound at (x, y): error E, bound B (R x); bound terms there: local L,
    position P, reads Q: <what the largest term says about the cause>``.  ``case``: the
    case's name and what it does, e.g. ``far_1e3 (everything moved 1e3 from the origin)``."""
    if t.passed or t.exact:
        return None
    where = f"{case}: " if case else ""
    x, y = t.worst_xy
    head = (f"{where}{t.key} ({t.backend}) over its bound at ({x}, {y}): error "
            f"{t.units(t.worst_error)}, bound {t.units(t.bound_at_worst)} "
            f"({t.worst_ratio:.3g}x)" if np.isfinite(t.worst_ratio) else
            f"{where}{t.key} ({t.backend}) at ({x}, {y}): a NaN or infinity on one side only")
    if t.ratio_map is None:
        return head
    h = t.ratio_map.shape[0]
    row, col = h - 1 - y, x
    if t.discontinuity_mask is not None and t.discontinuity_mask[row, col]:
        return head + "; a discontinuity of the technique's code (see its note)"
    terms = part_maps.get(t.key)
    if not terms:
        return head
    values = {k: _at(terms[k], row, col) for k in ("local", "position", "reads")}
    largest = max(values, key=values.get)
    base = t.key.partition(".")[0]
    tinfo = info.get(base)
    magnified = ""
    if largest == "reads" and tinfo is not None:
        factor, read = magnification(t.key, row, col, part_maps, info)
        if factor is not None:
            magnified = f", {read}'s bound magnified {factor:.3g}x"
    depth_plane = largest == "local" and tinfo is not None and tinfo.is_depth \
        and not t.key.endswith(".stencil")
    cause = CAUSES["local_depth" if depth_plane else largest].format(
        ratio=f"{t.worst_ratio:.3g}x larger", writers=", ".join(tinfo.writers) if tinfo else "?",
        reads=", ".join(tinfo.reads) if tinfo else "-", magnified=magnified)
    line = (f"{head}; bound terms there: local {t.units(values['local'])}, position "
            f"{t.units(values['position'])}, reads {t.units(values['reads'])}: {cause}")
    if t.edges > t.edge_bound:
        line += f"; {t.edges} pixels at coverage edges (more than the {t.edge_bound} admitted)"
    return line
