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

``--compare``: GL (llvmpipe) against CL per technique with the frames *interleaved* (GL, CL,
CL, GL, ... after a warm-up of each, as ``backends.py`` times them: a frame right after one of
the other backend ran up to 10% apart from one after its own, so neither always goes first),
so that both see the same load on a shared machine: the median wall time of each, their
ratio, and the ratio of process CPU time (all threads; less sensitive to other processes than
wall time).

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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import (DEFAULT_SCENE, TECHNIQUES, compile_spec, interleaved,  # noqa: E402
                    pass_profile, scene_at, set_threads)

STAGES = ("vertex", "setup", "bin", "raster")


def profile(pipe, scene, frames: int = 3) -> dict:
    """Median per-pass stage times (ms) and wall time of ``frames`` renders after a warm-up."""
    return pass_profile(lambda: pipe.render(scene),
                        lambda: ((t["pass"], t) for t in pipe.last_timings),
                        frames, STAGES, counts=("triangles", "tile_entries"))


def compare(gl, cl, scene, frames: int = 5) -> dict:
    """Interleaved GL/CL frames: median wall and CPU ms of each (see the module docstring)."""
    times = interleaved({"gl": lambda: gl.render(scene), "cl": lambda: cl.render(scene)},
                        frames, cpu=time.process_time)
    return {k: statistics.median(t * 1e3 for t in v) for k, v in times.items()}


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
    ap.add_argument("--compare", action="store_true",
                    help="GL vs CL with interleaved frames (wall and CPU time ratios)")
    ap.add_argument("techniques", nargs="*")
    args = ap.parse_args()
    set_threads(args.threads)
    scene = scene_at(args.scene or str(DEFAULT_SCENE), args.size)
    print(f"load: {os.getloadavg()[0]:.2f}; {scene.width}x{scene.height}, "
          f"{len(scene.objects)} objects, {len(scene.lights)} lights", file=sys.stderr)
    if args.compare:
        print(f"{'technique':<20} {'GL ms':>8} {'CL ms':>8} {'CL/GL':>6} {'GL cpu':>8} "
              f"{'CL cpu':>8} {'cpu CL/GL':>9}  load")
    for spec in args.techniques or TECHNIQUES:
        compiled = compile_spec(spec)
        pipe = compiled.pipeline("cl")
        if args.compare:
            gl = compiled.pipeline("gl")
            r = compare(gl, pipe, scene, args.frames)
            gl.release()
            print(f"{spec:<20} {r['gl']:>8.1f} {r['cl']:>8.1f} {r['cl'] / r['gl']:>5.2f}x "
                  f"{r['gl_cpu']:>8.1f} {r['cl_cpu']:>8.1f} {r['cl_cpu'] / r['gl_cpu']:>8.2f}x  "
                  f"{os.getloadavg()[0]:.1f}", flush=True)
        else:
            print(format_profile(spec, profile(pipe, scene, args.frames)))
        pipe.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
