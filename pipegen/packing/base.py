"""What every packing scheme shares: the ``Scheme`` base class, the checks of its options and
target, and the helpers its shader source and numpy mirror are written with.

The scheme modules (``light_index``, ``values``, ``normals``) build on this module;
``schemes`` ties them together.
"""

from __future__ import annotations

from typing import Callable, Optional

from pipegen.core.diagnostics import PipegenError, Span
from pipegen.core.formats import Format

# The scheme names the language accepts (``pack NAME = SCHEME(…)``): here, beside the base
# class, so that lowering a technique without packings reads them without importing every
# scheme (``schemes.py`` maps each to its class).
SCHEMES = ("bitplanes", "max_pairs", "channel_slots", "intensity_planes", "split16", "bitfield",
           "kircher", "spheremap", "octahedral")


class Scheme:
    """One configured scheme: built from ``(options, target format, span)``, it generates the
    shader functions of ``pack NAME = scheme(…)`` and their numpy mirrors."""

    OPTIONS: tuple[str, ...] = ()
    constants: dict = {}
    capacity: Optional[int] = None
    error: Optional[float] = None
    notes: list

    def functions(self, name: str) -> dict[str, str]:   # short name -> source text
        raise NotImplementedError

    def mirror(self) -> dict[str, Callable]:
        raise NotImplementedError


# ---- options and targets ---------------------------------------------------------------------


def int_option(scheme: str, options: dict, key: str, span: Optional[Span],
               default: Optional[int] = None) -> int:
    value = options.get(key, default)
    if value is None:
        raise PipegenError(span, f"{scheme} needs the option '{key}'",
                           f"write e.g. {scheme}({key}: 8, …)")
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            return int(value)
        raise PipegenError(span, f"{scheme} option '{key}' must be an integer, not {value!r}")
    return value


def need_target(scheme: str, fmt: Optional[Format], span: Optional[Span]) -> Format:
    if fmt is None:
        raise PipegenError(span, f"{scheme} needs a target",
                           f"write e.g. {scheme}(target: lightidx, …) naming an rgba8 target")
    return fmt


def cannot_fit(span: Optional[Span], what: str, hint: str = "") -> PipegenError:
    return PipegenError(span, f"packing cannot fit its target: {what}", hint)


# ---- tiny helpers shared by the source generators and the mirrors ----------------------------


def float_literal(x: float) -> str:
    """A float literal of the shader language (always with a decimal point, no exponent)."""
    s = repr(float(x))
    assert "e" not in s and "inf" not in s and "nan" not in s, s
    return s


def unorm_code_expr(v: str, scale: int) -> str:
    """The integer code of a unorm channel read as ``v``: round to nearest.

    ``floor(x*255+0.5)`` recovers the code from any value within ±0.5 code of it.  Trebilco's
    ``ceil(x*254.5)`` computes ``ceil(c + d - (c + d)/510)`` for code c read with error d, and
    gives c + 1 as soon as a value arrives slightly high (d = +0.01 breaks codes 1..5, d = +0.49
    every code below 250).  The clamp keeps out-of-range values (float targets) from the
    undefined negative float -> uint conversion.
    """
    sc = float_literal(scale)
    return f"uint(clamp(floor({v} * {sc} + 0.5), 0.0, {sc}))"


def unorm_codes(v: np.ndarray, scale: int) -> np.ndarray:
    """The mirror of ``unorm_code_expr``: float32 values to their uint32 codes."""
    import numpy as np
    F32 = np.float32
    v = np.asarray(v, dtype=F32)
    return np.clip(np.floor(v * F32(scale) + F32(0.5)), 0, scale).astype(np.uint32)


def as_uint32(x) -> np.ndarray:
    import numpy as np
    return np.asarray(x).astype(np.uint32)
