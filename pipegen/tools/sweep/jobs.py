"""The sweep's jobs: plain data in, plain data out, so that a local process pool or a Dask
worker can run them (the package docstring describes the two phases).

- a scene spec (``scene_spec``): a path (or a pickled ``Scene``) and a size; the scene and its
  float64 reference are loaded where the job runs, once per process;
- phase 1, ``render_job``: one variant rendered on each backend and measured against the
  references (``RENDER_ENV``: the environment of a pool's render processes);
- phase 2, ``time_job``: every variant timed in one fresh process, ``timing_main``
  (``python -m pipegen.tools.sweep``, JSON in on stdin, one JSON line out on stdout).
"""

from __future__ import annotations

import base64
import hashlib
import json
import math
import os
import pickle
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Optional

from pipegen.tools.sweep.progress import progress_bar
from pipegen.tools.timing import interleave
from pipegen.tools.sweep.worker import child_env, python_command

# -- scenes (loaded where the job runs: a job carries a path and a size, or a pickled Scene) -----

_SCENES: dict = {}
_REFERENCES: dict = {}
WORST_PIXELS = 5            # per row, the pixels of largest error results.json lists


def scene_spec(scene, size: Optional[tuple[int, int]]) -> dict:
    """What a job needs to load its scene: ``scene`` is a path (str or Path), a loaded
    ``Scene`` (pickled into the spec: a worker on another machine has no file of it) or None
    (the built-in scene)."""
    spec = {"path": None, "size": None if size is None else [int(size[0]), int(size[1])],
            "pickle": None, "key": None}
    if isinstance(scene, (str, os.PathLike)):
        spec["path"] = str(Path(scene).resolve())
        spec["key"] = spec["path"]
    elif scene is not None:
        if not hasattr(scene, "with_size") or not hasattr(scene, "lights"):
            from pipegen.core.diagnostics import PipegenError
            raise PipegenError(None, f"a sweep's scene is a path, a Scene or None, not "
                                     f"{type(scene).__name__}",
                               hint="load one with pipegen.scene.load_scene(PATH)")
        data = pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL)
        spec["pickle"] = base64.b64encode(data).decode("ascii")    # JSON for the timing process
        spec["key"] = "scene:" + hashlib.sha1(data).hexdigest()
    return spec


def spec_name(spec: dict, scene) -> str:
    """How results name the scene: its path, or the loaded Scene's name."""
    if spec["path"]:
        return spec["path"]
    return f"the scene {scene.name!r} (given as a Scene)" if spec["pickle"] \
        else "the built-in scene"


def load_spec_scene(spec: dict, say=None):
    """The scene of a job; ``say``: how to tell its load notes (the sweep says them once, in
    the parent: a worker loading it again stays quiet)."""
    key = (spec.get("key"), tuple(spec["size"] or ()))
    if key not in _SCENES:
        from pipegen.core.defaults import DEFAULT_SIZE
        from pipegen.scene.load import default_scene, load_scene_noting
        if spec.get("pickle"):
            s = pickle.loads(base64.b64decode(spec["pickle"]))
        elif spec["path"]:
            s = load_scene_noting(spec["path"], say or (lambda text: None))
        else:
            s = default_scene().with_size(*DEFAULT_SIZE)
        if spec["size"]:
            s = s.with_size(*spec["size"])
        _SCENES[key] = s
    return _SCENES[key]


def reference_data(spec) -> dict:
    """A ``references.ReferenceSpec`` as plain data for a job (a technique path made absolute:
    a worker may run elsewhere)."""
    return dict(kind=spec.kind, path=None if spec.path is None else str(Path(spec.path).resolve()),
                params=dict(spec.params), samples=int(spec.samples))


