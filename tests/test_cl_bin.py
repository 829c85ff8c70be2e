"""Binning on the device (``runtime/cl/bin.py``, ``templates/cl_bin.cl.j2``) gives the numpy
binning's tile lists (``cl_setup.bin_pairs`` + ``bins_from_pairs``): the same tiles, the
same triangles in each, in submission order; frames rendered with either are identical."""

import re
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]


def _frame(source: str, scene, size, device: bool, monkeypatch):
    from pipegen import compile_source
    from pipegen.runtime.cl import bin as cl_bin
    monkeypatch.setenv("PIPEGEN_CL_DEVICE_BIN", "1" if device else "0")
    assert cl_bin.enabled() is device
    pipe = compile_source(source).pipeline("cl", size)
    out = pipe.render(scene)
    # every bins object of the frame, keyed without the set-up's id (differs between runs)
    bins = {k[:1] + k[2:]: v for k, v in pipe.geometry.frame.items()
            if isinstance(k, tuple) and k[0] == "bins"}
    kinds = {type(v).__name__ for v in bins.values()}
    return out, {k: v.host for k, v in bins.items()}, kinds, pipe.last_blend_counts


def _assert_same(source: str, scene_name: str, size, monkeypatch) -> set:
    from pipegen import load_scene
    scene = load_scene(ROOT / "examples" / "scenes" / f"{scene_name}.toml")
    want, want_bins, want_kinds, want_counts = _frame(source, scene, size, False, monkeypatch)
    got, got_bins, got_kinds, got_counts = _frame(source, scene, size, True, monkeypatch)
    assert want_kinds <= {"Bins", "LightBins"}      # LightBins: a repeat group's (group_bins)
    assert want.keys() == got.keys()
    for name in want:
        assert np.array_equal(want[name], got[name]), name
    for name in want_counts:
        assert np.array_equal(want_counts[name], got_counts[name]), name
    assert want_bins.keys() == got_bins.keys()
    for key in want_bins:
        for part, a, b in zip(("tiles", "tile_start", "tile_tris"), want_bins[key],
                              got_bins[key]):
            assert np.array_equal(a, b), (key, part)
    return got_kinds


@pytest.mark.parametrize("technique,scene_name", [
    ("light_prepass", "many_lights"), ("light_prepass", "mixed_lights"),
    ("inferred", "street_lamps"), ("deferred_calver", "mixed_lights"),
    ("deferred", "mixed_lights"), ("lidr_cpu_sort", "edges"),
    ("lidr_transparent", "translucent_layers"), ("forward", "shadows")])
def test_device_bins_are_the_numpy_bins(technique, scene_name, monkeypatch):
    source = (ROOT / "pipelines" / f"{technique}.pipe").read_text()
    kinds = _assert_same(source, scene_name, (203, 117), monkeypatch)
    assert "DeviceBins" in kinds


def test_device_bins_of_multisampled_passes(monkeypatch):
    """With 4 samples a pixel the edge tests use the extreme sample positions."""
    source = (ROOT / "pipelines" / "light_prepass.pipe").read_text()
    source, n = re.subn(r"^(target \w+\s*:\s*\w+)", r"\1 samples 4", source, flags=re.M)
    assert n == 5
    assert "DeviceBins" in _assert_same(source, "mixed_lights", (160, 90), monkeypatch)


def test_box_tiles_bound_the_entries():
    """The tile lists are sized by the boxes' tiles: never fewer than binning writes."""
    from pipegen.runtime.cl import bin as cl_bin, setup as cl_setup
    rng = np.random.default_rng(7)
    clip = rng.uniform(-1.5, 1.5, (300 * 3, 4)).astype(np.float32)
    clip[:, 3] = rng.uniform(0.5, 2.0, len(clip)).astype(np.float32)
    tris = cl_setup.setup_triangles(clip, 97, 61)
    tri, _, _, _ = cl_setup.bin_pairs(tris, 97, 61, 16)
    assert tris.count > 100
    assert len(tri) <= cl_bin.box_tiles(tris.bbox, 16)


def _segment_calls(monkeypatch) -> list:
    """The number of passes each ``DeviceBinner.bin_segments`` call bins, as calls come."""
    from pipegen.runtime.cl import bin as cl_bin
    calls: list = []
    segments = cl_bin.DeviceBinner.bin_segments

    def counted(self, bufs, rows, *args, **kwargs):
        calls.append(len(rows))
        return segments(self, bufs, rows, *args, **kwargs)

    monkeypatch.setattr(cl_bin.DeviceBinner, "bin_segments", counted)
    return calls


def test_light_slots_binned_in_one_call_are_each_passs_own_lists(monkeypatch):
    """LIDR's four light-index slot passes draw disjoint light sets of one set-up: their bins
    come from one segmented device call (``DrawGeometry._shared_bins``, one triangle-row
    buffer for all), list for list the numpy binning of each pass on its own, and the frame
    is the same."""
    calls = _segment_calls(monkeypatch)
    source = (ROOT / "pipelines" / "lidr_cpu_sort.pipe").read_text()
    _assert_same(source, "many_lights", (120, 68), monkeypatch)
    assert max(calls) == 4, calls          # the four slots' lights in one call
    from pipegen import compile_source, load_scene
    pipe = compile_source(source).pipeline("cl", (120, 68))
    pipe.render(load_scene(ROOT / "examples" / "scenes" / "many_lights.toml"))
    slots = [v for k, v in pipe.geometry.frame.items()
             if isinstance(k, tuple) and k[0] == "bins" and isinstance(k[2], tuple)]
    assert len(slots) == 4 and len({id(b.tile_tris) for b in slots}) == 1


def test_a_fused_groups_members_binned_in_one_call(monkeypatch):
    """Deferred's fused light group: the marking pass's lists (every face of every light's
    volume) and the shading pass's (back faces) from one segmented call, the numpy lists
    each, the same frame."""
    calls = _segment_calls(monkeypatch)
    source = (ROOT / "pipelines" / "deferred.pipe").read_text()
    _assert_same(source, "many_lights", (120, 68), monkeypatch)
    assert 2 in calls, calls
