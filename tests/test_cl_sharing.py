"""What lets the CL runtime share work between passes without changing a value.

- ``setup_triangles`` results are per triangle: setting up two triangle lists together gives
  each triangle the values it gets alone (the runtime sets up all lights' volumes at once, and
  each light's passes draw their range), and per varying: a smooth varying's planes do not
  depend on which other varyings are set up with it (a scene draw is set up once with the
  union of the varyings of the passes drawing it).
- Bins of a subset (``subset=``, or cut from ``bin_pairs``) are the bins of those triangles
  set up alone, with their indices in the whole list.
- ``fma32``'s fast path is the exact rounding.
- ``light_table.light_list``: the lights a light draw instances, for both runtimes.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np

from pipegen.runtime.cl import setup as CS
from pipegen.backends.plan import draw_from_dict, plan_from_dict
from pipegen.runtime.draws import LightSelection, light_filter, light_type

PER_TRIANGLE = ("a", "b", "c", "z", "w", "coef", "zp", "zq", "flat", "scissor", "bbox")


def _triangles(rng, n, spread=1.3):
    clip = rng.normal(0.0, spread, (3 * n, 4)).astype(np.float32)
    clip[:, 3] = rng.uniform(0.3, 2.0, 3 * n).astype(np.float32)
    return clip


def _same(x, y):
    return x.shape == y.shape and x.dtype == y.dtype and np.array_equal(
        x.view(np.uint8), y.view(np.uint8))


def test_setup_is_per_triangle():
    rng = np.random.default_rng(3)
    first, second = _triangles(rng, 300), _triangles(rng, 200)       # both cross the viewport
    kw = dict(cull="none", depth_format="d24s8", polygon_offset=(1.5, 2.0), w_plane=True)
    a = CS.setup_triangles(first, 64, 48, flat=np.full((300, 4), 1, np.uint32), **kw)
    b = CS.setup_triangles(second, 64, 48, flat=np.full((200, 4), 2, np.uint32), **kw)
    both = CS.setup_triangles(np.concatenate([first, second]), 64, 48, flat=np.concatenate(
        [np.full((300, 4), 1, np.uint32), np.full((200, 4), 2, np.uint32)]), **kw)
    assert both.count == a.count + b.count and a.count and b.count
    part = both.flat[:, 3] == 1                     # submission order: first's triangles first
    assert part[:a.count].all() and not part[a.count:].any()
    for name in PER_TRIANGLE:
        whole = getattr(both, name)
        assert _same(whole[:a.count], getattr(a, name)), name
        assert _same(whole[a.count:], getattr(b, name)), name


def test_setup_is_per_varying():
    rng = np.random.default_rng(4)
    clip = _triangles(rng, 400)
    vary = rng.normal(0.0, 5.0, (3, 1200, 4)).astype(np.float32)
    kw = dict(cull="back", depth_format="d24s8", w_plane=False)
    union = CS.setup_triangles(clip, 80, 60, vary=vary, smooth=[0, 2], **kw)
    alone = CS.setup_triangles(clip, 80, 60, vary=vary[2:], smooth=[0], **kw)
    bare = CS.setup_triangles(clip, 80, 60, **kw)
    assert _same(union.coef[:, 1], alone.coef[:, 0])
    assert _same(union.vary[2], alone.vary[0])          # clipper-made vertices included
    assert union.vary.shape[1] > 1200
    for name in ("a", "b", "c", "z", "zp", "zq", "bbox"):
        assert _same(getattr(union, name), getattr(bare, name)), name
    assert _same(union.w, alone.w)


def test_bins_of_a_subset():
    rng = np.random.default_rng(5)
    tris = CS.setup_triangles(_triangles(rng, 600, spread=0.8), 100, 70, cull="none")
    subset = np.flatnonzero(rng.random(tris.count) < 0.4)
    sub = dataclasses.replace(tris, **{n: getattr(tris, n)[subset] for n in PER_TRIANGLE + ("vtx",)})
    start, local, tx, ty = CS.bin_triangles(sub, 100, 70, 16)
    got = CS.bin_triangles(tris, 100, 70, 16, subset=subset)
    assert np.array_equal(got[0], start) and (tx, ty) == got[2:]
    assert np.array_equal(got[1][:start[-1]], subset[local[:start[-1]]])
    # cut from the pairs of every triangle: a range, then a facing filter
    tri, tile_id, tx, ty = CS.bin_pairs(tris, 100, 70, 16)
    lo, hi = 100, 350
    a, b = np.searchsorted(tri, (lo, hi))
    front = (tris.flat[:, 0] & 1).astype(bool)
    keep = front[tri[a:b]]
    cut = CS.bins_from_pairs(tri[a:b][keep], tile_id[a:b][keep], tx * ty)
    rng_subset = np.arange(lo, hi)[front[lo:hi]]
    want = CS.bin_triangles(tris, 100, 70, 16, subset=rng_subset)
    assert np.array_equal(cut[0], want[0]) and np.array_equal(cut[1], want[1])
    # the pairs of the front faces are those of every face filtered (DrawGeometry._pairs)
    kept = front[tri]
    own = CS.bin_pairs(tris, 100, 70, 16, subset=np.flatnonzero(front))
    assert np.array_equal(own[0], tri[kept]) and np.array_equal(own[1], tile_id[kept])


def test_fma32_fast_path_is_the_exact_rounding():
    rng = np.random.default_rng(6)
    n = 200_000
    cases = [
        (rng.uniform(-1.5, 1.5, n).astype(np.float32), np.float32(320.0), np.float32(320.0)),
        ((rng.integers(-4096, 4096, n) / 2.0 ** rng.integers(0, 12, n)).astype(np.float32),
         (rng.integers(-4096, 4096, n) / 2.0 ** rng.integers(0, 12, n)).astype(np.float32),
         (rng.integers(-2 ** 24, 2 ** 24, n) * 2.0 ** rng.integers(-40, 10, n)).astype(np.float32)),
        ((rng.normal(0, 1, n) * 1e-20).astype(np.float32),
         (rng.normal(0, 1, n) * 1e-19).astype(np.float32),
         (rng.normal(0, 1, n) * 1e-38).astype(np.float32)),
    ]
    for a, b, c in cases:
        fast = CS.fma32(a, b, c)
        exact = CS._fma32_exact(*np.broadcast_arrays(a, b, c))
        assert np.array_equal(fast.view(np.uint32), exact.view(np.uint32))


def _light(position, radius, type_="point"):
    return SimpleNamespace(position=position, radius=radius, type=type_)


def test_light_list_types_and_sets():
    lights = [_light((0, 0, 0), 1.0), _light((5, 0, 0), 1.0, "spot"), _light((0.5, 0, 0), 1.0),
              _light((9, 9, 9), 0.0, 2)]
    assert [light_type(l) for l in lights] == ["point", "spot", "point", "directional"]
    plan = plan_from_dict({"light_sets": {"slots": 1}})

    def light_list(draw, lights, plan, selection=None):
        return (selection or LightSelection(plan, lights)).of(draw_from_dict(
            {"kind": "lights", **draw}))

    assert light_list({}, lights, plan) == [0, 1, 2, 3]
    assert light_list({"light_types": ["point"]}, lights, plan) == [0, 2]
    assert not light_filter(draw_from_dict({"kind": "lights"}))
    assert light_filter(draw_from_dict({"kind": "lights", "light_types": ["spot"]}))
    selection = LightSelection(plan, lights)
    sets, dropped = selection.sets, selection.dropped
    chosen = [light_list({"light_set": ["slots", k]}, lights, plan, selection)
              for k in range(3)]
    flat = sorted(i for c in chosen for i in c)
    assert sorted(flat + dropped["slots"]) == [0, 1, 2, 3] and "slots" in sets
    # overlapping spheres 0 and 2 never share a one-slot set
    assert not any({0, 2} <= set(c) for c in chosen)
