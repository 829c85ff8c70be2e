"""The float64 bound of a depth attachment holds its triangles' float32 depth planes
(``proof/depth_planes.py``, docs/tolerances.md "The bound").

llvmpipe sets a long, thin triangle's depth plane up with coefficients a fraction of a percent
off (``calc_coef4``'s products nearly cancel), 18 d24 codes at the far end of street_lamps'
road, where the bound once allowed 2 + the position term (3.5 codes) and `check --precision
f64` said OVER THE BOUND for llvmpipe and CL alike.  Here:

- forward on street_lamps (160x90): depth within the bound on both backends, the bound's local
  term at the worst pixel more than the 2 codes it was, colour unchanged;
- the term itself, on two triangles set up by hand: a long, thin one (its float32 plane off
  its exact plane by more than 10 codes) and a small one over part of it, which the float64
  depth says drew the pixels they share: each pixel takes the error of the triangle whose
  exact depth is the float64 depth there, not of the other one;
- why a depth attachment broke its bound is said in terms of the depth plane, not of a pass's
  arithmetic.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@functools.lru_cache(maxsize=None)
def _street_lamps_forward():
    from pipegen import compile_file, load_scene
    from pipegen.compiler.driver import for_scene
    from pipegen.proof.precision import precision_check
    scene = load_scene(ROOT / "examples" / "scenes" / "street_lamps.toml").with_size(160, 90)
    compiled = for_scene(compile_file(ROOT / "pipelines" / "forward.pipe"), scene)
    result = precision_check(compiled, scene, explain=False)
    return {b: {r.key: r for r in rs} for b, rs in result.rows.items()}, result.parts


@pytest.mark.gl
@pytest.mark.cl
def test_forward_depth_on_street_lamps_within_the_float64_bound():
    pytest.importorskip("pyopencl")
    rows, parts = _street_lamps_forward()
    d24 = 2 ** 24 - 1
    for b in ("gl", "cl"):
        assert rows[b]["color"].passed
        ds = rows[b]["ds"]
        assert ds.passed, (b, ds.worst_error * d24, ds.bound_at_worst * d24)
        assert ds.worst_error * d24 > 10          # the plane error is there, and bounded
    assert rows["gl"]["ds"].worst_error == rows["cl"]["ds"].worst_error
    assert parts["ds"]["local"] * d24 > 10        # 2 codes + the worst triangle's plane


def _two_triangles():
    """Set-up ``Triangles`` of a long, thin triangle and a small one over part of it, 64 x 32
    pixels, with their exact planes."""
    from pipegen.runtime.cl.setup import setup_triangles
    clip = np.array([
        # long and thin, its vertices at clip w 10.7-41.1, window depths 0.91, 0.88 and 0.13
        # (found by a random search for a large float32 plane error at this size)
        [-10.406662, 7.660155, 8.831514, 10.728518], [32.07935, 23.000986, 25.457083, 33.071495],
        [39.842617, 34.089958, -30.300165, 41.074863],
        # small, window depth ~0.75, over the right part of the thin one
        [0.30, 0.60, 0.50, 1.0], [0.90, 0.60, 0.50, 1.0], [0.60, 0.95, 0.52, 1.0],
    ], np.float32)
    return setup_triangles(clip, 64, 32, with_zp=True, with_zq=True)


def test_a_pixel_takes_the_plane_error_of_the_triangle_that_drew_it(monkeypatch):
    from pipegen.proof.depth_planes import _covered, plane_error, triangle_errors
    tris = _two_triangles()
    assert tris.count == 2
    h, w = 32, 64
    ys, xs = np.mgrid[0:h, 0:w]
    cover = [_covered(tris, i, xs, ys) for i in range(2)]
    exact = [triangle_errors(tris, i, xs, ys) for i in range(2)]
    # the float64 depth: the small triangle's where it covers (it drew those pixels), else
    # the thin one's, else the far plane
    depth = np.where(cover[1], exact[1][0], np.where(cover[0], exact[0][0], 1.0))
    term = plane_error([(tris, 0.5)], depth)
    only_thin = cover[0] & ~cover[1]
    both = cover[0] & cover[1]
    assert only_thin.sum() > 30 and both.sum() > 5
    np.testing.assert_array_equal(term[only_thin], exact[0][1][only_thin])
    np.testing.assert_array_equal(term[both], exact[1][1][both])   # not the hidden one's
    assert not term[~(cover[0] | cover[1])].any()
    # walked a few pixels at a time (as a large scene's boxes are), the same term
    import pipegen.proof.depth_planes as planes
    monkeypatch.setattr(planes, "CHUNK", 7)
    np.testing.assert_array_equal(planes.plane_error([(tris, 0.5)], depth), term)
    # the thin triangle's float32 plane is off its exact plane by more than the 2 codes the
    # store term allows somewhere, the small one's nowhere near that
    d24 = 2 ** 24 - 1
    assert exact[0][1][cover[0]].max() * d24 > 10
    assert exact[1][1][cover[1]].max() * d24 < 1


def test_why_a_depth_attachment_broke_its_bound_names_the_depth_plane():
    from pipegen.proof import tolerance as B
    from pipegen.proof.f64_compare import TargetResult
    from pipegen.proof.why import why_over
    ratio = np.zeros((4, 4))
    ratio[1, 2] = 3.0
    t = TargetResult(key="ds", format="d24s8", backend="cl", exact=False, worst_ratio=3.0,
                     worst_error=6 / (2 ** 24 - 1), bound_at_worst=2 / (2 ** 24 - 1), over=1,
                     edges=0, edge_bound=0, nonfinite_mismatch=0, ratio_map=ratio,
                     worst_xy=(2, 2))
    local = np.full((4, 4), 2 / (2 ** 24 - 1))
    parts = {"ds": {"local": local, "position": local * 0, "reads": local * 0}}
    from pipegen.core import formats as F

    def info_of(is_depth: bool) -> dict:
        return {"ds": B.TargetInfo("ds", F.get("d24s8"), False, ("scene",), (), (), is_depth)}

    info = info_of(True)
    line = why_over(t, parts, info)
    assert "float32 depth plane of the triangle" in line and "arithmetic" not in line, line
    # a colour target with the same figures is still said to be its pass's arithmetic
    assert "arithmetic" in why_over(t, parts, info_of(False))
