"""Turn target codes into pictures people can look at.

Colour targets are shown as they are; everything else is mapped so its structure is visible:
depth linearised between the camera planes, normals from [-1,1] to [0,1], light-index and ID
targets false-coloured per distinct value (so two different light sets never look alike),
other data auto-ranged.
"""

from __future__ import annotations

import numpy as np

from .formats import Format, Kind


def to_rgb8(codes: np.ndarray, fmt: Format, hint: str = "auto",
            near: float = 0.1, far: float = 100.0) -> np.ndarray:
    """``codes`` as returned by a pipeline for a target of ``fmt`` -> (H, W, 3) uint8.

    ``hint``: "color", "index", "normal", "depth", "stencil", "data" or "auto".
    """
    if hint == "auto":
        hint = _guess(fmt)
    if hint == "stencil" or (hint == "index" and codes.ndim == 2):
        return false_color(codes.astype(np.uint64))
    if hint == "index":
        packed = np.zeros(codes.shape[:2], np.uint64)
        for c in range(codes.shape[2]):
            packed = (packed << np.uint64(max(fmt.bits))) | codes[..., c].astype(np.uint64)
        return false_color(packed)
    if hint == "depth":
        return _gray(linear_depth(fmt.dequantize(codes) if fmt.kind is Kind.DEPTH_STENCIL
                                  else codes.astype(np.float64), near, far, invert=True))
    values = fmt.dequantize(codes)
    if values.ndim == 2:
        return _gray(_autorange(values))
    rgb = values[..., :3] if values.shape[2] >= 3 else np.dstack(
        [values, np.zeros(values.shape[:2] + (3 - values.shape[2],))])
    if hint == "normal" or (hint == "data" and np.nanmin(rgb) < 0):
        rgb = rgb * 0.5 + 0.5
    elif hint == "data" and np.nanmax(rgb) > 1:
        rgb = _autorange(rgb)
    return (np.clip(np.nan_to_num(rgb), 0, 1) * 255 + 0.5).astype(np.uint8)


def linear_depth(d: np.ndarray, near: float, far: float, invert: bool = False) -> np.ndarray:
    """Window depth in [0,1] -> distance mapped to [0,1] between near and far (sky = 1)."""
    z = d * 2.0 - 1.0
    lin = (2.0 * near * far) / np.maximum(far + near - z * (far - near), 1e-12)
    t = np.clip((lin - near) / (far - near), 0, 1)
    return 1.0 - t if invert else t


def false_color(values: np.ndarray) -> np.ndarray:
    """Distinct values -> distinct saturated colours; zero (empty) stays black."""
    v = values.astype(np.uint64)
    h = (v * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40)
    rgb = np.stack([(h >> np.uint64(s)) & np.uint64(0xFF) for s in (0, 8, 16)], -1)
    rgb = (rgb.astype(np.float64) * 0.7 + 255 * 0.3).astype(np.uint8)
    rgb[v == 0] = 0
    return rgb


def _guess(fmt: Format) -> str:
    if fmt.kind in (Kind.DEPTH, Kind.DEPTH_STENCIL):
        return "depth"
    if fmt.kind is Kind.UINT:
        return "index"
    return "color" if fmt.channels >= 3 and fmt.kind is Kind.UNORM else "data"


def _autorange(x: np.ndarray) -> np.ndarray:
    finite = np.isfinite(x)
    if not finite.any():
        return np.zeros_like(x)
    lo, hi = float(x[finite].min()), float(x[finite].max())
    return (np.where(finite, x, lo) - lo) / (hi - lo if hi > lo else 1.0)


def _gray(x: np.ndarray) -> np.ndarray:
    g = (np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8)
    return np.dstack([g, g, g])


def save_png(path, rgb8: np.ndarray) -> None:
    from PIL import Image
    # Targets are stored bottom row first (GL window coordinates); pictures are top row first.
    Image.fromarray(np.ascontiguousarray(rgb8[::-1])).save(path)
