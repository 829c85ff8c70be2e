"""A repeat group's passes in one raster launch against a launch per pass execution, on CL.

    python benchmarks/cl_fused_groups.py [--scene examples/scenes/many_lights.toml]
        [--sizes 160x90,320x180,640x360] [--frames 24] [technique ...]   (default: deferred)

Two pipelines of the technique compiled for the scene, one made with
``PIPEGEN_CL_FUSE_GROUPS=1`` (the default: ``runtime/cl/group_launch.py``) and one with ``0``,
render frames interleaved in one process (``common.interleaved``: ABBA, so drift in a shared
machine's load hits both), each call a full ``render()``; medians, and the fused frame as a
fraction of the other.  ``LP_NUM_THREADS`` and ``POCL_MAX_PTHREAD_COUNT`` are set to 2 before
PoCL loads.

Deferred on many_lights (81 point lights, a stencil-marking and a shading pass each), at
ede8d3e, ``python benchmarks/cl_fused_groups.py --frames 16`` (load 1-2; a run to the next
moves these by ~10 %): 160x90 18.3 against 23.0 ms (0.79x), 320x180 21.0 against 29.2 ms
(0.72x), 640x360 47.5 against 58.0 ms (0.82x).

The shadow-volume LIDR on many_lights (no shadow volumes there: its group keeps the index
volumes alone, a group of one pass, fused since 190170a), ``python
benchmarks/cl_fused_groups.py --frames 16 lidr_shadow_volumes`` (load 3, other work on the
machine): 160x90 15.1 against 20.5 ms (0.74x), 320x180 21.3 against 26.6 ms (0.80x), 640x360
39.6 against 49.7 ms (0.80x).
"""

from __future__ import annotations

import argparse
import os
import statistics

os.environ.setdefault("LP_NUM_THREADS", "2")
os.environ.setdefault("POCL_MAX_PTHREAD_COUNT", "2")

from common import DEFAULT_SCENE, compile_spec, interleaved  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("techniques", nargs="*", default=["deferred"])
    ap.add_argument("--scene", default=str(DEFAULT_SCENE))
    ap.add_argument("--sizes", default="160x90,320x180,640x360")
    ap.add_argument("--frames", type=int, default=24)
    args = ap.parse_args()
    from pipegen.compiler.driver import for_scene
    from pipegen.scene import load_scene
    scene = load_scene(args.scene)
    print(f"{'technique':20s} {'size':>9s} {'fused ms':>9s} {'per pass ms':>12s} {'ratio':>6s}")
    for name in args.techniques:
        compiled = for_scene(compile_spec(name), scene)
        for size in args.sizes.split(","):
            w, h = (int(v) for v in size.split("x"))
            pipes = {}
            for fuse in ("1", "0"):
                os.environ["PIPEGEN_CL_FUSE_GROUPS"] = fuse
                pipes[fuse] = compiled.pipeline("cl", (w, h))
            os.environ.pop("PIPEGEN_CL_FUSE_GROUPS")
            if not pipes["1"].groups.groups:
                print(f"{name:20s} {size:>9s}  (no repeat group fuses)")
                continue
            times = interleaved({k: (lambda p=p: p.render(scene)) for k, p in pipes.items()},
                                args.frames)
            a, b = (statistics.median(times[k]) * 1e3 for k in ("1", "0"))
            print(f"{name:20s} {size:>9s} {a:9.1f} {b:12.1f} {a / b:6.2f}")
            for p in pipes.values():
                p.release()


if __name__ == "__main__":
    main()
