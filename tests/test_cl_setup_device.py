"""The device set-up (runtime/cl/setup_device.py, templates/cl_setup.cl.j2) against the numpy
set-up it replaces (cl_setup.setup_triangles): every field of every triangle bit for bit,
on random clip-space triangles (many cross the clip planes: the device clipper sets up
their fans, merged back in submission order; its new vertices are numbered apart, so vertex
ids are compared through the varyings they hold), under each combination of the set-up's
switches; and whole frames of shipped techniques rendered both ways."""

import itertools
import os

import numpy as np
import pytest

pytestmark = pytest.mark.cl

FIELDS = ("a", "b", "c", "z", "w", "coef", "flat", "scissor", "bbox", "parent", "zq")


def _triangles(rng, T):
    """Small random triangles in clip space, some of them crossing clip planes or behind the
    eye (w from 0.2 to 5, vertices within 1.1 w of the axis)."""
    w = rng.uniform(0.2, 5.0, 3 * T).astype(np.float32)
    xyz = rng.uniform(-1.1, 1.1, (3 * T, 3)).astype(np.float32) * w[:, None]
    c = np.concatenate([xyz, w[:, None]], axis=1).astype(np.float32).reshape(T, 3, 4)
    jitter = np.array([1, 1, 1, 0], np.float32)
    for k in (1, 2):
        c[:, k] = c[:, 0] + rng.normal(0, 0.05, (T, 4)).astype(np.float32) * jitter
    return c.reshape(-1, 4)


def _same(ref, got) -> bool:
    if ref is None or got is None:
        return ref is None and got is None
    got = np.asarray(got)        # a field left on the device (DeviceRows) is read here
    if ref.shape != got.shape or ref.dtype != got.dtype:
        return False
    return bool(np.array_equal(ref.view(np.uint8), got.view(np.uint8)))


# (cull, samples, smooth slots, pixel centre, scissor, depth clamp): every pair of values of
# any two switches in some row (a pairwise covering set of the 64 combinations: each row is
# a program to build, ~1 s on a cold kernel cache).  "auto" culls per input triangle by bit 2
# of its flat word (random here)
SWITCHES = [("none", None, (), 0.5, False, False), ("none", 1, (0, 2), 0.0, True, True),
            ("back", None, (), 0.5, True, True), ("back", 1, (0, 2), 0.0, False, False),
            ("front", None, (), 0.0, False, True), ("front", 1, (0, 2), 0.5, True, False),
            ("none", None, (0, 2), 0.5, False, False), ("none", 1, (), 0.5, False, False),
            ("auto", None, (), 0.5, False, False), ("auto", 1, (0, 2), 0.0, True, True)]


def test_switch_rows_cover_every_pair():
    values = [{row[i] for row in itertools.product(["none", "back", "front", "auto"], [None, 1],
                                                     [(), (0, 2)], [0.5, 0.0], [False, True],
                                                     [False, True])} for i in range(6)]
    for i, j in itertools.combinations(range(6), 2):
        assert {(r[i], r[j]) for r in SWITCHES} == set(itertools.product(values[i], values[j]))


