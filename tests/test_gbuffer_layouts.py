"""The G-buffer layouts of the study notes (seeds/003; issue 28): Killzone 2's, StarCraft II's and
Hargreaves' 128-bit layout as example techniques.

Each compiles, renders on GL and CL within check's tolerances, and stores a normal and a depth
whose error against a float64 truth stays within a bound derived from its encoding.  The truth
is a small technique evaluated in float64 that writes each pixel's unit normal and world
position unquantised; a layout's targets, rendered in float32 on CL, are decoded here as its
light passes decode them (in float64), and compared pixel by pixel away from silhouettes
(where float32 and float64 may rasterise different surfaces).  The figures of docs/encodings.md
("G-buffer layouts of the study notes") are this module's ``measure`` (``python
tests/test_gbuffer_layouts.py``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUES = ROOT / "examples" / "techniques"
SCENES = ROOT / "examples" / "scenes"
LAYOUTS = ("killzone2", "starcraft2", "hargreaves128")
SMALL = (64, 36)

TRUTH = """technique gbuffer_truth "unit normal and world position, unquantised"
target tnormal : rgba32f clear 0
target tpos    : rgba32f clear 0
target ds      : d24s8 clear depth 1.0 stencil 0
output tnormal
pass geometry {
  draw scene.opaque
  writes tnormal, tpos
  depth ds less write
  cull back
  fragment {
    tnormal = vec4(normalize(normal), float(object_id) + 1.0);
    tpos = vec4(world_pos, 1.0);
  }
}
"""


def _path(layout: str) -> Path:
    return TECHNIQUES / f"{layout}_gbuffer.pipe"


def _unproject(scene, xy_ndc_z: np.ndarray) -> np.ndarray:
    """World positions of (..., 3) NDC points through the scene camera, float64."""
    cam = scene.camera
    inv = np.linalg.inv(np.asarray(cam.projection(scene.aspect) @ cam.view_matrix(), np.float64))
    p = np.concatenate([xy_ndc_z, np.ones(xy_ndc_z.shape[:-1] + (1,))], -1) @ inv.T
    return p[..., :3] / p[..., 3:4]


def _ndc_xy(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    x = (np.arange(w) + 0.5) / w * 2 - 1
    y = (np.arange(h) + 0.5) / h * 2 - 1
    return np.meshgrid(x, y)


def _from_window_depth(scene, z: np.ndarray) -> np.ndarray:
    X, Y = _ndc_xy(*z.shape)
    return _unproject(scene, np.stack([X, Y, 2 * z - 1], -1))


def _from_linear_depth(scene, d: np.ndarray) -> np.ndarray:
    """As the techniques' world_from_linear_depth: along the pixel's ray, -view z = d."""
    X, Y = _ndc_xy(*d.shape)
    near = _unproject(scene, np.stack([X, Y, -np.ones_like(X)], -1))
    eye = np.asarray(scene.camera.position, np.float64)
    ray = near - eye
    forward = np.linalg.inv(np.asarray(scene.camera.view_matrix(), np.float64))[:3, 2] * -1
    return eye + ray * (d / (ray @ forward))[..., None]


def _fmt(name: str):
    from pipegen.core import formats
    return formats.get(name)


def decode(layout: str, targets: dict, scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(world unit normals, world positions, covered) as the layout's light passes decode its
    float32 targets (codes as rendered, row 0 at the bottom), in float64."""
    if layout == "killzone2":
        from pipegen.reference.bitcasts import unpack_half2x16
        b = np.asarray(targets["gnormal"], np.uint32)
        xy = unpack_half2x16(b[..., 0] | (b[..., 1] << 8) | (b[..., 2] << 16)
                             | (b[..., 3] << 24)).astype(np.float64)
        view_n = np.concatenate([xy, np.sqrt(np.maximum(1 - np.sum(xy * xy, -1), 0))[..., None]],
                                -1)
        rot = np.linalg.inv(np.asarray(scene.camera.view_matrix(), np.float64))[:3, :3]
        n = view_n @ rot.T
        z = _fmt("d24s8").dequantize(targets["ds"])
        return n, _from_window_depth(scene, z), z < 1.0
    if layout == "starcraft2":
        v = _fmt("rgba16f").dequantize(targets["gnormal"])
        n, d = v[..., :3], v[..., 3]
    else:
        n = _fmt("rgb10a2").dequantize(targets["gnormal"])[..., :3] * 2 - 1
        d = _fmt("r32f").dequantize(targets["gdepth"])
        d = d[..., 0] if d.ndim == 3 else d
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return n, _from_linear_depth(scene, d), d > 0


