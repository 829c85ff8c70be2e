"""``pipegen sweep``: render techniques over the cartesian product of their parameters, on
each backend, and measure frame time, target memory and error against float64 references.

    pipegen sweep FILE [FILE ...] [--scene S] [--size WxH] [-p NAME=V1,V2,...]...
                  [--backend gl,cl] [--frames N] [--jobs N] [--threads T]
                  [--scheduler tcp://HOST:PORT] -o DIR [--force]

Variants.  ``-p NAME=V1,V2`` gives an axis (repeatable); without any ``-p`` every parameter
with declared allowed values (``param x = a in {a, b}``) is an axis, and so is every ``bool``
parameter (its type allows exactly ``false, true``).  Each file is swept over the axes it
declares (several files compare techniques on the same axes, e.g. the three LIDRs).

Two phases, never overlapping:

1. **Renders and errors** (:func:`render_job`, one job per variant) in a local process pool
   (``--jobs``, default: the CPUs this process may use) or, with ``--scheduler``, on a Dask
   distributed cluster.  Per variant: a render on each backend, the ``check`` verdict (GL vs
   CL, target by target, ``check.compare_targets``), the f64 evaluation
   (``compiled.pipeline("cl", precision="f64")``, where the compiler offers it), errors of the
   output target against the scene reference and the f64 evaluation (``accuracy.py``), mean
   ꟻLIP, and an error map.  Rendering is deterministic, so the pool and the cluster give the
   same numbers.
2. **Frame times** (:func:`time_job`), after every render job has finished: one fresh process
   (on this machine, or on one Dask worker) with ``LP_NUM_THREADS`` and
   ``POCL_MAX_PTHREAD_COUNT`` set to ``--threads`` and its CPU affinity pinned to that many
   CPUs, builds every variant's pipelines, renders each once untimed (shader and kernel
   compilation), then times ``--frames`` rounds; each round times every variant once, in
   alternating order (forward, then backward), so drift on the machine hits all variants
   alike.  The figure is the median.  GL: ``GLPipeline.frame`` (all passes, ``glFinish``, no
   read-back); CL: ``CLPipeline.render`` (all passes and the read-back of every target: the CL
   runtime has no frame without read-back).  ``--frames 0`` skips this phase.

Outputs in DIR (an output folder like ``run``'s: see docs/cli.md): ``results.csv`` and
``results.json`` (one row per variant and backend, :data:`COLUMNS`), ``table.txt`` (the printed
table), ``pareto.png`` (frame time against scene error per backend, the Pareto front drawn),
``errors/NN_<variant>_<backend>.png`` (error maps against the scene reference, 0 black to
``accuracy.ERROR_MAP_VMAX`` codes white).
"""

from __future__ import annotations

import argparse
import csv
import io
import itertools
import json
import math
import os
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

from pipegen.core.diagnostics import PipegenError
from pipegen.core.units import format_bytes, mebibytes
from pipegen.ir.memory import technique_bytes
from pipegen.tools.timing import interleave

# at least these columns, in this order, then the extras
COLUMNS = ["technique", "params", "backend", "frame_ms", "target_bytes", "rmse_scene",
           "p99_scene", "max_scene", "flip_scene", "rmse_f64", "p99_f64", "max_f64", "agree"]
EXTRA_COLUMNS = ["cpu_ms", "rmse_interior", "max_interior", "file", "width", "height", "notes"]
BACKEND_ORDER = ("gl", "cl")
DEFAULT_THREADS = 2
F64_NOTE = ("f64 columns are empty: this compiler's Compiled.pipeline does not take "
            "precision='f64' yet")

EXAMPLES = """\
  pipegen sweep pipelines/inferred.pipe --scene examples/scenes/edges.toml -p lbuffer_scale=0.5,0.625,0.75,1.0 -p dsf=false,true -o out/sweep-inferred
      lbuffer_scale x dsf, GL and CL, Pareto plot and error maps
  pipegen sweep pipelines/lidr_cpu_sort.pipe pipelines/lidr_max_stencil.pipe pipelines/lidr_bitplanes.pipe --scene examples/scenes/many_lights.toml -o out/sweep-lidr
      three techniques side by side on one scene (lidr_bitplanes over its index_bits)
  pipegen sweep pipelines/inferred.pipe -p lbuffer_scale=0.5,1.0 -p dsf=true --size 640x360 --frames 9 -o out/s
  pipegen sweep pipelines/inferred.pipe --scheduler tcp://scheduler-host:8786 -o out/s
      renders on a Dask cluster (pip install 'pipegen[dask]'); timings on one of its workers
"""


