"""The shortcuts of the CL runtime's host set-up (``cl_setup``) give the values of the general
code they stand in for, bit for bit:

- ``fma32``'s float32 path for a power-of-two ``b`` and its exact-window path for scalar
  ``b`` and ``c`` (the viewport transform) against the exact rounding (``_fma32_exact``);
- ``_outside`` (``|c| > w``) against ``_clip_mask`` having any bit set;
- ``setup_triangles(with_zp=False, with_zq=False)`` leaves every other field as it was.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipegen.runtime.cl import setup as CS

_SPECIAL = np.array([0.0, -0.0, 1.0, -1.0, 2.0, np.inf, -np.inf, np.nan, 1e-45, 2.0 ** -126,
                     2.0 ** -25, 2.0 ** -24, 3.4028235e38], np.float32)


def _bits(x):
    return np.ascontiguousarray(x).view(np.uint32)


@pytest.mark.parametrize("seed", range(4))
def test_fma32_shortcuts_are_the_exact_rounding(seed):
    rng = np.random.default_rng(seed)
    for trial in range(150):
        n = 2000
        vw, vx = int(rng.integers(1, 16385)), int(rng.integers(0, 16384))
        kind = trial % 4
        if kind == 0:            # viewport transform
            b, c = np.float32(vw * 0.5), np.float32(vx + vw * 0.5)
        elif kind == 1:          # power-of-two scale (the depth range)
            b = np.float32(2.0 ** int(rng.integers(-130, 100)) * rng.choice([1, -1]))
            c = np.float32(rng.normal() * 2.0 ** int(rng.integers(-140, 60)))
        elif kind == 2:          # power-of-two scale, per-element c
            b = np.float32(0.5)
            c = (rng.normal(0, 1, n) * 2.0 ** rng.integers(-140, 40, n)).astype(np.float32)
        else:                    # arbitrary scalars
            b = np.float32(rng.normal() * 2.0 ** int(rng.integers(-30, 30)))
            c = np.float32(rng.normal() * 2.0 ** int(rng.integers(-30, 30)))
        a = (rng.uniform(-2, 2, n) * 2.0 ** rng.integers(-40, 4, n)).astype(np.float32)
        if trial % 5 == 0:       # short significands: many exact float32 ties
            a = (np.round(rng.uniform(-2, 2, n) * 2 ** 12) / 2 ** 12).astype(np.float32)
        a[rng.integers(0, n, 40)] = rng.choice(_SPECIAL, 40)
        got = CS.fma32(a, b, c)
        want = CS._fma32_exact(*np.broadcast_arrays(a, b, c))
        assert np.array_equal(_bits(got), _bits(want)), (trial, b, c)


def test_outside_is_any_clip_bit():
    rng = np.random.default_rng(7)
    for trial in range(60):
        with np.errstate(over="ignore"):         # some overflow to infinity: wanted
            c = (rng.normal(0, 1, (3000, 4)) * 2.0 ** rng.integers(-150, 128, (3000, 4))
                 ).astype(np.float32)
        m = rng.random((3000, 4)) < 0.3
        c[m] = rng.choice(_SPECIAL, m.sum())
        if trial % 3 == 0:       # exactly on the planes
            c[:, 0] = c[:, 3] * rng.choice([1, -1], 3000)
        for clamp in (False, True):
            assert np.array_equal(CS._outside(np.ascontiguousarray(c.T), clamp),
                                  CS._clip_mask(c, clamp) != 0)


def test_setup_without_exact_planes():
    rng = np.random.default_rng(9)
    clip = rng.normal(0.0, 1.3, (3 * 400, 4)).astype(np.float32)
    clip[:, 3] = rng.uniform(0.3, 2.0, 3 * 400).astype(np.float32)
    vary = rng.normal(0.0, 5.0, (2, 1200, 4)).astype(np.float32)
    kw = dict(cull="back", depth_format="d24s8", polygon_offset=(1.5, 2.0), vary=vary)
    full = CS.setup_triangles(clip, 80, 60, **kw)
    bare = CS.setup_triangles(clip, 80, 60, with_zp=False, with_zq=False, **kw)
    assert bare.zp is None and bare.zq is None and full.count
    for name in ("a", "b", "c", "z", "w", "coef", "flat", "vtx", "scissor", "bbox", "vary"):
        x, y = getattr(full, name), getattr(bare, name)
        assert x.dtype == y.dtype and np.array_equal(x.view(np.uint8), y.view(np.uint8)), name
    zq = CS.setup_triangles(clip, 80, 60, with_zp=False, **kw).zq
    assert np.array_equal(zq.view(np.uint8), full.zq.view(np.uint8))
