"""What the benchmark scripts share: the technique list, the default scene, thread settings,
timing (single calls, medians, interleaved calls, per-pass profiles), technique specs, scenes."""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path

from pipegen.tools.timing import interleave

ROOT = Path(__file__).resolve().parents[1]
# Every shipped technique (pipelines/*.pipe), the default of the benchmarks that take a list.
TECHNIQUES = ["forward", "forward_multipass", "deferred", "lidr_cpu_sort", "lidr_max_stencil",
              "lidr_bitplanes", "lidr_transparent", "lidr_msaa_texture", "lidr_nearest_edge",
              "lidr_shadow_volumes", "lidr_shadow_prepass", "lidr_shadow_indexed",
              "light_prepass", "inferred", "deferred_calver"]
# The scene of the benchmarks that take ``--scene``.
DEFAULT_SCENE = ROOT / "examples/scenes/many_lights.toml"


def set_threads(threads: str) -> None:
    """llvmpipe's and PoCL's thread counts; call before either runtime loads."""
    os.environ["LP_NUM_THREADS"] = threads
    os.environ["POCL_MAX_PTHREAD_COUNT"] = threads


def timed(fn) -> float:
    """Wall time (s) of one call of ``fn``."""
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def median_time(fn, repeat: int, warmup: bool = True) -> float:
    """Median wall time of ``repeat`` calls of ``fn`` (after one untimed call if ``warmup``:
    shader/kernel compilation and buffer creation are not frame time)."""
    if warmup:
        fn()
    return statistics.median([timed(fn) for _ in range(repeat)])


def interleaved(fns: dict, frames: int, alternate: bool = True, cpu=None,
                warmup: bool = True) -> dict[str, list[float]]:
    """Each of ``fns`` (name -> callable) called once a frame for ``frames`` frames, so that
    drift in the machine's load hits all alike: in the dict's order, reversed on odd frames if
    ``alternate`` (ABBA: none always runs first), after one untimed call of each if ``warmup``.
    Returns, per name, the wall time (s) of each call and, if ``cpu`` (a clock in seconds, e.g.
    ``time.process_time``) is given, under ``name + "_cpu"`` the CPU time of each call.  The
    loop is ``pipegen.tools.timing.interleave``, the one ``pipegen sweep`` times with."""
    out: dict[str, list[float]] = {}
    for name, s in interleave(fns, frames, alternate=alternate, cpu=cpu,
                              warmup=warmup).items():
        out[name] = s.wall
        if cpu is not None:
            out[name + "_cpu"] = s.cpu
    return out


def in_blocks(fns: dict, frames: int, block: int) -> dict[str, list[float]]:
    """Each of ``fns`` (name -> callable) called in turns of ``block`` (> 1) timed calls, the turns
    in the dict's order then reversed (ABBA), each turn after one untimed call (the first
    call after another callable's: its caches, its threads woken), until each has ``frames``
    timed calls; after one untimed call of each.  The steady state of back-to-back frames,
    where ``interleaved`` times every frame right after the other's.  Returns, per name, the
    wall time (s) of each timed call (``pipegen.tools.timing.interleave`` with ``block``)."""
    return {name: s.wall for name, s in interleave(fns, frames, block=block).items()}


def pass_profile(frame, passes, frames: int, fields, counts=(), before=None) -> dict:
    """Where ``frames`` frames go, pass by pass, after one untimed warm-up ``frame()``.

    Before each timed frame ``before()`` runs (if given, untimed); after it, ``passes()`` gives
    the frame's ``(pass name, {field: value})``, one per execution of a pass.  Per pass the
    executions are summed (``runs`` counts them): ``fields`` are then the medians over the
    frames, ``counts`` (e.g. triangles) the first frame's sums.  Returns ``{"wall": median ms of
    the timed frames, "passes": [{"pass", "runs", *counts, *fields}, ...]}`` in the first
    frame's pass order."""
    frame()
    walls, per_frame = [], []
    for _ in range(frames):
        if before is not None:
            before()
        walls.append(timed(frame) * 1e3)
        sums: dict = {}
        for name, values in passes():
            row = sums.setdefault(name, {"pass": name, "runs": 0, **{k: 0 for k in counts},
                                         **{k: 0.0 for k in fields}})
            row["runs"] += 1
            for k in (*fields, *counts):
                row[k] += values.get(k, 0)
        per_frame.append(sums)
    rows = []
    for name in per_frame[0]:
        row = dict(per_frame[0][name])
        for k in fields:
            row[k] = statistics.median(f[name][k] for f in per_frame)
        rows.append(row)
    return {"wall": statistics.median(walls), "passes": rows}


def parse_spec(spec: str) -> tuple[str, dict]:
    """``name:a=1,b=x`` -> ("name", {"a": "1", "b": "x"}) (the compiler parses the values)."""
    name, _, rest = spec.partition(":")
    return name, dict(kv.split("=", 1) for kv in rest.split(",") if kv)


def compile_spec(spec: str):
    from pipegen.compiler.driver import compile_file
    name, params = parse_spec(spec)
    return compile_file(ROOT / f"pipelines/{name}.pipe", params=params or None)


def scene_at(path: str, size: str):
    from pipegen.scene import load_scene
    w, h = (int(v) for v in size.split("x"))
    return load_scene(path).with_size(w, h)
