"""Inferred lighting, light pre-pass and Calver's deferred lighting against float64 references.

Tolerances, per technique (rgba8 codes on pixels off silhouettes and creases):

- light pre-pass vs the float64 *light-buffer* equation (``reference.light_buffer``): 2 codes.
  The L-buffer is rgba16f (relative error 2^-11 per stored sum) and positions are rebuilt from
  an r32f depth: well under a code, plus the final rgba8 rounding.
- inferred lighting at lbuffer_scale 1.0 vs the same equation: 2 codes.  Normals go through
  Kircher's encoding in rg16f (0.2 degrees, packing report) and linear depth through 16 bits.
- the light-buffer equation itself vs the shared equation (``reference.lighting``): it rebuilds
  a specular colour from the diffuse light's chroma, exact under one light, approximate where
  differently coloured lights overlap; measured p99 3 codes, max 17 on many_lights: bounded at
  p99 <= 5 codes.
- inferred lighting at reduced resolution vs the full-resolution shared reference: lighting is
  computed at lbuffer_scale and inferred back, so silhouettes thinner than an L-buffer texel
  cannot be right; bounded by RMSE (measured on edges: 6.5 codes at 0.5, 5.5 at 0.625 with
  DSF, 13.2 / 12.2 with plain bilinear), asserted at RMSE <= 8 with DSF and DSF < 0.7 x
  bilinear.
- Calver vs the shared equation: 2 codes.  Shaping and attenuation functions are 1024-texel
  r16f tables sampled bilinearly; screen-space positions are 16-bit x, y and a depth split
  over two 16-bit channels (float32 precision); normals are 10-bit.
"""

from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file
from pipegen.reference.light_buffer import light_buffer_reference
from pipegen.reference.lighting import reference_image
from pipegen.reference.metrics import rgb_error
from pipegen.reference.translucent import reference_composite
from pipegen.scene import load_scene

pytestmark = [pytest.mark.gl]

ROOT = Path(__file__).resolve().parents[1]


def scene(name, size=None):
    s = load_scene(ROOT / f"examples/scenes/{name}.toml")
    return s.with_size(*size) if size else s


def render(technique, s, **params):
    compiled = compile_file(ROOT / f"pipelines/{technique}.pipe", params=params or None,
                            verify_each=True)
    return compiled.pipeline("gl").render(s)[compiled.technique.output]


OPAQUE_SCENES = [("small", None), ("edges", None), ("many_lights", (320, 180))]


@pytest.mark.parametrize("name, size", OPAQUE_SCENES)
def test_light_prepass_matches_its_float64_equation(name, size):
    s = scene(name, size)
    ref, gb = light_buffer_reference(s)
    e = rgb_error(render("light_prepass", s), ref, ~gb.silhouette)
    assert e["max"] <= 2, e


@pytest.mark.parametrize("name, size", OPAQUE_SCENES)
def test_inferred_at_full_resolution_matches_the_light_buffer_equation(name, size):
    s = scene(name, size)
    ref, gb = light_buffer_reference(s)
    e = rgb_error(render("inferred", s, lbuffer_scale=1.0), ref, ~gb.silhouette)
    assert e["max"] <= 2, e


def test_light_buffer_specular_approximation_is_bounded():
    s = scene("many_lights", (320, 180))
    lb, gb = light_buffer_reference(s)
    shared, _ = reference_image(s)
    codes = np.rint(np.clip(lb, 0, 1) * 255)
    diff = np.abs(codes - np.rint(np.clip(shared, 0, 1) * 255)).max(-1)[~gb.silhouette]
    assert np.percentile(diff, 99) <= 5 and diff.max() > 0


@pytest.mark.parametrize("scale", [0.5, 0.625])
def test_dsf_beats_bilinear_on_the_edges_scene(scale):
    s = scene("edges")
    ref, _ = reference_composite(s)
    dsf = rgb_error(render("inferred", s, lbuffer_scale=scale, dsf=True), ref)
    bilinear = rgb_error(render("inferred", s, lbuffer_scale=scale, dsf=False), ref)
    assert dsf["rmse"] <= 8.0, dsf
    assert dsf["rmse"] < 0.7 * bilinear["rmse"], (dsf, bilinear)


def test_translucent_layers_are_lit():
    s = scene("translucent_layers")
    composite, info = reference_composite(s)
    opaque_only = info["opaque"]
    img = render("inferred", s, lbuffer_scale=1.0)
    covered = info["covered"] & ~info["silhouette"]
    vs_composite = rgb_error(img, composite, covered)
    vs_opaque = rgb_error(img, opaque_only, covered)
    lit = img[::-1][covered][:, :3]
    assert lit.mean() > 20, "translucent pixels are (nearly) black"
    assert vs_composite["mean"] < 0.25 * vs_opaque["mean"], (vs_composite, vs_opaque)
    assert vs_composite["rmse"] <= 8.0, vs_composite


@pytest.mark.parametrize("name, size", OPAQUE_SCENES + [("mixed_lights", None)])
def test_calver_matches_the_shared_equation(name, size):
    s = scene(name, size)
    ref, gb = reference_image(s)
    e = rgb_error(render("deferred_calver", s), ref, ~gb.silhouette)
    assert e["max"] <= 2, e