# -- variants ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Variant:
    """One technique file with one value per swept parameter."""

    index: int
    file: str
    technique: str
    params: tuple = ()            # ((name, value), ...): the swept axes, in axis order

    @property
    def params_text(self) -> str:
        return " ".join(f"{k}={_value_text(v)}" for k, v in self.params)

    @property
    def label(self) -> str:
        return f"{self.technique} {self.params_text}".strip()

    @property
    def slug(self) -> str:
        parts = [f"{k}-{_value_text(v)}" for k, v in self.params]
        return "_".join([f"{self.index:02d}", self.technique, *parts])


def _value_text(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return f"{v:g}" if isinstance(v, float) else str(v)


def parse_axes(items: list) -> dict[str, list]:
    """``["lbuffer_scale=0.5,1.0", ("dsf", True), ...]`` -> ``{name: [values]}``, in order."""
    from pipegen.compiler.inputs import literal
    axes: dict[str, list] = {}
    for item in items:
        if isinstance(item, tuple):
            name, values = item[0], item[1]
            values = values if isinstance(values, (list, tuple)) else [values]
            if len(values) == 1 and isinstance(values[0], str):
                values = [literal(v.strip()) for v in values[0].split(",")]
        else:
            name, sep, text = str(item).partition("=")
            if not sep or not name.strip() or not text.strip():
                raise PipegenError(None, f"bad parameter axis {item!r}: write NAME=V1,V2,...",
                                   hint="e.g. -p lbuffer_scale=0.5,0.625,1.0")
            values = [literal(v.strip()) for v in text.split(",") if v.strip()]
        name = name.strip()
        axes.setdefault(name, [])
        axes[name] += [v for v in values if v not in axes[name]]
    return axes


def declared_axes(technique) -> dict[str, list]:
    """The axes a technique sweeps without ``-p``: parameters with declared allowed values, in
    declaration order, and ``bool`` parameters (``false, true``)."""
    out = {}
    for p in technique.params:
        if p.allowed:
            out[p.name] = list(p.allowed)
        elif getattr(p.type.scalar, "value", None) == "bool" and p.type.size == 1:
            out[p.name] = [False, True]
    return out


def plan_variants(files: list, axes: Optional[dict] = None) -> tuple[list[Variant], dict]:
    """Every (file, combination of its axes) as a ``Variant``, each compiled once here (a bad
    value fails now, before any job); returns (variants, {variant index: Compiled})."""
    from pipegen.compiler.driver import compile_file
    variants, compiled = [], {}
    used: set[str] = set()
    for file in files:
        base = compile_file(file)
        names = {p.name for p in base.technique.params}
        if axes:
            file_axes = {k: v for k, v in axes.items() if k in names}
        else:
            file_axes = declared_axes(base.technique)
        used |= set(file_axes)
        keys = list(file_axes)
        for combo in itertools.product(*(file_axes[k] for k in keys)):
            params = tuple(zip(keys, combo))
            c = compile_file(file, dict(params)) if params else base
            v = Variant(len(variants), str(file), c.technique.name, params)
            variants.append(v)
            compiled[v.index] = c
    if axes:
        unknown = [k for k in axes if k not in used]
        if unknown:
            raise PipegenError(None, f"no technique given has a parameter "
                                     f"{', '.join(map(repr, unknown))}",
                               hint="pipegen info FILE lists a technique's parameters")
    return variants, compiled


def f64_supported() -> bool:
    """Does ``Compiled.pipeline`` take ``precision`` (the f64 evaluation)?"""
    import inspect
    from pipegen.compiler.driver import Compiled
    return "precision" in inspect.signature(Compiled.pipeline).parameters


# -- scenes (loaded where the job runs: a job carries a path and a size) -----------------------

_SCENES: dict = {}
_REFERENCES: dict = {}


def scene_spec(path: Optional[str], size: Optional[tuple[int, int]]) -> dict:
    return {"path": None if path is None else str(Path(path).resolve()),
            "size": None if size is None else [int(size[0]), int(size[1])]}


def load_spec_scene(spec: dict):
    key = (spec["path"], tuple(spec["size"] or ()))
    if key not in _SCENES:
        from pipegen.core.defaults import DEFAULT_SIZE
        from pipegen.scene.load import default_scene, load_scene
        s = load_scene(spec["path"]) if spec["path"] else default_scene().with_size(*DEFAULT_SIZE)
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
    """Render one variant on each backend and measure it (module docstring, phase 1).

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


def _render_worker_init() -> None:
    """Render workers share the cores: one rasteriser thread each (results do not depend on
    it; only timings would, and none are taken here)."""
    os.environ["LP_NUM_THREADS"] = "1"
    os.environ["POCL_MAX_PTHREAD_COUNT"] = "1"


# -- phase 2: timing in one fresh process ------------------------------------------------------


def time_job(job: dict) -> dict:
    """Time every variant in one fresh Python process (module docstring, phase 2).  ``job``:
    ``variants`` [{file, params}], ``scene``, ``backends``, ``frames``, ``threads``.  Returns
    ``{"ms": [{backend: ms}, ...] (per variant), "how": text}``."""
    env = dict(os.environ)
    env["LP_NUM_THREADS"] = env["POCL_MAX_PTHREAD_COUNT"] = str(job["threads"])
    proc = subprocess.run([sys.executable, "-m", "pipegen.tools.sweep"], input=json.dumps(job),
                          capture_output=False, stdout=subprocess.PIPE, text=True, env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"the timing process failed (exit {proc.returncode})")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _timing_main() -> int:
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
    bar = _progress(len(job["variants"]) * len(backends) * (frames + 1), "timing",
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


# -- executors: a local process pool or a Dask cluster ------------------------------------------


class _LocalPool:
    name = "local process pool"

    def __init__(self, jobs: int):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        self.jobs = jobs
        self.ex = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"),
                                      initializer=_render_worker_init)
        self.where = f"a local process pool of {jobs} (spawned processes, 1 render thread each)"

    def map_unordered(self, fn, items):
        from concurrent.futures import as_completed
        futures = {self.ex.submit(fn, x): i for i, x in enumerate(items)}
        for f in as_completed(futures):
            yield futures[f], f.result()

    def run_alone(self, fn, arg):
        return fn(arg)                          # here, after the pool's jobs have all finished

    def close(self) -> None:
        self.ex.shutdown()


class _DaskPool:
    name = "dask"

    def __init__(self, address: str):
        try:
            from distributed import Client
        except ImportError:
            raise PipegenError(None, "--scheduler needs Dask distributed, which is not installed",
                               hint="pip install 'pipegen[dask]'") from None
        try:
            self.client = Client(address, timeout="20s")
        except OSError as e:
            raise PipegenError(None, f"cannot reach the Dask scheduler at {address}: {e}",
                               hint="start one with `dask scheduler` and workers with "
                                    "`dask worker ADDRESS`") from None
        n = len(self.client.scheduler_info().get("workers", {}))
        self.where = f"the Dask cluster at {address} ({n} workers)"

    def map_unordered(self, fn, items):
        from distributed import as_completed
        futures = {self.client.submit(fn, x, pure=False): i for i, x in enumerate(items)}
        for f in as_completed(list(futures)):
            yield futures[f], f.result()

    def run_alone(self, fn, arg):
        workers = sorted(self.client.scheduler_info().get("workers", {}))
        return self.client.submit(fn, arg, pure=False, workers=workers[:1],
                                  allow_other_workers=False).result()

    def close(self) -> None:
        self.client.close()


def _progress(total: int, desc: str, enabled: bool = True):
    try:
        from tqdm import tqdm
    except ImportError:                         # pragma: no cover - tqdm is a dependency
        class _Null:
            def update(self, n=1): pass
            def close(self): pass
            def set_postfix_str(self, s): pass
        return _Null()
    return tqdm(total=total, desc=desc, unit="job" if desc != "timing" else "frame",
                disable=not enabled, file=sys.stderr, dynamic_ncols=True, leave=True)


# -- the sweep ---------------------------------------------------------------------------------


@dataclass
class SweepResult:
    rows: list[dict]                       # one per (variant, backend): COLUMNS + EXTRA_COLUMNS
    scene: str
    width: int
    height: int
    lights: int
    backends: tuple
    where: str                             # where the renders ran
    timing: str                            # how frame times were taken (or why not)
    notes: list[str] = field(default_factory=list)
    maps: dict = field(default_factory=dict)   # {file name under errors/: PNG bytes}

    def table(self) -> str:
        return format_table(self.rows)

    def summary(self) -> str:
        head = (f"sweep on {self.scene} at {self.width}x{self.height} ({self.lights} lights), "
                f"{len({r['file'] + r['params'] for r in self.rows})} variants x "
                f"{len(self.backends)} backends")
        lines = [head, self.table(), f"renders and error maps: {self.where}", self.timing]
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines) + "\n"


def run_sweep(files: list, scene: Optional[str] = None, size: Optional[tuple] = None,
              axes: Optional[dict] = None, backends=BACKEND_ORDER, frames: int = 5,
              jobs: Optional[int] = None, scheduler: Optional[str] = None,
              threads: int = DEFAULT_THREADS, progress: bool = True) -> SweepResult:
    """Sweep ``files`` (module docstring) and return the rows; nothing is written."""
    backends = tuple(backends)
    variants, compiled = plan_variants(list(files), axes)
    spec = scene_spec(scene, size)
    s = load_spec_scene(spec)
    use_f64 = f64_supported()
    notes = []
    if not use_f64:
        notes.append(F64_NOTE)
    from pipegen.proof.accuracy import FLIP_NOTE
    if FLIP_NOTE:
        notes.append(FLIP_NOTE)
    job_list = [dict(file=v.file, params=dict(v.params), scene=spec, backends=list(backends),
                     f64=use_f64) for v in variants]
    pool = _DaskPool(scheduler) if scheduler else \
        _LocalPool(max(1, jobs or len(_cpus())))
    results: list = [None] * len(variants)
    try:
        bar = _progress(len(job_list), "renders", progress)
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


def _cpus() -> list:
    return sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
        else list(range(os.cpu_count() or 1))


# -- outputs -----------------------------------------------------------------------------------


def _fmt(value, digits: int) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.{digits}f}"


def format_table(rows: list[dict]) -> str:
    header = ("technique", "params", "backend", "frame ms", "targets MiB", "rmse", "p99",
              "max", "ꟻLIP", "rmse f64", "p99 f64", "max f64", "agree")
    body = [(r["technique"], r["params"] or "-", r["backend"], _fmt(r["frame_ms"], 1),
             format_bytes(r["target_bytes"], "MiB", suffix=False), _fmt(r["rmse_scene"], 2),
             _fmt(r["p99_scene"], 0), _fmt(r["max_scene"], 0), _fmt(r["flip_scene"], 4),
             _fmt(r["rmse_f64"], 3), _fmt(r["p99_f64"], 0), _fmt(r["max_f64"], 0),
             {True: "yes", False: "NO", None: "-"}[r["agree"]]) for r in rows]
    table = [header, *body]
    widths = [max(len(x[i]) for x in table) for i in range(len(header))]
    right = set(range(3, 12))
    lines = ["  ".join((c.rjust(w) if i in right else c.ljust(w))
                       for i, (c, w) in enumerate(zip(x, widths))).rstrip() for x in table]
    lines.insert(1, "errors in rgba8 codes vs the scene reference (rmse, p99, max: whole "
                    "image) and vs the f64 evaluation; ꟻLIP: mean, vs the scene reference")
    return "\n".join(lines)


def csv_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS + EXTRA_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in rows:
        out = {}
        for k in COLUMNS + EXTRA_COLUMNS:
            v = r.get(k)
            if isinstance(v, bool):
                v = "true" if v else "false"
            elif v is None or (isinstance(v, float) and math.isnan(v)):
                v = ""
            elif isinstance(v, float):
                v = repr(round(v, 6))
            out[k] = v
        w.writerow(out)
    return buf.getvalue()


def json_text(result: SweepResult) -> str:
    from pipegen.proof.accuracy import finite_or_none
    rows = []
    for r in result.rows:
        rows.append({k: (finite_or_none(r[k]) if isinstance(r[k], float) else r[k])
                     for k in COLUMNS + EXTRA_COLUMNS})
    meta = dict(scene=result.scene, width=result.width, height=result.height,
                lights=result.lights, backends=list(result.backends), renders=result.where,
                timing=result.timing, notes=result.notes, columns=COLUMNS + EXTRA_COLUMNS)
    return json.dumps(dict(meta, rows=rows), indent=1) + "\n"


def load_result(folder) -> SweepResult:
    """A ``SweepResult`` read back from ``DIR/results.json`` (rows and metadata; no error
    maps), e.g. to redraw ``pareto.png``."""
    data = json.loads((Path(folder) / "results.json").read_text())
    rows = [{k: (math.nan if v is None and k in NUMERIC else v) for k, v in r.items()}
            for r in data["rows"]]
    return SweepResult(rows, data["scene"], data["width"], data["height"], data["lights"],
                       tuple(data["backends"]), data["renders"], data["timing"], data["notes"])


NUMERIC = {"frame_ms", "cpu_ms", "rmse_scene", "p99_scene", "max_scene", "flip_scene", "rmse_f64",
           "p99_f64", "max_f64", "rmse_interior", "max_interior"}


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats on both x and y (lower is better), sorted
    by x."""
    idx = [i for i, (x, y) in enumerate(points) if math.isfinite(x) and math.isfinite(y)]
    idx.sort(key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in idx:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def pareto_png(result: SweepResult, path, title: str = "") -> None:
    """Frame time (or, without timings, target memory) against RMSE vs the scene reference,
    one panel per backend, the Pareto front drawn, every point labelled."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    timed = any(math.isfinite(r["frame_ms"]) for r in result.rows)
    ylabel = "frame time (ms)" if timed else "target memory (MiB; no timings)"
    backends = list(result.backends)
    fig, axes = plt.subplots(1, len(backends), figsize=(6.4 * len(backends), 5.2),
                             squeeze=False)
    files = sorted({r["file"] for r in result.rows}, key=[r["file"] for r in result.rows].index)
    colours = {f: plt.get_cmap("tab10")(i % 10) for i, f in enumerate(files)}
    names = {"gl": "GL (llvmpipe)", "cl": "CL (PoCL)"}
    for ax, b in zip(axes[0], backends):
        rows = [r for r in result.rows if r["backend"] == b]
        pts = [(r["rmse_scene"], r["frame_ms"] if timed else mebibytes(r["target_bytes"]))
               for r in rows]
        order = sorted(range(len(rows)), key=lambda i: pts[i][1])
        for rank, i in enumerate(order):
            r, (x, y) = rows[i], pts[i]
            ax.scatter([x], [y], color=colours[r["file"]], s=36, zorder=3,
                       edgecolors="black" if r["agree"] is False else "none")
            label = r["params"] or r["technique"]
            if len(files) > 1 and r["params"]:
                label = f"{r['technique']} {r['params']}"
            # neighbours in y alternate above and below their points: fewer overlaps
            ax.annotate(label, (x, y), textcoords="offset points",
                        xytext=(5, 3 if rank % 2 == 0 else -9), ha="left", fontsize=7)
        ys = [y for _, y in pts if math.isfinite(y) and y > 0]
        if ys and max(ys) > 5 * min(ys):
            ax.set_yscale("log")
        xs = [x for x, _ in pts if math.isfinite(x)]
        if xs:
            lo, hi = min(xs), max(xs)
            span = (hi - lo) or max(hi, 1e-3)
            ax.set_xlim(lo - 0.08 * span, hi + 0.45 * span)      # room for the labels
        front = pareto_front(pts)
        if front:
            fx = [pts[i][0] for i in front]
            fy = [pts[i][1] for i in front]
            ax.step(fx, fy, where="post", color="0.4", linestyle="--", linewidth=1, zorder=2,
                    label="Pareto front")
        for f in files:
            ax.scatter([], [], color=colours[f], label=Path(f).stem)
        ax.set_xlabel("RMSE vs float64 scene reference (rgba8 codes)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{names.get(b, b)}: {Path(result.scene).name} "
                     f"{result.width}x{result.height}", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_outputs(result: SweepResult, out) -> Path:
    """results.csv, results.json, table.txt, pareto.png and errors/ into ``out`` (a path or an
    ``outdir.OutputDir``), through a staging folder like every pipegen output."""
    from pipegen.core.outdir import as_output_dir
    out = as_output_dir(out, "sweep")
    with out.staging() as tmp:
        (tmp / "results.csv").write_text(csv_text(result.rows))
        (tmp / "results.json").write_text(json_text(result))
        (tmp / "table.txt").write_text(result.summary())
        pareto_png(result, tmp / "pareto.png")
        (tmp / "errors").mkdir()
        for name, data in result.maps.items():
            (tmp / "errors" / name).write_bytes(data)
    return out.path


# -- command line --------------------------------------------------------------------------------


def add_parser(sub, size_arg, output_note: str, default_size_text: str, max_size: int):
    """Add ``sweep`` to the ``pipegen`` subcommands (``cli.build_parser``)."""
    p = sub.add_parser(
        "sweep", help="render parameter variants, measure frame time and error",
        description="Render every combination of parameter values of one or more techniques "
                    "on each backend; measure frame time, target memory, error against the "
                    "float64 scene reference and the f64 evaluation, and GL/CL agreement.",
        epilog="examples:\n" + EXAMPLES + "\n" + output_note,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", nargs="+", metavar="FILE", help="techniques (.pipe files)")
    p.add_argument("-p", "--param", action="append", default=[], metavar="NAME=V1,V2,...",
                   help="an axis: values of a parameter to sweep (repeatable; default: every "
                        "parameter with declared allowed values, and every bool parameter)")
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="output folder (required; only files pipegen wrote are replaced)")
    p.add_argument("--scene", metavar="FILE",
                   help="scene .toml (default: the built-in default scene)")
    p.add_argument("--size", type=size_arg, metavar="WxH",
                   help=f"output size (default: the scene file's width x height, "
                        f"{default_size_text} for the built-in scene; each side 1..{max_size})")
    p.add_argument("--backend", type=_backends_arg, default=BACKEND_ORDER, metavar="gl,cl",
                   help="backends, comma-separated (default: gl,cl; agreement needs both)")
    p.add_argument("--frames", type=_count_arg, default=5, metavar="N",
                   help="timed frames per variant and backend, median taken after one warm-up "
                        "(default: 5; 0: no timing)")
    p.add_argument("--jobs", type=_count_arg, default=None, metavar="N",
                   help="render processes in the local pool (default: the CPUs available)")
    p.add_argument("--threads", type=_count_arg, default=DEFAULT_THREADS, metavar="T",
                   help=f"rasteriser threads while timing (LP_NUM_THREADS, "
                        f"POCL_MAX_PTHREAD_COUNT; the timing process is pinned to T CPUs; "
                        f"default: {DEFAULT_THREADS})")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run renders on a Dask distributed cluster, e.g. tcp://HOST:8786 "
                        "(pip install 'pipegen[dask]')")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--force", action="store_true",
                   help="write into an output folder that holds files pipegen did not write")
    p.set_defaults(func=cmd_sweep)
    return p


def _backends_arg(text: str) -> tuple:
    from pipegen.backends import registry
    names = tuple(dict.fromkeys(b.strip() for b in text.split(",") if b.strip()))
    bad = [b for b in names if b not in registry.BACKENDS]
    if not names or bad:
        raise argparse.ArgumentTypeError(
            f"bad backend list {text!r}: choose from {', '.join(registry.BACKENDS)}, "
            f"comma-separated")
    return names


def _count_arg(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        raise argparse.ArgumentTypeError(f"bad count {text!r}: a whole number >= 0")
    return n


def cmd_sweep(args) -> int:
    from pipegen.compiler.inputs import looks_like_scene
    from pipegen.core.outdir import OutputDir
    out = OutputDir(args.out, "sweep", args.force)          # before any work
    for f in args.files:
        if Path(f).suffix.lower() == ".toml" or looks_like_scene(Path(f)):
            raise PipegenError(None, f"{f}: this looks like a scene file (.toml), not a "
                                     f"technique (.pipe)",
                               hint="give the scene with --scene")
    if args.scene and Path(args.scene).suffix.lower() == ".pipe":
        raise PipegenError(None, f"{args.scene}: this looks like a technique (.pipe), not a "
                                 f"scene file (.toml)", hint="--scene takes a scene .toml")
    if args.jobs == 0:
        raise PipegenError(None, "--jobs must be at least 1")
    axes = parse_axes(args.param) if args.param else None
    result = run_sweep(args.files, args.scene, args.size, axes, args.backend, args.frames,
                       args.jobs, args.scheduler, max(1, args.threads),
                       progress=not args.no_progress)
    write_outputs(result, out)
    print(result.summary(), end="")
    print(f"wrote {out}/: results.csv, results.json, table.txt, pareto.png, "
          f"errors/ ({len(result.maps)} maps)")
    return 0


if __name__ == "__main__":
    sys.exit(_timing_main())
