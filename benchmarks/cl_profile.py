"""Where the CL (PoCL) backend's frame time goes: per pass, host stages (vertex kernel + clipping
and set-up in numpy, binning) against the raster kernel's device time (OpenCL profiling
events), and the frame's wall time.

    python benchmarks/cl_profile.py [--scene examples/scenes/many_lights.toml] [--size 640x360]
        [--frames 3] [--threads 2] [technique[:param=value,...] ...]

``profile(pipeline, scene, frames)`` is the function ``benchmarks/backends.py`` (or anything
else) can call with a built ``CLPipeline``: it returns ``{"wall": median ms, "passes": [...]}``
with, per pass (summed over the lights of a repeat group), the medians over the frames of
``vertex``, ``setup``, ``bin`` (host, ms), ``raster`` (kernel, ms), ``runs`` (executions),
``triangles`` and ``tile_entries``.  ``raster`` is device time: the kernels run while the host
sets up the next pass, so the frame's wall time is about the larger of host and kernel time
plus the read-back, not their sum.

Both ``LP_NUM_THREADS`` and ``POCL_MAX_PTHREAD_COUNT`` are set to ``--threads`` before PoCL
loads.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

STAGES = ("vertex", "setup", "bin", "raster")


def profile(pipe, scene, frames: int = 3) -> dict:
    """Median per-pass stage times (ms) and wall time of ``frames`` renders after a warm-up."""
    pipe.render(scene)
    walls, per_frame = [], []
    for _ in range(frames):
        t0 = time.perf_counter()
        pipe.render(scene)
        walls.append((time.perf_counter() - t0) * 1e3)
        passes: dict = {}
        for t in pipe.last_timings:
            row = passes.setdefault(t["pass"], {"pass": t["pass"], "runs": 0, "triangles": 0,
                                                "tile_entries": 0, **{s: 0.0 for s in STAGES}})
            row["runs"] += 1
            for s in STAGES:
                row[s] += t.get(s, 0.0)
            row["triangles"] += t.get("triangles", 0)
            row["tile_entries"] += t.get("tile_entries", 0)
        per_frame.append(passes)
    rows = []
    for name in per_frame[0]:
        row = dict(per_frame[0][name])
        for s in STAGES:
            row[s] = statistics.median(f[name][s] for f in per_frame)
        rows.append(row)
    return {"wall": statistics.median(walls), "passes": rows}


def format_profile(name: str, prof: dict) -> str:
    lines = [f"{name}: wall {prof['wall']:.1f} ms",
             f"  {'pass':<22} {'runs':>5} {'tris':>7} {'entries':>8} {'vertex':>7} "
             f"{'setup':>7} {'bin':>7} {'host':>7} {'raster':>8}"]
    tot = {s: 0.0 for s in STAGES}
    for r in prof["passes"]:
        host = r["vertex"] + r["setup"] + r["bin"]
        for s in STAGES:
            tot[s] += r[s]
        lines.append(f"  {r['pass']:<22} {r['runs']:>5} {r['triangles']:>7} "
                     f"{r['tile_entries']:>8} {r['vertex']:>7.1f} {r['setup']:>7.1f} "
                     f"{r['bin']:>7.1f} {host:>7.1f} {r['raster']:>8.1f}")
    host = tot["vertex"] + tot["setup"] + tot["bin"]
    lines.append(f"  {'total':<22} {'':>5} {'':>7} {'':>8} {tot['vertex']:>7.1f} "
                 f"{tot['setup']:>7.1f} {tot['bin']:>7.1f} {host:>7.1f} {tot['raster']:>8.1f}")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=None)
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--threads", default="2")
    ap.add_argument("techniques", nargs="*")
    args = ap.parse_args()
    os.environ["LP_NUM_THREADS"] = args.threads
    os.environ["POCL_MAX_PTHREAD_COUNT"] = args.threads
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import ROOT, compile_spec, scene_at

    from common import TECHNIQUES
    scene = scene_at(args.scene or str(ROOT / "examples/scenes/many_lights.toml"), args.size)
    print(f"load: {os.getloadavg()[0]:.2f}; {scene.width}x{scene.height}, "
          f"{len(scene.objects)} objects, {len(scene.lights)} lights", file=sys.stderr)
    for spec in args.techniques or TECHNIQUES:
        pipe = compile_spec(spec).pipeline("cl")
        print(format_profile(spec, profile(pipe, scene, args.frames)))
        pipe.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
