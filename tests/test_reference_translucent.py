"""The float64 reference for lit translucent layers (reference/translucent.py) and the image
metrics (reference/metrics.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.reference.lighting import reference_image, to_rgba8
from pipegen.reference.metrics import (
    dilate, error_image, error_map_png, reference_codes, rgb_error, silhouette_mask, to_top_down)
from pipegen.reference.translucent import reference_composite, stippled_gbuffer
from pipegen.scene import load_scene, parse_scene, stipple_map

from scenes_for_tests import plane, planes_scene

SCENES = Path(__file__).resolve().parent.parent / "examples" / "scenes"

# Camera on +z looking at the origin; planes rotated to face +z.  No lights: every surface is
# lit by the ambient term alone (0.5 * albedo), so the composite is known exactly.
def _planes(amb: float = 0.5, near_layer=None, far_layer=None):
    return parse_scene(planes_scene(
        plane("near", [0, 1, 0], translate=[0.5, 0.5, 1], scale=1, alpha=0.25, layer=near_layer),
        plane("opaque", [0, 0, 1], translate=[0, 0, -2], scale=4),
        plane("far", [1, 0, 0], scale=2, alpha=0.5, layer=far_layer),
        plane("over sky", [1, 1, 1], translate=[2.2, 0, 0], scale=0.8, alpha=0.5),
        plane("hidden", [1, 1, 0], translate=[0, 0, -3], scale=2, alpha=0.5),
        ambient=amb))


def test_composite_back_to_front_exact():
    s = _planes()
    rgb, info = reference_composite(s)
    near, far, sky, hidden = info["surfaces"]
    assert [x.object.name for x in info["surfaces"]] == ["near", "far", "over sky", "hidden"]
    assert hidden.gbuffer.coverage.any() and not hidden.visible.any()    # behind the opaque plane
    both = near.visible & far.visible
    far_only = far.visible & ~near.visible
    assert both.sum() > 20 and far_only.sum() > 20 and sky.visible.sum() > 5
    assert not (sky.visible & info["gbuffer"].coverage).any()
    opaque = np.array([0.0, 0.0, 0.5])
    lerp = lambda a, b, t: a + (b - a) * t                                 # noqa: E731
    np.testing.assert_allclose(rgb[far_only], np.tile(lerp(opaque, [0.5, 0, 0], 0.5), (far_only.sum(), 1)))
    # the near plane is listed first in the file but blended last
    expect = lerp(lerp(opaque, [0.5, 0, 0], 0.5), [0, 0.5, 0], 0.25)
    np.testing.assert_allclose(rgb[both], np.tile(expect, (both.sum(), 1)))
    np.testing.assert_allclose(rgb[sky.visible], 0.25)                    # over the clear colour
    plain = info["gbuffer"].coverage & ~info["covered"]
    np.testing.assert_allclose(rgb[plain], np.tile(opaque, (plain.sum(), 1)))
    # counts, masks and the back-to-front order
    np.testing.assert_array_equal(info["count"], near.visible.astype(int) + far.visible + sky.visible)
    np.testing.assert_array_equal(info["covered"], info["count"] > 0)
    assert np.all(info["order"][0][both] == 1) and np.all(info["order"][1][both] == 0)
    assert np.all(info["layer_masks"][0] == info["gbuffer"].coverage)
    assert not info["conflict"].any()
    assert (info["silhouette"] >= info["gbuffer"].silhouette).all()
    assert info["silhouette"].sum() > info["gbuffer"].silhouette.sum()   # the planes' outlines
    assert not info["silhouette"][far_only & ~dilate(~far_only, 2)].any()  # not inside a plane


def test_composite_automatic_layers_and_conflicts():
    s = _planes()
    # far -> near by distance to the bounding-box centre: hidden 8, over sky 5.46, far 5, near 4.06
    layers = {o.name: o.layer for o in s.objects}
    assert layers == {"opaque": 0, "hidden": 1, "over sky": 2, "far": 3, "near": 1}
    _, info = reference_composite(s)
    assert not info["conflict"].any()
    # the same layer on two overlapping planes is a conflict where both are visible
    s2 = _planes(near_layer=2, far_layer=2)
    assert [o.layer for o in s2.objects if o.name in ("near", "far")] == [2, 2]
    _, info2 = reference_composite(s2)
    near, far = info2["surfaces"][:2]
    np.testing.assert_array_equal(info2["conflict"], near.visible & far.visible)


def test_composite_clamps_layers_like_unorm_blending():
    s = _planes(amb=4.0)                                                   # everything lit > 1
    rgb, info = reference_composite(s)
    near, far = info["surfaces"][:2]
    far_only = far.visible & ~near.visible
    # opaque (0, 0, 4) and far (4, 0, 0) clamp to (0, 0, 1) and (1, 0, 0) before blending
    np.testing.assert_allclose(rgb[far_only], np.tile([0.5, 0.0, 0.5], (far_only.sum(), 1)))
    raw, _ = reference_composite(s, clamp_layers=False)
    np.testing.assert_allclose(raw[far_only], np.tile([2.0, 0.0, 2.0], (far_only.sum(), 1)))
    plain = ~info["covered"]
    np.testing.assert_array_equal(rgb[plain], info["opaque"][plain])      # untouched, unclamped


@pytest.fixture(scope="module")
def layered():
    s = load_scene(SCENES / "translucent_layers.toml")
    rgb, info = reference_composite(s)
    return s, rgb, info


def test_translucent_layers_scene_has_at_most_three_layers(layered):
    s, rgb, info = layered
    assert info["count"].max() == 3                                       # three deep somewhere ...
    assert (info["count"] == 3).sum() > 50
    assert (info["count"] == 2).sum() > 300
    assert not info["conflict"].any()                                      # ... each on its own layer
    np.testing.assert_array_equal(info["layer_masks"][1:].sum(axis=0), info["count"])
    assert all(info["layer_masks"][k].sum() > 200 for k in (1, 2, 3))
    assert 0.1 < info["covered"].mean() < 0.5


def test_translucent_layers_composite_vs_opaque(layered):
    s, rgb, info = layered
    opaque, gb = reference_image(s)
    np.testing.assert_array_equal(info["opaque"], opaque)
    cov = info["covered"]
    np.testing.assert_array_equal(rgb[~cov], opaque[~cov])                # equal elsewhere
    diff = np.abs(rgb - opaque).max(axis=-1)
    assert (diff[cov] > 1e-3).mean() > 0.99                               # changed under glass
    assert np.abs(to_rgba8(rgb)[cov].astype(int) - to_rgba8(opaque)[cov]).max() > 40
    assert np.isfinite(rgb).all() and rgb.min() >= 0
    from PIL import Image
    Image.fromarray(to_rgba8(rgb)).save("/tmp/ref_translucent_layers.png")


def test_stippled_gbuffer(layered):
    s, _, _ = layered
    low = s.with_size(96, 54)                                             # a half-resolution G-buffer
    gb, layer = stippled_gbuffer(low)
    _, info = reference_composite(low)
    opaque = info["gbuffer"]
    owner = stipple_map(96, 54)
    # layer-0 pixels and pixels without a surface of their layer keep the opaque surface
    keep = layer == 0
    assert (keep | (owner != 0)).all()
    np.testing.assert_array_equal(gb.object_id[keep], opaque.object_id[keep])
    np.testing.assert_array_equal(gb.depth[keep], opaque.depth[keep])
    # every visible translucent surface is stored exactly at the pixels its layer owns
    for surf in info["surfaces"]:
        here = surf.visible & (owner == surf.layer)
        assert np.all(gb.object_id[here] == surf.object.id) and np.all(layer[here] == surf.layer)
        np.testing.assert_array_equal(gb.position[here], surf.gbuffer.position[here])
        assert not (gb.object_id[surf.visible & (owner != surf.layer)] == surf.object.id).any()
    for k in (1, 2, 3):
        assert (layer == k).sum() > 30
    owned = np.take_along_axis(info["layer_masks"], owner[None], axis=0)[0]  # a surface of its layer
    np.testing.assert_array_equal(layer > 0, (owner > 0) & owned)


# -- metrics -------------------------------------------------------------------------------------


def test_rgb_error_flips_rows_once():
    rng = np.random.default_rng(5)
    ref = rng.uniform(-0.1, 1.1, (6, 8, 3))                               # top row first
    codes = to_rgba8(ref)[::-1].copy()                                     # bottom row first
    e = rgb_error(codes, ref)
    assert e == dict(rmse=0.0, max=0.0, p99=0.0, mean=0.0, pixels=48, worst=(0, 0))
    np.testing.assert_array_equal(to_top_down(codes), to_rgba8(ref))
    np.testing.assert_array_equal(reference_codes(ref), to_rgba8(ref)[..., :3])
    # one pixel off by 6 codes in green at x = 2, top-down row 1 (bottom-up row 4)
    bad = codes.copy()
    bad[4, 2, 1] = np.uint8(int(bad[4, 2, 1]) + 6 if bad[4, 2, 1] < 200 else int(bad[4, 2, 1]) - 6)
    bad[4, 2, 3] = 0                                                       # alpha is ignored
    e = rgb_error(bad, ref)
    assert e["max"] == 6 and e["worst"] == (2, 1) and e["pixels"] == 48
    assert e["rmse"] == pytest.approx(np.sqrt(36 / 144)) and e["mean"] == pytest.approx(6 / 144)
    assert e["p99"] == pytest.approx(np.percentile([6] + [0] * 47, 99))
    err = error_image(bad, ref)
    assert err.shape == (6, 8, 3) and err[1, 2, 1] == 6 and err.sum() == 6
    # a top-down mask excluding that pixel
    mask = np.ones((6, 8), bool)
    mask[1, 2] = False
    assert rgb_error(bad, ref, mask)["max"] == 0 and rgb_error(bad, ref, mask)["pixels"] == 47
    assert rgb_error(bad, ref, np.zeros((6, 8), bool))["pixels"] == 0
    with pytest.raises(ValueError):
        rgb_error(bad, ref, np.ones((8, 6), bool))
    with pytest.raises(ValueError):
        rgb_error(bad[:5], ref)


def test_error_map_png(tmp_path):
    from PIL import Image
    err = np.zeros((4, 5, 3))
    err[0, 0] = [0, 10, 2]
    err[3, 4] = 5
    path = error_map_png(tmp_path / "e.png", err)
    img = np.asarray(Image.open(path))
    assert img.shape == (4, 5, 3)
    assert img[0, 0].tolist() == [255, 255, 255] and img[1, 1].tolist() == [0, 0, 0]
    assert img[3, 4, 0] > img[3, 4, 2]                                     # halfway: red-ish
    mask = np.ones((4, 5), bool)
    mask[2, 2] = False
    img = np.asarray(Image.open(error_map_png(tmp_path / "m.png", err[..., 0], vmax=1, mask=mask)))
    assert img[2, 2].tolist() == [0, 0, 60] and img[3, 4].tolist() == [255, 255, 255]


def test_silhouette_mask(layered):
    s, _, info = layered
    opaque_only = silhouette_mask(s, translucent=False)
    np.testing.assert_array_equal(opaque_only, info["gbuffer"].silhouette)
    full = silhouette_mask(s)
    assert full.shape == (s.height, s.width) and (full >= opaque_only).all()
    assert full.sum() > opaque_only.sum()                                  # glass outlines added
    grown = silhouette_mask(s, radius=1)
    assert (grown >= full).all() and grown.sum() > full.sum()
    np.testing.assert_array_equal(grown, dilate(full, 1))
    one = np.zeros((5, 5), bool)
    one[2, 2] = True
    assert dilate(one, 1).sum() == 9 and dilate(one, 2).sum() == 25
