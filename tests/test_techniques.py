"""The shipped techniques: each compiles, its shaders pass glslangValidator, and on a scene
within every packing's capacity all seven render the same image, which matches a float64 numpy
evaluation of the shared lighting equation.

Tolerances (rgba8 codes, interior pixels):
- technique vs technique: 2 codes.  Each image is one rgba8 quantisation of nearly the same
  float value (1 code); G-buffer techniques also quantise albedo/specular to 8 bits and normals
  to half before lighting, which moves the result by < 1 code more.
- technique vs float64 reference: 2 codes, for the same reasons.
Pixels on silhouettes and creases (the reference's silhouette mask) are excluded, and their
share is bounded; coverage there depends on each rasteriser's vertex arithmetic.
"""

from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file
from pipegen.reference.lighting import lights_per_pixel, reference_image
from pipegen.scene import load_scene

pytestmark = [pytest.mark.gl]

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUES = ["forward", "forward_multipass", "deferred", "lidr_cpu_sort", "lidr_max_stencil",
              "lidr_bitplanes", "lidr_transparent"]
TOLERANCE_CODES = 2


@pytest.fixture(scope="module")
def scene():
    return load_scene(ROOT / "examples/scenes/small.toml")


class Reference:
    """The float64 reference in the runtimes' row order (row 0 = bottom, GL window y)."""

    def __init__(self, scene):
        rgb, self.gbuffer = reference_image(scene)
        self.rgb = rgb[::-1]
        self.edge = self.gbuffer.silhouette[::-1]


@pytest.fixture(scope="module")
def reference(scene):
    return Reference(scene)


@pytest.fixture(scope="module")
def images(scene):
    out = {}
    for name in TECHNIQUES:
        compiled = compile_file(ROOT / f"pipelines/{name}.pipe", verify_each=True)
        out[name] = compiled.pipeline("gl").render(scene)[compiled.technique.output]
    return out


def test_scene_stays_within_packing_capacity(scene, reference):
    assert lights_per_pixel(reference.gbuffer, scene).max() <= 4


@pytest.mark.parametrize("name", TECHNIQUES)
def test_technique_renders_something(images, name):
    img = images[name]
    assert img.dtype == np.uint8 and img.shape[2] == 4
    assert img[..., :3].max() > 100, "the image is (nearly) black"


@pytest.mark.parametrize("name", TECHNIQUES[1:])
def test_technique_matches_single_pass_forward(images, reference, name):
    interior = ~reference.edge
    diff = np.abs(images[name][..., :3].astype(int) - images["forward"][..., :3].astype(int))
    assert diff[interior].max() <= TOLERANCE_CODES, _where(diff, interior)


@pytest.mark.parametrize("name", TECHNIQUES)
def test_technique_matches_float64_reference(images, reference, name):
    expected = np.rint(np.clip(reference.rgb, 0, 1) * 255).astype(int)
    interior = ~reference.edge
    diff = np.abs(images[name][..., :3].astype(int) - expected)
    assert diff[interior].max() <= TOLERANCE_CODES, _where(diff, interior)
    assert reference.edge.mean() < 0.1, "edge pixels excluded from the comparison stay few"


def _where(diff, mask):
    d = np.where(mask[..., None], diff, 0)
    y, x, c = np.unravel_index(np.argmax(d), d.shape)
    return f"max {d.max()} codes at pixel (x={x}, y={y}) channel {c}"


def test_benchmarks_default_to_every_shipped_technique():
    """benchmarks/backends.py, frame_times.py and cl_profile.py run common.TECHNIQUES by
    default: a technique missing there is never measured."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("bench_common", ROOT / "benchmarks" / "common.py")
    common = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(common)
    assert sorted(common.TECHNIQUES) == sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe"))
