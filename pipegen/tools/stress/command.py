"""The ``pipegen stress`` subcommand (added to ``cli.build_parser`` by ``add_parser``)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from pipegen.tools.stress import DEFAULT_SIZE

EXAMPLES = """\
  pipegen stress pipelines/deferred.pipe
      every case on the built-in scene at 96x64: table on stdout, exit 1 if a bound breaks
  pipegen stress pipelines/inferred.pipe --cases quick --size 48x32
      the quick group (13 cases); --cases ci is what the tests run on every shipped technique
  pipegen stress pipelines/forward.pipe --scene examples/scenes/small.toml --cases far_1e3,far_1e4 -o out/stress
      two cases on another base scene; PNGs of the worst pixels and the failing scenes in out/stress
  pipegen stress pipelines/forward.pipe --cases none --random 20 --seed 3 -o out/stress
      20 random scenes (hypothesis, seeded); the first failure shrunk and saved as TOML
"""


def add_parser(sub, size_arg, output_note: str):
    from pipegen.tools.stress.cases import CASES, GROUPS
    p = sub.add_parser(
        "stress", help="render adversarial scenes, hold every target to its error bound",
        description="Build adversarial scenes from the technique and a base scene (the hard "
                    "cases of docs/stress.md), render each on GL, CL and the technique's float64 evaluation, and "
                    "hold every target of both float32 backends to an error bound composed "
                    "through the pipeline's stores, blends and reads (docs/stress.md). Exit 1 "
                    "when a bound breaks on the output target or GL and CL disagree.",
        epilog="examples:\n" + EXAMPLES + "\ncases: " + ", ".join(CASES) + "\ngroups: "
               + ", ".join(f"{k} ({len(v)})" for k, v in GROUPS.items()) + "\n\n"
               + output_note,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", help="the technique, a .pipe file")
    p.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                   help="override a parameter (repeatable)")
    p.add_argument("--scene", metavar="FILE",
                   help="base scene .toml (default: the built-in default scene)")
    p.add_argument("--size", type=size_arg, default=DEFAULT_SIZE, metavar="WxH",
                   help=f"render size of every case (default: "
                        f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]})")
    p.add_argument("--cases", default="all", metavar="A,B,...",
                   help="cases and groups, comma-separated; 'none' for only --random "
                        "(default: all)")
    p.add_argument("--random", type=int, default=0, metavar="N",
                   help="also N random scenes (hypothesis, seeded); the first failing one "
                        "is shrunk and saved as TOML (default: 0)")
    p.add_argument("--seed", type=int, default=0, help="seed of --random (default: 0)")
    from pipegen.proof.references import REFERENCE_HELP, SAMPLES_HELP
    p.add_argument("--reference", metavar="R",
                   help="also measure each case's output against the reference R (a table "
                        "after the bounds, column vs ref p99; the bounds stay the technique's "
                        "own float64 evaluation's): " + REFERENCE_HELP)
    p.add_argument("--reference-samples", type=int, default=1, metavar="N",
                   help=SAMPLES_HELP)
    p.add_argument("--general", action="store_true",
                   help="render every case with the general build, compiled for every scene "
                        "(default: each case with the variant compiled for its scene's "
                        "features, one per distinct set of features, as pipegen run renders "
                        "that scene; docs/specialise.md)")
    p.add_argument("-o", "--out", metavar="DIR",
                   help="folder for worst-pixel PNGs and failing scenes (default: "
                        "build/stress/<technique>)")
    p.add_argument("--force", action="store_true",
                   help="write into an output folder that holds files pipegen did not write")
    p.set_defaults(func=cmd_stress, parser=p)
    return p


def cmd_stress(args) -> int:
    from pipegen.compiler.inputs import compile_technique
    from pipegen.core.diagnostics import PipegenError
    from pipegen.core.outdir import OutputDir, safe_name
    from pipegen.tools.stress import report
    from pipegen.tools.stress.cases import build, case_names, random_scene_toml, scene_toml
    from pipegen.tools.stress.run import Stress
    t_start = time.perf_counter()
    measured = args.reference is not None or args.reference_samples != 1
    if measured:                     # the text checked before any work
        from pipegen.proof.references import check_samples, choose_reference, parse_reference
        check_samples(args.reference_samples)
        if args.reference is not None:
            parse_reference(args.reference, args.reference_samples)
    compiled = compile_technique(args.file, args.param)
    size = args.size
    out = OutputDir(Path(args.out) if args.out else Path("build/stress") / compiled.name,
                    "stress", args.force)
    try:
        names = [] if args.cases == "none" else case_names(args.cases)
    except ValueError as e:
        raise PipegenError(None, str(e)) from None
    base = _base_scene(args).with_size(*size)

    def say(msg: str) -> None:
        print(f"  … {msg}", file=sys.stderr)

    reference = choose_reference(args.reference, compiled, args.reference_samples) \
        if measured else None
    runner = Stress(compiled, reference=reference, general=args.general, path=args.file)
    results = []
    for case in build(base, names) if names else []:
        say(case.name)
        results.append(runner.run_case(case))
    failing_random = None
    if args.random:
        from pipegen.tools.stress.search import random_search
        randoms, failing_random = random_search(runner, args.random, size, args.seed, say)
        results += randoms
    print(f"{compiled.name}: stress on {base.name} at {size[0]}x{size[1]} "
          f"({len(results)} cases; error of each float32 target against the float64 "
          f"evaluation, divided by its bound; {runner.builds_text()})")
    print(report.table(results))
    for line in report.notes(results):
        print(f"note: {line}")
    if reference is not None:
        print()
        print("\n".join(reference_table(results, reference)))
    failed = [r for r in results if r.failed]
    with out.staging() as tmp:
        for r in failed:
            for t in r.targets:
                if not t.passed and r.images:
                    report.worst_pixels_png(r, t, tmp / safe_name(
                        f"{r.case}_{t.backend}_{t.key}", ".png"))
            if not r.case.startswith("random"):
                scene_toml(r.scene, tmp, safe_name(r.case, ""))
        if failing_random is not None:
            params, res = failing_random
            (tmp / "random_minimal.toml").write_text(
                random_scene_toml(params, *size) + "\n")
    counts = {}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    summary = ", ".join(f"{n} {s}" for s, n in counts.items())
    print(f"{summary}; {time.perf_counter() - t_start:.1f}s")
    if failing_random is not None:
        print(f"random search: minimal failing scene ({failing_random[1].case}) saved as "
              f"{out.path / 'random_minimal.toml'}")
    if failed:
        print("BOUND BROKEN: " + ", ".join(r.case for r in failed)
              + f"; scenes and worst-pixel PNGs in {out.path}/")
        return 1
    return 0


def reference_table(results, reference) -> list[str]:
    """Each case's output against the chosen reference, in rgba8 codes: rmse, ``vs ref p99``
    and max of the worse float32 backend, and its worst pixel (y from the top)."""
    lines = [f"against {reference.describe()}: the output of each case in rgba8 codes "
             f"(the worse of GL and CL)"]
    if reference.spec.why:
        lines.append(f"  (the default reference: {reference.spec.why})")
    notes = {n for r in results if r.scene is not None for n in reference.notes(r.scene)}
    lines += [f"  note: {n}" for n in sorted(notes)]
    header = ("case", "vs ref rmse", "vs ref p99", "vs ref max", "worst pixel (x, y): got vs ref")
    rows = [header]
    for r in results:
        figures = r.vs_reference
        if "error" in figures:
            rows.append((r.case, "-", "-", "-", f"not evaluated: {figures['error']}"))
            continue
        if not figures:
            rows.append((r.case, "-", "-", "-", "not rendered"))
            continue
        b, e = max(figures.items(), key=lambda kv: (kv[1]["p99"], kv[1]["rmse"]))
        where = "-"
        if e["worst"]:
            x, y, got, want = e["worst"][0]
            where = f"({x}, {y}) {b}: {got} vs {want}"
        rows.append((r.case, f"{e['rmse']:.2f}", f"{e['p99']:.0f}", f"{e['max']:.0f}", where))
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
    return lines


def _base_scene(args):
    from pipegen.scene.load import default_scene, load_scene_noting
    if args.scene:
        return load_scene_noting(args.scene)
    return default_scene()