def job_reference(job: dict, compiled):
    """The variant's reference (``references.Reference``), one per process for each distinct
    reference evaluation: the scene reference is shared by every variant, ``self`` by the
    variants that agree on the parameters without an ``accurate`` value."""
    from pipegen.proof.references import Reference, ReferenceSpec
    data = job["reference"]
    spec = ReferenceSpec(data["kind"], data["path"], dict(data["params"]), data["samples"])
    ref = Reference(spec, compiled)
    evaluated = {}
    if spec.kind == "self":
        evaluated = {"file": job["file"], **(job["params"] or {}), **ref.accurate_params()}
    elif spec.kind == "technique":
        evaluated = {"file": spec.path, **spec.params}
    key = (spec.kind, spec.samples, job["scene"].get("key"), tuple(job["scene"]["size"] or ()),
           tuple(sorted((k, repr(v)) for k, v in evaluated.items())))
    if key not in _REFERENCES:
        _REFERENCES[key] = ref
    return _REFERENCES[key]


# -- phase 1: one render job per variant -------------------------------------------------------


def render_job(job: dict) -> dict:
    """Render one variant on each backend and measure it (``pipegen.tools.sweep``, phase 1).

    ``job``: ``file``, ``params`` ({name: value}), ``scene`` (``scene_spec``), ``backends``,
    ``f64`` (ask for the f64 evaluation), ``reference`` (``reference_data``), ``general``
    (render the general build; else the variant compiled for the scene, as ``pipegen run``:
    compiled here, once per process and facts).  Returns plain
    data: ``metrics`` {backend: {...}, the *_scene errors against the reference, ``worst``,
    ``targets``: the intermediate targets' errors (``intermediate_errors``)},
    ``agree`` (None with fewer than both backends), ``disagree`` (targets over tolerance),
    ``maps`` {backend: PNG bytes of the error map}, ``images`` {backend: PNG bytes of the
    output}, ``devices`` {backend: ``Backend.label()`` here, "GL (llvmpipe)"}, ``notes``,
    ``clamps`` (the CL frame's ``Clamp`` records as dicts, ``warned`` added: not the
    output's highlights), ``technique`` (the IR of the variant rendered, for
    its memory and bandwidth figures; None for the general build, which the parent has).
    """
    from pipegen.proof import accuracy
    scene = load_spec_scene(job["scene"])
    general = compile_variant(job["file"], job["params"], scene, True)
    ref = job_reference(job, general)
    ref_rgb = ref.output_rgb(scene)            # float64, top row first: errors against it
    notes = [m.message for m in general.mismatches(scene)]   # worded as run words them
    compiled = compile_variant(job["file"], job["params"], scene, job.get("general", False),
                               general)
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
        clamps = list(getattr(pipes.get("cl"), "last_clamps", None) or [])
        f64_codes = f64_values = None
        if job.get("f64"):
            try:
                f64 = compiled.pipeline("cl", size=None, precision="f64")
                f64_values = f64.render(scene)
                f64_codes = accuracy.f64_output_codes(compiled, f64_values)
                getattr(f64, "release", lambda: None)()
            except Exception as e:      # the f64 evaluation is optional: NaN and say why
                notes.append(f"no f64 evaluation: {type(e).__name__}: {e}")
        from pipegen.backends import registry
        devices = {b: registry.get(b).label() for b in renders}   # where this worker rendered
    finally:
        for p in pipes.values():
            getattr(p, "release", lambda: None)()
    from pipegen.reference.metrics import to_top_down
    metrics, maps, images = {}, {}, {}
    for b, targets in renders.items():
        codes = accuracy.output_codes(compiled, targets)
        e = accuracy.codes_vs_reference(codes, ref, scene, worst=WORST_PIXELS)
        m = dict(rmse_scene=e["rmse"], p99_scene=e["p99"], max_scene=e["max"],
                 rmse_interior=e["rmse_interior"], max_interior=e["max_interior"],
                 flip_scene=accuracy.flip_mean(codes, ref_rgb),
                 rmse_f64=math.nan, p99_f64=math.nan, max_f64=math.nan,
                 worst=[[x, y, list(got), list(want)] for x, y, got, want in e["worst"]])
        if f64_codes is not None:
            d = accuracy.codes_error(codes, f64_codes)
            m.update(rmse_f64=d["rmse"], p99_f64=d["p99"], max_f64=d["max"])
        m["targets"], target_notes = intermediate_errors(compiled, targets, ref, scene,
                                                         f64_values)
        metrics[b] = m
        maps[b] = accuracy.png_bytes(accuracy.error_map_rgb(codes, ref_rgb))
        images[b] = accuracy.png_bytes(to_top_down(codes)[..., :3])
    notes += list(dict.fromkeys(target_notes)) if renders else []
    from pipegen.proof.clamps import record
    output = compiled.technique.output
    return dict(metrics=metrics, agree=agree, disagree=disagree, maps=maps, images=images,
                notes=notes, clamps=[record(c, output) for c in clamps], devices=devices,
                technique=compiled.technique if compiled is not general else None)


