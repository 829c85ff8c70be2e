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
from pipegen.proof.discontinuity import Explainer, distance
from pipegen.proof.f64_bound import F64Bound
from pipegen.proof.f64_compare import (TargetResult, comparable, compare_values,
                                       comparison_units)

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


def compare_with_f64(compiled, scene, renders: dict, f64: dict, bound: dict,
                     blends: Optional[dict] = None,
                     explain: bool = True) -> dict[str, list[TargetResult]]:
    """Every target of each float32 render (``renders``: backend -> targets) against the
    float64 evaluation ``f64`` within ``bound`` (``F64Bound.bounds``).  With ``explain``, the
    pixels where the float32 render fell on the other side of a step of the technique's code
    (``discontinuity.py``) are found among those that differ by more than the target's local
    error (``tolerance.local_bound``: store, blends, arithmetic), listed on the row as its
    discontinuities and not counted against the bound."""
    from pipegen.proof.tolerance import local_bound, plan_targets
    info = plan_targets(compiled)
    output = compiled.technique.output
    blends = blends or {}
    rows: dict[str, list[TargetResult]] = {}
    explainer = Explainer(compiled, scene, f64, comparison_units(info)) if explain else None
    for b, got in renders.items():
        rows[b] = []
        for key in sorted(got):
            base, _, aspect = key.partition(".")
            t = info[base]
            exact = t.exact or aspect == "stencil"
            row = compare_values(key, t.format, b, got[key], f64[key], bound[key], exact)
            if explainer is not None and explainer.sites and not aspect:
                g, want = comparable(key, t.format, got[key], f64[key], exact)
                smooth = np.zeros(g.shape) if exact else local_bound(t, want, blends.get(base))
                candidates = distance(g, want) > (smooth.max(axis=-1) if smooth.ndim == 3
                                                   else smooth)
                found, left = explainer.explain(key, candidates, [g], smooth)
                if found:
                    explained = candidates & ~left
                    row = compare_values(key, t.format, b, got[key], f64[key], bound[key],
                                         exact, exclude=explained)
                    row.discontinuities, row.discontinuity_mask = found, explained
            row.output = base == output
            rows[b].append(row)
    return rows


@dataclass
class PrecisionResult:
    technique: str
    rows: dict[str, list[TargetResult]]      # per float32 backend, one row per target
    parts: dict = field(default_factory=dict)  # per target: the bound's terms (largest)
    notes: list[str] = field(default_factory=list)
    outputs: dict = field(default_factory=dict)  # per backend and "f64": output rgba8 codes
    why: list[str] = field(default_factory=list)  # per target over its bound (proof/why.py)

    def discontinuities(self) -> int:
        return max((sum(r.discontinuity_count for r in rows) for rows in self.rows.values()),
                   default=0)

    def table(self, backend: str) -> str:
        header = ("target", "format", "max error", "bound there", "over", "edges/bound",
                  "discontinuities", "")
        rows = [header]
        for r in self.rows[backend]:
            rows.append((r.key, r.format, r.units(r.worst_error),
                         r.units(r.bound_at_worst) if not r.exact else "exact", str(r.over),
                         f"{r.edges}/{r.edge_bound}", str(r.discontinuity_count),
                         "ok" if r.passed else "OVER THE BOUND"))
        widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip()
                         for r in rows)


def precision_check(compiled, scene, backends: tuple[str, ...] = F32_BACKENDS,
                    progress: Callable[[str], None] = lambda msg: None,
                    explain: bool = True) -> PrecisionResult:
    """Every target of each float32 backend against the float64 evaluation, within the bound of
    the tolerance model (the one ``pipegen stress`` holds every case to), discontinuities
    counted apart."""
    renders = {}
    pipes = {}
    for b in dict.fromkeys(backends + ("cl",)):    # CL counts the blends into each pixel
        progress(f"rendering on {registry.get(b).label()}")
        pipes[b] = compiled.pipeline(b)
        renders[b] = pipes[b].render(scene)
    blends = getattr(pipes["cl"], "last_blend_counts", None) or {}
    progress("rendering the float64 evaluation (CL) and measuring the bound")
    model = F64Bound(compiled)
    f64 = model.f64.render(scene)
    bound, parts = model.bounds(scene, f64, blends)
    progress("comparing")
    rows = compare_with_f64(compiled, scene, {b: renders[b] for b in backends}, f64, bound,
                            blends, explain)
    from pipegen.proof.accuracy import f64_output_codes, output_codes
    outputs = {b: output_codes(compiled, renders[b]) for b in backends}
    outputs["f64"] = f64_output_codes(compiled, f64)
    from pipegen.proof.why import why_over
    why = [w for b in backends for w in (why_over(r, model.part_maps, model.info)
                                         for r in rows[b]) if w]
    return PrecisionResult(compiled.name, rows, parts, outputs=outputs, why=why)


