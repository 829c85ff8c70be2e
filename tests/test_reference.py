"""The float64 reference: rasteriser rules against analytic answers, and the lighting equation
on its hard cases (DESIGN.md §8)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.reference.lighting import (
    attenuation, light_contribution, lights_per_pixel, reference_image, safe_normalize, shade,
    to_rgba8)
from pipegen.reference.raster import edge_mask, rasterize, rasterize_each, rasterize_triangles
from pipegen.scene import Light, default_scene, load_scene, parse_scene

SCENES = Path(__file__).resolve().parent.parent / "examples" / "scenes"
W, H = 16, 12


def ndc(x: float, y: float, z: float = 0.0) -> list[float]:
    """Image-space pixel coordinates (x right, y down, pixel centres at +0.5) -> NDC (w = 1)."""
    return [2.0 * x / W - 1.0, 1.0 - 2.0 * y / H, z]


def raster(tris, cull="none"):
    """Rasterise triangles given in image-space pixel coordinates; returns (coverage count per
    pixel when drawn one by one, winners of drawing them all)."""
    pos = np.array([[ndc(*v) for v in t] for t in tris], dtype=np.float64)
    nrm = np.zeros_like(pos)
    count = np.zeros(W * H, dtype=int)
    for k in range(len(pos)):
        f = rasterize_triangles(pos[k:k + 1], nrm[k:k + 1], np.eye(4), W, H, cull)
        np.add.at(count, f.pixel, 1)
    return count.reshape(H, W), rasterize_triangles(pos, nrm, np.eye(4), W, H, cull)


# -- rasteriser ----------------------------------------------------------------------------------


def test_quad_covers_known_pixels():
    # pixel boundaries: columns 3..9, rows 2..6 exactly
    count, _ = raster([[(3, 2), (3, 7), (10, 7)], [(3, 2), (10, 7), (10, 2)]])
    expect = np.zeros((H, W), dtype=int)
    expect[2:7, 3:10] = 1
    np.testing.assert_array_equal(count, expect)


def test_top_left_rule_on_edges_through_pixel_centres():
    # a square whose edges and diagonal run exactly through pixel centres
    count, _ = raster([[(0.5, 0.5), (8.5, 8.5), (8.5, 0.5)], [(0.5, 0.5), (0.5, 8.5), (8.5, 8.5)]])
    expect = np.zeros((H, W), dtype=int)
    expect[0:8, 0:8] = 1          # left and top edges included, right and bottom excluded
    np.testing.assert_array_equal(count, expect)


def test_shared_edges_cover_each_pixel_once():
    # eight triangles fanned around a pixel centre, with horizontal, vertical and diagonal edges
    c = (6.5, 5.5)
    ring = [(2.5, 1.5), (6.5, 1.5), (10.5, 1.5), (10.5, 5.5), (10.5, 9.5), (6.5, 9.5), (2.5, 9.5), (2.5, 5.5)]
    tris = [[c, ring[k], ring[(k + 1) % 8]] for k in range(8)]
    count, _ = raster(tris)
    expect = np.zeros((H, W), dtype=int)
    expect[1:9, 2:10] = 1        # edges through centres: left/top included, right/bottom not
    np.testing.assert_array_equal(count, expect)
    # and for arbitrary sub-pixel positions: a random triangulated grid
    rng = np.random.default_rng(3)
    xs = np.linspace(-1, W + 1, 6) + rng.uniform(-0.4, 0.4, 6)
    ys = np.linspace(-1, H + 1, 5) + rng.uniform(-0.4, 0.4, 5)
    grid = [[(xs[i], ys[j]) for i in range(6)] for j in range(5)]
    tris = []
    for j in range(4):
        for i in range(5):
            a, b, cc, d = grid[j][i], grid[j][i + 1], grid[j + 1][i + 1], grid[j + 1][i]
            tris += [[a, b, cc], [a, cc, d]]
    count, _ = raster(tris)
    assert np.all(count == 1)


def test_back_face_culling():
    # ccw in GL window space (y up) is clockwise in image space (y down)
    front = [(2, 2), (2, 8), (8, 2)]      # image-space: down, then up-right -> ccw in GL
    back = [(2, 2), (8, 2), (2, 8)]
    assert raster([front], cull="back")[0].sum() > 0
    assert raster([back], cull="back")[0].sum() == 0
    assert raster([back], cull="none")[0].sum() == raster([front], cull="none")[0].sum()
    assert raster([front], cull="front")[0].sum() == 0


def test_depth_less_and_primitive_order():
    full = lambda z: [[(0, 0, z), (0, H, z), (W, H, z)], [(0, 0, z), (W, H, z), (W, 0, z)]]  # noqa: E731
    for tris, winner in [(full(0.5) + full(-0.5), 2), (full(-0.5) + full(0.5), 0), (full(0.1) + full(0.1), 0)]:
        _, f = raster(tris)
        assert len(f.pixel) == W * H
        assert set((f.triangle // 2 * 2).tolist()) == {winner}
    _, f = raster(full(0.5))
    np.testing.assert_allclose(f.depth, 0.75)


def test_edge_mask():
    ids = -np.ones((6, 6), dtype=int)
    ids[2:4, 2:4] = 7
    e = edge_mask(ids)
    assert e[1:5, 1:5].all() and not e[0].any() and not e[:, 5].any()


def _plane_scene(camera: str, floor: str) -> str:
    return f"""
