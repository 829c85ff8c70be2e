"""The stress table and the worst-pixel pictures of failing cases."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pipegen.core import formats as F
from pipegen.proof.f64_compare import TargetResult
from pipegen.tools.stress.run import CaseResult

HEADER = ("case", "status", "worst target", "err/bound", "error", "bound", "over/edges",
          "discont.", "NaN,inf gl|cl|f64", "GL=CL", "lights dropped", "s")


def _discontinuities(res: CaseResult) -> str:
    """Pixels where a float32 backend fell on the other side of a step of the technique's
    code (the larger of the two backends' counts, all targets)."""
    by_backend: dict[str, int] = {}
    for t in res.targets:
        by_backend[t.backend] = by_backend.get(t.backend, 0) + t.discontinuity_count
    return str(max(by_backend.values(), default=0))


def _nf(res: CaseResult) -> str:
    if not res.nonfinite:
        return "-"
    return "|".join(f"{n},{i}" for n, i in (res.nonfinite.get(b, (0, 0))
                                            for b in ("gl", "cl", "f64")))


def _worst(res: CaseResult):
    """The row that decides the case: the output's worst (or any failing target's)."""
    rows = [t for t in res.targets if not t.exact]
    failing = [t for t in res.targets if not t.passed and (t.output or res.status != "FAIL")]
    pool = failing or [t for t in rows if t.output] or rows
    return max(pool, key=lambda t: t.worst_ratio) if pool else None


def row(res: CaseResult) -> tuple[str, ...]:
    w = _worst(res)
    if w is None:
        return (res.case, res.status, "-", "-", "-", "-", "-", "-", _nf(res),
                "-" if res.agree is None else ("yes" if res.agree else "NO"), res.dropped,
                f"{res.seconds:.2f}")
    ratio = "inf" if not np.isfinite(w.worst_ratio) else f"{w.worst_ratio:.3g}"
    return (res.case, res.status, f"{w.key} ({w.backend})", ratio, w.units(w.worst_error),
            w.units(w.bound_at_worst), f"{w.over}/{w.edges}", _discontinuities(res), _nf(res),
            "-" if res.agree is None else ("yes" if res.agree else "NO"),
            res.dropped, f"{res.seconds:.2f}")


def table(results: list[CaseResult]) -> str:
    return table_of_rows([row(r) for r in results])


def table_of_rows(rows: list) -> str:
    """The table of ``row`` tuples (or a journal's lists of them), under ``HEADER``."""
    return aligned([HEADER] + [tuple(r) for r in rows])


def aligned(rows: list) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)


REFERENCE_HEADER = ("case", "vs ref rmse", "vs ref p99", "vs ref max",
                    "worst pixel (x, y): got vs ref")


def reference_row(res: CaseResult) -> tuple[str, ...]:
    """A case's output against the chosen reference (``CaseResult.vs_reference``): rmse,
    p99 and max of the worse float32 backend in rgba8 codes, and its worst pixel."""
    figures = res.vs_reference
    if "error" in figures:
        return (res.case, "-", "-", "-", f"not evaluated: {figures['error']}")
    if not figures:
        return (res.case, "-", "-", "-", "not rendered")
    b, e = max(figures.items(), key=lambda kv: (kv[1]["p99"], kv[1]["rmse"]))
    where = "-"
    if e["worst"]:
        x, y, got, want = e["worst"][0]
        where = f"({x}, {y}) {b}: {got} vs {want}"
    return (res.case, f"{e['rmse']:.2f}", f"{e['p99']:.0f}", f"{e['max']:.0f}", where)


def reference_lines(reference, rows: list, notes: set) -> list[str]:
    """The table against the chosen reference: ``rows`` (``reference_row``), ``notes`` (what
    the reference says of the cases' scenes)."""
    lines = [f"against {reference.describe()}: the output of each case in rgba8 codes "
             f"(the worse of GL and CL)"]
    if reference.spec.why:
        lines.append(f"  (the default reference: {reference.spec.why})")
    lines += [f"  note: {n}" for n in sorted(notes)]
    table_text = aligned([REFERENCE_HEADER] + [tuple(r) for r in rows])
    return lines + table_text.splitlines()


