"""What the lights-per-pixel question costs in ``mismatches()``: the float64 rasterisation
and per-pixel count of light volumes it used to make for every scene ("before"), against the
tile bound / sampled surface / full surface of ``reference.light_bound`` ("after"), for one
technique on every example scene, in one run.  Prints seconds (best of ``--repeat``), their
ratio and what each says about the packing.

    LP_NUM_THREADS=2 POCL_MAX_PTHREAD_COUNT=2 python benchmarks/light_bound.py \\
        [--size 1280x720] [--repeat 3] [--technique lidr_bitplanes]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import ROOT  # noqa: E402


def before(technique, scene) -> str:
    """The former question: rasterise at full size, count the volumes at every pixel."""
    from pipegen.compiler.capabilities import capabilities
    from pipegen.reference.lighting import lights_per_pixel
    from pipegen.reference.raster import rasterize
    cap = capabilities(technique)
    rules = {r[0]: r[1:] for r in cap.index_rules}
    g, said = None, []
    for pack, _scheme, capacity, types in cap.index_packings:
        faces, bank = rules.get(pack, ("back", None))
        lights = tuple(l for i, l in enumerate(scene.lights) if l.type in types
                       and (bank is None or i % bank[0] == bank[1]))
        if not lights:
            continue
        g = rasterize(scene) if g is None else g
        n = lights_per_pixel(g, dataclasses.replace(scene, lights=lights), conservative=True,
                             faces=faces, sky=faces == "front" and scene.has_translucent)
        if n.max() > capacity:
            said.append(f"{pack}: up to {n.max()}, will")
    return "; ".join(said) or "fits"


def after(technique, scene) -> str:
    from pipegen.compiler.mismatches import mismatches
    said = [m.message for m in mismatches(technique, scene) if m.kind == "capacity"]
    short = []
    for m in said:
        verdict = "will" if "will be dropped" in m else "may"
        count = m.split()[0] if verdict == "will" else m.split("up to ")[1].split()[0]
        short.append(f"{'reach ' if verdict == 'will' else 'up to '}{count}, {verdict}")
    return "; ".join(short) or "fits"


def best(fn, repeat: int) -> tuple[float, str]:
    times, said = [], ""
    for _ in range(repeat):
        t0 = time.perf_counter()
        said = fn()
        times.append(time.perf_counter() - t0)
    return min(times), said


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--technique", default="lidr_bitplanes")
    args = ap.parse_args()
    warnings.simplefilter("ignore")         # the OBJ loader's notes on ignored statements
    from pipegen.compiler.driver import compile_file
    from pipegen.scene import load_scene
    w, h = (int(x) for x in args.size.split("x"))
    tech = compile_file(ROOT / f"pipelines/{args.technique}.pipe").technique
    print(f"mismatches()' light-index capacity question, {args.technique} at {w}x{h}, "
          f"best of {args.repeat}, seconds")
    print(f"{'scene':20s} {'before':>7s} {'after':>7s} {'after/before':>12s}  before says | "
          f"after says")
    for path in sorted((ROOT / "examples/scenes").glob("*.toml")):
        scene = dataclasses.replace(load_scene(path), width=w, height=h)
        scene.geometry(())                  # built once, outside both timings
        t_before, said_before = best(lambda: before(tech, scene), args.repeat)
        t_after, said_after = best(lambda: after(tech, scene), args.repeat)
        print(f"{path.stem:20s} {t_before:7.3f} {t_after:7.3f} {t_after / t_before:12.2f}  "
              f"{said_before} | {said_after}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
