"""The sweep's jobs: plain data in, plain data out, so that a local process pool or a Dask
worker can run them (the package docstring describes the two phases).

- a scene spec (``scene_spec``): a path and a size; the scene and its float64 reference are
  loaded where the job runs, once per process;
- phase 1, ``render_job``: one variant rendered on each backend and measured against the
  references (``render_worker_init`` sets up a pool's render processes);
- phase 2, ``time_job``: every variant timed in one fresh process, ``timing_main``
  (``python -m pipegen.tools.sweep``, JSON in on stdin, one JSON line out on stdout).
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Optional

from pipegen.tools.sweep.progress import progress_bar
from pipegen.tools.timing import interleave

# -- scenes (loaded where the job runs: a job carries a path and a size) -----------------------

_SCENES: dict = {}
_REFERENCES: dict = {}


def scene_spec(path: Optional[str], size: Optional[tuple[int, int]]) -> dict:
    return {"path": None if path is None else str(Path(path).resolve()),
            "size": None if size is None else [int(size[0]), int(size[1])]}


def load_spec_scene(spec: dict, say=None):
    """The scene of a job; ``say``: how to tell its load notes (the sweep says them once, in
    the parent: a worker loading it again stays quiet)."""
    key = (spec["path"], tuple(spec["size"] or ()))
    if key not in _SCENES:
        from pipegen.core.defaults import DEFAULT_SIZE
        from pipegen.scene.load import default_scene, load_scene_noting
        s = load_scene_noting(spec["path"], say or (lambda text: None)) if spec["path"] \
            else default_scene().with_size(*DEFAULT_SIZE)
        if spec["size"]:
            s = s.with_size(*spec["size"])
        _SCENES[key] = s
    return _SCENES[key]


def _scene_reference(spec: dict):
    key = (spec["path"], tuple(spec["size"] or ()))
    if key not in _REFERENCES:
        from pipegen.proof.accuracy import scene_reference
        _REFERENCES[key] = scene_reference(load_spec_scene(spec))
    return _REFERENCES[key]


# -- phase 1: one render job per variant -------------------------------------------------------


def render_job(job: dict) -> dict:
    """Render one variant on each backend and measure it (``pipegen.tools.sweep``, phase 1).

    ``job``: ``file``, ``params`` ({name: value}), ``scene`` (``scene_spec``), ``backends``,
    ``f64`` (ask for the f64 evaluation).  Returns plain data: ``metrics`` {backend: {...}},
    ``agree`` (None with fewer than both backends), ``disagree`` (targets over tolerance),
    ``maps`` {backend: PNG bytes}, ``notes``.
    """
    from pipegen.proof import accuracy
    from pipegen.compiler.driver import compile_file

    scene = load_spec_scene(job["scene"])
    ref = _scene_reference(job["scene"])
    compiled = compile_file(job["file"], job["params"] or None)
    notes = [m.message for m in compiled.mismatches(scene)]
    renders, pipes = {}, {}
    try:
        for b in job["backends"]:
            pipes[b] = compiled.pipeline(b)
            renders[b] = pipes[b].render(scene)
        agree, disagree = None, []
        if "gl" in renders and "cl" in renders:
            from pipegen.proof.check import compare_targets
            rows = compare_targets(compiled, renders["gl"], renders["cl"], len(scene.lights),
                                   counts=getattr(pipes["cl"], "last_blend_counts", None))
            disagree = [r.name for r in rows if not r.passed]
            agree = not disagree
            if disagree:
                notes.append("GL and CL disagree on " + ", ".join(disagree))
        f64_codes = None
        if job.get("f64"):
            try:
                f64 = compiled.pipeline("cl", size=None, precision="f64")
                f64_codes = accuracy.f64_output_codes(compiled, f64.render(scene))
                getattr(f64, "release", lambda: None)()
            except Exception as e:      # the f64 evaluation is optional: NaN and say why
                notes.append(f"no f64 evaluation: {type(e).__name__}: {e}")
    finally:
        for p in pipes.values():
            getattr(p, "release", lambda: None)()
    metrics, maps = {}, {}
    for b, targets in renders.items():
        codes = accuracy.output_codes(compiled, targets)
        e = accuracy.scene_error(codes, ref)
        m = dict(rmse_scene=e["rmse"], p99_scene=e["p99"], max_scene=e["max"],
                 rmse_interior=e["rmse_interior"], max_interior=e["max_interior"],
                 flip_scene=accuracy.flip_mean(codes, ref.rgb),
                 rmse_f64=math.nan, p99_f64=math.nan, max_f64=math.nan)
        if f64_codes is not None:
            d = accuracy.codes_error(codes, f64_codes)
            m.update(rmse_f64=d["rmse"], p99_f64=d["p99"], max_f64=d["max"])
        metrics[b] = m
        maps[b] = accuracy.png_bytes(accuracy.error_map_rgb(codes, ref.rgb))
    return dict(metrics=metrics, agree=agree, disagree=disagree, maps=maps, notes=notes)


def render_worker_init() -> None:
    """Render workers share the cores: one rasteriser thread each (results do not depend on
    it; only timings would, and none are taken here)."""
    os.environ["LP_NUM_THREADS"] = "1"
    os.environ["POCL_MAX_PTHREAD_COUNT"] = "1"


# -- phase 2: timing in one fresh process ------------------------------------------------------


def time_job(job: dict) -> dict:
    """Time every variant in one fresh Python process (``pipegen.tools.sweep``, phase 2).
    ``job``: ``variants`` [{file, params}], ``scene``, ``backends``, ``frames``, ``threads``.
    Returns ``{"ms": [{backend: ms}, ...] (per variant), "how": text}``."""
    env = dict(os.environ)
    env["LP_NUM_THREADS"] = env["POCL_MAX_PTHREAD_COUNT"] = str(job["threads"])
    # the package, not this module, as __main__ (tools/sweep/__main__.py calls timing_main):
    # run as a script, jobs.py would be loaded twice, once as __main__ and once by name
    proc = subprocess.run([sys.executable, "-m", "pipegen.tools.sweep"], input=json.dumps(job),
                          capture_output=False, stdout=subprocess.PIPE, text=True, env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"the timing process failed (exit {proc.returncode})")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def timing_main() -> int:
    """The timing process: JSON job on stdin, one JSON line on stdout."""
    job = json.loads(sys.stdin.read())
    threads = int(job["threads"])
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    pinned = cpus[:threads]
    if pinned:
        os.sched_setaffinity(0, pinned)
    from pipegen.compiler.driver import compile_file
    scene = load_spec_scene(job["scene"])
    backends, frames = job["backends"], int(job["frames"])
    pipes = []                                  # per variant {backend: (pipeline, frame fn)}
    bar = progress_bar(len(job["variants"]) * len(backends) * (frames + 1), "timing",
                       job.get("progress", True))
    for v in job["variants"]:
        compiled = compile_file(v["file"], v["params"] or None)
        row = {}
        for b in backends:
            p = compiled.pipeline(b)
            fn = (lambda p=p: p.frame(scene)) if hasattr(p, "frame") else \
                (lambda p=p: p.render(scene))
            fn()                                # warm-up: shader / kernel compilation
            bar.update(1)
            row[b] = fn
        pipes.append(row)
    samples = interleave({(b, i): row[b] for b in backends for i, row in enumerate(pipes)},
                         frames, cpu=time.process_time, warmup=False,
                         after_call=lambda _: bar.update(1))
    bar.close()
    ms = [{b: statistics.median(samples[b, i].wall) * 1e3 for b in backends}
          for i in range(len(pipes))]
    cpu_ms = [{b: statistics.median(samples[b, i].cpu) * 1e3 for b in backends}
              for i in range(len(pipes))]
    how = (f"frame times: median of {frames} frames after 1 warm-up, "
           f"in one fresh process ({os.uname().nodename}, "
           f"pid {os.getpid()}) with LP_NUM_THREADS = POCL_MAX_PTHREAD_COUNT = {threads}, "
           f"pinned to CPU{'s' if len(pinned) != 1 else ''} "
           f"{','.join(map(str, pinned)) or '(no affinity support)'}; variants interleaved "
           f"(each round times every variant once, alternating forward and backward order); "
           f"GL: frame() to glFinish without read-back; CL: render() with read-back; "
           f"cpu_ms: the process's CPU time per frame, all its threads (steadier than wall "
           f"time where other work shares the CPUs)")
    sys.stdout.write(json.dumps({"ms": ms, "cpu_ms": cpu_ms, "how": how}) + "\n")
    return 0