def _interior(ids: np.ndarray) -> np.ndarray:
    """Pixels whose 3x3 neighbourhood shows one object (no silhouette, no sky)."""
    pad = np.pad(ids, 1, constant_values=0)
    h, w = ids.shape
    same = ids > 0
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            same &= pad[dy:dy + h, dx:dx + w] == ids
    return same


def measure(layout: str, scene_path: Path, size: tuple[int, int]) -> dict:
    """The layout's normal (degrees) and position (scene units) error against the float64
    truth, per pixel away from silhouettes, with the truth's view-space normal z there."""
    from pipegen.compiler.driver import compile_file, compile_source
    from pipegen.scene.load import load_scene
    scene = load_scene(scene_path).with_size(*size)
    truth = compile_source(TRUTH, "gbuffer_truth.pipe").pipeline("cl", precision="f64") \
        .render(scene)
    got = compile_file(_path(layout)).pipeline("cl").render(scene)
    n, p, covered = decode(layout, got, scene)
    tn, tp = np.asarray(truth["tnormal"], np.float64), np.asarray(truth["tpos"], np.float64)
    inside = _interior(np.rint(tn[..., 3]).astype(int)) & covered
    cos = np.clip(np.sum(n * tn[..., :3], -1), -1.0, 1.0)
    angle = np.degrees(np.arccos(cos))[inside]
    dist = np.linalg.norm(p - tp[..., :3], axis=-1)[inside]
    view_z = (tn[..., :3] @ np.asarray(scene.camera.view_matrix(), np.float64)[:3, :3].T)[..., 2]
    depth = -(np.c_[tp[..., :3].reshape(-1, 3), np.ones(tp[..., 0].size)]
              @ np.asarray(scene.camera.view_matrix(), np.float64)[2])
    return dict(angle=angle, dist=dist, view_z=view_z[inside],
                depth=depth.reshape(tp.shape[:2])[inside], pixels=int(inside.sum()))


# -- the bounds, from each layout's encoding --------------------------------------------------

HALF_ULP_BELOW_1 = 2.0 ** -11      # a half's spacing in [0.5, 1): the largest below 1


def normal_bound_deg(layout: str, view_z: np.ndarray) -> np.ndarray:
    """Per pixel, the largest angle the layout's normal storage allows (first order, x1.05):
    Killzone 2: x and y rounded to the nearest half (|dxy| <= sqrt(2) 2^-12), z rebuilt, which
    divides the error by the normal's view z; StarCraft II: three halves stored rounding toward
    zero (< 1 half ulp each: |d| < sqrt(3) 2^-11); Hargreaves: three 10-bit unorm channels
    over [-1, 1], 2/1023 a step, each rounded to within half a step plus half a 16-bit step
    (llvmpipe's store converts through 16 bits: 0.508 of a step)."""
    if layout == "killzone2":
        rad = math.sqrt(2) * HALF_ULP_BELOW_1 / 2 / np.maximum(view_z, 1e-9)
    elif layout == "starcraft2":
        rad = np.full(view_z.shape, math.sqrt(3) * HALF_ULP_BELOW_1)
    else:
        rad = np.full(view_z.shape, math.sqrt(3) * (0.5 + 0.5 * 1023 / 65535) * 2 / 1023)
    return np.degrees(rad) * 1.05


