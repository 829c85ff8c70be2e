"""The light-buffer equation of the light pre-pass and inferred lighting, in float64.

Those techniques sum per light into a buffer (``pipelines/common/light_buffer.pipe``)

    D = Σ color * att * max(n·l, 0)                   (RGB)
    S = Σ luminance(color) * att * spec               (A)

and the material pass computes ``ambient * albedo + albedo * D + specular * S * D / lum(D)``:
the specular colour is rebuilt from the diffuse light's chroma.  Where one light reaches a
pixel (or all reaching lights share a colour) this equals the shared equation of
``reference.lighting``; where differently coloured lights overlap it does not — that
difference is the technique's, not a backend's, and is measured against ``reference.lighting``
separately.
"""

from __future__ import annotations

import numpy as np

from pipegen.scene.model import Scene
from pipegen.reference.lighting import light_contribution
from pipegen.reference.raster import GBuffer, rasterize
from pipegen.reference.rounding import as_float32

LUMA = np.array([0.2126, 0.7152, 0.0722])


def light_buffer_sums(gbuffer: GBuffer, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(D (n, 3), S (n,)) at the covered pixels of ``gbuffer``, in coverage order."""
    cov = gbuffer.coverage
    P, N, shin = gbuffer.position[cov], gbuffer.normal[cov], gbuffer.shininess[cov]
    cam = np.asarray(scene.camera.position, dtype=np.float64)
    ones, zeros = np.ones((len(P), 3)), np.zeros(len(P))
    D = np.zeros((len(P), 3))
    S = np.zeros(len(P))
    for light in scene.lights:
        diffuse = light_contribution(light, P, N, cam, ones, zeros, shin)
        spec_rgb = light_contribution(light, P, N, cam, 0 * ones, np.ones(len(P)), shin)
        D += diffuse
        S += spec_rgb @ LUMA
    return D, S


def shade_light_buffer(gbuffer: GBuffer, scene: Scene) -> np.ndarray:
    """float64 (H, W, 3) colour of the light-buffer equation (top row first), sky = clear."""
    out = np.zeros((gbuffer.height, gbuffer.width, 3))
    out[:] = scene.clear_color
    cov = gbuffer.coverage
    D, S = light_buffer_sums(gbuffer, scene)
    albedo, spec = gbuffer.albedo[cov], gbuffer.specular[cov]
    chroma = D / np.maximum(D @ LUMA, 1e-6)[:, None]
    out[cov] = as_float32(scene.ambient) * albedo + albedo * D + (spec * S)[:, None] * chroma
    return out


def light_buffer_reference(scene: Scene) -> tuple[np.ndarray, GBuffer]:
    gb = rasterize(scene, ("opaque",))
    return shade_light_buffer(gb, scene), gb
