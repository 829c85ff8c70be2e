"""Scene specialisation: frame time of the general and the specialised technique, per technique
and scene, on both backends, as ratios measured in one run; and compile time with a scene.

    python benchmarks/specialise.py [--scenes small,mixed_lights,translucent_layers,many_lights]
        [--size 640x360] [--frames 3] [--compiles 3] [--stat median|min] [--threads 2]
        [technique[:param=value,...] ...]

Default: every shipped technique (``pipelines/*.pipe``) on the four scenes at 640x360. Both
variants run the full ``render()`` (all passes, then read-back of every target the variant has),
interleaved frame by frame (ABBA) so that drift in the machine's load hits both alike; each
figure is the median of ``--frames`` renders after one warm-up render (which compiles shaders
and kernels); ``--stat min`` takes the fastest instead, the better estimate on a machine shared
with other work. ``spec/gen`` below 1 means the specialised variant is faster. Compile time is
``compile_file(path)`` against ``compile_file(path, scene=scene)`` with the variant cache
cleared (so the scene phases, and the recompile that shrinks the light table, are counted), the
same statistic over ``--compiles`` runs. ``LP_NUM_THREADS`` and ``POCL_MAX_PTHREAD_COUNT`` are
set to ``--threads`` before either runtime loads.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

from common import ROOT, interleaved, parse_spec, scene_at, set_threads, timed

SCENES = ["small", "mixed_lights", "translucent_layers", "many_lights"]


def shipped() -> list[str]:
    return sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe"))


STAT = statistics.median


def paired(a, b, frames: int) -> tuple[float, float]:
    """Times of ``a`` and ``b`` (``STAT`` of ``frames`` each), one warm-up each, then
    alternating in ABBA order (neither always runs first)."""
    t = interleaved({"a": a, "b": b}, frames)
    return STAT(t["a"]), STAT(t["b"])


def progress(items):
    try:
        from tqdm import tqdm
    except ImportError:
        n = len(items)
        for i, item in enumerate(items, 1):
            print(f"[{i}/{n}] {item[0]} on {item[1]}", file=sys.stderr, flush=True)
            yield item
        return
    bar = tqdm(items, file=sys.stderr, unit="case")
    for item in bar:
        bar.set_description(f"{item[0]} on {item[1]}")
        yield item


def measure(spec: str, scene_name: str, scene, frames: int, compiles: int) -> dict:
    from pipegen.compiler.driver import compile_file
    from pipegen.compiler.specialise import clear_cache
    name, params = parse_spec(spec)
    path = ROOT / f"pipelines/{name}.pipe"
    params = params or None
    general = compile_file(path, params)
    compile_general, compile_scene = [], []
    for _ in range(compiles):
        compile_general.append(timed(lambda: compile_file(path, params)))
        clear_cache()
        compile_scene.append(timed(lambda: compile_file(path, params, scene=scene)))
    special = compile_file(path, params, scene=scene)
    cuts = special.specialisation.cuts
    row = {"technique": spec, "scene": scene_name,
           "passes": f"{len(general.technique.passes)}->{len(special.technique.passes)}",
           "targets": f"{len(general.technique.targets)}->{len(special.technique.targets)}",
           "cuts": len(cuts),
           "compile": STAT(compile_general),
           "compile_scene": STAT(compile_scene)}
    for backend in ("gl", "cl"):
        g, s = general.pipeline(backend), special.pipeline(backend)
        row[backend] = paired(lambda: g.render(scene), lambda: s.render(scene), frames)
        for p in (g, s):
            release = getattr(p, "release", None)
            if release is not None:
                release()
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default=",".join(SCENES),
                    help="scene names in examples/scenes/, comma-separated")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--compiles", type=int, default=3)
    ap.add_argument("--stat", choices=("median", "min"), default="median")
    ap.add_argument("--threads", default="2")
    ap.add_argument("techniques", nargs="*", default=None)
    args = ap.parse_args()
    global STAT
    STAT = min if args.stat == "min" else statistics.median
    set_threads(args.threads)
    from pipegen.core.diagnostics import PipegenError

    techniques = args.techniques or shipped()
    scenes = {n: scene_at(str(ROOT / f"examples/scenes/{n}.toml"), args.size)
              for n in args.scenes.split(",") if n}
    print(f"{', '.join(scenes)} at {args.size}; {args.stat} of {args.frames} frames after a "
          f"warm-up, of {args.compiles} compiles; "
          f"LP_NUM_THREADS = POCL_MAX_PTHREAD_COUNT = {args.threads}")
    cases = [(t, s) for t in techniques for s in scenes]
    rows, failed = [], []
    t0 = time.perf_counter()
    for spec, scene_name in progress(cases):
        try:
            rows.append(measure(spec, scene_name, scenes[scene_name], args.frames, args.compiles))
        except PipegenError as e:
            failed.append((spec, scene_name, e.message.splitlines()[0]))

    header = ("technique", "scene", "passes", "targets", "GL gen ms", "GL spec ms", "spec/gen",
              "CL gen ms", "CL spec ms", "spec/gen", "compile ms", "+scene ms")
    table = [header]
    for r in rows:
        (gg, gs), (cg, cs) = r["gl"], r["cl"]
        table.append((r["technique"], r["scene"], r["passes"], r["targets"],
                      f"{gg * 1e3:.1f}", f"{gs * 1e3:.1f}", f"{gs / gg:.2f}",
                      f"{cg * 1e3:.1f}", f"{cs * 1e3:.1f}", f"{cs / cg:.2f}",
                      f"{r['compile'] * 1e3:.0f}", f"{r['compile_scene'] * 1e3:.0f}"))
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    for row in table:
        print("  ".join(c.ljust(w) if i < 4 else c.rjust(w)
                        for i, (c, w) in enumerate(zip(row, widths))).rstrip())
    for spec, scene_name, message in failed:
        print(f"{spec} on {scene_name}: not measured: {message}")
    if rows:
        for b, k in (("GL", "gl"), ("CL", "cl")):
            ratios = [r[k][1] / r[k][0] for r in rows]
            print(f"{b} spec/gen: geometric mean {statistics.geometric_mean(ratios):.2f}, "
                  f"range {min(ratios):.2f}-{max(ratios):.2f}")
    print(f"measured in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
