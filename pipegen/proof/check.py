"""``pipegen check``: render a technique on both backends and compare every target.

Limits come from ``formats.py`` (docs/tolerances.md): unorm targets may differ by 1 + P codes
where P counts the blend steps into the target, float targets by ulps, and packed light-index
or ID targets and stencil must be exact.  P is per pixel where the CL backend counted the
fragments it blended into each pixel (``CLPipeline.last_blend_counts``: a light-volume pass
blends once per overlapping light); otherwise ``blend_steps`` counts blended passes (once per
light in repeat groups) for the whole target.  When a target disagrees, both backends are re-run
capturing every target after every pass, and the first pass whose outputs diverge is named.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from pipegen.core import formats
from pipegen.backends import registry
from pipegen.backends.plan import plan_from_dict
from pipegen.proof.compare import TargetComparison, compare_target
from pipegen.views.outputs import packed_channels, target_hints
from pipegen.views.visualize import save_png


@dataclass
class CheckResult:
    technique: str
    rows: list[TargetComparison]
    first_divergence: Optional[str] = None
    notes: list[str] = field(default_factory=list)
    max_discontinuities: int = 0
    renders: dict = field(default_factory=dict, repr=False)   # backend -> {target: codes}

    @property
    def rows_passed(self) -> bool:
        return all(r.passed for r in self.rows)

    @property
    def discontinuities(self) -> int:
        return sum(r.discontinuity_count for r in self.rows)

    @property
    def passed(self) -> bool:
        """Every target within tolerance, and no more discontinuities than allowed."""
        return self.rows_passed and self.discontinuities <= self.max_discontinuities

    def table(self) -> str:
        header = ("target", "format", "max error", "rmse", "tolerance", "over", "edges/bound",
                  "discontinuities", "")
        rows = [header] + [r.row() for r in self.rows]
        widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
        lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
        return "\n".join(lines)


def blend_steps(plan, target: str, lights: int) -> int:
    """How many times per frame a target is blended into (repeat groups: once per light)."""
    n = 0
    for p in plan_from_dict(plan).passes:
        if target in p.writes and p.state.blend_for(target).enabled:
            n += lights if p.repeat_group is not None else 1
    return n


def compare_targets(compiled, gl: dict, cl: dict, lights: int,
                    only: Optional[set] = None,
                    counts: Optional[dict] = None,
                    exclude: Optional[dict] = None) -> list[TargetComparison]:
    """One comparison per target; ``counts``: per-pixel blend counts ``{target: (H, W)}`` (the
    CL backend's ``last_blend_counts``), P of a target that has none is ``blend_steps``;
    ``exclude``: ``{key: (H, W)}`` pixels not counted (discontinuities)."""
    tech = compiled.technique
    plan = compiled.plan("gl")
    hints = target_hints(tech)
    packed = packed_channels(tech)
    rows = []
    for key in sorted(gl):
        base, _, aspect = key.partition(".")
        if only is not None and base not in only:
            continue
        fmt = tech.target(base).format
        channels = packed.get(base, ()) if not aspect else ()
        exact = aspect == "stencil" or (hints.get(base) == "index" and all(channels))
        tol = formats.Tolerance("exact", 0) if exact else None
        if key not in cl:
            raise AssertionError(f"the CL backend returned no {key!r}")
        p = blend_steps(plan, base, lights)
        per_pixel = (counts or {}).get(base) if not aspect else None
        if per_pixel is not None and per_pixel.shape == gl[key].shape[:2]:
            p = per_pixel
        rows.append(compare_target(key, fmt, gl[key], cl[key], p,
                                   tolerance=tol, exact_channels=channels,
                                   exclude=(exclude or {}).get(key)))
    return rows


# what ``check`` compares: the system's GL against the software reference, which counts the
# fragments it blends per pixel (``last_blend_counts``) for the per-pixel tolerance
CHECKED = ("gl", "cl")


def check(compiled, scene, out_dir: Optional[Path] = None,
          progress: Callable[[str], None] = lambda msg: None,
          max_discontinuities: int = 0, localise: bool = True) -> CheckResult:
    """GL against CL, every target within the tolerance model's limits (docs/tolerances.md).
    Pixels over a limit where one backend fell on the other side of a step of the
    technique's code are discontinuities (``discontinuity.py``): listed per target, not
    counted as disagreement; more than ``max_discontinuities`` of them in all fails.
    ``localise``: on disagreement, replay both pass by pass to name the first pass that
    diverges (``first_divergence``; several renders more)."""
    gl_pipe, cl_pipe = (compiled.pipeline(b) for b in CHECKED)
    progress(f"rendering on {registry.get(CHECKED[0]).label()}")
    gl = gl_pipe.render(scene)
    progress(f"rendering on {registry.get(CHECKED[1]).label()}")
    cl = cl_pipe.render(scene)
    counts = getattr(cl_pipe, "last_blend_counts", None)
    rows = compare_targets(compiled, gl, cl, len(scene.lights), counts=counts)
    if any(r.over and "." not in r.name for r in rows):
        progress("looking for discontinuities among the pixels that differ")
        rows = explain_disagreements(compiled, scene, gl, cl, rows, counts)
    result = CheckResult(compiled.name, rows, max_discontinuities=max_discontinuities,
                         renders={"gl": gl, "cl": cl})
    if out_dir is not None:
        write_error_images(result.rows, out_dir)
    if not result.rows_passed and localise:
        progress("localising the first divergent pass")
        result.first_divergence = first_divergent_pass(compiled, gl_pipe, cl_pipe, scene)
    return result


def explain_disagreements(compiled, scene, gl: dict, cl: dict, rows: list,
                          counts: Optional[dict], f64: Optional[dict] = None
                          ) -> list[TargetComparison]:
    """The rows again, the pixels over tolerance where GL and CL took different sides of a
    step of the technique's code taken out and listed as discontinuities (``f64``: the
    float64 evaluation's render of ``scene``, if made already)."""
    from pipegen.proof.discontinuity import Explainer
    from pipegen.proof.f64_compare import comparable, comparison_units
    from pipegen.proof.tolerance import local_bound, plan_targets
    info = plan_targets(compiled)
    if f64 is None:
        f64 = compiled.pipeline("cl", precision="f64").render(scene)
    explainer = Explainer(compiled, scene, f64, comparison_units(info))
    found_by_key, exclude = {}, {}
    for r in rows:
        if not r.over or "." in r.name or r.name not in f64:
            continue
        t = info[r.name]
        a, want = comparable(r.name, t.format, gl[r.name], f64[r.name], t.exact)
        b, _ = comparable(r.name, t.format, cl[r.name], f64[r.name], t.exact)
        smooth = np.zeros(a.shape) if t.exact else \
            local_bound(t, want, (counts or {}).get(r.name))
        found, left = explainer.explain(r.name, r.over_mask, [a, b], smooth)
        if found:
            found_by_key[r.name] = found
            exclude[r.name] = r.over_mask & ~left
    if not found_by_key:
        return rows
    again = {r.name: r for r in compare_targets(compiled, gl, cl, len(scene.lights),
                                                only=set(exclude), counts=counts,
                                                exclude=exclude)}
    out = []
    for r in rows:
        if r.name in found_by_key:
            r = again[r.name]
            r.discontinuities, r.discontinuity_mask = found_by_key[r.name], exclude[r.name]
        out.append(r)
    return out


def first_divergent_pass(compiled, gl_pipe, cl_pipe, scene) -> Optional[str]:
    """Replay both backends pass by pass; the first pass after which a target it wrote
    (colour, depth or stencil) differs beyond tolerance."""
    _, gl_caps = gl_pipe.render(scene, capture_passes=True)
    _, cl_caps = cl_pipe.render(scene, capture_passes=True)
    passes = {p.name: p for p in compiled.technique.passes}
    for g, c in zip(gl_caps, cl_caps):
        assert (g["pass"], g["light"]) == (c["pass"], c["light"]), "backends ran different passes"
        p = passes[g["pass"]]
        written = set(p.writes) | ({p.depth_target} if p.depth_target else set())
        rows = compare_targets(compiled, g["targets"], c["targets"], len(scene.lights), written,
                               counts=c.get("blend_counts"))
        bad = [r.name for r in rows if not r.passed]
        if bad:
            where = g["pass"] if g["light"] is None else f"{g['pass']} (light {g['light']})"
            return f"{where}: {', '.join(bad)}"
    return None


def error_image(row: TargetComparison) -> np.ndarray:
    """Black: equal; grey ramp: within tolerance; red: over tolerance; yellow: over, admitted
    as a coverage edge; blue: a discontinuity (``discontinuity.py``).  Row 0 at the bottom."""
    e = row.error_map
    tol = row.tolerance.limit if row.limit_map is None else row.limit_map
    limit = np.maximum(tol, 1)
    img = np.zeros(e.shape + (3,), np.uint8)
    within = (e > 0) & (e <= tol)
    ratio = e / limit
    img[within] = (60 + 120 * np.minimum(ratio[within], 1.0))[:, None].astype(np.uint8)
    img[e > tol] = (230, 200, 40)
    if row.discontinuity_mask is not None:
        img[row.discontinuity_mask] = (60, 120, 255)
    img[row.over_mask if row.over_mask is not None else e > tol] = (255, 40, 40)
    return img


def write_error_images(rows: list[TargetComparison], out_dir) -> None:
    """``error_<target>.png`` per row into ``out_dir`` (a path or an ``outdir.OutputDir``):
    replaces only the files pipegen wrote there, refuses a folder holding others."""
    from pipegen.core.outdir import as_output_dir, safe_name
    with as_output_dir(out_dir, "check").staging() as tmp:
        for r in rows:
            save_png(tmp / safe_name(f"error_{r.name}", ".png"), error_image(r))


def off_model_notes(backends) -> list[str]:
    """A note per backend that rendered on a device the limits were not measured on (a GPU):
    there a DISAGREE may be the device's arithmetic, not the technique."""
    out = []
    for b in backends:
        name = registry.get(b).off_model()
        if name:
            out.append(f"note: {registry.get(b).label()} is not the device these limits were "
                       f"measured on ({registry.get(b).calibrated}): its set-up and built-ins may "
                       f"differ beyond them (on an NVIDIA H200, depth by up to 434 d24 codes where "
                       f"a surface grazes the view; docs/tolerances.md, \"On a GPU\")")
    return out


def main_check(compiled, scene, out_dir: Path, mismatches: Optional[list] = None,
               max_discontinuities: int = 0) -> int:
    """``pipegen check``; ``mismatches``: what the technique will not render of the scene
    (``Compiled.mismatches``, already printed as warnings), recalled under the table: GL and
    CL agreeing says nothing about what neither draws."""
    def say(msg: str) -> None:
        print(f"  … {msg}", file=sys.stderr)

    result = check(compiled, scene, out_dir, say, max_discontinuities)
    print(f"{compiled.name} on {scene.width}x{scene.height}, {len(scene.lights)} lights: "
          + " vs ".join(registry.get(b).label() for b in CHECKED))
    print(result.table())
    for r in result.rows:
        for d in r.discontinuities:
            print(f"  {r.name}: discontinuity: {d.describe()}")
    if result.discontinuities:
        print(f"discontinuities: {result.discontinuities} px where the backends took different "
              f"sides of a step in the technique's code (allowed: {max_discontinuities}; "
              f"--max-discontinuities N)")
    print(f"error images: {out_dir}/error_<target>.png")
    for line in off_model_notes(CHECKED):
        print(line)
    if mismatches:
        n = len(mismatches)
        print(f"note: {n} thing{'s' if n != 1 else ''} in this scene the technique does not "
              f"render, on either backend (the warnings above):")
        for m in mismatches:
            print(f"  {m.message}")
    if result.passed:
        print("all targets agree")
        return 0
    if result.rows_passed:
        print(f"DISAGREE: {result.discontinuities} discontinuities, more than the "
              f"{max_discontinuities} allowed")
        return 1
    print(f"DISAGREE; first divergent pass: {result.first_divergence or 'not localised'}")
    return 1
