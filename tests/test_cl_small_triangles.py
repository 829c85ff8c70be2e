"""Small triangles that cover no sample are dropped at set-up (``abi.SMALL_BOX``): a triangle
whose box holds at most that many pixels is tested at each of their samples with the raster
kernel's own edge functions, by the device set-up (cl_setup.cl.j2's setup_tri) and the numpy
one (``setup.covers_a_sample``) alike.  The frames are bit for bit those drawing every
triangle, with far fewer triangles to bin and rasterise at small sizes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl

ROOT = Path(__file__).resolve().parents[1]


def _raster_covers(X, Y, area, box, samples) -> bool:
    """The raster kernel's coverage test (cl_pass.cl.j2's coverage macro), written out pixel
    by pixel and sample by sample: int32 edge coefficients, top-left edges inclusive."""
    from pipegen.backends.opencl.abi import sample_positions
    s = 1 if area > 0 else -1
    edges = []
    for i1, i2 in ((1, 2), (2, 0), (0, 1)):
        a = int(np.int32((Y[i1] - Y[i2]) * s))
        b = int(np.int32((X[i2] - X[i1]) * s))
        c = -((Y[i1] - Y[i2]) * s * X[i1] + (X[i2] - X[i1]) * s * Y[i1])
        edges.append((a, b, c, a > 0 or (a == 0 and b > 0)))
    x0, y0, x1, y1 = box
    for py in range(y0, y1 + 1):
        for px in range(x0, x1 + 1):
            for dx, dy in zip(*sample_positions(samples)):
                xs, ys = px * 256 + dx, py * 256 + dy
                if all(a * xs + b * ys + c >= (0 if inc else 1) for a, b, c, inc in edges):
                    return True
    return False


@pytest.mark.parametrize("samples", [1, 4])
def test_covers_a_sample_is_the_raster_test(samples):
    """On random small triangles (boxes of 1 to 16 pixels, vertices anywhere in 1/256 pixel),
    ``covers_a_sample`` answers as the raster kernel's test does, both ways."""
    from pipegen.runtime.cl.setup import covers_a_sample
    rng = np.random.default_rng(samples)
    n = 3000
    base = rng.integers(0, 40 * 256, (1, n, 2))
    V = base + rng.integers(-3 * 256, 3 * 256, (3, n, 2))
    X, Y = V[..., 0].astype(np.int64), V[..., 1].astype(np.int64)
    area = (X[1] - X[0]) * (Y[2] - Y[0]) - (X[2] - X[0]) * (Y[1] - Y[0])
    lo, hi = (128, 128) if samples == 1 else (255, 1)
    x0 = -((lo - X.min(axis=0)) >> 8)
    x1 = (X.max(axis=0) - hi) >> 8
    y0 = -((lo - Y.min(axis=0)) >> 8)
    y1 = (Y.max(axis=0) - hi) >> 8
    ok = (area != 0) & (x0 <= x1) & (y0 <= y1) & ((x1 - x0 + 1) * (y1 - y0 + 1) <= 16)
    idx = np.flatnonzero(ok)
    got = covers_a_sample(X[:, idx], Y[:, idx], area[idx], x0[idx], y0[idx], x1[idx], y1[idx],
                          samples)
    want = [_raster_covers(X[:, i], Y[:, i], area[i], (x0[i], y0[i], x1[i], y1[i]), samples)
            for i in idx]
    assert got.tolist() == want
    assert 0.05 < np.mean(want) < 0.95        # both answers are common here


