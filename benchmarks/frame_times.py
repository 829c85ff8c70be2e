"""Compile time and GL frame time per technique, measured in one run.

    LP_NUM_THREADS=2 python benchmarks/frame_times.py [--scene examples/scenes/many_lights.toml]
        [--size 1280x720] [--frames 5] [technique[:param=value,...] ...]

Compile time is ``compile_file`` plus GLSL emission (median of 5).  Frame time is the median of
``--frames`` renders after one warm-up, each ending in ``glFinish`` with no read-back.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from common import DEFAULT_SCENE, TECHNIQUES, compile_spec, median_time, scene_at


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=str(DEFAULT_SCENE))
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("techniques", nargs="*", default=TECHNIQUES)
    args = ap.parse_args()
    os.environ.setdefault("LP_NUM_THREADS", "2")

    scene = scene_at(args.scene, args.size)
    w, h = scene.width, scene.height
    print(f"scene {Path(args.scene).name}: {len(scene.objects)} objects, {len(scene.lights)} "
          f"lights, {w}x{h}; LP_NUM_THREADS={os.environ['LP_NUM_THREADS']}", file=sys.stderr)
    rows = []
    for name in args.techniques:
        compile_s = median_time(lambda: compile_spec(name).plan("gl"), 5)
        pipeline = compile_spec(name).pipeline("gl")
        frame_s = median_time(lambda: pipeline.frame(scene), args.frames)
        pipeline.release()
        rows.append((name, compile_s, frame_s))
        print(f"  {name}: compile {compile_s * 1e3:.0f} ms, GL frame {frame_s * 1e3:.0f} ms",
              file=sys.stderr)
    base = dict((r[0], r[2]) for r in rows).get("forward")
    width = max(20, *(len(r[0]) for r in rows))
    print(f"{'technique':<{width}} {'compile ms':>10} {'GL frame ms':>12} {'vs forward':>10}")
    for name, c, f in rows:
        ratio = f"{f / base:.2f}x" if base else "-"
        print(f"{name:<{width}} {c * 1e3:>10.1f} {f * 1e3:>12.1f} {ratio:>10}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
