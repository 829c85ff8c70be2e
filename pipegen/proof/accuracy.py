"""How far a rendered image is from the truth: the float64 references of a scene, error
statistics in rgba8 codes, ꟻLIP, and error maps.  What ``pipegen sweep`` and the accuracy tests
share.

Two references, both *top row first* (``reference.metrics``' convention; the runtimes return
targets *bottom row first* and :func:`pipegen.reference.metrics.to_top_down` flips them):

- the **scene reference** (:func:`scene_reference`): the scene as the shared lighting equation
  (``reference.lighting``) lights it in float64, at full resolution, with its translucent
  objects blended over the opaque surface back to front (``reference.translucent``; without
  translucent objects that is ``reference.lighting.reference_image``), the shadow-casting
  lights' exact (ray-cast) shadows on the opaque surface.  One truth for every
  technique: what a technique approximates (a low-resolution L-buffer, a light-buffer specular
  colour, packed light indices that drop lights) counts as its error.
- the **equation reference** (:func:`equation_reference`): the float64 evaluation of the
  equation a technique family computes (the light-buffer equation for the light pre-pass and
  inferred lighting, ``reference.light_buffer``; the shared equation for the others), which is
  what ``tests/test_techniques.py`` and ``tests/test_issue4_techniques.py`` hold each technique
  to on pixels off silhouettes.

A user chooses what output errors are measured against (``references.py``: ``scene``, the
scene reference above; ``self``, the technique at its most accurate parameter values; another
``.pipe``; each optionally supersampled): :func:`codes_vs_reference` gives the figures against
any of them, with the worst pixels located.

Errors are in rgba8 codes (alpha ignored): ``rmse`` over every channel value, ``p99`` of the
per-pixel error (the largest of its three channels), ``max``.  Silhouette and crease pixels (the
reference G-buffer's edges, plus translucent outlines) depend on each rasteriser's coverage and
are counted in the whole-image figures; the ``interior`` figures leave them out.

ꟻLIP (Andersson et al. 2020) comes from the ``flip-evaluator`` package (import
``flip_evaluator``), LDR mode, default viewing conditions (67 pixels per degree); both images
are given as display values in [0, 1] (codes / 255 and the clamped reference).  Without the
package :func:`flip_mean` returns NaN and :data:`FLIP_NOTE` says why.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pipegen.core import formats
from pipegen.scene.shadows import shadow_lights
from pipegen.reference.metrics import (dilate, heat_map, reference_codes, rgb_error,
                                       to_top_down)

# families whose image is the light-buffer equation (reference.light_buffer), by technique name
LIGHT_BUFFER_TECHNIQUES = ("light_prepass", "inferred")
ERROR_MAP_VMAX = 32            # codes shown white in error maps: one scale for every variant

FLIP_NOTE = ""
try:                                       # an optional metric: NaN without the package
    import flip_evaluator as _flip  # noqa: F401
except Exception as e:                     # pragma: no cover - depends on the environment
    _flip = None
    FLIP_NOTE = (f"flip columns are NaN: the flip-evaluator package is not importable "
                 f"({type(e).__name__}: {e}); pip install flip-evaluator")


@dataclass
class SceneReference:
    """The scene reference at the scene's output size, top row first."""

    rgb: np.ndarray            # float64 (H, W, 3), before clamping
    silhouette: np.ndarray     # bool (H, W): opaque silhouettes, creases, translucent outlines
    translucent: bool          # the scene has translucent objects (blended into ``rgb``)

    @property
    def interior(self) -> np.ndarray:
        """bool (H, W): pixels one pixel or more away from every silhouette."""
        return ~dilate(self.silhouette, 1)


def scene_reference(scene) -> SceneReference:
    """The scene as the shared lighting equation renders it in float64 (module docstring);
    the lights that cast shadows (``shadows = true``) shadow the opaque surface exactly
    (``reference.shadows.visibility``: ray casting, the hard shadows shadow maps approximate)."""
    from pipegen.reference.shadows import ExactShadows
    from pipegen.reference.translucent import reference_composite
    casting = bool(shadow_lights(scene.lights))
    rgb, info = reference_composite(scene, shadows=ExactShadows() if casting else None)
    return SceneReference(rgb, info["silhouette"], bool(len(info["surfaces"])))


def equation_reference(technique_name: str, scene) -> tuple[np.ndarray, np.ndarray]:
    """(rgb float64 (H, W, 3), silhouette bool (H, W)), top row first: the float64 equation
    the technique family computes on the scene's opaque objects (module docstring)."""
    if technique_name in LIGHT_BUFFER_TECHNIQUES:
        from pipegen.reference.light_buffer import light_buffer_reference
        rgb, gb = light_buffer_reference(scene)
    else:
        from pipegen.reference.lighting import reference_image
        rgb, gb = reference_image(scene)
    return rgb, gb.silhouette


# -- images ------------------------------------------------------------------------------------


def output_codes(compiled, targets: dict) -> np.ndarray:
    """The output target of a render as rgba8 codes (H, W, 4) uint8, bottom row first.  An
    output in another colour format is read as the values it stores and quantised as rgba8."""
    tech = compiled.technique
    codes = np.asarray(targets[tech.output])
    fmt = tech.target(tech.output).format
    if fmt.name == "rgba8":
        return codes
    return values_to_rgba8(fmt.dequantize(codes))


