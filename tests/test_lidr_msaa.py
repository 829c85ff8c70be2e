"""Trebilco's LIDR MSAA techniques 1 and 3 (issue 27): pipelines/lidr_msaa_texture.pipe (the
index target multisampled, read per sample) and pipelines/lidr_nearest_edge.pipe (a
single-sampled index target, the nearest texel of the polygon within one pixel).

- GL = CL (``pipegen check``'s tolerance model) on five scenes: four example scenes (edges,
  translucent_layers, mixed_lights, street_lamps: spots and a sun) and tests/data/thin_poles
  (poles 0.3-0.4 px wide at 64x36);
- the output against the float64 scene reference supersampled 4 x 4 per pixel (box filter,
  ``choose_reference("scene", ..., 4)``, as test_inferred_msaa and ``sweep
  --reference-samples 4``): the mean of each pixel's largest channel error in rgba8 codes, on
  the scene geometry's silhouette pixels and off them, on CL at 64x36;
- technique 3's search fails where the paper says it does (sub-pixel polygons): its
  ``edge_miss`` target marks those pixels, many on thin_poles, and they carry its error there;
  ``run``/``check`` warn before rendering (``mismatches.nearest_texel_misses``: a float64
  count of the pixels whose polygon covers samples but no pixel centre within one pixel).
"""

from __future__ import annotations

import numpy as np
import pytest

from pipegen.proof.accuracy import output_codes
from pipegen.proof.references import choose_reference
from pipegen.reference.metrics import reference_codes
from pipegen.compiler.mismatches import nearest_texel_misses
from pipegen.testing.api import (assert_backends_agree, for_scene, load_technique,
                                 load_test_scene, render)

TEXTURE = "pipelines/lidr_msaa_texture.pipe"
NEAREST = "pipelines/lidr_nearest_edge.pipe"
SIZE = (64, 36)
EDGES = "examples/scenes/edges.toml"
POLES = "tests/data/thin_poles.toml"

pytestmark = pytest.mark.cl


@pytest.mark.gl
@pytest.mark.parametrize("technique", [TEXTURE, NEAREST])
@pytest.mark.parametrize("scene", [EDGES, "examples/scenes/translucent_layers.toml", POLES,
                                   "examples/scenes/mixed_lights.toml",
                                   "examples/scenes/street_lamps.toml"])
def test_gl_and_cl_agree(technique, scene):
    result = assert_backends_agree(technique, scene, (48, 27))
    assert {r.name for r in result.rows} >= {"color", "lightidx", "diridx"}


@pytest.fixture(scope="module")
def measured():
    """{(technique, scene): (per-pixel error, silhouette mask, targets)} on CL at 64x36."""
    out = {}
    for path in (EDGES, POLES):
        scene = load_test_scene(path, SIZE)
        ref = choose_reference("scene", load_technique(TEXTURE), 4)
        want = reference_codes(ref.output_rgb(scene)).astype(np.int64)
        edges = ref.edges(scene)
        for technique in (TEXTURE, NEAREST):
            compiled = for_scene(load_technique(technique), scene)
            targets = render(compiled, scene, "cl")
            codes = output_codes(compiled, {k: t.values for k, t in targets.items()})
            err = np.abs(codes[::-1, :, :3].astype(np.int64) - want).max(axis=-1)
            out[technique, path] = (err, edges, targets)
    return out


# Measured at 64x36 (CL; mean of the largest channel error, rgba8 codes), on / off the
# silhouette pixels (493 of 2304 on edges, 805 on thin_poles); lidr_bitplanes (no MSAA) for
# scale: 18.7 / 0.38 on edges, 19.2 / 0.25 on thin_poles, lidr_transparent (technique 2)
# 9.2 / 0.39 and 6.2 / 0.25.
#   lidr_msaa_texture  edges 5.69 / 0.39   thin_poles 2.17 / 0.25
#   lidr_nearest_edge  edges 5.98 / 0.39   thin_poles 7.36 / 0.25 (325 pixels' search failed)
# Off the silhouettes all are within a code of each other: one surface per pixel, the same
# lights.  The bounds leave ~20 % over the measured means.
BOUNDS = {(TEXTURE, EDGES): (7.0, 0.5), (TEXTURE, POLES): (2.7, 0.35),
          (NEAREST, EDGES): (7.2, 0.5), (NEAREST, POLES): (8.9, 0.35)}


@pytest.mark.parametrize("technique, scene", list(BOUNDS), ids=[
    f"{t.split('/')[-1][:-5]}-{s.split('/')[-1][:-5]}" for t, s in BOUNDS])
def test_error_against_the_supersampled_reference(measured, technique, scene):
    err, edges, _ = measured[technique, scene]
    on, off = BOUNDS[technique, scene]
    assert err[edges].mean() <= on, (err[edges].mean(), on)
    assert err[~edges].mean() <= off, (err[~edges].mean(), off)


def test_per_sample_indices_beat_the_nearest_texel_on_thin_poles(measured):
    # the paper's "long thin polygon case": technique 1 has each sample's own lights,
    # technique 3 has none to find where a pole covers no pixel centre near it
    texture = measured[TEXTURE, POLES][0][measured[TEXTURE, POLES][1]].mean()
    nearest = measured[NEAREST, POLES][0][measured[NEAREST, POLES][1]].mean()
    assert texture <= 0.5 * nearest, (texture, nearest)


def test_the_nearest_edge_search_reports_where_it_fails(measured):
    err, edges, targets = measured[NEAREST, POLES]
    missed = targets["edge_miss"].values[::-1] > 0        # top row first, as err
    # 325 of 2304 pixels at 64x36: the poles (0.3-0.4 px wide) and their neighbours
    assert 200 <= missed.sum() <= 450, missed.sum()
    assert (missed & edges).sum() >= 0.9 * missed.sum()   # on silhouettes, where poles are
    # where it failed the pixel read the lights of the surface behind: the error is there
    assert err[missed].mean() >= 2 * err[edges & ~missed].mean(), (
        err[missed].mean(), err[edges & ~missed].mean())
    # on edges (grille bars and poles 1-2 px wide at 192x108) it fails far less often
    on_edges = measured[NEAREST, EDGES][2]["edge_miss"].values > 0
    assert on_edges.sum() <= 0.25 * missed.sum(), on_edges.sum()


def test_run_and_check_warn_where_the_search_will_fail(measured):
    poles = load_test_scene(POLES, SIZE)
    warned = [m for m in load_technique(NEAREST).mismatches(poles) if m.kind == "search"]
    assert len(warned) == 1 and "narrower than a pixel" in warned[0].message, warned
    # the float64 count (2x2 samples per pixel, object ids) against the shader's own (4x
    # MSAA positions, tangent planes): 295 and 325 px at 64x36
    counted, _ = nearest_texel_misses(poles)
    rendered = int((measured[NEAREST, POLES][2]["edge_miss"].values > 0).sum())
    assert 0.7 * rendered <= counted <= 1.3 * rendered, (counted, rendered)
    # nothing narrower than a pixel on mixed_lights; techniques 1 and 2 do not search
    assert nearest_texel_misses(load_test_scene("examples/scenes/mixed_lights.toml", SIZE))[0] == 0
    for other in (TEXTURE, "pipelines/lidr_transparent.pipe"):
        assert not [m for m in load_technique(other).mismatches(poles) if m.kind == "search"]
