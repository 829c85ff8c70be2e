"""reference.light_bound: the tile bound is conservative (at every pixel it is at least the
per-pixel count of light volumes, which is at least the lights reaching the surface), and so
is its refinement over 4-pixel and 1-pixel tiles for every capacity, the
pruned per-pixel maximum is exactly lighting.lights_per_pixel's, the sampled surface lies on
its pixel centres, and mismatches() words a capacity overflow as surely as the counts allow."""

from __future__ import annotations

import dataclasses
import re
import warnings
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from pipegen.compiler.driver import compile_file
from pipegen.compiler.mismatches import lights_per_pixel_bound, mismatches
from pipegen.reference import light_bound as LB
from pipegen.reference.lighting import lights_per_pixel
from pipegen.reference.raster import rasterize
from pipegen.scene import load_scene, parse_scene

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted((ROOT / "examples/scenes").glob("*.toml"))
STREET = Path(__file__).resolve().parent / "data/street_twelve_lamps.toml"


@lru_cache(maxsize=None)
def example(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")        # the OBJ loader's notes on ignored statements
        return load_scene(path)


@lru_cache(maxsize=None)
def bitplanes():
    return compile_file(ROOT / "pipelines/lidr_bitplanes.pipe").technique


def per_tile_pixel(scene, tiles: np.ndarray) -> np.ndarray:
    """The tile counts spread over the tiles' pixels, (H, W)."""
    big = np.repeat(np.repeat(tiles, LB.TILE, axis=0), LB.TILE, axis=1)
    return big[:scene.height, :scene.width]


def assert_counts_nest(scene):
    """tile bound >= volumes marked >= lights reaching the surface, at every pixel, for
    passes drawing back faces and front faces; the pruned maximum equals the full one."""
    g = rasterize(scene)
    full = LB.Surface.from_gbuffer(g)
    lights = [l for l in scene.lights if l.type in ("point", "spot")]
    sub = dataclasses.replace(scene, lights=tuple(lights))
    tiles = per_tile_pixel(scene, LB.tile_counts(scene, lights))
    reach = np.zeros(g.coverage.shape, dtype=np.int64)
    reach[full.rows, full.cols] = LB.reaching(full.position, lights)
    for faces, sky in (("back", False), ("front", scene.has_translucent)):
        volumes = lights_per_pixel(g, sub, conservative=True, faces=faces, sky=sky)
        assert (tiles >= volumes).all(), (scene.name, faces)
        assert (volumes >= reach).all(), (scene.name, faces)
        assert LB.volume_bound(scene, lights, full, faces, sky) == volumes.max()
        for capacity in range(int(tiles.max()) + 1):      # 0: every tile down to 1 pixel
            refined = LB.refined_bound(scene, lights, capacity)
            assert volumes.max() <= refined <= tiles.max(), (scene.name, faces, capacity)
    assert LB.reaching_max(scene, lights, full) == reach.max()


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_counts_nest_on_the_example_scenes(path):
    """At the scene's size, or a quarter of it for the 1280x720 one (to keep tests quick)."""
    s = example(path)
    if s.width * s.height > 320 * 320:
        s = dataclasses.replace(s, width=s.width // 4, height=s.height // 4)
    assert_counts_nest(s)


def random_scene(boxes, lights, eye) -> str:
    text = [f'name = "random"\nwidth = 48\nheight = 27\n[camera]\nposition = {list(eye)}\n'
            f'target = [0, 0, 0]\nfov_y_deg = 60\nnear = 0.2\nfar = 40\n']
    text.append('[[objects]]\nname = "floor"\nmesh = "plane"\ntranslate = [0, -1, 0]\n'
                'scale = 12\nmaterial = { albedo = [0.5, 0.5, 0.5] }\n')
    for i, (pos, size) in enumerate(boxes):
        text.append(f'[[objects]]\nname = "b{i}"\nmesh = "box"\ntranslate = {list(pos)}\n'
                    f'scale = {size}\nmaterial = {{ albedo = [0.5, 0.5, 0.5] }}\n')
    for pos, radius, spot, direction, outer in lights:
        extra = (f'direction = {list(direction)}\ninner_deg = {outer / 2}\nouter_deg = {outer}\n'
                 if spot else "")
        text.append(f'[[lights]]\ntype = "{"spot" if spot else "point"}"\n'
                    f'position = {list(pos)}\nradius = {radius}\ncolor = [1, 1, 1]\n{extra}')
    return "\n".join(text)


coord = st.floats(-3, 3, allow_nan=False)
vec = st.tuples(coord, coord, coord)
away = st.tuples(coord, st.floats(0.5, 3), st.floats(-3, 3)).filter(
    lambda d: sum(x * x for x in d) > 0.1)


@settings(max_examples=12, deadline=None)
@given(boxes=st.lists(st.tuples(vec, st.floats(0.3, 2)), max_size=3),
       lights=st.lists(st.tuples(vec, st.floats(0.5, 5), st.booleans(), away.map(
           lambda d: (d[0], -d[1], d[2])), st.floats(10, 80)), min_size=1, max_size=12),
       eye=st.tuples(st.floats(-6, 6), st.floats(0.5, 5), st.floats(4, 8)))
def test_counts_nest_on_random_scenes(boxes, lights, eye):
    """Lights anywhere, the camera inside some of their volumes too."""
    assert_counts_nest(parse_scene(random_scene(boxes, lights, eye)))


@pytest.mark.parametrize("stride", [2, 4])
def test_sampled_surface_lies_on_its_pixel_centres(stride):
    """A sample's surface point projects within stride/512 pixel of its pixel centre (its
    vertices snap to 1/256 of a sample); every sample pixel covered at full resolution away
    from edges is covered."""
    s = example(ROOT / "examples/scenes/street_lamps.toml")
    sampled, g = LB.surface(s, stride), rasterize(s)
    mvp = s.camera.projection(s.aspect) @ s.camera.view_matrix()
    clip = np.concatenate([sampled.position, np.ones((len(sampled.rows), 1))], axis=1) @ mvp.T
    x = (clip[:, 0] / clip[:, 3] + 1) / 2 * s.width
    y = (1 - clip[:, 1] / clip[:, 3]) / 2 * s.height
    tol = stride / 512 + 1e-9
    assert np.abs(x - sampled.cols - 0.5).max() <= tol
    assert np.abs(y - sampled.rows - 0.5).max() <= tol
    grid = np.zeros_like(g.coverage)
    grid[stride // 2::stride, stride // 2::stride] = True
    seen = np.zeros_like(g.coverage)
    seen[sampled.rows, sampled.cols] = True
    assert not (grid & g.coverage & ~g.edge & ~seen).any()
    assert g.coverage[sampled.rows, sampled.cols].all()


def capacity(scene) -> list[str]:
    return [m.message for m in mismatches(bitplanes(), scene) if m.kind == "capacity"]


def test_a_street_lit_by_twelve_lamps_may_drop_lights_but_will_not():
    """Up to 11 lamp volumes lie on one pixel, at most 3 lamps reach its surface: the
    packing (4) may drop lights, it is not said to drop them."""
    s = example(STREET)
    lights = [l for l in s.lights if l.type == "spot"]
    assert LB.reaching_max(s, lights, LB.surface(s)) == 3
    assert lights_per_pixel_bound(s, {"point", "spot"}) == 11
    assert capacity(s) == [
        "the packing `slots` (bitplanes) holds 4: lights may be dropped (a conservative "
        "bound: up to 11 point/spot light volumes cover a pixel; at most 3 of them reach the "
        "surface it shows)"]


def test_large_frames_say_will_from_a_sample_and_may_from_the_tile_bound():
    """At 640x360 (every 2nd pixel sampled): stress_overlap's sampled surface already shows
    more lights reaching a point than the packing holds, a count the full surface reaches
    too; street_lamps' sample shows more volumes than it holds but at most 3 lights
    reaching, and the message quotes the tile bound, at least the per-pixel one."""
    over = dataclasses.replace(example(ROOT / "examples/scenes/stress_overlap.toml"),
                               width=640, height=360)
    [message] = capacity(over)
    said = int(message.split()[0])
    lights = [l for l in over.lights if l.type in ("point", "spot")]
    assert 4 < said <= LB.reaching_max(over, lights, LB.surface(over))
    assert message.endswith("lights will be dropped")
    street = dataclasses.replace(example(ROOT / "examples/scenes/street_lamps.toml"),
                                 width=640, height=360)
    [message] = capacity(street)
    bound = int(re.search(r"up to (\d+) ", message).group(1))
    assert "lights may be dropped (a conservative bound" in message
    assert bound >= lights_per_pixel_bound(street, {"point", "spot"}) > 4
    lights = [l for l in street.lights if l.type in ("point", "spot")]
    assert LB.reaching_max(street, lights, LB.surface(street)) <= 4


def test_refining_the_tiles_fits_what_the_16_pixel_tiles_overflow(monkeypatch):
    """lidr_transparent on many_lights at 1280x720: a bank's 16x16 tile bound is 5 (the
    packing holds 4) where no pixel's is; the 4- and 1-pixel tiles show it fits, without
    rasterising anything.  lidr_bitplanes there may drop lights: the refined bound it quotes
    is at most the tile bound and at least the per-pixel count's maximum on the full surface."""
    s = example(ROOT / "examples/scenes/many_lights.toml")
    assert (s.width, s.height) == (1280, 720)
    banks = [[l for i, l in enumerate(s.lights) if l.type in ("point", "spot") and i % 3 == k]
             for k in (0, 1, 2)]                    # lidr_transparent's banks b0, b1, b2
    assert max(int(LB.tile_counts(s, b).max()) for b in banks) == 5
    assert max(LB.refined_bound(s, b, 4) for b in banks) == 4

    def no_raster(*args, **kwargs):
        raise AssertionError("rasterised")
    with monkeypatch.context() as m:
        m.setattr(LB, "rasterize_triangles", no_raster)
        transparent = compile_file(ROOT / "pipelines/lidr_transparent.pipe").technique
        assert [x.message for x in mismatches(transparent, s) if x.kind == "capacity"] == []
    [message] = capacity(s)
    said = int(re.search(r"up to (\d+) ", message).group(1))
    lights = [l for l in s.lights if l.type in ("point", "spot")]
    assert "lights may be dropped (a conservative bound" in message
    assert lights_per_pixel_bound(s, {"point", "spot"}) <= said \
        <= int(LB.tile_counts(s, lights).max())


def test_a_scene_the_tile_bound_fits_is_not_rasterised(monkeypatch):
    """small.toml's tile bound fits the packing: no surface is rasterised at all."""
    def no_raster(*args, **kwargs):
        raise AssertionError("rasterised")
    monkeypatch.setattr(LB, "rasterize_triangles", no_raster)
    s = dataclasses.replace(example(ROOT / "examples/scenes/small.toml"), width=1280, height=720)
    assert capacity(s) == []