def compile_variant(file: str, params: Optional[dict], scene, general: bool, base=None):
    """What a sweep renders of ``file`` with ``params`` on ``scene``: the variant compiled for
    the scene (``driver.for_scene``, cached in this process by facts, its light table shrunk
    from the file), or with ``general`` the general build.  ``base``: the general build,
    when already compiled."""
    from pipegen.compiler.driver import compile_file, for_scene
    base = base or compile_file(file, params or None)
    return for_scene(base, scene, general, file)


def intermediate_errors(compiled, targets: dict, ref, scene, f64_values) -> tuple[list, list]:
    """Each intermediate target's attributes against the reference technique's same target
    (``proof.attributes``), or, against the scene reference (which has no targets), against
    the variant's own float64 evaluation: then the figures are its precision error alone.
    Returns (plain dicts with ``against``, notes)."""
    from pipegen.proof.attributes import attribute_errors, values_lookup
    if ref.technique() is not None:
        against = ref.label
        errors, notes = attribute_errors(compiled.technique, targets,
                                         ref.technique().technique,
                                         lambda name, shape: ref.target_at(scene, name, shape),
                                         scene, worst=WORST_PIXELS)
    elif f64_values is not None:
        against = "f64"
        errors, notes = attribute_errors(compiled.technique, targets, compiled.technique,
                                         values_lookup(f64_values), scene, worst=WORST_PIXELS)
    else:
        return [], ["intermediate targets not measured: the scene reference has no targets "
                    "and there is no float64 evaluation"]
    return [dict(e.as_dict(), against=against) for e in errors], \
        [f"intermediate target {n}" for n in notes]


# render processes share the cores: one rasteriser thread each (results do not depend on it;
# only timings would, and none are taken there)
RENDER_ENV = {"LP_NUM_THREADS": "1", "POCL_MAX_PTHREAD_COUNT": "1"}


# -- phase 2: timing in one fresh process ------------------------------------------------------