def position_bound(layout: str, depth: np.ndarray, scene) -> np.ndarray:
    """Per pixel, the largest position error the layout's depth storage allows: StarCraft II
    a half of the linear depth (toward zero: < 1 ulp), Hargreaves a float32 (x4 ulp for the
    rasteriser's interpolation), Killzone 2 a D24 code (and the float32 window depth
    before it: 2^-23) through the perspective's dz_view/dz_window = d^2 (f - n) / (n f);
    each along the view ray, at most 1/cos of the corner's angle off axis."""
    cam = scene.camera
    half_y = math.tan(math.radians(cam.fov_y_deg) / 2)
    stretch = math.sqrt(1 + half_y ** 2 * (1 + scene.aspect ** 2))
    if layout == "starcraft2":
        step = 2.0 ** (np.floor(np.log2(depth)) - 10)
    elif layout == "hargreaves128":
        step = 4 * 2.0 ** (np.floor(np.log2(depth)) - 23)
    else:
        n, f = cam.near, cam.far
        step = (0.5 / (2 ** 24 - 1) + 2.0 ** -23) * depth ** 2 * (f - n) / (n * f)
    return step * stretch * 1.05 + 1e-6


# -- tests ------------------------------------------------------------------------------------

@pytest.mark.parametrize("layout", LAYOUTS)
def test_layout_compiles_with_its_targets(layout):
    from pipegen.compiler.driver import compile_file
    c = compile_file(_path(layout))
    gbuffer = {"killzone2": {"lacc", "gnormal", "gmotion", "galbedo"},
               "starcraft2": {"unlit", "gnormal", "galbedo", "gspecular"},
               "hargreaves128": {"gdepth", "gnormal", "gdiffuse", "gmaterial"}}[layout]
    bits = {t.name: sum(t.format.bits) for t in c.technique.targets}
    assert sum(bits[t] for t in gbuffer) == {"killzone2": 128, "starcraft2": 256,
                                             "hargreaves128": 128}[layout]
    ds = c.technique.target("ds").format
    assert sum(ds.bits) + ds.stencil_bits == 32         # D24S8


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("layout", LAYOUTS)
# CI: shadows (every light type, every light casting); mixed_lights, the same light types
# without shadows, with --exhaustive (each scene is a variant compiled and built for it)
@pytest.mark.parametrize("scene", ("shadows", pytest.param("mixed_lights",
                                                            marks=pytest.mark.exhaustive)))
def test_backends_agree(layout, scene):
    from pipegen.testing.api import assert_backends_agree
    assert_backends_agree(_path(layout), SCENES / f"{scene}.toml", size=SMALL)


@pytest.mark.cl
@pytest.mark.parametrize("layout", LAYOUTS)
def test_normal_and_position_within_their_encoding(layout):
    """On edges.toml (the figures' scene) at 64x36: every interior pixel's normal and position
    within the bound of its storage; Killzone 2's rebuilt z judged where the true view z >=
    0.05 (first order; nearer the silhouette the error grows as 1/z and, for normals facing
    away, the z >= 0 assumption fails)."""
    from pipegen.scene.load import load_scene
    scene = load_scene(SCENES / "edges.toml").with_size(*SMALL)
    m = measure(layout, SCENES / "edges.toml", SMALL)
    assert m["pixels"] > 500
    judged = m["view_z"] >= 0.05 if layout == "killzone2" else np.ones(m["pixels"], bool)
    assert judged.mean() > 0.9
    over = m["angle"][judged] > normal_bound_deg(layout, m["view_z"][judged])
    assert not over.any(), (np.max(m["angle"][judged]), int(over.sum()))
    assert np.all(m["dist"] <= position_bound(layout, m["depth"], scene)), np.max(m["dist"])
    # and the storage shows: the errors are not zero
    assert np.max(m["angle"]) > 1e-3 and np.max(m["dist"]) > 1e-7


def _table(size=(160, 90)):
    scene = SCENES / "edges.toml"
    print(f"edges.toml at {size[0]}x{size[1]}, CL float32 vs the float64 truth, interior pixels")
    print("layout         pixels  normal p99/max (deg)  position p99/max (scene units)")
    for layout in LAYOUTS:
        m = measure(layout, scene, size)
        a, d = m["angle"], m["dist"]
        print(f"{layout:<14} {m['pixels']:>6}  {np.percentile(a, 99):.3g}/{a.max():.3g}"
              f"{'':>12}{np.percentile(d, 99):.3g}/{d.max():.3g}")


if __name__ == "__main__":
    _table(tuple(int(v) for v in sys.argv[1].split("x")) if len(sys.argv) > 1 else (160, 90))
