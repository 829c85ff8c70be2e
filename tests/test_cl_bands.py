"""Tile lists a band of rows tall (``cl_bin.band_for``, ``geometry.Bins``): a raster kernel's
tile row walks only the triangles its band's boxes reach, and nothing drawn depends on the
band.  Every height a 16-pixel tile divides into renders every target, blend count and clamp
count bit for bit as one list per tile does; the device's lists equal numpy's at each height;
the height chosen follows the triangles' size."""

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]


def _render(technique: str, scene_name: str, band: int, monkeypatch, size=(100, 60),
            device_bins: bool = True, fuse: bool = True):
    from pipegen import compile_file, load_scene
    from pipegen.runtime.cl import bin as cl_bin
    monkeypatch.setattr(cl_bin, "band_for", lambda bbox, tile, w, h: band)
    monkeypatch.setenv("PIPEGEN_CL_DEVICE_BIN", "1" if device_bins else "0")
    monkeypatch.setenv("PIPEGEN_CL_FUSE_GROUPS", "1" if fuse else "0")
    scene = load_scene(ROOT / "examples" / "scenes" / f"{scene_name}.toml")
    pipe = compile_file(ROOT / "pipelines" / f"{technique}.pipe").pipeline("cl", size)
    out = pipe.render(scene)
    bins = [v for k, v in pipe.geometry.frame.items()
            if isinstance(k, tuple) and k[0] == "bins"]
    assert bins and all(b.band == band for b in bins if b.triangles)
    lists = {k[:1] + k[2:]: v.host for k, v in pipe.geometry.frame.items()
             if isinstance(k, tuple) and k[0] == "bins"}
    return out, dict(pipe.last_blend_counts), lists


def _assert_same_images(a, b):
    assert a[0].keys() == b[0].keys()
    for name in a[0]:
        assert np.array_equal(a[0][name], b[0][name]), name
    assert a[1].keys() == b[1].keys()
    for name in a[1]:
        assert np.array_equal(a[1][name], b[1][name]), name


# a fused repeat group (deferred), the same executions one by one (per-light lists cut from
# one sort), a run of lights in one launch (light pre-pass), scene draws with shadow maps,
# four samples a pixel, and the sorted slot passes of light-indexed deferred rendering
CASES = [("deferred", "mixed_lights", True), ("deferred", "street_lamps", False),
         ("light_prepass", "many_lights", True), ("forward", "shadows", True),
         ("lidr_msaa_texture", "mixed_lights", True), ("lidr_cpu_sort", "edges", True)]


@pytest.mark.parametrize("technique,scene_name,fuse", CASES)
def test_every_band_height_renders_what_tile_lists_render(technique, scene_name, fuse,
                                                           monkeypatch):
    tiles = _render(technique, scene_name, 16, monkeypatch, fuse=fuse)
    for band in (1, 2, 4, 8):
        _assert_same_images(tiles, _render(technique, scene_name, band, monkeypatch, fuse=fuse))


@pytest.mark.parametrize("technique,scene_name,fuse", CASES[:3])
def test_device_band_lists_are_the_numpy_lists(technique, scene_name, fuse, monkeypatch):
    """Binned on the device and in numpy, lists a row and 4 rows tall hold the same
    triangles in the same order, and their tiles to launch are the same."""
    for band in (1, 4):
        host = _render(technique, scene_name, band, monkeypatch, fuse=fuse, device_bins=False)
        dev = _render(technique, scene_name, band, monkeypatch, fuse=fuse, device_bins=True)
        _assert_same_images(host, dev)
        assert host[2].keys() == dev[2].keys() and host[2]
        for key in host[2]:
            for part, a, b in zip(("tiles", "starts", "tris"), host[2][key], dev[2][key]):
                assert np.array_equal(a, b), (band, key, part)


def test_band_height_follows_the_triangles():
    from pipegen.runtime.cl.bin import band_for
    rng = np.random.default_rng(3)

    def boxes(n, rows, width, height):
        x = rng.integers(0, width - 8, n)
        y = rng.integers(0, height - rows, n)
        return np.stack([x, y, x + 3, y + rows - 1], axis=1).astype(np.int32)
    # light volumes at 160x90: thousands of triangles 1-3 rows tall: a list per row
    assert band_for(boxes(25_000, 2, 160, 90), 16, 160, 90) == 1
    # taller triangles share lists a few rows tall, and very tall ones a tile's
    mid = band_for(boxes(7_000, 12, 1280, 720), 16, 1280, 720)
    assert 2 <= mid <= 8
    assert band_for(boxes(50, 300, 1280, 720), 16, 1280, 720) == 16
    # always a divisor of the tile (the kernels index a tile's lists by py / band)
    for rows in (1, 2, 5, 9, 30):
        for tile in (16, 12, 7):
            b = band_for(boxes(500, rows, 400, 300), tile, 400, 300)
            assert tile % b == 0
    assert band_for(np.zeros((0, 4), np.int32), 16, 64, 64) == 16


def test_tiles_with_triangles_from_their_lists():
    from pipegen.runtime.cl.bin import tiles_with
    # 3 tiles across, a 40-row pass in 16-row tiles: lists 4 rows tall, 10 bands (the last
    # tile row has 2 bands of its 4)
    has = np.zeros((10, 3), bool)
    has[1, 0] = has[3, 2] = has[9, 1] = True
    got = tiles_with(has.ravel(), 3, 4)
    want = np.zeros((3, 3), bool)
    want[0, 0] = want[0, 2] = want[2, 1] = True
    assert np.array_equal(got, want.ravel())
    assert np.array_equal(tiles_with(has.ravel(), 3, 1), has.ravel())
    # per light (leading axes kept)
    both = tiles_with(np.stack([has.ravel(), np.zeros(30, bool)]), 3, 4)
    assert np.array_equal(both, np.stack([want.ravel(), np.zeros(9, bool)]))
