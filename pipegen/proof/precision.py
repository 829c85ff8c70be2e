"""Precision error: a technique's float32 images against its own float64 evaluation.

``Compiled.pipeline("cl", precision="f64")`` renders the technique's exact meaning (its
arithmetic in double, every target stored unquantised in its declared range; docs/internals.md,
"The float64 evaluation").  Two references per image then split the error of a float32 image:

- against the **scene reference** (``pipegen.reference``: the float64 evaluation of the scene's
  lighting, the physical intent): the *total* error;
- against the technique's **own float64 evaluation** (same variant, exact arithmetic): the
  *precision* error;
- the float64 evaluation against the scene reference: what the *algorithm* gives up.

``quantize_targets`` turns a float64 render into the codes a float32 run stores (so they
compare code for code), ``precision_check`` is ``pipegen check --precision f64`` (every target
of the float32 backends against the quantised float64 evaluation, in the format's units, with
``compare.py``'s edge handling: a pixel whose value some neighbour matches, next to a
discontinuity, is a coverage difference, counted apart), ``error_split`` the three errors of
an rgba8 output (``reference.metrics.rgb_error``'s statistics).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from pipegen.core import formats
from pipegen.backends import registry
from pipegen.proof.compare import TargetComparison, compare_target

# the float32 backends ``precision_check`` compares with the float64 evaluation
F32_BACKENDS = ("gl", "cl")


def quantize_targets(technique, values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A float64 render (``{target: float64 values}``) as the codes a float32 run stores:
    ``Format.quantize`` of each value (depth too), integer targets and ``.stencil`` aspects
    their integer codes in the format's dtype."""
    out = {}
    for key, v in values.items():
        base, _, aspect = key.partition(".")
        fmt = technique.target(base).format
        if aspect == "stencil":
            out[key] = np.asarray(v).astype(np.uint8)
        elif fmt.is_integer:
            out[key] = np.asarray(v).astype(fmt.dtype)
        else:
            out[key] = np.asarray(fmt.quantize(v)).astype(fmt.dtype)
    return out


def precision_tolerance(fmt: formats.Format, aspect: str = "") -> formats.Tolerance:
    """What a float32 store may differ from the quantised exact value by and still be the exact
    value rounded: 1 code (fixed point, d24 depth), 1 ulp plus the format's floor (float),
    exact for integers and stencil."""
    if aspect == "stencil" or fmt.is_integer:
        return formats.Tolerance("exact", 0)
    base = fmt.tolerance(0)
    if base.units == "code":
        return formats.Tolerance("code", 1)
    return formats.Tolerance("ulp", 1, base.abs_floor)


@dataclass
class PrecisionResult:
    technique: str
    rows: dict[str, list[TargetComparison]]      # per float32 backend, one row per target
    notes: list[str] = field(default_factory=list)

    def table(self, backend: str) -> str:
        header = ("target", "format", "max error", "rmse", "limit", "over", "edges/bound", "")
        # the last column says whether the target is the exact value rounded (within the
        # limit away from edges), not pass/fail: precision error is what it is
        rows = [header] + [r.row()[:-1] + ("rounding" if r.passed else "more than rounding",)
                           for r in self.rows[backend]]
        widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip()
                         for r in rows)


def precision_check(compiled, scene, backends: tuple[str, ...] = F32_BACKENDS,
                    progress: Callable[[str], None] = lambda msg: None) -> PrecisionResult:
    """Every target of each float32 backend against the quantised float64 evaluation (CL)."""
    progress("rendering the float64 evaluation (CL)")
    exact = quantize_targets(compiled.technique,
                             compiled.pipeline("cl", precision="f64").render(scene))
    rows: dict[str, list[TargetComparison]] = {}
    for b in backends:
        progress(f"rendering on {registry.get(b).title}")
        got = compiled.pipeline(b).render(scene)
        rows[b] = []
        for key in sorted(got):
            base, _, aspect = key.partition(".")
            fmt = compiled.technique.target(base).format
            rows[b].append(compare_target(key, fmt, got[key], exact[key],
                                          tolerance=precision_tolerance(fmt, aspect)))
    return PrecisionResult(compiled.name, rows)


def main_precision_check(compiled, scene, out_dir: Optional[Path] = None) -> int:
    """``pipegen check --precision f64``: print the precision error of every target on each
    float32 backend (error images ``error_<backend>_<target>.png`` in ``out_dir``).  A
    measurement, not a test: the exit status is 0 (a technique may well store values less
    precisely than a code; ``pipegen check`` without ``--precision`` is the pass/fail
    cross-check)."""
    def say(msg: str) -> None:
        print(f"  … {msg}", file=sys.stderr)

    result = precision_check(compiled, scene, progress=say)
    print(f"{compiled.name} on {scene.width}x{scene.height}, {len(scene.lights)} lights: "
          f"precision error against the float64 evaluation (quantised to each target's "
          f"format; over = pixels beyond the limit away from primitive edges)")
    for b, rows in result.rows.items():
        print(f"\n{registry.get(b).title}")
        print(result.table(b))
    if out_dir is not None:
        from pipegen.proof.check import error_image
        from pipegen.core.outdir import as_output_dir, safe_name
        from pipegen.views.visualize import save_png
        with as_output_dir(out_dir, "check").staging() as tmp:
            for b, rows in result.rows.items():
                for r in rows:
                    save_png(tmp / safe_name(f"error_{b}_{r.name}", ".png"), error_image(r))
        print(f"\nerror images: {out_dir}/error_<backend>_<target>.png")
    return 0


def error_split(f32_codes: np.ndarray, f64_values: np.ndarray,
                reference_rgb_top_down: Optional[np.ndarray] = None,
                mask: Optional[np.ndarray] = None) -> dict:
    """The errors of an rgba8 output image in rgba8 codes (``reference.metrics.rgb_error``
    statistics; ``mask``: bool (H, W), top row first).  ``f32_codes``: (H, W, 4) as a float32
    run returns it (row 0 at the bottom); ``f64_values``: the same target of the float64
    evaluation; ``reference_rgb_top_down``: the scene reference (H, W, 3), top row first.
    Returns ``{"precision": f32 vs f64}`` and, with a reference, ``"total"`` (f32 vs the
    reference) and ``"algorithm"`` (the quantised f64 vs the reference)."""
    from pipegen.reference.metrics import rgb_error, to_top_down
    exact = np.asarray(f64_values, np.float64)
    out = {"precision": rgb_error(f32_codes, to_top_down(exact)[..., :3], mask)}
    if reference_rgb_top_down is not None:
        codes = formats.get("rgba8").quantize(exact)
        out["total"] = rgb_error(f32_codes, reference_rgb_top_down, mask)
        out["algorithm"] = rgb_error(codes, reference_rgb_top_down, mask)
    return out