@pytest.mark.parametrize("cull,samples,smooth,center,scissor,depth_clamp", SWITCHES)
def test_device_setup_matches_numpy_setup(cull, samples, smooth, center, scissor, depth_clamp):
    import pyopencl as cl
    from pipegen.runtime.cl import context as cl_context
    from pipegen.runtime.cl.setup import setup_triangles
    from pipegen.runtime.cl.geometry import select_triangles
    from pipegen.runtime.cl.setup_device import HOST_FIELDS, DeviceRows, DeviceSetup
    ctx, queue = cl_context.get_context()
    rng = np.random.default_rng(len(SWITCHES) + SWITCHES.index(
        (cull, samples, smooth, center, scissor, depth_clamp)))
    T, S, W, H = 1500, 3, 160, 90
    clip = _triangles(rng, T)
    vary = rng.normal(0, 3, (S, 3 * T, 4)).astype(np.float32)
    flat = rng.integers(0, 1000, (T, 4)).astype(np.uint32)
    rects = None
    if scissor:
        rects = rng.integers(-20, 120, (T, 4)).astype(np.int32)
        rects[:, 2:] += rects[:, :2]
    with_zq = center == 0.0
    kw = dict(cull=cull, flat=flat, scissor=rects, samples=samples, smooth=list(smooth),
              pixel_center=center, w_plane=True, with_zq=with_zq, depth_clamp=depth_clamp)
    ref = setup_triangles(clip, W, H, vary=vary, with_zp=False, **kw)
    mf = cl.mem_flags
    clip_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=clip)
    vary_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=vary)
    setup = DeviceSetup(ctx, queue)
    job = setup.enqueue(clip_buf, vary_buf, T, 3 * T, W, H, slots=S, **dict(kw, smooth=smooth))
    got, bufs, index = setup.finish(job)
    assert (job.status == 2).any() and (job.status == 1).any()   # both kernels ran
    # only the boxes and flat words come back to the host; the rest on first use
    assert {f for f in FIELDS + ("vtx",) if isinstance(getattr(got, f), DeviceRows)} \
        == {"a", "b", "c", "z", "w", "coef", "scissor", "vtx"} | ({"zq"} if with_zq else set())
    assert set(HOST_FIELDS) == {"flat", "bbox"}
    pick = rng.permutation(got.count)[:got.count // 3]
    sub = select_triangles(got, pick)       # cull auto's selection, still on the device
    assert isinstance(sub.a, DeviceRows)
    for f in ("a", "c", "coef", "bbox"):
        assert _same(getattr(ref, f)[pick], getattr(sub, f)), f
    for f in FIELDS:
        assert _same(getattr(ref, f), getattr(got, f)), f
    # the clipper's vertices have other ids (9 per clipped triangle, not consecutive): the
    # input vertices are the same, and every triangle's corners hold the same varyings
    n = 3 * T
    rv, gv = ref.vtx[:, :3], got.vtx[:, :3]
    assert np.array_equal(rv < n, gv < n) and np.array_equal(rv[rv < n], gv[gv < n])
    assert _same(ref.vary[:, rv], got.vary[:, gv])
    assert _same(ref.vary[:, :n], got.vary[:, :n])
    # the device rows the tile lists will name hold the same triangles
    dev = np.empty((int(index.max()) + 1, 4), np.int32)
    cl.enqueue_copy(queue, dev, bufs["bbox"])
    assert np.array_equal(dev[index], got.bbox)


@pytest.mark.parametrize("technique", ["deferred", "light_prepass", "lidr_transparent"])
def test_frames_with_and_without_device_setup_are_identical(technique, monkeypatch):
    from pipegen.compiler.driver import compile_file
    from pipegen.scene import load_scene
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    # the ground plane crosses the near and side planes: both set-up paths run
    scene = load_scene(os.path.join(root, "examples", "scenes", "many_lights.toml"))
    scene = scene.with_size(96, 64)
    compiled = compile_file(os.path.join(root, "pipelines", f"{technique}.pipe"))
    device = compiled.pipeline("cl").render(scene)
    monkeypatch.setenv("PIPEGEN_CL_DEVICE_SETUP", "0")
    host = compiled.pipeline("cl").render(scene)
    assert device.keys() == host.keys()
    for name in device:
        assert np.array_equal(device[name], host[name]), name


@pytest.mark.parametrize("technique", ["light_prepass", "deferred_calver"])
def test_frames_reusing_buffers_are_identical_to_fresh_ones(technique):
    """A pipeline's later frames reuse its earlier frames' geometry buffers
    (``cl_context.FramePool``: vertex outputs, set-up fields, cut varyings, not the full-screen
    draws kept across frames): frames of two scenes with different triangle counts, in turn,
    give what a fresh pipeline gives each scene, and buffers were in fact handed out again."""
    from pipegen.compiler.driver import compile_file
    from pipegen.scene import load_scene
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    compiled = compile_file(os.path.join(root, "pipelines", f"{technique}.pipe"))
    scenes = [load_scene(os.path.join(root, "examples", "scenes", f"{n}.toml")).with_size(96, 54)
              for n in ("many_lights", "mixed_lights")]
    fresh = [compiled.pipeline("cl").render(s) for s in scenes]
    pipe = compiled.pipeline("cl")
    handed = []
    for _ in range(2):
        for scene, ref in zip(scenes, fresh):
            out = pipe.render(scene)
            handed.append({id(b) for _, b in pipe.geometry.pool._used})
            for name in ref:
                assert np.array_equal(out[name], ref[name], equal_nan=True), name
    assert handed[2] & handed[0] and handed[3] & handed[1]      # the same buffers again
