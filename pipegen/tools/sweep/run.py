"""A sweep from start to finish in memory: plan the variants, run the render jobs on a pool,
then time them alone (the package docstring); ``run_sweep`` returns a ``SweepResult`` and
writes nothing."""

from __future__ import annotations

import sys

import math
from typing import Optional

from pipegen.ir.memory import technique_bytes
from pipegen.tools.sweep.jobs import load_spec_scene, render_job, scene_spec, time_job
from pipegen.tools.sweep.pools import DaskPool, LocalPool, available_cpus
from pipegen.tools.sweep.progress import progress_bar
from pipegen.tools.sweep.result import SweepResult
from pipegen.tools.sweep.variants import plan_variants

BACKEND_ORDER = ("gl", "cl")
DEFAULT_THREADS = 2
F64_NOTE = ("f64 columns are empty: this compiler's Compiled.pipeline does not take "
            "precision='f64' yet")


def f64_supported() -> bool:
    """Does ``Compiled.pipeline`` take ``precision`` (the f64 evaluation)?"""
    import inspect
    from pipegen.compiler.driver import Compiled
    return "precision" in inspect.signature(Compiled.pipeline).parameters


def run_sweep(files: list, scene: Optional[str] = None, size: Optional[tuple] = None,
              axes: Optional[dict] = None, backends=BACKEND_ORDER, frames: int = 5,
              jobs: Optional[int] = None, scheduler: Optional[str] = None,
              threads: int = DEFAULT_THREADS, progress: bool = True) -> SweepResult:
    """Sweep ``files`` (the package docstring) and return the rows; nothing is written."""
    backends = tuple(backends)
    variants, compiled = plan_variants(list(files), axes)
    spec = scene_spec(scene, size)
    s = load_spec_scene(spec, say=lambda text: print(text, file=sys.stderr))
    use_f64 = f64_supported()
    notes = []
    if not use_f64:
        notes.append(F64_NOTE)
    from pipegen.proof.accuracy import FLIP_NOTE
    if FLIP_NOTE:
        notes.append(FLIP_NOTE)
    job_list = [dict(file=v.file, params=dict(v.params), scene=spec, backends=list(backends),
                     f64=use_f64) for v in variants]
    pool = DaskPool(scheduler) if scheduler else \
        LocalPool(max(1, jobs or len(available_cpus())))
    results: list = [None] * len(variants)
    try:
        bar = progress_bar(len(job_list), "renders", progress)
        for i, res in pool.map_unordered(render_job, job_list):
            results[i] = res
            bar.update(1)
        bar.close()
        if frames > 0:
            timing = pool.run_alone(time_job, dict(
                variants=[dict(file=v.file, params=dict(v.params)) for v in variants],
                scene=spec, backends=list(backends), frames=frames, threads=threads,
                progress=progress))
            ms, cpu_ms, how = timing["ms"], timing["cpu_ms"], timing["how"]
            how = how.replace("in one fresh process", "after every render job had finished, "
                              "in one fresh process alone" + (" on one Dask worker"
                                                              if scheduler else ""), 1)
        else:
            ms, how = [{} for _ in variants], "frame times: not measured (--frames 0)"
            cpu_ms = ms
    finally:
        pool.close()

    rows, maps = [], {}
    for v, res in zip(variants, results):
        tb = technique_bytes(compiled[v.index].technique, s.width, s.height)
        for b in backends:
            m = res["metrics"][b]
            row = dict(technique=v.technique, params=v.params_text, backend=b,
                       frame_ms=ms[v.index].get(b, math.nan), target_bytes=tb,
                       cpu_ms=cpu_ms[v.index].get(b, math.nan),
                       agree=res["agree"], file=v.file, width=s.width, height=s.height,
                       notes="; ".join(res["notes"]))
            row.update({k: m[k] for k in m})
            rows.append(row)
            from pipegen.core.outdir import safe_name
            maps[safe_name(f"{v.slug}_{b}", ".png")] = res["maps"][b]
    return SweepResult(rows, spec["path"] or "the built-in scene", s.width, s.height,
                       len(s.lights), backends, pool.where, how, notes, maps)