def within_note(compiled, result) -> Optional[str]:
    """Where a target is over its bound and some pass draws ``within light radius``: that the
    float64 evaluation draws every object for every light, so the error may be light the pass
    adds beyond the radius, which the float32 backends leave out (docs/language.md)."""
    passes = [p.name for p in compiled.technique.passes if p.draw.within]
    if not passes or all(r.passed for rows in result.rows.values() for r in rows):
        return None
    return (f"pass{'es' if len(passes) > 1 else ''} {', '.join(passes)} draw"
            f"{'' if len(passes) > 1 else 's'} only the objects within each light's radius "
            f"(`within light radius`), the float64 evaluation every object: an error over the "
            f"bound may be light the pass adds beyond the radius, which its output must not do")


def main_precision_check(compiled, scene, out_dir: Optional[Path] = None,
                         reference=None) -> int:
    """``pipegen check --precision f64``: the precision error of every target on each float32
    backend, against the bound of the tolerance model (docs/tolerances.md), with the
    discontinuities found (error images ``error_<backend>_<target>.png`` in ``out_dir``).  A
    measurement: the exit status is 0 (``pipegen check`` without ``--precision`` is the
    pass/fail cross-check; ``pipegen.testing.assert_close_to_f64`` the assertion).  With
    ``reference`` (``references.Reference``, ``--reference``) also the output's error against
    it, per backend and for the float64 evaluation (``reference_lines``)."""
    def say(msg: str) -> None:
        print(f"  … {msg}", file=sys.stderr)

    result = precision_check(compiled, scene, progress=say)
    print(f"{compiled.name} on {scene.width}x{scene.height}, {len(scene.lights)} lights: "
          f"every target against the float64 evaluation, within the bound of the tolerance "
          f"model (docs/tolerances.md; over = pixels beyond it away from primitive edges and "
          f"discontinuities)")
    for b, rows in result.rows.items():
        print(f"\n{registry.get(b).label()}")
        print(result.table(b))
        for r in rows:
            for d in r.discontinuities:
                print(f"  {r.key}: discontinuity: {d.describe()}")
        for w in result.why:
            if f" ({b}) " in w:
                print(f"  why: {w}")
    note = within_note(compiled, result)
    if note:
        print(f"\nnote: {note}")
    from pipegen.proof.check import off_model_notes
    notes = off_model_notes([b for b in result.rows if b in registry.BACKENDS])
    if notes:
        print()
        print("\n".join(notes))
    if reference is not None:
        say(f"evaluating the reference ({reference.label})")
        print()
        print("\n".join(reference_lines(result, reference, scene, compiled.technique.output)))
    if out_dir is not None:
        from pipegen.core.outdir import as_output_dir, safe_name
        with as_output_dir(out_dir, "check").staging() as tmp:
            for b, rows in result.rows.items():
                for r in rows:
                    ratio_png(tmp / safe_name(f"error_{b}_{r.key}", ".png"), r, b)
        print(f"\nerror images: {out_dir}/error_<backend>_<target>.png")
    return 0


def reference_lines(result: PrecisionResult, reference, scene, output: str) -> list[str]:
    """``against <reference>: ...``: the output's rmse/p99/max in rgba8 codes against the
    chosen reference, per float32 backend (with its worst pixel) and for the float64
    evaluation (what the algorithm gives up against that reference, precision aside)."""
    from pipegen.proof.accuracy import codes_vs_reference
    lines = [f"against {reference.describe()}: rmse/p99/max of the output '{output}' in "
             f"rgba8 codes"]
    if reference.spec.why:
        lines.append(f"  (the default reference: {reference.spec.why})")
    lines += [f"  note: {n}" for n in reference.notes(scene)]
    for b, codes in result.outputs.items():
        e = codes_vs_reference(codes, reference, scene, worst=1)
        who = "float64 evaluation" if b == "f64" else registry.get(b).label()
        text = (f"  {who}: rmse {e['rmse']:.2f}, p99 {e['p99']:.0f}, max {e['max']:.0f} "
                f"(away from edges: rmse {e['rmse_interior']:.2f}, max {e['max_interior']:.0f})")
        if e["worst"]:
            x, y, got, want = e["worst"][0]
            text += (f"; worst at (x={x}, y={y} from the top): {got} vs "
                     f"{reference.label} {want}")
        lines.append(text)
    return lines


