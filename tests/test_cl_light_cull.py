"""Light volumes are culled at set-up where every pass drawing them culls the same faces
(``DrawGeometry._light_cull``; ``cull auto``: each light's faces as the host chooses them):
the frames are the ones a set-up without culling gives (each pass then culling its own,
``_cull_auto`` filtering per light), targets and blend counts alike."""

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]


def _render(technique: str, scene, culled: bool, monkeypatch):
    from pipegen import compile_file
    from pipegen.runtime.cl import geometry as G
    if not culled:
        monkeypatch.setattr(G.DrawGeometry, "_light_cull", lambda self, key: "none")
    else:
        monkeypatch.undo()
    pipe = compile_file(ROOT / "pipelines" / f"{technique}.pipe").pipeline("cl", (160, 90))
    out = pipe.render(scene)
    modes = sorted(v for k, v in pipe.geometry.frame.items()
                   if isinstance(k, tuple) and k[0] == "light cull")
    return out, pipe.last_blend_counts, modes


@pytest.mark.parametrize("technique,scene_name,modes", [
    ("light_prepass", "mixed_lights", ["front", "front", "none"]),
    ("lidr_bitplanes", "street_lamps", ["front", "front", "none"]),
    ("inferred", "mixed_lights", ["front", "none", "none"]),
    ("deferred", "mixed_lights", ["none", "none", "none"]),
    # cull auto: each light's faces chosen on the host, culled at set-up (lights around the
    # camera drawn with their back faces)
    ("deferred_calver", "stress_overlap", ["auto"]),
    ("lidr_transparent", "mixed_lights", ["auto", "auto", "none"])])
def test_light_volumes_culled_at_set_up_render_as_culled_per_pass(technique, scene_name,
                                                                   modes, monkeypatch):
    from pipegen import load_scene
    scene = load_scene(ROOT / "examples" / "scenes" / f"{scene_name}.toml")
    plain, plain_counts, _ = _render(technique, scene, False, monkeypatch)
    culled, counts, got_modes = _render(technique, scene, True, monkeypatch)
    assert got_modes == modes
    if scene_name == "stress_overlap":     # some lights drawn with their back faces
        from pipegen import compile_file
        pipe = compile_file(ROOT / "pipelines" / f"{technique}.pipe").pipeline("cl", (160, 90))
        pipe.render(scene)
        flats = [np.asarray(g.tris.flat) for g in pipe.geometry.frame.values()
                 if getattr(g, "setup_cull", None) == "auto"]
        assert any(((f[:, 0] >> 1) & 1).any() for f in flats)
    assert plain.keys() == culled.keys()
    for name in plain:
        assert np.array_equal(plain[name], culled[name]), name
    for name in plain_counts:
        assert np.array_equal(plain_counts[name], counts[name]), name


def test_cull_auto_at_set_up_in_the_float64_evaluation(monkeypatch):
    """The float64 evaluation sets triangles up in numpy (``cl_setup.setup_triangles``, which
    culls per triangle too): the same values as culling per pass."""
    from pipegen import compile_file, load_scene
    from pipegen.runtime.cl import geometry as G
    scene = load_scene(ROOT / "examples" / "scenes" / "stress_overlap.toml")
    compiled = compile_file(ROOT / "pipelines" / "deferred_calver.pipe")
    culled = compiled.pipeline("cl", (97, 61), precision="f64").render(scene)
    monkeypatch.setattr(G.DrawGeometry, "_light_cull", lambda self, key: "none")
    plain = compiled.pipeline("cl", (97, 61), precision="f64").render(scene)
    for name in plain:
        assert np.array_equal(plain[name], culled[name]), name
