"""Calver's material table and emissive term in deferred_calver (issue 28): the technique's
``material { diffuse_fn, kspec_blend, kamb, kemm, emissive }`` record, looked up per pixel by
the material index the G-buffer stores (the object id, gspecular.a, 8 bits), the emissive term
added once in global_lights; the float64 reference is ``reference/calver_materials.py``.

- the block is the reference's schema, and the reference with the defaults is the shared
  lighting equation (today's deferred_calver image with objects that set no field is pinned byte
  for byte by tests/test_light_table_images.py: its colour hashes did not change);
- GL = CL (``pipegen check``) on four scenes: examples/scenes/calver_materials.toml, shadows.toml
  with every light casting (point, spot, directional) and material fields added, mixed_lights,
  cornell_box;
- the images against the float64 reference (with the same shadow maps on the shadow scene);
- the emissive colour lands once on its object's pixels, whatever the number of lights.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file
from pipegen.reference.calver_materials import CALVER_MATERIAL, calver_shade
from pipegen.reference.lighting import shade
from pipegen.reference.metrics import error_image, rgb_error
from pipegen.reference.raster import rasterize
from pipegen.reference.shadows import MappedShadows, shadow_maps
from pipegen.scene import load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[1]
PIPE = ROOT / "pipelines/deferred_calver.pipe"
SCENES = ROOT / "examples/scenes"
MATERIALS = SCENES / "calver_materials.toml"
ATLAS = 768                         # 3 x 3 tiles: the point light's six, two spots and the sun
SHADOW_PARAMS = {"shadow_tiles": 3, "shadow_size": ATLAS, "shadow_bias": 0.25, "pcf_taps": 16}


def materials_scene(edit=lambda text: text):
    return parse_scene(edit(MATERIALS.read_text()), str(MATERIALS), base_dir=SCENES)


def shadow_scene():
    """shadows.toml at 64x36 with its point light casting too (9 tiles) and material fields on
    the box (emissive, flat diffuse), the sphere (metallic, wrap) and the pillar (half ambient,
    half-Lambert, glowing by its specular colour)."""
    path = SCENES / "shadows.toml"
    text = path.read_text()
    for old, new in (("shininess = 32 }", "shininess = 32, emissive = [0.3, 0.1, 0.0], diffuse_fn = 3 }"),
                     ("shininess = 64 }", "shininess = 64, kspec_blend = 1, diffuse_fn = 1 }"),
                     ("shininess = 48 }", "shininess = 48, kamb = 0.5, diffuse_fn = 2, kemm = 0.5 }")):
        assert old in text
        text = text.replace(old, new)
    s = parse_scene(text, str(path), base_dir=path.parent)
    return dataclasses.replace(s, lights=tuple(dataclasses.replace(l, shadows=True)
                                                 for l in s.lights), width=64, height=36)


# ---- the schema and the reference -----------------------------------------------------------------

def test_the_technique_declares_the_references_schema():
    fields = compile_file(PIPE).technique.materials.fields
    assert [(f.name, str(f.type), f.default) for f in fields] == list(CALVER_MATERIAL)


def test_the_reference_with_default_fields_is_the_shared_lighting_equation():
    s = load_scene(SCENES / "mixed_lights.toml").with_size(64, 36)
    gb = rasterize(s, ("opaque",))
    np.testing.assert_allclose(calver_shade(gb, s), shade(gb, s), rtol=0, atol=1e-12)


# ---- GL against OpenCL -------------------------------------------------------------------------

CHECKS = [("calver_materials", {}), ("shadows", SHADOW_PARAMS), ("mixed_lights", {}),
          ("cornell_box", {})]


def _scene(name):
    if name == "shadows":
        return shadow_scene()
    if name == "calver_materials":
        return materials_scene()
    return load_scene(SCENES / f"{name}.toml").with_size(64, 48)


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.filterwarnings("ignore::UserWarning")        # cornell_box.obj's ignored statements
@pytest.mark.parametrize("name, params", CHECKS, ids=[c[0] for c in CHECKS])
def test_check_gl_against_cl(name, params, tmp_path):
    pytest.importorskip("pyopencl")
    from pipegen.proof.check import check
    result = check(compile_file(PIPE, params=params), _scene(name), tmp_path)
    assert result.passed, "\n" + result.table()
    rows = {r.name: r for r in result.rows}
    assert rows["color"].max_error <= 1 and rows["gspecular"].max_error == 0


# ---- against the float64 reference --------------------------------------------------------------

@lru_cache(maxsize=None)
def _render(backend: str, name: str) -> dict:
    params = SHADOW_PARAMS if name == "shadows" else {}
    return compile_file(PIPE, params=params).pipeline(backend).render(_scene(name))


BACKENDS = [pytest.param("gl", marks=pytest.mark.gl), pytest.param("cl", marks=pytest.mark.cl)]


# Measured (GL and CL alike, non-silhouette pixels): calver_materials max 1 code, mean 0.31 (the
# r16f shaping tables and the rgba16f accumulator), no pixel over 1 code; the shadow scene
# (pcf 16, the parameters test_point_shadows compiles too) max 2, mean 0.074 against the same
# shadow maps, one pixel over 1 code (a PCF tap flipping within float32 rounding: 1/16 of a
# light).  Without the table (every field at its default) the reference is 229 / 128 codes
# off: the fields are what the image shows.
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ["calver_materials", "shadows"])
def test_image_against_the_float64_reference(backend, name):
    s = _scene(name)
    gb = rasterize(s, ("opaque",))
    shadows = None
    if name == "shadows":
        shadows = MappedShadows(shadow_maps(s, 3, ATLAS, ATLAS), SHADOW_PARAMS["pcf_taps"],
                                SHADOW_PARAMS["shadow_bias"])
    ref = calver_shade(gb, s, shadows)
    out = _render(backend, name)["color"]
    mask = ~gb.silhouette
    e = rgb_error(out, ref, mask)
    assert e["max"] <= 2 and e["mean"] <= 0.4, e
    assert int((error_image(out, ref).max(axis=2)[mask] > 1).sum()) <= 3
    plain = rgb_error(out, shade(gb, s, shadows), mask)
    assert plain["max"] > 40, plain


@pytest.mark.parametrize("backend", BACKENDS)
def test_emissive_is_added_once_on_its_objects_pixels(backend):
    """In the accumulator, the lamp's pixels gain exactly its emissive colour in a scene with
    four lights, three of which reach it: added once, not per light (rgba16f: a sum near 1 to
    2 is stored to 2^-10, so 2e-3 covers the two roundings; the rgba8 output clamps some)."""
    lit = _render(backend, "calver_materials")
    dark = compile_file(PIPE).pipeline(backend).render(materials_scene(
        lambda t: t.replace("emissive = [0.9, 0.6, 0.2]", "emissive = [0, 0, 0]")))
    lamp = next(o.id for o in materials_scene().objects if o.name == "lamp")
    on = lit["gspecular"][..., 3] == lamp                # the material index the G-buffer holds
    assert on.sum() > 10
    diff = lit["accum"][..., :3].astype(np.float64) - dark["accum"][..., :3]
    np.testing.assert_allclose(diff[on], np.broadcast_to([0.9, 0.6, 0.2], diff[on].shape),
                               atol=2e-3)
    assert np.abs(diff[~on]).max() == 0
