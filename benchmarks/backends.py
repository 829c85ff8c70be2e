"""GL (llvmpipe) vs CL (PoCL) frame time per technique, measured in one run.

    python benchmarks/backends.py [--scene examples/scenes/many_lights.toml] [--size 640x360]
        [--frames 3] [--threads 2] [technique[:param=value,...] ...]

e.g. ``inferred:lbuffer_scale=0.625 inferred:lbuffer_scale=1.0 light_prepass deferred forward``.

Both backends run the full ``render()`` (all passes, then read-back of every target), so the
ratio compares like with like.  ``LP_NUM_THREADS`` and ``POCL_MAX_PTHREAD_COUNT`` are set to
``--threads`` before either runtime loads.  Each figure is the median of ``--frames`` renders
after one warm-up render (which compiles shaders and kernels).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from common import ROOT, TECHNIQUES, compile_spec, median_time, scene_at


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=str(ROOT / "examples/scenes/many_lights.toml"))
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--threads", default="2")
    ap.add_argument("techniques", nargs="*", default=TECHNIQUES)
    args = ap.parse_args()
    os.environ["LP_NUM_THREADS"] = args.threads
    os.environ["POCL_MAX_PTHREAD_COUNT"] = args.threads

    scene = scene_at(args.scene, args.size)
    w, h = scene.width, scene.height
    print(f"{Path(args.scene).name} at {w}x{h}: {len(scene.objects)} objects, "
          f"{len(scene.lights)} lights; LP_NUM_THREADS = POCL_MAX_PTHREAD_COUNT = {args.threads}",
          file=sys.stderr)
    rows = []
    for i, spec in enumerate(args.techniques, 1):
        compiled = compile_spec(spec)
        name = spec
        gl, cl = compiled.pipeline("gl"), compiled.pipeline("cl")
        print(f"[{i}/{len(args.techniques)}] {name}", file=sys.stderr)
        gl_s = median_time(lambda: gl.render(scene), args.frames)
        cl_s = median_time(lambda: cl.render(scene), args.frames)
        gl.release()
        rows.append((name, gl_s, cl_s))
    width = max(20, *(len(r[0]) for r in rows))
    print(f"{'technique':<{width}} {'GL ms':>8} {'CL ms':>8} {'CL/GL':>7}")
    for name, g, c in rows:
        print(f"{name:<{width}} {g * 1e3:>8.1f} {c * 1e3:>8.1f} {c / g:>6.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
