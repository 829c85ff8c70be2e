"""A ``repeat per light`` group's bins are found for all its lights at once
(``DrawGeometry._group_bins``): the render is bit-identical to binning each light's pairs on
its own, and each light's cached bins are the ones the per-light path builds.  (With the group
fused into one launch, the default, no bins per light are made: the pass executions one by
one are what falls back where a frame does not fit, ``runtime/cl/group_launch.py``.)"""

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]


def _render(technique: str, scene_name: str, grouped: bool, monkeypatch):
    from pipegen import compile_file, load_scene
    from pipegen.runtime.cl import geometry as G
    if not grouped:
        monkeypatch.setattr(G.DrawGeometry, "_group_bins", lambda *a, **k: None)
    else:
        monkeypatch.undo()
    # the executions one by one: a fused group (group_launch.py) bins each pass once
    monkeypatch.setenv("PIPEGEN_CL_FUSE_GROUPS", "0")
    scene = load_scene(ROOT / "examples" / "scenes" / f"{scene_name}.toml")
    pipe = compile_file(ROOT / "pipelines" / f"{technique}.pipe").pipeline("cl", (96, 54))
    out = pipe.render(scene)
    # one light's bins: ("bins", id(triangles), (light,), cull, width, height)
    bins = {k[2:]: v.host for k, v in pipe.geometry.frame.items()
            if k[0] == "bins" and len(k) == 6 and len(k[2]) == 1}
    return out, bins


@pytest.mark.parametrize("technique,scene_name", [("deferred", "mixed_lights"),
                                                  ("deferred", "street_lamps")])
def test_grouped_bins_render_and_bin_as_per_light_bins(technique, scene_name, monkeypatch):
    alone, alone_bins = _render(technique, scene_name, False, monkeypatch)
    grouped, grouped_bins = _render(technique, scene_name, True, monkeypatch)
    assert alone.keys() == grouped.keys()
    for name in alone:
        assert np.array_equal(alone[name], grouped[name]), name
    assert alone_bins.keys() == grouped_bins.keys()
    assert len(alone_bins) > 2, "the scene should draw lights one by one"
    for k in alone_bins:
        for a, b in zip(alone_bins[k], grouped_bins[k]):
            assert np.array_equal(a, b), k
