"""The scene's values as the shaders receive them: rounded to float32 (the light table and
uniforms are float32 on both backends), held in float64 for the oracle's arithmetic."""

from __future__ import annotations

import numpy as np


def as_float32(x) -> np.ndarray:
    """``x`` rounded to float32, as a float64 array."""
    return np.asarray(x, dtype=np.float32).astype(np.float64)
