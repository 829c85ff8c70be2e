"""CL frames with the device's worker threads under ``SCHED_BATCH`` (what the CL runtime sets,
``runtime/cl/context.batch_schedule``) against ``SCHED_OTHER`` (Linux's default), in one
process: blocks of frames alternate between the two policies (ABBA), so that drift in a
shared machine's load hits both alike; the medians of the frames' wall ms and their ratio.

    python benchmarks/cl_workers_ab.py [--size 160x90] [--blocks 16] [--frames 8]
        [--scene examples/scenes/many_lights.toml] [--gl] [technique ...]

``--gl`` does the same to llvmpipe's threads under the GL runtime (which leaves them as they
are), to show whether GL would gain as much.  ``LP_NUM_THREADS`` and ``POCL_MAX_PTHREAD_COUNT``
are 2 unless set.  Linux only.

Figures (load 0.7-1.5, 2 cores; ``--blocks 16`` at 160x90, ``--blocks 8`` larger; the frame
loop of ``CLPipeline.frame``, no read-back):

    CL, ms a frame      SCHED_OTHER  SCHED_BATCH  ratio
    light_prepass  160x90    9.36      8.16        0.87
    inferred       160x90    6.38      5.66        0.89
    lidr_cpu_sort  160x90    9.68      8.52        0.88
    light_prepass  320x180  12.88     11.86        0.92
    deferred       320x180  22.85     19.75        0.86
    forward        320x180  17.87     15.55        0.87
    light_prepass  640x360  22.10     21.17        0.96
    deferred       640x360  39.86     38.72        0.97
    forward        640x360  44.97     44.00        0.98

GL with llvmpipe's five threads moved likewise (``--gl``, 160x90): light_prepass 10.48 ->
10.31, inferred 8.17 -> 8.09, lidr_cpu_sort 11.23 -> 11.24 ms: no gain (llvmpipe's host
thread queues a frame's draws, then waits while its threads rasterise at the flush).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

DEFAULT = ("light_prepass", "inferred", "lidr_cpu_sort", "deferred", "forward")


def _threads() -> set[int]:
    return {int(t) for t in os.listdir("/proc/self/task")}


def _policy(threads: list[int], batch: bool) -> None:
    for tid in threads:
        os.sched_setscheduler(tid, os.SCHED_BATCH if batch else os.SCHED_OTHER,
                              os.sched_param(0))


def measure(technique: str, scene_path: str, size: str, blocks: int, frames: int,
            gl: bool) -> tuple[float, float, int]:
    """(median ms under SCHED_OTHER, under SCHED_BATCH, worker threads moved)."""
    from common import compile_spec, scene_at
    scene = scene_at(scene_path, size)
    compiled = compile_spec(technique).specialise(scene)
    before = _threads()
    pipe = compiled.pipeline("gl" if gl else "cl")
    for _ in range(3):                      # kernels or shaders built, buffers made
        pipe.frame(scene)
    if gl:
        workers = sorted(_threads() - before)
    else:
        from pipegen.runtime.cl import context
        workers = context.batch_workers()
        if not workers:
            raise SystemExit("the CL device's workers are not known (opened before pipegen "
                             "made its context, or $PIPEGEN_CL_BATCH_WORKERS=0)")
    times: dict[bool, list[float]] = {False: [], True: []}
    for b in range(blocks):
        for batch in ((False, True) if b % 2 == 0 else (True, False)):
            _policy(workers, batch)
            pipe.frame(scene)               # the first frame after a switch: not counted
            for _ in range(frames):
                t = time.perf_counter()
                pipe.frame(scene)
                times[batch].append(time.perf_counter() - t)
    _policy(workers, not gl)                # as the runtime leaves them
    return (1000 * statistics.median(times[False]), 1000 * statistics.median(times[True]),
            len(workers))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("techniques", nargs="*", default=list(DEFAULT))
    ap.add_argument("--size", default="160x90")
    ap.add_argument("--blocks", type=int, default=16)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--scene", default=str(ROOT / "examples/scenes/many_lights.toml"))
    ap.add_argument("--gl", action="store_true",
                    help="move llvmpipe's threads under the GL runtime instead")
    args = ap.parse_args()
    if not hasattr(os, "SCHED_BATCH") or not os.path.isdir("/proc/self/task"):
        raise SystemExit("Linux only (SCHED_BATCH, /proc/self/task)")
    os.environ.setdefault("LP_NUM_THREADS", "2")
    os.environ.setdefault("POCL_MAX_PTHREAD_COUNT", "2")
    backend = "GL" if args.gl else "CL"
    print(f"{backend} at {args.size}, {args.blocks} blocks of {args.frames} frames a policy; "
          f"load {os.getloadavg()[0]:.2f}")
    print(f"{'technique':<22} {'threads':>7} {'SCHED_OTHER ms':>15} {'SCHED_BATCH ms':>15} "
          f"{'ratio':>6}")
    for name in args.techniques:
        other, batch, n = measure(name, args.scene, args.size, args.blocks, args.frames,
                                  args.gl)
        print(f"{name:<22} {n:7d} {other:15.2f} {batch:15.2f} {batch / other:6.2f}")
    print(f"load after {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
