"""pipegen.testing (issue 24, item 2): render, the three assertions, lossless goldens, the
failure messages and error images, the records the plugin's report reads."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from pipegen.testing import api, records, settings

ROOT = Path(__file__).resolve().parent.parent
TOON = ROOT / "examples" / "techniques" / "toon_deferred.pipe"


def test_importing_pipegen_testing_imports_nothing_heavy():
    code = ("import sys, pipegen.testing, pipegen.testing.plugin\n"
            "heavy = [m for m in ('numpy', 'moderngl', 'pyopencl', 'pipegen.compiler.driver')"
            " if m in sys.modules]\n"
            "print(heavy)\n"
            "pipegen.testing.render\n"
            "print('numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd="/").stdout.split("\n")
    assert out[0] == "[]" and out[1] == "True", out


@pytest.mark.parametrize("dtype, shape, suffix", [
    (np.uint8, (5, 7, 4), ".png"), (np.uint8, (5, 7), ".png"), (np.uint8, (5, 7, 2), ".png"),
    (np.uint16, (5, 7), ".png"), (np.uint16, (5, 7, 4), ".npy"), (np.float16, (5, 7, 4), ".npy"),
    (np.float32, (5, 7, 4), ".npy"), (np.uint32, (5, 7, 2), ".npy"), (np.float32, (5, 7), ".npy"),
])
def test_goldens_are_lossless_and_png_where_png_is(tmp_path, dtype, shape, suffix):
    rng = np.random.default_rng(1)
    if np.dtype(dtype).kind == "f":
        values = rng.normal(size=shape).astype(dtype)
        values.flat[0] = np.nan
    else:
        values = rng.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True).astype(dtype)
    path = api.golden_path(tmp_path, "t.x", values)
    assert path.suffix == suffix and path.name.startswith("t.x")
    api.write_golden(path, values)
    back = api.read_golden(path, values)
    assert back.dtype == values.dtype and back.shape == values.shape
    np.testing.assert_array_equal(back, values)          # NaN equal to NaN: bit for bit
    if suffix == ".png":        # the picture is upright: its top row is the target's last
        top = np.asarray(Image.open(path))[0]
        np.testing.assert_array_equal(top.reshape(values[-1].shape), values[-1])
    assert [p.name for p in tmp_path.iterdir()] == [path.name]   # no temporary left


@pytest.mark.gl
def test_render_targets_formats_size_and_command():
    t = api.render(TOON)
    assert t.backend == "gl" and t.technique == "toon_deferred"
    assert (t.scene.width, t.scene.height) == api.TEST_SIZE
    assert {k: v.format for k, v in t.items()} == {
        "color": "rgba8", "ds": "d24s8", "ds.stencil": "d24s8", "galbedo": "rgba8",
        "gnormal": "rgba8", "gpos": "rgba32f"}
    assert t["color"].values.shape == (36, 64, 4) and t["color"].values.dtype == np.uint8
    assert t["color"].picture().shape == (36, 64, 3)
    assert "pipegen run" in t.command and "--size 64x36" in t.command \
        and "--backend gl" in t.command
    t5 = api.render(TOON, size=(32, 18), params={"bands": 5.0})
    assert t5["color"].values.shape == (18, 32, 4) and "-p bands=5.0" in t5.command


@pytest.mark.gl
@pytest.mark.cl
def test_backends_agree_records_every_target():
    records.take()
    result = api.assert_backends_agree(TOON)
    assert result.passed
    made = records.take()
    assert {c.target for c in made} == {"color", "ds", "ds.stencil", "galbedo", "gnormal",
                                        "gpos"}
    assert all(c.kind == "backends" and c.passed and "pipegen check" in c.command
               for c in made)


@pytest.mark.gl
@pytest.mark.cl
def test_goldens_written_then_matched_across_backends_then_a_change_fails(tmp_path,
                                                                          monkeypatch):
    monkeypatch.setattr(settings, "artifacts_dir", tmp_path / "artifacts")
    monkeypatch.setattr(settings, "update_goldens", False)
    goldens = tmp_path / "goldens"
    cl = api.render(TOON, backend="cl")
    with pytest.raises(api.ComparisonFailure) as e:
        api.assert_matches_golden(cl, goldens)
    assert "no golden for 'color'" in str(e.value) and "--pipegen-update-goldens" in str(e.value)
    assert not goldens.exists()                       # never written in a normal run
    api.assert_matches_golden(cl, goldens, update=True)
    assert sorted(p.name for p in goldens.iterdir()) == [
        "color.png", "ds.npy", "ds.stencil.png", "galbedo.png", "gnormal.png", "gpos.npy"]
    # GL against CL's goldens: the limits of two float32 renderings
    made = api.assert_matches_golden(api.render(TOON, backend="gl"), goldens)
    assert all(c.passed for c in made) and len(made) == 6
    # a one-token change (4 bands -> 5) moves whole bands
    changed = api.render(TOON, backend="gl", params={"bands": 5.0})
    with pytest.raises(api.ComparisonFailure) as e:
        api.assert_matches_golden(changed, goldens, only={"color"})
    msg = str(e.value)
    assert "target 'color' (rgba8)" in msg and "worst at (x=" in msg and "limit ≤1" in msg
    assert "render (" in msg and "vs golden (" in msg
    failed = [c for c in e.value.comparisons if not c.passed]
    assert [c.target for c in failed] == ["color"]
    diff = Path(failed[0].artifacts["difference"])
    assert diff.parent == tmp_path / "artifacts" and str(diff) in msg
    assert Image.open(diff).size == (64, 36)
    red = np.all(np.asarray(Image.open(diff)) == (255, 40, 40), axis=-1)
    assert red.sum() == int(msg.split(": ")[1].split(" px")[0])     # one red pixel per px over
    # the FLIP option: a loose threshold accepts the change, a strict one does not
    api.assert_matches_golden(changed, goldens, only={"color"}, flip_mean=0.5)
    with pytest.raises(api.ComparisonFailure, match="ꟻLIP over its threshold"):
        api.assert_matches_golden(changed, goldens, only={"color"}, flip_mean=0.001,
                                  flip_percentile=(99, 0.01))


@pytest.mark.gl
@pytest.mark.cl
def test_keep_images_gives_the_report_its_pictures(tmp_path, monkeypatch):
    monkeypatch.setattr(settings, "keep_images", True)
    monkeypatch.setattr(settings, "artifacts_dir", tmp_path)
    cl = api.render(TOON, backend="cl", size=(32, 18))
    api.assert_matches_golden(cl, tmp_path / "g", update=True)
    records.take()
    made = api.assert_matches_golden(api.render(TOON, backend="gl", size=(32, 18)),
                                     tmp_path / "g", only={"color"}, flip_mean=0.5)
    (c,) = made
    assert set(c.images) == {"expected", "actual", "difference", "flip"}
    assert all(im.shape == (18, 32, 3) and im.dtype == np.uint8 for im in c.images.values())
    assert records.take() == made