width = 80
height = 50
[camera]
{camera}
fov_y_deg = 50
near = 0.2
far = 200
[[objects]]
mesh = "plane"
{floor}
material = {{ albedo = [0.5, 0.5, 0.5] }}
"""


@pytest.mark.parametrize("camera,floor", [
    # the floor in front of the camera only
    ("position = [0, 3, 6]\ntarget = [0, 0, 0]", "translate = [0, 0, -10]\nscale = [40, 1, 30]"),
    # the floor all around the camera: triangles cross the near plane and w = 0
    ("position = [0.3, 1.0, 0.2]\ntarget = [2, 0.2, -5]", "scale = 100"),
])
def test_perspective_correct_positions_and_depth(camera, floor):
    scene = parse_scene(_plane_scene(camera, floor))
    gb = rasterize(scene)
    cov = gb.coverage
    assert cov.sum() > 0.3 * cov.size
    P = gb.position[cov]
    assert np.isfinite(P).all()
    np.testing.assert_allclose(P[:, 1], 0.0, atol=1e-9)                  # on the plane
    # reprojecting the interpolated position lands on the pixel centre (within the 1/256 snap)
    mvp = scene.camera.projection(scene.aspect) @ scene.camera.view_matrix()
    clip = np.concatenate([P, np.ones((len(P), 1))], axis=1) @ mvp.T
    ndc_ = clip[:, :3] / clip[:, 3:]
    rows, cols = np.nonzero(cov)
    sx = (ndc_[:, 0] + 1) * 0.5 * scene.width
    sy = (1 - ndc_[:, 1]) * 0.5 * scene.height
    assert np.abs(sx - (cols + 0.5)).max() < 0.01
    assert np.abs(sy - (rows + 0.5)).max() < 0.01
    np.testing.assert_allclose(gb.depth[cov], ndc_[:, 2] * 0.5 + 0.5, atol=1e-5)
    np.testing.assert_allclose(gb.normal[cov], np.tile([0, 1, 0], (len(P), 1)), atol=1e-7)
    assert np.all(gb.object_id[cov] == 1) and np.all(gb.object_id[~cov] == -1)
    assert np.all(gb.depth[~cov] == 1.0)


def test_gbuffer_attributes_default_scene():
    s = default_scene()
    gb = rasterize(s)
    assert gb.coverage.all()                                               # the floor fills the view
    ids = set(np.unique(gb.object_id).tolist())
    assert ids == {o.id for o in s.objects}                                # every object is visible
    sphere = next(o for o in s.objects if o.name == "white sphere")
    m = gb.object_id == sphere.id
    np.testing.assert_allclose(gb.albedo[m], np.tile(sphere.material.albedo, (m.sum(), 1)), rtol=1e-7)
    assert np.all(gb.normal_group[m] == 0)
    # smooth sphere normals: interpolated, nearly unit, pointing away from the centre
    centre = sphere.matrix[:3, 3]
    radial = safe_normalize(gb.position[m] - centre)
    assert np.all(np.einsum("ij,ij->i", safe_normalize(gb.normal[m]), radial) > 0.98)
    assert 0.02 < gb.edge.mean() < 0.3


# -- lighting ------------------------------------------------------------------------------------


def _point(radius=2.0, color=(1.0, 1.0, 1.0)) -> Light:
    return Light("point", color, position=(0.0, 0.0, 0.0), radius=radius)


def _contrib(light, P, n=(-1.0, 0.0, 0.0), cam=(5.0, 5.0, 0.0), spec=0.5, shin=16.0):
    P = np.atleast_2d(np.asarray(P, dtype=np.float64))
    k = len(P)
    return light_contribution(light, P, np.tile(n, (k, 1)), np.asarray(cam, dtype=np.float64),
                              np.full((k, 3), 0.8), np.full(k, spec), np.full(k, shin))


def test_attenuation_at_the_radius():
    r = 2.0
    at = np.array([r])
    assert attenuation(at * at, r)[0] == 0.0
    inside, outside = np.nextafter(r, 0.0), np.nextafter(r, 4.0)
    assert attenuation(np.array([outside * outside]), r)[0] == 0.0
    a = attenuation(np.array([inside * inside]), r)[0]
    assert 0.0 < a < 1e-20 and np.isfinite(a)
    assert attenuation(np.array([0.0]), r)[0] == 1.0


def test_point_light_hard_cases():
    light = _point()
    r = 2.0
    assert np.all(_contrib(light, [r, 0, 0]) == 0.0)                             # exactly at r
    assert np.all(_contrib(light, [np.nextafter(r, 4.0), 0, 0]) == 0.0)         # 1 ulp beyond
    c = _contrib(light, [np.nextafter(r, 0.0), 0, 0])                            # 1 ulp inside
    assert np.isfinite(c).all() and np.all(c >= 0) and np.all(c < 1e-20)
    at_centre = _contrib(light, [0.0, 0.0, 0.0])                                 # d = 0
    assert np.isfinite(at_centre).all() and np.all(at_centre >= 0)
    near = _contrib(light, [1e-300, 0.0, 0.0])
    assert np.isfinite(near).all()
    # degenerate normal and camera at the point: no NaN
    z = _contrib(light, [1.0, 0, 0], n=(0.0, 0.0, 0.0), cam=(1.0, 0.0, 0.0))
    assert np.isfinite(z).all()


def test_point_light_value():
    light = _point(radius=4.0, color=(1.0, 0.5, 0.25))
    P, n, cam = np.array([[0.0, -1.0, 0.0]]), (0.0, 1.0, 0.0), (0.0, 3.0, 0.0)
    c = _contrib(light, P, n=n, cam=cam, spec=0.5, shin=8.0)
    att = (1 - 1 / 16) ** 2
    expect = np.array([1.0, 0.5, 0.25]) * att * (0.8 * 1.0 + 0.5 * 1.0)      # l = v = h = n
    np.testing.assert_allclose(c[0], expect, rtol=1e-12)
    # light behind the surface: nothing, not even specular
    assert np.all(_contrib(light, P, n=(0.0, -1.0, 0.0), cam=cam) == 0.0)


def test_spot_and_directional():
    spot = Light("spot", (1.0, 1.0, 1.0), position=(0.0, 2.0, 0.0), radius=10.0,
                 direction=(0.0, -1.0, 0.0), inner_deg=20.0, outer_deg=30.0)
    n = (0.0, 1.0, 0.0)
    cam = (0.0, 5.0, 5.0)
    on_axis = _contrib(spot, [0.0, 0.0, 0.0], n=n, cam=cam)
    point = _contrib(Light("point", (1.0, 1.0, 1.0), position=(0.0, 2.0, 0.0), radius=10.0),
                     [0.0, 0.0, 0.0], n=n, cam=cam)
    np.testing.assert_allclose(on_axis, point)                                   # inside inner: 1
    outside = 2.0 * np.tan(np.radians(31.0))
    assert np.all(_contrib(spot, [outside, 0.0, 0.0], n=n, cam=cam) == 0.0)
    between = 2.0 * np.tan(np.radians(25.0))
    mid = _contrib(spot, [between, 0.0, 0.0], n=n, cam=cam)
    full = _contrib(Light("point", (1.0, 1.0, 1.0), position=(0.0, 2.0, 0.0), radius=10.0),
                    [between, 0.0, 0.0], n=n, cam=cam)
    assert np.all(mid > 0) and np.all(mid < full)
    sun = Light("directional", (0.5, 0.5, 0.5), direction=(0.0, -1.0, 0.0))
    far = _contrib(sun, [[1e4, 0.0, -3e3], [0.0, 0.0, 0.0]], n=n, cam=cam, spec=0.0)
    np.testing.assert_allclose(far, 0.5 * 0.8)                                   # att = 1, ndl = 1


def test_shade_sky_and_ambient():
    scene = parse_scene(_plane_scene("position = [0, 3, 6]\ntarget = [0, 0, -20]",
                                     "translate = [0, 0, -10]\nscale = [40, 1, 30]")
                        .replace("height = 50", "height = 50\nambient = [0.1, 0.2, 0.3]"))
    gb = rasterize(scene)
    assert (~gb.coverage).any() and gb.coverage.any()
    rgb = shade(gb, scene)
    assert np.all(rgb[~gb.coverage] == 0.0)
    np.testing.assert_allclose(rgb[gb.coverage], np.tile([0.05, 0.1, 0.15], (gb.coverage.sum(), 1)),
                               rtol=1e-6)
    rgba = to_rgba8(rgb)
    assert rgba.dtype == np.uint8 and np.all(rgba[..., 3] == 255)


# -- the example scenes --------------------------------------------------------------------------


def _save(rgb: np.ndarray, path: str) -> None:
    from PIL import Image
    Image.fromarray(to_rgba8(rgb)).save(path)


def _check_looks_lit(rgb: np.ndarray, gb) -> None:
    assert np.isfinite(rgb).all()
    lum = rgb[gb.coverage].mean(axis=1)
    assert lum.mean() > 0.05                      # not black
    assert (lum > 0.3).mean() > 0.05              # visible pools of light
    assert (rgb > 1.0).any(axis=-1).mean() < 0.01  # not blown out
    hue_spread = np.std(rgb[gb.coverage] / np.maximum(rgb[gb.coverage].sum(1, keepdims=True), 1e-9), axis=0)
    assert hue_spread.max() > 0.05                # coloured, not grey


def test_default_scene_renders():
    s = default_scene()
    rgb, gb = reference_image(s)
    _check_looks_lit(rgb, gb)
    _save(rgb, "/tmp/ref_default.png")
    assert lights_per_pixel(gb, s).max() <= 4
    assert lights_per_pixel(gb, s, conservative=True).max() <= 4


def test_small_scene_within_four_lights():
    s = load_scene(SCENES / "small.toml")
    rgb, gb = reference_image(s)
    assert rgb.mean() > 0.05
    lpp = lights_per_pixel(gb, s)
    assert lpp.max() <= 4 and lights_per_pixel(gb, s, conservative=True).max() <= 4
    assert lpp.max() >= 2                         # the lights do overlap somewhere


def test_many_lights_scene_renders():
    s = load_scene(SCENES / "many_lights.toml").with_size(320, 180)
    rgb, gb = reference_image(s)
    _check_looks_lit(rgb, gb)
    _save(rgb, "/tmp/ref_many_lights.png")
    assert len(np.unique(gb.object_id)) > 60
    assert lights_per_pixel(gb, s).max() <= 4


def test_stress_scene_overlaps_more_than_four():
    s = load_scene(SCENES / "stress_overlap.toml")
    rgb, gb = reference_image(s)
    assert np.isfinite(rgb).all() and rgb.mean() > 0.02
    assert lights_per_pixel(gb, s).max() > 4


def test_mixed_scene_opaque_and_all():
    s = load_scene(SCENES / "mixed_lights.toml")
    rgb, gb = reference_image(s)
    glass = next(o.id for o in s.objects if o.material.translucent)
    assert glass not in gb.object_id
    assert glass in rasterize(s, ()).object_id
    assert np.isfinite(rgb).all() and rgb.mean() > 0.05


def test_rasterize_each_object_on_its_own():
    s = load_scene(SCENES / "mixed_lights.toml")
    (glass, gb), = rasterize_each(s)                                      # default: translucent
    assert glass.material.translucent
    together = rasterize(s, ("translucent",))
    np.testing.assert_array_equal(gb.coverage, together.coverage)
    np.testing.assert_array_equal(gb.depth, together.depth)
    each = rasterize_each(s, ("opaque",))
    assert [o for o, _ in each] == s.select(("opaque",))
    opaque = rasterize(s, ("opaque",))
    nearest = np.min([g.depth for _, g in each], axis=0)                 # per-pixel fragment lists
    np.testing.assert_array_equal(nearest, opaque.depth)
    for o, g in each:
        assert set(np.unique(g.object_id[g.coverage]).tolist()) <= {o.id}


def test_edges_scene_renders_with_strong_discontinuities():
    s = load_scene(SCENES / "edges.toml")
    rgb, gb = reference_image(s)
    _check_looks_lit(rgb, gb)
    _save(rgb, "/tmp/ref_edges.png")
    assert lights_per_pixel(gb, s).max() <= 4
    # horizontally adjacent pixels on different objects: the nearer one much darker than the
    # farther one (dark box before the bright wall) and much brighter (lit sphere, white block
    # before the dark wall)
    lum = np.clip(rgb, 0, 1).mean(axis=-1)
    a, b = (slice(None), slice(None, -1)), (slice(None), slice(1, None))
    near_minus_far = np.where(gb.depth[a] < gb.depth[b], lum[a] - lum[b], lum[b] - lum[a])
    across = gb.object_id[a] != gb.object_id[b]
    assert (across & (near_minus_far < -0.3)).sum() > 100
    assert (across & (near_minus_far > 0.3)).sum() > 30
    # thin geometry: poles and grille bars one to three pixels wide
    thin = [o for o in s.objects if o.name.startswith(("pole", "grille v"))]
    widths = [np.median((gb.object_id == o.id).sum(axis=1)[(gb.object_id == o.id).any(axis=1)])
              for o in thin]
    assert len(thin) >= 10 and max(widths) <= 3


def test_translucent_layers_scene_opaque_renders():
    s = load_scene(SCENES / "translucent_layers.toml")
    rgb, gb = reference_image(s)
    _check_looks_lit(rgb, gb)
    assert not any(o.material.translucent for o in s.objects if o.id in set(gb.object_id.ravel()))
