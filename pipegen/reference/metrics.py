"""Comparing a rendered rgba8 image with a float64 reference, in rgba8 codes.

Row order: the runtimes return targets *bottom row first* (GL window coordinates: row 0 is
window y = 0), the references (``reference_image``, ``reference_composite``, G-buffer masks)
are *top row first* (like a PNG).  The flip happens in one place, :func:`to_top_down`, and
everything else here works top row first: ``mask`` arguments, returned error maps and the
PNGs written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pipegen.reference.lighting import to_rgba8
from pipegen.reference.raster import rasterize, rasterize_each


def to_top_down(image_codes_bottom_up: np.ndarray) -> np.ndarray:
    """A runtime target (row 0 = bottom, GL window y) as a picture (row 0 = top)."""
    return np.asarray(image_codes_bottom_up)[::-1]


def reference_codes(reference_rgb_top_down: np.ndarray) -> np.ndarray:
    """int (H, W, 3): the rgba8 codes a technique should write for the reference colour
    (clamp to [0, 1], x255 in float32, round half to even: ``lighting.to_rgba8``)."""
    return to_rgba8(np.asarray(reference_rgb_top_down, dtype=np.float64))[..., :3].astype(np.int64)


def error_image(image_codes_bottom_up: np.ndarray, reference_rgb_top_down: np.ndarray) -> np.ndarray:
    """int (H, W, 3), top row first: |image - reference| per channel, in rgba8 codes."""
    img = to_top_down(image_codes_bottom_up)[..., :3].astype(np.int64)
    ref = reference_codes(reference_rgb_top_down)
    if img.shape != ref.shape:
        raise ValueError(f"image {img.shape[:2]} and reference {ref.shape[:2]} differ in size")
    return np.abs(img - ref)


def rgb_error(image_codes_bottom_up: np.ndarray, reference_rgb_top_down: np.ndarray,
              mask: np.ndarray | None = None) -> dict:
    """Error statistics of an rgba8 image (H, W, 4) uint8, *bottom row first* as the runtimes
    return it, against a float64 reference (H, W, 3) *top row first*, over the pixels where
    ``mask`` (bool (H, W), top row first; default: all) is true.  Alpha is ignored.

    Returns ``dict(rmse, max, p99, mean, pixels, worst)``, in rgba8 codes: ``rmse`` and
    ``mean`` over every selected channel value, ``max`` the largest channel error, ``p99`` the
    99th percentile of the per-pixel error (the largest of its three channels), ``pixels``
    how many were compared and ``worst`` the (x, y_top_down) of the largest error (or None).
    An empty selection gives zeros.
    """
    err = error_image(image_codes_bottom_up, reference_rgb_top_down)
    sel = np.ones(err.shape[:2], dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    if sel.shape != err.shape[:2]:
        raise ValueError(f"mask {sel.shape} does not match the image {err.shape[:2]}")
    e = err[sel].astype(np.float64)                        # (n, 3)
    if len(e) == 0:
        return dict(rmse=0.0, max=0.0, p99=0.0, mean=0.0, pixels=0, worst=None)
    per_pixel = e.max(axis=1)
    masked = np.where(sel, err.max(axis=2), -1)
    y, x = np.unravel_index(int(np.argmax(masked)), masked.shape)
    return dict(rmse=float(np.sqrt(np.mean(e * e))), max=float(e.max()),
                p99=float(np.percentile(per_pixel, 99)), mean=float(e.mean()),
                pixels=int(len(e)), worst=(int(x), int(y)))


def dilate(mask: np.ndarray, radius: int = 1) -> np.ndarray:
    """Grow a bool (H, W) mask by ``radius`` pixels (a square neighbourhood)."""
    out = np.asarray(mask, dtype=bool)
    for _ in range(int(radius)):
        p = np.pad(out, 1, mode="edge")
        h, w = out.shape
        out = np.logical_or.reduce([p[i:i + h, j:j + w] for i in range(3) for j in range(3)])
    return out


def silhouette_mask(scene, translucent: bool = True, radius: int = 0) -> np.ndarray:
    """bool (H, W), top row first: the opaque G-buffer's ``GBuffer.silhouette`` (object,
    normal-group and sky boundaries) at the scene's output size, plus with ``translucent`` the
    silhouette of every translucent object rasterised on its own; then grown by ``radius``
    pixels (a technique that lights at a lower resolution needs about ``1 / scale`` more)."""
    mask = rasterize(scene, ("opaque",)).silhouette
    if translucent:
        for _, gb in rasterize_each(scene, ("translucent",)):
            mask |= gb.silhouette
    return dilate(mask, radius)


def heat_map(t: np.ndarray) -> np.ndarray:
    """[0, 1] -> black, dark red, red, yellow, white (uint8 (..., 3))."""
    stops = np.array([[0, 0, 0], [128, 0, 0], [255, 32, 0], [255, 220, 0], [255, 255, 255]], np.float64)
    x = np.clip(t, 0.0, 1.0) * (len(stops) - 1)
    i = np.minimum(x.astype(np.int64), len(stops) - 2)
    f = (x - i)[..., None]
    return np.rint(stops[i] * (1 - f) + stops[i + 1] * f).astype(np.uint8)


def error_map_png(path, err: np.ndarray, vmax: float | None = None, mask: np.ndarray | None = None) -> Path:
    """Write an error map as a heat-map PNG (top row first, as given): 0 black, then dark
    red, red, yellow, white at ``vmax`` (default: the largest error, at least 1).  ``err`` is
    (H, W) or (H, W, C) (the largest channel is shown), e.g. ``error_image(...)``.  Pixels
    outside ``mask`` (where given) are drawn dark blue.  Returns the path."""
    from PIL import Image

    e = np.asarray(err, dtype=np.float64)
    if e.ndim == 3:
        e = e.max(axis=2)
    top = float(vmax) if vmax is not None else max(float(e.max(initial=0.0)), 1.0)
    rgb = heat_map(e / top)
    if mask is not None:
        rgb[~np.asarray(mask, dtype=bool)] = (0, 0, 60)
    path = Path(path)
    Image.fromarray(rgb).save(path)
    return path