def notes(results: list[CaseResult]) -> list[str]:
    out = []
    for r in results:
        for m in r.mismatches:
            out.append(f"{r.case}: {m}")
        found: dict = {}            # once per target and site, with the backends it was on
        for t in r.targets:
            for d in t.discontinuities:
                key = (t.key, d.site.index if d.site else None)
                text, backends = found.get(key, (f"{r.case}: {t.key}: discontinuity: "
                                                 f"{d.describe()}", []))
                found[key] = (text, backends + [t.backend])
        out += [f"{text} ({', '.join(backends)})" for text, backends in found.values()]
        if r.disagree:
            out.append(f"{r.case}: GL and CL disagree beyond pipegen check's tolerance on "
                       f"{', '.join(r.disagree)}")
        bad = sorted({t.key for t in r.targets if not t.passed})
        if bad and r.status in ("warn", "FAIL", "unsupported"):
            out.append(f"{r.case}: over the bound on {', '.join(bad)}"
                       + (" (intermediate targets: reported, not failed)"
                          if r.status == "warn" else ""))
            out += [f"  why: {w}" for w in r.why]
    return out


def _picture(values: np.ndarray, fmt: F.Format) -> np.ndarray:
    """(H, W[, C]) values -> (H, W, 3) uint8, GL row order (scaled to the finite range)."""
    v = np.asarray(values, np.float64)
    if v.ndim == 3:
        v = v[..., :3] if v.shape[2] >= 3 else np.repeat(v[..., :1], 3, axis=2)
    else:
        v = np.repeat(v[..., None], 3, axis=2)
    finite = np.isfinite(v)
    lo = float(v[finite].min()) if finite.any() else 0.0
    hi = float(v[finite].max()) if finite.any() else 1.0
    if fmt.is_normalized and lo >= 0 and hi <= 1:
        lo, hi = 0.0, 1.0
    img = (np.where(finite, v, hi) - lo) / max(hi - lo, 1e-300)
    img = np.where(finite, img, 0.0)
    out = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
    out[~finite.all(axis=2)] = (255, 0, 255)
    return out


def worst_pixels_png(res: CaseResult, target: TargetResult, path: Path, scale: int = 4,
                     count: int = 16) -> None:
    """Three panels, side by side, ``scale`` x nearest: the float32 target (GL), the float64
    evaluation, and error / bound (black 0, white 1, red over the bound); the ``count`` worst
    pixels boxed in yellow on every panel; under each panel its title (the case, the target,
    the worst ratio) and a note or legend (``views.visualize.compose``)."""
    key = target.key
    fmt = F.get(target.format)
    gl = res.images["gl"][key]
    f64 = res.images["f64"][key]
    shown = fmt.dequantize(gl) if not key.endswith(".stencil") else gl
    ratio = target.ratio_map
    r = np.where(np.isfinite(ratio), ratio, 10.0)
    err = np.repeat((np.clip(r, 0, 1) * 255).astype(np.uint8)[..., None], 3, axis=2)
    err[r > 1] = (255, 40, 40)
    panels = [_picture(shown, fmt), _picture(f64, fmt), err]
    flat = np.argsort(r.ravel())[::-1][:count]
    ys, xs = np.unravel_index(flat, r.shape)
    out = []
    for p in panels:
        big = np.kron(p, np.ones((scale, scale, 1), np.uint8))
        for y, x in zip(ys, xs):
            if r[y, x] <= 0:
                continue
            y0, x0 = y * scale, x * scale
            big[y0, x0:x0 + scale] = big[y0 + scale - 1, x0:x0 + scale] = (255, 220, 0)
            big[y0:y0 + scale, x0] = big[y0:y0 + scale, x0 + scale - 1] = (255, 220, 0)
        out.append(big)
    from pipegen.views.visualize import Panel, compose
    ratio_text = "inf" if not np.isfinite(target.worst_ratio) else f"{target.worst_ratio:.3g}"
    x, y = target.worst_xy
    where = f"{res.case}: {key} ({target.format})"
    panels = [Panel(out[0], f"{where}, float32 (GL)",
                    note=f"yellow boxes: the {count} worst pixels"),
              Panel(out[1], "float64 evaluation", note=f"worst at ({x}, {y} from the top)"),
              Panel(out[2], f"error / bound: worst {ratio_text}",
                    legend=[("0", (0, 0, 0)), ("1", (255, 255, 255)),
                            ("over", (255, 40, 40))])]
    compose(panels).save(path)
