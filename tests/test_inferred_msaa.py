"""Inferred lighting with MSAA (issue 27; Kircher & Lawrance, Figures 1, 3, 9): the material and
translucent passes render into an N-sample colour and depth target from the single-sampled,
low-resolution L-buffer, and the output is that target resolved.

GL here is llvmpipe, which renders at most 4 samples (GL_MAX_SAMPLES) and rounds 2 up to 4, so
GL = CL is checked at 4 samples; 8 samples are measured on CL, against the technique's own
float64 evaluation at its most accurate values (lbuffer_scale 1.0, samples 1) supersampled
4 x 4 per pixel (box filter): 16 shaded samples per pixel.  Renders are 64x36 to keep the suite quick.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipegen.core.diagnostics import PipegenError
from pipegen.proof.accuracy import output_codes
from pipegen.proof.references import choose_reference
from pipegen.reference.metrics import reference_codes
from pipegen.testing.api import (assert_backends_agree, assert_close_to_f64, for_scene,
                                 load_technique, load_test_scene, render)

PIPE = "pipelines/inferred.pipe"
SIZE = (64, 36)

pytestmark = pytest.mark.cl


@pytest.mark.gl
@pytest.mark.parametrize("scene", ["examples/scenes/edges.toml",
                                   "examples/scenes/translucent_layers.toml"])
def test_gl_and_cl_agree_at_4_samples(scene):
    result = assert_backends_agree(PIPE, scene, SIZE, params={"samples": 4})
    assert {r.name for r in result.rows} >= {"color", "lbuf"}


@pytest.mark.parametrize("scene", ["examples/scenes/edges.toml",
                                   "examples/scenes/translucent_layers.toml"])
def test_cl_at_8_samples_is_within_the_bound_of_its_float64_evaluation(scene):
    # GL cannot render 8 samples here: CL float32 against CL float64, the output within the
    # tolerance model's bound (docs/tolerances.md).  The output only: the model's bound on a
    # multisampled depth target is short by ~0.3 codes at silhouettes (ds, at 4x too), and
    # lbuf is 2 px over at 64x36 on edges at 1x already; neither is what samples changes
    assert_close_to_f64(PIPE, scene, SIZE, params={"samples": 8}, backends=("cl",),
                        only={"color"})


@pytest.mark.gl
def test_gl_refuses_a_sample_count_it_would_round_up():
    with pytest.raises(PipegenError, match="renders them as 4"):
        render(load_technique(PIPE, {"samples": 2}), load_test_scene(
            "examples/scenes/small.toml", SIZE), "gl")


def _errors(samples: int, scene, ref, edges) -> tuple[float, float]:
    """Mean of each pixel's largest channel error (rgba8 codes) on the silhouette pixels and
    off them."""
    compiled = for_scene(load_technique(PIPE, {"samples": samples}), scene)
    targets = render(compiled, scene, "cl")
    codes = output_codes(compiled, {k: t.values for k, t in targets.items()})
    got = codes[::-1, :, :3].astype(np.int64)                     # top row first
    want = reference_codes(ref.output_rgb(scene)).astype(np.int64)
    err = np.abs(got - want).max(axis=-1)
    return float(err[edges].mean()), float(err[~edges].mean())


def test_8_samples_are_closer_to_the_supersampled_reference_on_edges():
    scene = load_test_scene("examples/scenes/edges.toml", SIZE)
    ref = choose_reference("self", load_technique(PIPE), 4)
    edges = ref.edges(scene)                 # the scene geometry's silhouette pixels
    assert edges.sum() > 400                 # 670 of 2304 pixels at 64x36
    (one, one_off), (eight, eight_off) = (_errors(n, scene, ref, edges) for n in (1, 8))
    # measured at lbuffer_scale 0.625 with DSF: on edges 1x 16.8, 4x 12.5, 8x 13.0 codes
    # (8x: 0.77x); off edges 2.06 and 1.96 (MSAA changes little where one surface covers a
    # pixel)
    assert eight <= 0.85 * one, (one, eight)
    assert abs(eight_off - one_off) <= 0.5, (one_off, eight_off)
