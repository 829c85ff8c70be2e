"""Calver's HDR accumulation without float blending (issue 27): ``deferred_calver.pipe`` with
``hdr_accumulate = copy_back`` sums each light into ``accum_temp`` from the lit buffer it reads
and copies the pixels back by drawing the light's volume again; ``blend`` (the default) blends
every light into the rgba16f lit buffer.

The bound.  Both modes add the same float32 light terms to the same float16 running sums in
the same light order (directional, point, spot, each in light order).  Each stored sum is
rounded to float16 once, within half an ulp (2^-11 relative) of the value being stored, so
after N lights each mode is within N/2 ulps of the final value from the exactly rounded sum
of its terms, and the two modes within N ulps of each other (N = the scene's lights; per
channel of ``accum``, the ulp of the larger of the two values).  The resolve writes
clamp(accum, 0, 1) to rgba8, so the codes differ by at most floor(255 * N ulps) + 1 (the +1
for rounding to the nearest code; the clamp only shrinks a difference).  Blending in llvmpipe
and in the OpenCL runtime rounds the float32 sum of the stored value and the shader output
once, as copy_back's store does, so in practice the modes agree bit for bit: measured 0 on
mixed_lights and street_lamps, GL and CL, lit buffer and output; the bound is what holds for
blending that rounds the source to float16 first or blends in another order.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file
from pipegen.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
PIPE = ROOT / "pipelines/deferred_calver.pipe"
SIZE = (64, 36)


@lru_cache(maxsize=None)
def scene(name: str):
    return load_scene(ROOT / f"examples/scenes/{name}.toml")


@lru_cache(maxsize=None)
def compiled(mode: str):
    return compile_file(PIPE, params={"hdr_accumulate": mode}, verify_each=True)


def render(mode: str, backend: str, name: str) -> dict:
    return compiled(mode).pipeline(backend, size=SIZE).render(scene(name))


def accum_bound(a: np.ndarray, b: np.ndarray, lights: int) -> np.ndarray:
    """N ulps of float16 at the larger magnitude of each pair of lit-buffer values."""
    larger = np.maximum(np.abs(a.astype(np.float32)), np.abs(b.astype(np.float32)))
    return lights * np.spacing(larger.astype(np.float16)).astype(np.float64)


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("backend", ["gl", "cl"])
@pytest.mark.parametrize("name", ["mixed_lights", "street_lamps"])
def test_copy_back_matches_blending_within_the_rounding_bound(backend, name):
    if backend == "cl":
        pytest.importorskip("pyopencl")
    lights = len(scene(name).lights)
    blend, copy = render("blend", backend, name), render("copy_back", backend, name)
    assert "accum_temp" in copy and "accum_temp" not in blend
    a, b = blend["accum"][..., :3], copy["accum"][..., :3]
    assert np.isfinite(a).all() and np.isfinite(b).all()
    bound = accum_bound(a, b, lights)
    diff = np.abs(a.astype(np.float64) - b.astype(np.float64))
    assert (diff <= bound).all(), float((diff - bound).max())
    codes = np.abs(blend["color"][..., :3].astype(int) - copy["color"][..., :3].astype(int))
    assert (codes <= np.floor(255.0 * bound) + 1).all()
    # the lights do reach the image: the lit buffer is not just the ambient pass's
    assert (a > 0.05).mean() > 0.05


@pytest.mark.gl
@pytest.mark.cl
# CI: every light type (mixed_lights) and every light casting (shadows); small and
# street_lamps with --exhaustive (each scene is a variant compiled and built for it)
@pytest.mark.parametrize("name", [
    pytest.param(n, marks=() if n in ("mixed_lights", "shadows") else pytest.mark.exhaustive)
    for n in ("small", "mixed_lights", "street_lamps", "shadows")])
def test_check_agrees_gl_cl_in_copy_back(name, tmp_path, capsys):
    pytest.importorskip("pyopencl")
    from pipegen.cli.main import main
    status = main(["check", str(PIPE), "-p", "hdr_accumulate=copy_back",
                   "--scene", str(ROOT / f"examples/scenes/{name}.toml"), "--size", "48x27",
                   "-o", str(tmp_path)])
    out = capsys.readouterr().out
    assert status == 0, out
    assert "all targets agree" in out
