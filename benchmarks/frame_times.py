"""Compile time and GL frame time per technique, measured in one run.

    LP_NUM_THREADS=2 python benchmarks/frame_times.py [--scene examples/scenes/many_lights.toml]
        [--size 1280x720] [--frames 5]

Compile time is ``compile_file`` plus GLSL emission (median of 5).  Frame time is the median of
``--frames`` renders after one warm-up, each ending in ``glFinish`` with no read-back.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUES = ["forward", "forward_multipass", "deferred", "lidr_cpu_sort", "lidr_max_stencil",
              "lidr_bitplanes"]


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=str(ROOT / "examples/scenes/many_lights.toml"))
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("techniques", nargs="*", default=TECHNIQUES)
    args = ap.parse_args()
    os.environ.setdefault("LP_NUM_THREADS", "2")

    from pipegen.compiler import compile_file
    from pipegen.scene import load_scene

    w, h = (int(v) for v in args.size.split("x"))
    scene = load_scene(args.scene).with_size(w, h)
    print(f"scene {Path(args.scene).name}: {len(scene.objects)} objects, {len(scene.lights)} "
          f"lights, {w}x{h}; LP_NUM_THREADS={os.environ['LP_NUM_THREADS']}", file=sys.stderr)
    rows = []
    for name in args.techniques:
        path = ROOT / f"pipelines/{name}.pipe"
        compile_s = median_time(lambda: compile_file(path).plan("gl"), 5)
        pipeline = compile_file(path).pipeline("gl")
        pipeline.frame(scene)                      # warm-up: buffers, shader variants
        frame_s = median_time(lambda: pipeline.frame(scene), args.frames)
        pipeline.release()
        rows.append((name, compile_s, frame_s))
        print(f"  {name}: compile {compile_s * 1e3:.0f} ms, GL frame {frame_s * 1e3:.0f} ms",
              file=sys.stderr)
    base = dict((r[0], r[2]) for r in rows).get("forward")
    print(f"{'technique':<20} {'compile ms':>10} {'GL frame ms':>12} {'vs forward':>10}")
    for name, c, f in rows:
        ratio = f"{f / base:.2f}x" if base else "-"
        print(f"{name:<20} {c * 1e3:>10.1f} {f * 1e3:>12.1f} {ratio:>10}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
