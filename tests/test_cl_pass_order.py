"""The CL runtime prepares each pass execution's host work (set-up read-backs, bins) when its
turn comes, after the device work of the one before is queued, so that the device rasterises
pass k while the host prepares k + 1 (``CLPipeline._draw``).  ``$PIPEGEN_CL_HOST_FIRST=1``
prepares every pass first, as before; both orders render the same targets, blend counts and
clamps bit for bit, on techniques with shadow maps, CPU-sorted light slots, runs of lights
drawn in one launch, a fused repeat group and several render-target sizes.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]
SIZE = (64, 36)


@functools.lru_cache(maxsize=None)
def _scene(name: str):
    from pipegen import load_scene
    return load_scene(ROOT / "examples" / "scenes" / f"{name}.toml")


@functools.lru_cache(maxsize=None)
def _compiled(name: str, scene: str):
    from pipegen import compile_file
    from pipegen.compiler.driver import for_scene
    return for_scene(compile_file(ROOT / "pipelines" / f"{name}.pipe"), _scene(scene))


def _render(compiled, scene, host_first: bool, monkeypatch):
    """(targets, blend counts, clamps, the order of host preparations and raster launches)
    of a second frame."""
    monkeypatch.setenv("PIPEGEN_CL_HOST_FIRST", "1" if host_first else "0")
    pipe = compiled.pipeline("cl", SIZE)
    pipe.render(scene)
    order: list = []
    prepare, launch = pipe._prepare_pass, pipe._launch

    def logged_prepare(k, light):
        order.append(("prepare", k))
        return prepare(k, light)

    def logged_launch(k, *args, **kwargs):
        order.append(("launch", k))
        return launch(k, *args, **kwargs)

    pipe._prepare_pass, pipe._launch = logged_prepare, logged_launch
    out = pipe.render(scene)
    return out, pipe.last_blend_counts, pipe.last_clamps, order


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for name in a:
        assert a[name].dtype == b[name].dtype, name
        assert np.array_equal(a[name].view(np.uint8), b[name].view(np.uint8)), name


@pytest.mark.parametrize("technique, scene", [
    ("light_prepass", "many_lights"),
    ("inferred", "many_lights"),             # a smaller L-buffer: passes of two sizes
    ("lidr_cpu_sort", "many_lights"),        # CPU-sorted slot sets
    ("lidr_shadow_prepass", "mixed_lights"),  # shadow-map tiles, then the lights
    ("forward_multipass", "mixed_lights"),   # a run of lights in one launch
    ("deferred", "many_lights"),             # a fused repeat group
])
def test_passes_prepared_in_turn_render_what_preparing_first_renders(technique, scene,
                                                                      monkeypatch):
    compiled, s = _compiled(technique, scene), _scene(scene)
    in_turn = _render(compiled, s, False, monkeypatch)
    first = _render(compiled, s, True, monkeypatch)
    _assert_same(in_turn[0], first[0])
    _assert_same(in_turn[1], first[1])
    assert in_turn[2] == first[2]
    # the same work in another order: preparing first, no launch before the last preparation
    assert sorted(in_turn[3]) == sorted(first[3])
    kinds = [kind for kind, _ in first[3]]
    if "launch" in kinds and "prepare" in kinds:
        assert max(i for i, k in enumerate(kinds) if k == "prepare") \
            < min(i for i, k in enumerate(kinds) if k == "launch")


def test_in_turn_a_pass_is_launched_before_the_next_is_prepared(monkeypatch):
    compiled, s = _compiled("light_prepass", "many_lights"), _scene("many_lights")
    order = _render(compiled, s, False, monkeypatch)[3]
    launched = [k for kind, k in order if kind == "launch"]
    assert len(launched) >= 2
    first = order.index(("launch", launched[0]))
    assert ("prepare", launched[1]) in order[first + 1:]


def test_every_clipper_before_any_raster_and_the_first_bins_before_the_last(monkeypatch):
    """The device's queue in a frame: each set-up's clipper is queued before the next set-up
    kernel, every one before the first raster kernel (a clipper behind a raster kernel would
    hold up the host's next pass), and the first pass's binning before the last set-up's
    clipper (so that the device bins it right after setting up the others, not after the
    host's wait for the last set-up and its own preparation).  inferred on street_lamps: three
    set-ups, each clipping triangles that cross the near plane."""
    import pyopencl as cl
    compiled, s = _compiled("inferred", "street_lamps"), _scene("street_lamps")
    pipe = compiled.pipeline("cl", SIZE)
    pipe.render(s)
    names: list = []
    queue_kernel = cl.enqueue_nd_range_kernel

    def logged(queue, kernel, *args, **kwargs):
        names.append(kernel.function_name)
        return queue_kernel(queue, kernel, *args, **kwargs)

    monkeypatch.setattr(cl, "enqueue_nd_range_kernel", logged)
    pipe.render(s)
    clips = [i for i, n in enumerate(names) if n == "pg_clip_setup"]
    setups = [i for i, n in enumerate(names) if n == "pg_setup"]
    rasters = [i for i, n in enumerate(names) if n == "pg_raster"]
    bins = [i for i, n in enumerate(names) if n == "pg_bin_count"]
    assert len(clips) >= 2 and len(setups) >= 3 and rasters and bins, names
    assert max(clips) < min(rasters)
    assert min(bins) < max(clips)
    # a set-up's clipper before the next set-up kernel (the first set-up clips, and so does
    # at least one more before the last)
    assert clips[0] < setups[1] and clips[-2] < setups[-1], names