def values_to_rgba8(values: np.ndarray) -> np.ndarray:
    """Stored values (H, W, C) in [0, 1] -> rgba8 codes (H, W, 4); missing channels are 0,
    a missing alpha 1."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 2:
        v = v[..., None]
    h, w, c = v.shape
    out = np.zeros((h, w, 4))
    out[..., 3] = 1.0
    out[..., :min(c, 4)] = v[..., :4]
    return formats.get("rgba8").quantize(out)


def f64_output_codes(compiled, values: dict) -> np.ndarray:
    """The f64 evaluation's output target (unquantised stored values, GL row order) as the
    codes its format stores, as rgba8 (H, W, 4), bottom row first."""
    tech = compiled.technique
    fmt = tech.target(tech.output).format
    codes = fmt.quantize(np.asarray(values[tech.output], dtype=np.float64))
    return codes if fmt.name == "rgba8" else values_to_rgba8(fmt.dequantize(codes))


# -- statistics --------------------------------------------------------------------------------


def scene_error(codes_bottom_up: np.ndarray, ref: SceneReference) -> dict:
    """Whole-image and interior statistics against the scene reference, in rgba8 codes:
    ``rmse, p99, max, mean`` and ``rmse_interior, max_interior``."""
    whole = rgb_error(codes_bottom_up, ref.rgb)
    inner = rgb_error(codes_bottom_up, ref.rgb, ref.interior)
    return dict(rmse=whole["rmse"], p99=whole["p99"], max=whole["max"], mean=whole["mean"],
                rmse_interior=inner["rmse"], max_interior=inner["max"])


def codes_vs_reference(codes_bottom_up: np.ndarray, ref, scene, worst: int = 5) -> dict:
    """The error of an rgba8 output (H, W, 4), bottom row first, against a reference
    (``references.Reference``) on ``scene``, in rgba8 codes: ``rmse, p99, max, mean`` over
    the image, ``rmse_interior, max_interior`` away from edges (``Reference.edges`` grown by a
    pixel), ``reference`` (its label) and ``worst``: up to ``worst`` pixels with the largest
    error, ``[(x, y, got_rgb, ref_rgb), ...]``, y top row first, both as rgba8 codes (the
    reference clamped and quantised as ``metrics.reference_codes`` does)."""
    rgb = ref.output_rgb(scene)
    interior = ~dilate(ref.edges(scene), 1)
    whole = rgb_error(codes_bottom_up, rgb)
    inner = rgb_error(codes_bottom_up, rgb, interior)
    got = to_top_down(codes_bottom_up)[..., :3].astype(np.int64)
    want = reference_codes(rgb)
    per_pixel = np.abs(got - want).max(axis=-1).ravel()
    order = np.argsort(-per_pixel, kind="stable")[:worst]
    w = got.shape[1]
    spots = [(int(i % w), int(i // w), tuple(int(c) for c in got.reshape(-1, 3)[i]),
              tuple(int(c) for c in want.reshape(-1, 3)[i]))
             for i in order if per_pixel[i] > 0]
    return dict(rmse=whole["rmse"], p99=whole["p99"], max=whole["max"], mean=whole["mean"],
                rmse_interior=inner["rmse"], max_interior=inner["max"], reference=ref.label,
                worst=spots)


def codes_error(a_codes: np.ndarray, b_codes: np.ndarray) -> dict:
    """``rmse, p99, max`` of |a - b| over the RGB channels of two rgba8 images (same row
    order), in codes; ``p99`` of the per-pixel largest channel error."""
    d = np.abs(np.asarray(a_codes)[..., :3].astype(np.int64)
               - np.asarray(b_codes)[..., :3].astype(np.int64)).astype(np.float64)
    if d.size == 0:
        return dict(rmse=0.0, p99=0.0, max=0.0)
    per_pixel = d.max(axis=-1).ravel()
    return dict(rmse=float(np.sqrt(np.mean(d * d))), p99=float(np.percentile(per_pixel, 99)),
                max=float(d.max()))


def flip_mean(codes_bottom_up: np.ndarray, reference_rgb_top_down: np.ndarray) -> float:
    """Mean ꟻLIP (LDR) of an rgba8 image against a float64 reference; NaN without
    ``flip_evaluator`` (:data:`FLIP_NOTE`)."""
    if _flip is None:
        return math.nan
    test = to_top_down(codes_bottom_up)[..., :3].astype(np.float32) / np.float32(255.0)
    ref = np.clip(np.asarray(reference_rgb_top_down, dtype=np.float64), 0.0, 1.0)
    ref = ref.astype(np.float32)
    _, mean, _ = _flip.evaluate(np.ascontiguousarray(ref), np.ascontiguousarray(test), "LDR",
                                applyMagma=False)
    return float(mean)


# -- error maps --------------------------------------------------------------------------------


def error_map_rgb(codes_bottom_up: np.ndarray, reference_rgb_top_down: np.ndarray,
                  vmax: float = ERROR_MAP_VMAX) -> np.ndarray:
    """uint8 (H, W, 3), top row first: the per-pixel largest channel error against the
    reference as a heat map (black 0, dark red, red, yellow, white at ``vmax`` codes)."""
    img = to_top_down(codes_bottom_up)[..., :3].astype(np.int64)
    err = np.abs(img - reference_codes(reference_rgb_top_down)).max(axis=-1)
    return heat_map(err / float(vmax))


def png_bytes(rgb: np.ndarray) -> bytes:
    """An (H, W, 3) uint8 picture as PNG file content."""
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb)).save(buf, format="PNG")
    return buf.getvalue()


def finite_or_none(x: Optional[float]) -> Optional[float]:
    """A float for JSON: None for NaN / missing."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None