RATIO_LEGEND = [("within the bound", (180, 180, 180)), ("over", (255, 40, 40)),
                ("over, a coverage edge", (230, 200, 40)), ("discontinuity", (60, 120, 255))]


def ratio_png(path, row: TargetResult, backend: str) -> None:
    """:func:`ratio_image` titled (backend, target, the worst error against its bound, where)
    with its legend (``views.visualize.compose``)."""
    from pipegen.views.visualize import Panel, compose
    ratio = "inf" if not np.isfinite(row.worst_ratio) else f"{row.worst_ratio:.3g}"
    x, y = row.worst_xy
    title = f"{backend}: {row.key} ({row.format}) error / bound"
    note = ("exact: every code equal" if row.exact and row.passed else
            f"worst {ratio} at ({x}, {y} from the top); {row.over} over")
    img = ratio_image(row)
    zoom = max(1, 256 // max(img.shape[1], 1))         # small targets drawn larger, unblurred
    box = (img.shape[1] * zoom, img.shape[0] * zoom)
    compose([Panel(img, title, RATIO_LEGEND, note, categorical=True)], box=box).save(path)


def ratio_image(row: TargetResult) -> np.ndarray:
    """Black: equal; grey ramp: within the bound (error / bound); red: over it; yellow: over,
    admitted as a coverage edge; blue: a discontinuity.  Row 0 at the bottom, as the target
    (``save_png`` turns it)."""
    r = np.nan_to_num(np.asarray(row.ratio_map, np.float64), nan=np.inf)
    img = np.zeros(r.shape + (3,), np.uint8)
    within = (r > 0) & (r <= 1)
    img[within] = (60 + 120 * r[within])[:, None].astype(np.uint8)
    img[r > 1] = (230, 200, 40)            # over, admitted as a coverage edge
    if row.discontinuity_mask is not None:
        img[row.discontinuity_mask] = (60, 120, 255)
    if row.over_mask is not None:
        img[row.over_mask] = (255, 40, 40)
    return img


def error_split(f32_codes: np.ndarray, f64_values: np.ndarray,
                reference_rgb_top_down: Optional[np.ndarray] = None,
                mask: Optional[np.ndarray] = None, reference=None, scene=None) -> dict:
    """The errors of an rgba8 output image in rgba8 codes (``reference.metrics.rgb_error``
    statistics; ``mask``: bool (H, W), top row first).  ``f32_codes``: (H, W, 4) as a float32
    run returns it (row 0 at the bottom); ``f64_values``: the same target of the float64
    evaluation.  The reference the total and algorithm errors are against: ``reference`` (a
    ``references.Reference``, evaluated on ``scene``: the one the user chose) or
    ``reference_rgb_top_down`` (H, W, 3), top row first (e.g. the scene reference's image).
    Returns ``{"precision": f32 vs f64}`` and, with a reference, ``"total"`` (f32 vs the
    reference), ``"algorithm"`` (the quantised f64 vs the reference) and ``"reference"`` (its
    label; "" for a bare image)."""
    from pipegen.reference.metrics import rgb_error, to_top_down
    exact = np.asarray(f64_values, np.float64)
    out = {"precision": rgb_error(f32_codes, to_top_down(exact)[..., :3], mask)}
    if reference is not None:
        assert scene is not None, "a Reference is evaluated on a scene"
        reference_rgb_top_down = reference.output_rgb(scene)
    if reference_rgb_top_down is not None:
        codes = formats.get("rgba8").quantize(exact)
        out["total"] = rgb_error(f32_codes, reference_rgb_top_down, mask)
        out["algorithm"] = rgb_error(codes, reference_rgb_top_down, mask)
        out["reference"] = reference.label if reference is not None else ""
    return out
