"""The OpenCL wide path against the scalar one, pass by pass: one technique built twice (every
pass scalar: ``wide.ENABLED`` off; and as the cost model chooses, or with ``--force`` every pass
the wide form supports wide), each the variant compiled for the scene as ``pipegen run``
renders it (``--general``: the general build), frames of the two interleaved in one process
(ABBA), so that the load of a shared machine hits both alike.  Per pass that is wide in the
second build: the median raster kernel time (device ms, summed over a repeat group's lights)
of each, their ratio, and the spread (min-max) of the ratios frame by frame; then the frames'
wall times.

    python benchmarks/cl_wide_passes.py [--scene examples/scenes/many_lights.toml]
        [--size 320x180] [--frames 15] [--threads 2] [--force] [--general]
        technique[:param=value,...]

e.g. multi-pass forward's light pass, specialised to many_lights' point lights (cost 117 since
``pow`` counts its polynomials, ``wide/cost.py``), ``--size 640x360 --frames 5``: 530 ms
scalar, 301 ms wide.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import DEFAULT_SCENE, compile_spec, interleaved, scene_at, set_threads  # noqa: E402


def _raster(pipe) -> dict[str, float]:
    """Raster kernel ms per pass of the last frame (a repeat group's runs summed)."""
    out: dict[str, float] = {}
    for t in pipe.last_timings:
        out[t["pass"]] = out.get(t["pass"], 0.0) + t.get("raster", 0.0)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=str(DEFAULT_SCENE))
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--threads", default="2")
    ap.add_argument("--force", action="store_true",
                    help="every pass the wide form supports wide (MIN_COST 0, no gather costs)")
    ap.add_argument("--general", action="store_true",
                    help="the general build (default: the variant compiled for the scene)")
    ap.add_argument("technique")
    args = ap.parse_args()
    set_threads(args.threads)
    from pipegen.backends.opencl import wide
    scene = scene_at(args.scene, args.size)
    from pipegen.compiler.specialise import clear_cache

    def build():
        clear_cache()       # the variants are cached per process: each build compiles its own
        compiled = compile_spec(args.technique)
        return (compiled if args.general else compiled.specialise(scene)).pipeline("cl")

    wide.ENABLED = False
    scalar = build()
    wide.ENABLED = True
    if args.force:
        wide.MIN_COST, wide.GATHER_COST, wide.LANE_GATHER_WORK = 0, 0, 0
    widep = build()
    names = [p.name for p in widep.plan.passes
             if p.code.fragment and wide.MARK in p.code.fragment]
    rasters: dict[str, list] = {"scalar": [], "wide": []}

    def frame(name, pipe):
        def run():
            pipe.render(scene)
            rasters[name].append(_raster(pipe))
        return run

    walls = interleaved({"scalar": frame("scalar", scalar), "wide": frame("wide", widep)},
                        args.frames)
    s_all, w_all = rasters["scalar"][1:], rasters["wide"][1:]     # after the warm-up frame
    print(f"{args.technique} on {Path(args.scene).name} {args.size}, {args.frames} frames, "
          f"{args.threads} threads{' (--force)' if args.force else ''}")
    print(f"  {'pass':<24} {'scalar ms':>10} {'wide ms':>10} {'wide/scalar':>12} {'spread':>14}")
    for n in names:
        s = [f[n] for f in s_all if f.get(n)]
        w = [f[n] for f in w_all if f.get(n)]
        if not s or not w:          # no draw in this scene (no light of its type)
            continue
        ratios = sorted(b / a for a, b in zip(s, w) if a > 0)
        print(f"  {n:<24} {statistics.median(s):>10.2f} {statistics.median(w):>10.2f} "
              f"{statistics.median(w) / statistics.median(s):>12.2f} "
              f"{ratios[0]:>6.2f}-{ratios[-1]:<6.2f}")
    ws, ww = (statistics.median(walls[k]) * 1e3 for k in ("scalar", "wide"))
    print(f"  {'frame wall':<24} {ws:>10.1f} {ww:>10.1f} {ww / ws:>12.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