@pytest.mark.parametrize("samples", [1, 4])
def test_device_and_numpy_set_ups_drop_the_same_triangles(samples):
    """Triangles whose corners lie on the half-pixel grid (128x128 viewport, clip coordinates
    k/128 - 1 map to window k/2 exactly): their edges run through sample positions, where the
    inclusive-edge rule decides.  The device set-up keeps exactly the rows the numpy one keeps,
    and drops some."""
    import pyopencl as cl
    from pipegen.runtime.cl import context as cl_context
    from pipegen.runtime.cl.setup import setup_triangles
    from pipegen.runtime.cl.setup_device import DeviceSetup
    ctx, queue = cl_context.get_context()
    rng = np.random.default_rng(7 + samples)
    T, W = 4000, 128
    k = rng.integers(8, 248, (T, 1, 2)) + rng.integers(-4, 5, (T, 3, 2))
    clip = np.ones((T, 3, 4), np.float32)
    clip[..., :2] = k / 128.0 - 1.0
    clip[..., 2] = 0.5
    clip = clip.reshape(-1, 4)
    kw = dict(samples=samples, pixel_center=0.5 if samples == 1 else 0.0, w_plane=True,
              with_zq=samples > 1)
    ref = setup_triangles(clip, W, W, with_zp=False, **kw)
    assert ref.count < T - 500              # degenerate, and empty small ones, dropped
    setup = DeviceSetup(ctx, queue)
    buf = cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=clip)
    got, _, _ = setup.finish(setup.enqueue(buf, buf, T, 3 * T, W, W, **kw))
    assert np.array_equal(got.parent, ref.parent)
    assert np.array_equal(np.asarray(got.a), ref.a) and np.array_equal(got.bbox, ref.bbox)
    with pytest.MonkeyPatch.context() as m:       # and without the test: only empty ones more
        from pipegen.runtime.cl import setup as cl_setup
        m.setattr(cl_setup, "SMALL_BOX", 0)
        every = setup_triangles(clip, W, W, with_zp=False, **kw)
    gone = np.setdiff1d(every.parent, ref.parent)
    assert len(gone) and set(ref.parent) <= set(every.parent)
    # what the raster kernel would have drawn of each: nothing
    for r in np.searchsorted(every.parent, gone):
        assert not _row_covers(every, r, samples), r


def _row_covers(tris, r, samples) -> bool:
    """Whether set-up row ``r`` covers a sample of its box, read as pg_raster reads it: its
    int32 edge coefficients a, b, int64 c, and a.w's inclusive-edge bits."""
    from pipegen.backends.opencl.abi import sample_positions
    a, b, c = (np.asarray(f)[r].astype(np.int64) for f in (tris.a, tris.b, tris.c))
    x0, y0, x1, y1 = (int(v) for v in tris.bbox[r])
    for py in range(y0, y1 + 1):
        for px in range(x0, x1 + 1):
            for dx, dy in zip(*sample_positions(samples)):
                xs, ys = px * 256 + dx, py * 256 + dy
                if all(a[k] * xs + b[k] * ys + c[k] >= (~int(a[3]) >> k) & 1 for k in range(3)):
                    return True
    return False


@pytest.mark.parametrize("technique", ["deferred", "forward", "lidr_bitplanes", "inferred"])
def test_frames_are_those_drawing_every_triangle(technique, monkeypatch):
    """CL frames of shipped techniques on many_lights at 96x54, with small empty triangles
    dropped and with none dropped (``SMALL_BOX`` 0 in both set-ups): every target bit for bit,
    and fewer triangles drawn."""
    from pipegen.compiler.driver import compile_file
    from pipegen.backends.opencl import programs
    from pipegen.runtime.cl import setup
    from pipegen.scene import load_scene
    scene = load_scene(ROOT / "examples/scenes/many_lights.toml").with_size(96, 54)
    compiled = compile_file(ROOT / f"pipelines/{technique}.pipe").specialise(scene)

    def frame():
        pipe = compiled.pipeline("cl")
        out = pipe.render(scene)
        drawn = sum(t.get("triangles", 0) for t in pipe.last_timings)
        return out, drawn

    dropped, fewer = frame()
    with monkeypatch.context() as m:
        m.setattr(programs, "SMALL_BOX", 0)
        m.setattr(setup, "SMALL_BOX", 0)
        every, more = frame()
    for name in every:
        assert np.array_equal(dropped[name].view(np.uint8), every[name].view(np.uint8)), name
    assert fewer < more
