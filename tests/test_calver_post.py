"""Calver's post-processing in deferred_calver (issue 12, part 3): HDR tone mapping, distance
fog and depth of field, each switched by a parameter, against their float64 references
(``pipegen.reference.post``, applied to the float64 lighting reference) on ``mixed_lights.toml``
(160x90), and GL against OpenCL with each effect on.

With every effect off (the defaults) the resolve pass is the plain copy it was: the conditions
on the parameters fold away at compile time, so the emitted shaders and kernels are byte
for byte those of before (tests/test_emitted_golden.py); a disabled effect leaves no trace in
the emitted text (tested below).  Fog and depth of field need the view depth in the resolve
pass, which reads only the lit buffer: the ambient pass writes it into the lit buffer's alpha
(rgba16f, which the light passes leave alone: ``alpha add(zero, one)``) when either is on, 1 (as
before) otherwise; sky pixels keep the clear alpha 1, read as infinitely far.

Bounds (rgba8 codes, GL vs the reference; measured on mixed_lights, and on street_lamps with
``python tests/test_calver_post.py``):

- tone map (exposure 0.5, 1, 2) and fog (linear; exponential at density 0.05 and 0.15): max 2
  codes off silhouettes, the bound of Calver's lighting itself (test_issue4_techniques): the
  lit buffer is rgba16f (2^-11 relative per stored sum); Reinhard's slope is
  exposure / (1 + x)^2 <= exposure, so at exposure <= 2 that stays under a code; the fog weight
  moves by at most |d f / d depth| x the depth's float16 rounding (2^-12 relative): < 1e-3.
  Measured: max 1 on mixed_lights; on street_lamps max 1, 2 for linear fog at the default
  range (the plain lighting there is at 2 already).
- depth of field (4, 8, 16 taps): p99 1 code, mean <= 0.25, max 8, on pixels farther than
  ceil(dof_max_coc) + 1 pixels from a silhouette (a gather there mixes in silhouette pixels,
  where the lighting itself is not compared).  The gather is discontinuous in depth: which
  texel a tap reads (floor of position + offset x circle of confusion) and whether a tap
  counts fully (behind the centre) or by its blur.  The pass reads the depth rebuilt from the
  packed G-buffer position and rounded to float16; the reference rounds its float64 depth to
  float16 the same way, but the two land in different float16 values on about half the texels
  (one float16 step, 2^-11 relative), so now and then a tap reads the neighbouring texel or
  switches weight: a few pixels off by more than a code.  Measured (max / p99 / mean):
  mixed_lights 4 taps 1/1/0.13, 8 taps at focus 8 range 4 4/1/0.13, 16 taps 2/1/0.13;
  street_lamps 4 taps 6/1/0.07, 8 taps 2/1/0.06, 16 taps 2/1/0.06.
- everything on (16 taps, linear fog, tone map at exposure 2): the depth-of-field bound.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file
from pipegen.reference import post
from pipegen.reference.lighting import to_rgba8
from pipegen.reference.metrics import rgb_error
from pipegen.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
PIPE = ROOT / "pipelines/deferred_calver.pipe"

TONEMAP = [dict(tonemap=True), dict(tonemap=True, exposure=2.0), dict(tonemap=True, exposure=0.5)]
FOG = [dict(fog=1), dict(fog=2), dict(fog=2, fog_density=0.15), dict(fog=1, fog_start=8.0,
                                                                     fog_end=14.0)]
DOF = [dict(dof_taps=4), dict(dof_taps=8, focus_distance=8.0, focus_range=4.0),
       dict(dof_taps=16, focus_distance=8.0, focus_range=4.0)]
ALL = [dict(dof_taps=16, fog=1, tonemap=True, exposure=2.0)]


def _key(params: dict) -> tuple:
    return tuple(sorted(params.items()))


@lru_cache(maxsize=None)
def scene(name="mixed_lights"):
    return load_scene(ROOT / f"examples/scenes/{name}.toml")


@lru_cache(maxsize=None)
def compiled(params: tuple = ()):
    return compile_file(PIPE, params=dict(params) or None, verify_each=True)


def render(params: dict, name="mixed_lights"):
    c = compiled(_key(params))
    return c.pipeline("gl").render(scene(name))[c.technique.output]


def dilate(mask: np.ndarray, r: int) -> np.ndarray:
    out = mask.copy()
    h, w = mask.shape
    padded = np.pad(mask, r)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out |= padded[r + dy:r + dy + h, r + dx:r + dx + w]
    return out


def compared_pixels(params: dict, gb) -> np.ndarray:
    """Off silhouettes; with depth of field, also off every gather that reaches one."""
    if not params.get("dof_taps"):
        return ~gb.silhouette
    return ~dilate(gb.silhouette, int(np.ceil(post.PostParams.of(params).dof_max_coc)) + 1)


def error(params: dict, name="mixed_lights") -> dict:
    ref, gb = post.post_reference(scene(name), params)
    return rgb_error(render(params, name), ref, compared_pixels(params, gb))


def emitted(params: dict, tmp_path: Path) -> str:
    folder = tmp_path / "out"
    compiled(_key(params)).write(folder)
    return "\n".join(f.read_text() for f in sorted(folder.rglob("*"))
                     if f.suffix in (".frag", ".vert", ".cl"))


# ---------------------------------------------------------------------------------------------
# no backend: what is emitted, and the references themselves
# ---------------------------------------------------------------------------------------------

EFFECT_NAMES = {
    "tonemap": ["post_process"],
    "fog": ["post_process", "apply_fog", "post_depth"],
    "dof": ["post_process", "depth_of_field", "dof_tap", "dof_blur", "post_depth"],
}


@pytest.mark.parametrize("params, on", [
    ({}, set()), (dict(tonemap=True), {"tonemap"}), (dict(fog=2), {"fog"}),
    (dict(dof_taps=8), {"dof"}), (dict(fog=1, dof_taps=4), {"fog", "dof"})])
def test_a_disabled_effect_leaves_no_trace(params, on, tmp_path):
    text = emitted(params, tmp_path)
    present = {n for effect in on for n in EFFECT_NAMES[effect]}
    for name in {n for names in EFFECT_NAMES.values() for n in names}:
        assert (name in text) == (name in present), name
    # the view depth reaches the lit buffer's alpha only for fog and depth of field
    assert ("view_z" in text) == bool(on & {"fog", "dof"})


def test_post_parameters_have_the_techniques_defaults_and_sweepable_values():
    declared = {p.name: p for p in compiled(()).technique.params}
    defaults = post.PostParams()
    for name in post.PostParams.__dataclass_fields__:
        assert declared[name].default == getattr(defaults, name), name
    allowed = {name: p.allowed for name, p in declared.items()}
    assert set(allowed["tonemap"]) == {False, True}
    assert set(allowed["fog"]) == {0, 1, 2}
    assert set(allowed["dof_taps"]) == {0, 4, 8, 16}


def test_reference_operations():
    p = post.PostParams(fog=1, fog_start=5.0, fog_end=40.0)
    depth = np.array([0.0, 5.0, 22.5, 40.0, 100.0, np.inf])
    assert np.allclose(post.fog_factor(depth, p), [0, 0, 0.5, 1, 1, 1])
    e = post.PostParams(fog=2, fog_density=0.05)
    assert np.allclose(post.fog_factor(depth, e), 1 - np.exp(-0.05 * depth))
    assert np.array_equal(post.tone_map(np.array([0.0, 1.0, 3.0]), 1.0), [0, 0.5, 0.75])
    assert post.tone_map(np.array([1.0]), 2.0)[0] == pytest.approx(2 / 3)
    taps = post.DOF_TAPS
    assert np.allclose(np.hypot(taps[:, 0], taps[:, 1]), [1.0] * 8 + [0.5] * 8, atol=1e-7)
    # in focus (blur 0) the gather is the identity; out of focus it blurs
    rng = np.random.default_rng(1)
    colour = rng.random((12, 16, 3))
    focused = np.full((12, 16), 10.0)
    d = post.PostParams(dof_taps=16, focus_distance=10.0)
    assert np.array_equal(post.depth_of_field(colour, focused, d), colour)
    far = np.full((12, 16), 30.0)
    blurred = post.depth_of_field(colour, far, d)
    assert blurred.std() < 0.6 * colour.std()
    # nothing on: the lit image as it is
    assert np.array_equal(post.post_process(colour, far, post.PostParams()), colour)


def test_each_effect_changes_the_reference():
    """The comparisons below are not vacuous: each effect moves the reference image by many
    codes from the plain lighting."""
    base, _ = post.post_reference(scene(), {})
    for params in TONEMAP + FOG + DOF:
        ref, _ = post.post_reference(scene(), params)
        diff = np.abs(to_rgba8(ref)[..., :3].astype(int) - to_rgba8(base)[..., :3].astype(int))
        assert diff.max() >= 20 and diff.mean() >= 0.5, (params, diff.max(), diff.mean())


# ---------------------------------------------------------------------------------------------
# GL against the references
# ---------------------------------------------------------------------------------------------

@pytest.mark.gl
def test_all_off_is_the_plain_lighting():
    ref, gb = post.post_reference(scene(), {})
    e = rgb_error(render({}), ref, ~gb.silhouette)
    assert e["max"] <= 2, e


@pytest.mark.gl
@pytest.mark.parametrize("params", TONEMAP, ids=str)
def test_tone_mapping_matches_its_reference(params):
    e = error(params)
    assert e["max"] <= 2, e


@pytest.mark.gl
@pytest.mark.parametrize("params", FOG, ids=str)
def test_fog_matches_its_reference(params):
    e = error(params)
    assert e["max"] <= 2, e


@pytest.mark.gl
@pytest.mark.parametrize("params", DOF + ALL, ids=str)
def test_depth_of_field_matches_its_reference(params):
    e = error(params)
    assert e["pixels"] > 8000, e
    assert e["p99"] <= 1 and e["mean"] <= 0.25 and e["max"] <= 8, e


@pytest.mark.gl
def test_depth_of_field_keeps_the_focal_plane_sharp():
    """Pixels whose depth is the focus distance (blur 0) are exactly the image without depth
    of field: every tap lands on the centre texel and weighs 0."""
    params = dict(dof_taps=16, focus_distance=9.0, focus_range=4.0)
    _, gb = post.post_reference(scene(), {})
    depth = post.view_depth(gb, scene())
    sharp = np.abs(depth - 9.0) < 0.02
    assert sharp.sum() >= 20
    with_dof, without = render(params)[::-1], render({})[::-1]
    assert np.array_equal(with_dof[sharp], without[sharp])
    assert (with_dof != without).any(axis=-1).mean() > 0.2


# ---------------------------------------------------------------------------------------------
# GL against OpenCL
# ---------------------------------------------------------------------------------------------

@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("params", [TONEMAP[1], FOG[0], FOG[1], DOF[2], ALL[0]], ids=str)
def test_check_gl_against_cl(params, tmp_path):
    pytest.importorskip("pyopencl")
    from pipegen.proof.check import check
    result = check(compiled(_key(params)), scene(), tmp_path)
    assert result.passed, "\n" + result.table() + f"\nfirst divergence: {result.first_divergence}"


# ---------------------------------------------------------------------------------------------
# the error table: python tests/test_calver_post.py
# ---------------------------------------------------------------------------------------------

def error_table() -> str:
    rows = [f"{'parameters':70s} {'scene':13s} {'max':>4s} {'p99':>4s} {'mean':>6s}"]
    for name in ("mixed_lights", "street_lamps"):
        for params in [{}] + TONEMAP + FOG + DOF + ALL:
            e = error(params, name)
            rows.append(f"{str(params):70s} {name:13s} {e['max']:4.0f} {e['p99']:4.0f} "
                        f"{e['mean']:6.3f}")
    return "\n".join(rows)


if __name__ == "__main__":
    print(error_table())
