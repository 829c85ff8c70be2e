"""``tune()``: the search from Python, and what it writes (``tune.json``).

    from pipegen.tools.tune.run import tune
    result = tune("pipelines/inferred.pipe", ["examples/scenes/edges.toml"], "p99<=2",
                  size=(96, 54))
    result.pick.params        # {"lbuffer_scale": 1.0, "dsf": True, ...}
"""

from __future__ import annotations

import json
import math
from typing import Callable, Optional

from pipegen.core.diagnostics import PipegenError
from pipegen.tools.tune.budget import parse_budget
from pipegen.tools.tune.measure import Evaluator, Measured, Reference, finite
from pipegen.tools.tune.search import Search, TuneResult, order_key, within

MINIMISE = ("memory", "time")


def load_scenes(scenes: list, size: Optional[tuple] = None, say=None) -> list:
    """Scene files (or loaded ``Scene`` objects) at ``size`` (default: each file's own)."""
    from pipegen.scene.load import load_scene_noting
    out = []
    for s in scenes:
        scene = load_scene_noting(s, say) if isinstance(s, str) or hasattr(s, "__fspath__") \
            else s
        out.append(scene.with_size(*size) if size else scene)
    return out


def tune(file: str, scenes: list, budget, reference: Optional[str] = None,
         minimise: str = "memory", backend: str = "gl", size: Optional[tuple] = None,
         frames: int = 5, samples: int = 1, axes: Optional[dict] = None,
         say: Callable[[str], None] = lambda text: None, general: bool = False) -> TuneResult:
    """The cheapest configuration of ``file``'s declared parameter values within ``budget``
    (text or ``budget.Budget``) on every scene (search.py's docstring).  ``axes``: {name:
    [values]} searched instead of a parameter's declared values; ``general``: render the
    general builds (else each scene's variant, as ``pipegen run``).  Nothing is written."""
    search = _search(file, scenes, budget, reference, minimise, backend, size, frames,
                     samples, axes, say, general)
    return _finish(search, search.run())


def exhaustive(file: str, scenes: list, budget, reference: Optional[str] = None,
               backend: str = "gl", size: Optional[tuple] = None, samples: int = 1,
               axes: Optional[dict] = None) -> TuneResult:
    """What rendering every configuration finds (``sweep``'s way), ranked as ``tune`` ranks:
    the answer ``tune`` must reproduce with fewer renders.  Memory as cost; no timing."""
    search = _search(file, scenes, budget, reference, "memory", backend, size, 0, samples,
                     axes, lambda text: None)
    for key in search.keys:
        search.ev.render(key, search.params(key))
    found = sorted(search.passing(), key=lambda m: order_key(search.budget, "memory", m,
                                                              search.index[m.key]))
    return _finish(search, search.result(found[:2], "every configuration rendered"))


def _search(file, scenes, budget, reference, minimise, backend, size, frames, samples, axes,
            say, general: bool = False) -> Search:
    from pipegen.compiler.driver import compile_file
    from pipegen.tools.sweep.variants import declared_axes
    if minimise not in MINIMISE:
        raise PipegenError(None, f"minimise {minimise!r}: choose memory or time")
    if minimise == "time" and frames < 1:
        raise PipegenError(None, "minimising time needs timed frames", hint="--frames 5")
    if not scenes:
        raise PipegenError(None, "tune needs at least one scene", hint="--scene FILE.toml")
    budget = parse_budget(budget) if isinstance(budget, str) else budget
    base = compile_file(file)
    declared = declared_axes(base.technique)
    unknown = [k for k in (axes or {}) if k not in {p.name for p in base.technique.params}]
    if unknown:
        raise PipegenError(None, f"{base.name} has no parameter {', '.join(map(repr, unknown))}",
                           hint="pipegen info FILE lists a technique's parameters")
    axes = {**declared, **(axes or {})}
    if not axes:
        raise PipegenError(None, f"{file}: {base.name} declares no parameter values to tune",
                           hint="declare them: param x = a in {a, b, c}")
    loaded = load_scenes(scenes, size, say)
    ref = Reference(reference, base, samples)
    ev = Evaluator(file, loaded, ref, backend, frames, general)
    search = Search(ev, axes, budget, minimise, say)
    search.loaded, search.ref = loaded, ref
    return search


def _finish(search: Search, result: TuneResult) -> TuneResult:
    ev, ref, loaded, file = search.ev, search.ref, search.loaded, search.ev.file
    base = ev.compiled({})
    result.notes += [f"reference: {ref.describe}"] + ([ref.why] if ref.why else [])
    result.notes.append("each scene rendered by the general build (--general)" if ev.general
                        else "each scene rendered by the variant compiled for it, as pipegen "
                             "run renders it (--general: the general build)")
    result.technique, result.file, result.reference = base.name, str(file), ref.label
    result.scenes = [f"{s.name} ({s.width}x{s.height})" for s in loaded]
    result.backend = ev.backend
    result.compiled_pick = (ev.compiled(result.pick.params) if result.pick else None)
    return result


def _params_json(params: dict) -> dict:
    return {k: v for k, v in params.items()}


def measured_json(m: Optional[Measured], budget) -> Optional[dict]:
    if m is None:
        return None
    return dict(params=_params_json(m.params),
                figures={k: finite(float(v)) for k, v in m.figures.items()},
                per_scene=[{k: (finite(v) if isinstance(v, float) else v) for k, v in
                            e.items()} for e in m.per_scene],
                target_bytes=m.memory, time_ms=finite(m.time_ms),
                time_iqr=list(m.time_q) if m.time_q else None, frames=m.frames,
                within_budget=within(budget, m), rendered=m.rendered, notes=m.notes)


def result_json(r: TuneResult, stress: Optional[dict] = None) -> str:
    miss = None
    if r.pick is None and r.closest is not None:
        miss = [dict(term=t.text, value=finite(float(v)), over_by=finite(float(d)))
                for t, v, d in r.budget.misses(r.closest.figures)]
    data = dict(technique=r.technique, file=r.file, scenes=r.scenes, backend=r.backend,
                reference=r.reference, budget=r.budget.text, minimise=r.minimise,
                search=r.how, configurations=r.total, renders=r.renders,
                timed_frames=r.timed_frames, pruned_by_monotonicity=r.pruned,
                monotonicity=dict(pairs_checked=r.pairs_checked, violations=r.violations),
                axes={a.name: [v for v in a.values] for a in r.axes},
                pick=measured_json(r.pick, r.budget),
                runner_up=measured_json(r.runner_up, r.budget),
                closest=measured_json(r.closest, r.budget), closest_misses=miss,
                tried=[measured_json(m, r.budget) for m in r.tried],
                free=[measured_json(m, r.budget) for m in r.analytic],
                stress=stress, notes=r.notes)
    return json.dumps(data, indent=1, default=_jsonable) + "\n"


def _jsonable(x):
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return str(x)