def time_job(job: dict) -> dict:
    """Time every variant in one fresh Python process (``pipegen.tools.sweep``, phase 2).
    ``job``: ``variants`` [{file, params}], ``scene``, ``backends``, ``frames``, ``threads``,
    ``general`` (time the general builds; else each variant compiled for the scene).
    Returns ``{"ms": [{backend: median ms}, ...] (per variant), "q1", "q3" (the quartiles,
    alike), "cpu_ms", "how": text}``."""
    env = child_env(LP_NUM_THREADS=str(job["threads"]),
                    POCL_MAX_PTHREAD_COUNT=str(job["threads"]))
    # the package, not this module, as __main__ (tools/sweep/__main__.py calls timing_main):
    # run as a script, jobs.py would be loaded twice, once as __main__ and once by name
    proc = subprocess.Popen(python_command("pipegen.tools.sweep"), stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    tail = forward_stderr(proc.stderr)          # its progress bar shows; its last lines kept
    try:
        # not communicate(): it would read stderr too, racing the thread above for its lines
        with proc.stdin:
            proc.stdin.write(json.dumps(job).encode())
        with proc.stdout:
            out = proc.stdout.read()
        proc.wait()
    except BaseException:                       # Ctrl-C: the timing stops with the sweep
        proc.kill()
        proc.wait()
        raise
    tail.join()
    out = out.decode()
    if proc.returncode != 0:
        from pipegen.core.diagnostics import PipegenError
        said = next((line for line in reversed(tail.lines) if line.startswith("error:")),
                    tail.lines[-1] if tail.lines else "")
        raise PipegenError(None, f"the timing process failed (exit {proc.returncode})"
                                 + (f": {said.removeprefix('error: ')}" if said else ""),
                           hint="the renders finished; --frames 0 skips the timing")
    return json.loads(out.strip().splitlines()[-1])


def forward_stderr(stream, keep: int = 20):
    """A thread copying a child's stderr (a binary pipe) to ours as it comes (progress bars
    included), with ``.lines``: its last ``keep`` lines."""
    import collections
    import threading

    class Tail(threading.Thread):
        def __init__(self):
            super().__init__(daemon=True)
            self.lines: collections.deque = collections.deque(maxlen=keep)

        def run(self):
            pending = ""
            # chunks, not lines: a progress bar redraws with "\r" and no newline
            for chunk in iter(lambda: os.read(stream.fileno(), 4096), b""):
                text = chunk.decode(errors="replace")
                sys.stderr.write(text)
                sys.stderr.flush()
                *done, pending = (pending + text).replace("\r", "\n").split("\n")
                self.lines.extend(line for line in done if line.strip())
            if pending.strip():
                self.lines.append(pending)

    t = Tail()
    t.start()
    return t


def quartiles(xs: list) -> tuple[float, float, float]:
    """(first quartile, median, third quartile) of ``xs``, interpolated linearly between the
    sorted values (numpy's default): one value gives it three times, two give their quarter
    points."""
    v = sorted(xs)

    def at(q: float) -> float:
        pos = q * (len(v) - 1)
        lo = math.floor(pos)
        hi = min(lo + 1, len(v) - 1)
        return v[lo] + (v[hi] - v[lo]) * (pos - lo)

    return at(0.25), at(0.5), at(0.75)


def timing_main() -> int:
    """The timing process: JSON job on stdin, one JSON line on stdout."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # Ctrl-C: the parent ends this process
    job = json.loads(sys.stdin.read())
    threads = int(job["threads"])
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    pinned = cpus[:threads]
    if pinned:
        os.sched_setaffinity(0, pinned)
    scene = load_spec_scene(job["scene"])
    backends, frames = job["backends"], int(job["frames"])
    pipes = []                                  # per variant {backend: (pipeline, frame fn)}
    bar = progress_bar(len(job["variants"]) * len(backends) * (frames + 1), "timing",
                       job.get("progress", True))
    for v in job["variants"]:
        compiled = compile_variant(v["file"], v["params"], scene, job.get("general", False))
        row = {}
        for b in backends:
            p = compiled.pipeline(b)
            if hasattr(p, "alias"):             # timed frames read nothing back: the targets
                p.alias = True                  # share storage as the frame graph plans it
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
    spread = [{b: quartiles(samples[b, i].wall) for b in backends} for i in range(len(pipes))]
    ms = [{b: q[b][1] * 1e3 for b in backends} for q in spread]
    q1 = [{b: q[b][0] * 1e3 for b in backends} for q in spread]
    q3 = [{b: q[b][2] * 1e3 for b in backends} for q in spread]
    cpu_ms = [{b: statistics.median(samples[b, i].cpu) * 1e3 for b in backends}
              for i in range(len(pipes))]
    how = (f"frame times: median of {frames} frames after 1 warm-up, with the interquartile "
           f"range (frame_ms_q1..frame_ms_q3: times whose ranges overlap are ties), "
           f"in one fresh process ({os.uname().nodename}, "
           f"pid {os.getpid()}) with LP_NUM_THREADS = POCL_MAX_PTHREAD_COUNT = {threads}, "
           f"pinned to CPU{'s' if len(pinned) != 1 else ''} "
           f"{','.join(map(str, pinned)) or '(no affinity support)'}; variants interleaved "
           f"(each round times every variant once, alternating forward and backward order); "
           f"GL: frame() to glFinish, CL: frame() until its queue is empty, neither reading "
           f"a target back, targets sharing storage as the frame graph plans it (alias); "
           f"cpu_ms: the process's CPU time per frame, all its threads (steadier than wall "
           f"time where other work shares the CPUs)")
    sys.stdout.write(json.dumps({"ms": ms, "q1": q1, "q3": q3, "cpu_ms": cpu_ms, "how": how})
                     + "\n")
    return 0

