"""Two source trees' CL runtimes side by side: per technique, the medians of the main thread's
CPU ms, the process CPU ms and the wall ms per ``render()``, blocks of frames alternated
between the trees (ABBA), so that drift in a shared machine's load hits both alike.

    python benchmarks/cl_host_ab.py BEFORE_DIR AFTER_DIR [--size 160x90] [--blocks 10]
        [--frames 6] [--scene examples/scenes/many_lights.toml] [technique ...]

Each directory is a pipegen tree (``pipegen/``, ``templates/``, ``pipelines/``, ``benchmarks/``;
e.g. ``git worktree add`` or ``git archive REV | tar -x -C DIR``); a worker process per tree
imports pipegen from it, compiles each technique for the scene and renders on request.
The main thread's CPU time is the runtime's host work (Python, queueing, read-backs), the
least sensitive of the three to other processes; wall time needs the whole machine.
``LP_NUM_THREADS`` and ``POCL_MAX_PTHREAD_COUNT`` are 2 in the workers.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path


def worker(tree: str, technique: str, size: str, scene_path: str) -> None:
    """Render on request: each stdin line ``n`` renders n frames and prints the per-frame
    main-thread CPU, process CPU and wall ms."""
    sys.path.insert(0, str(Path(tree) / "benchmarks"))
    from common import compile_spec, scene_at
    scene = scene_at(scene_path, size)
    pipe = compile_spec(technique).specialise(scene).pipeline("cl")
    for _ in range(3):           # kernels built, buffers made
        pipe.render(scene)
    print("ready", flush=True)
    for line in sys.stdin:
        n = int(line)
        h0, c0, w0 = time.thread_time(), time.process_time(), time.perf_counter()
        for _ in range(n):
            pipe.render(scene)
        print(f"{(time.thread_time() - h0) / n * 1e3} {(time.process_time() - c0) / n * 1e3} "
              f"{(time.perf_counter() - w0) / n * 1e3}", flush=True)


def compare(trees: dict, technique: str, args) -> dict:
    """{tree name: [median host ms, process ms, wall ms]} of one technique."""
    procs = {}
    for name, tree in trees.items():
        env = dict(os.environ, PYTHONPATH=str(tree), LP_NUM_THREADS="2",
                   POCL_MAX_PTHREAD_COUNT="2")
        procs[name] = subprocess.Popen(
            [sys.executable, __file__, "--worker", str(tree), technique, args.size, args.scene],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env, cwd=str(tree))
    try:
        for name, proc in procs.items():
            if proc.stdout.readline().strip() != "ready":
                raise SystemExit(f"{name}: the worker for {technique} did not start")
        rows = {name: [] for name in procs}
        names = list(procs)
        for block in range(args.blocks):
            for name in names if block % 2 == 0 else names[::-1]:
                procs[name].stdin.write(f"{args.frames}\n")
                procs[name].stdin.flush()
                rows[name].append([float(v) for v in procs[name].stdout.readline().split()])
    finally:
        for proc in procs.values():
            proc.stdin.close()
            proc.wait()
    return {name: [statistics.median(r[i] for r in v) for i in range(3)]
            for name, v in rows.items()}


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(*sys.argv[2:6])
        return 0
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DEFAULT_SCENE, TECHNIQUES
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--size", default="160x90")
    ap.add_argument("--blocks", type=int, default=10, help="blocks per tree")
    ap.add_argument("--frames", type=int, default=6, help="frames per block")
    ap.add_argument("--scene", default=str(DEFAULT_SCENE))
    ap.add_argument("techniques", nargs="*", default=TECHNIQUES)
    args = ap.parse_intermixed_args()
    args.scene = str(Path(args.scene).resolve())
    trees = {"before": Path(args.before).resolve(), "after": Path(args.after).resolve()}
    print(f"{args.size}, {args.blocks} blocks of {args.frames} frames per tree, medians "
          f"(ms per frame; after / before)")
    for t in args.techniques:
        m = compare(trees, t, args)
        b, a = m["before"], m["after"]
        print(f"{t:<20} host {b[0]:6.2f} -> {a[0]:6.2f} ({a[0] / b[0]:.2f}x)  process CPU "
              f"{b[1]:7.2f} -> {a[1]:7.2f} ({a[1] / b[1]:.2f}x)  wall {b[2]:7.1f} -> "
              f"{a[2]:7.1f} ({a[2] / b[2]:.2f}x)  load {os.getloadavg()[0]:.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
