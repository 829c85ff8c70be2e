"""``pipegen tune`` on the command line (added to ``cli.build_parser`` by ``add_parser``): the
search, its printed report, ``DIR/tune.json`` and ``stress`` at the pick."""

from __future__ import annotations

import argparse
import math
import sys

from pipegen.core.units import format_bytes
from pipegen.tools.tune.budget import METRICS
from pipegen.tools.tune.measure import overlap
from pipegen.tools.tune.search import TuneResult, show, within

EXAMPLES = """\
  pipegen tune pipelines/inferred.pipe --scene examples/scenes/edges.toml --budget "p99<=2" --size 96x54
      the least target memory with p99 <= 2 codes against the scene reference
  pipegen tune pipelines/lidr_bitplanes.pipe --scene examples/scenes/stress_overlap.toml --budget "lights_dropped==0"
      no light dropped: exit 1 naming the closest configuration when none holds them all
  pipegen tune pipelines/inferred.pipe --scene examples/scenes/edges.toml --scene examples/scenes/many_lights.toml --size 160x90 --budget "p99<=6, max<=40" --minimise time -o out/tune
      the fastest within budget on both scenes; DIR/tune.json, then stress at the pick
"""


def add_parser(sub, size_arg, output_note: str):
    p = sub.add_parser(
        "tune", help="find the cheapest parameter values within an error budget",
        description="Search a technique's declared parameter values (param x = a in {a, b, "
                    "c}) for the cheapest configuration whose output error against the "
                    "reference stays within the budget on every scene, without rendering "
                    "every combination (docs/accuracy.md, `pipegen tune`); then run stress at "
                    "the pick. Exit 1 when no configuration meets the budget.",
        epilog="examples:\n" + EXAMPLES + "\nbudget metrics:\n"
               + "".join(f"  {k}: {v}\n" for k, v in METRICS.items()) + "\n" + output_note,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", metavar="FILE", help="the technique, a .pipe file")
    p.add_argument("--scene", action="append", required=True, metavar="FILE",
                   help="scene .toml (repeatable: the budget must hold on every scene)")
    p.add_argument("--budget", required=True, metavar="TERMS",
                   help='METRIC<=NUMBER terms joined by commas, e.g. "p99<=2" or '
                        '"p99<=2, lights_dropped==0" (metrics: ' + ", ".join(METRICS) + ")")
    p.add_argument("-p", "--param", action="append", default=[], metavar="NAME=V1,V2,...",
                   help="search only these values of a parameter (repeatable; default: every "
                        "declared value of every parameter declaring them, bools both ways)")
    p.add_argument("--reference", metavar="R",
                   help="what the error is measured against: scene, self or "
                        "FILE.pipe[:name=value,...] (default: scene for techniques shaded "
                        "by the shipped lighting library, else self)")
    p.add_argument("--minimise", "--minimize", choices=("memory", "time"), default="memory",
                   help="the cost: target memory (exact) or frame time (measured; ties "
                        "within the spread resolved by memory) (default: memory)")
    p.add_argument("--backend", choices=("gl", "cl"), default="gl",
                   help="the backend that renders and is timed (default: gl)")
    p.add_argument("--size", type=size_arg, metavar="WxH",
                   help="render every scene at this size (default: each scene file's own)")
    p.add_argument("--frames", type=int, default=5, metavar="N",
                   help="timed frames per configuration, median taken (default: 5)")
    p.add_argument("--stress", default="quick", metavar="CASES",
                   help="stress cases run at the pick (default: quick; none: skip)")
    from pipegen.compiler.driver import GENERAL_HELP
    p.add_argument("--general", action="store_true", help=GENERAL_HELP)
    p.add_argument("-o", "--out", metavar="DIR", help="write DIR/tune.json")
    p.add_argument("--force", action="store_true",
                   help="write into an output folder that holds files pipegen did not write")
    p.set_defaults(func=cmd_tune, parser=p)
    return p


def cmd_tune(args) -> int:
    from pipegen.core.diagnostics import PipegenError
    from pipegen.core.outdir import OutputDir
    from pipegen.tools.tune.budget import parse_budget
    from pipegen.tools.tune.run import result_json, tune
    try:
        budget = parse_budget(args.budget)              # before any work
    except PipegenError as e:                           # misuse of the command line: exit 2
        args.parser.print_usage(sys.stderr)
        print(e.render(), file=sys.stderr)
        return 2
    out = OutputDir(args.out, "tune", args.force) if args.out else None
    if args.frames < 0:
        raise PipegenError(None, f"--frames {args.frames}: a count >= 0")

    def say(text: str) -> None:
        print(f"  … {text}", file=sys.stderr)

    axes = None
    if args.param:
        from pipegen.tools.sweep.variants import parse_axes
        axes = parse_axes(args.param)
    r = tune(args.file, list(args.scene), budget, args.reference, args.minimise,
             args.backend, args.size, args.frames, axes=axes, say=say, general=args.general)
    print(report(r))
    stress = None
    if r.pick is not None and args.stress != "none":
        stress = run_stress(r, args.scene[0], args.stress, say, args.general)
        print(stress["line"])
    if out is not None:
        with out.staging() as tmp:
            (tmp / "tune.json").write_text(result_json(r, stress))
        print(f"wrote {out}/tune.json")
    return 0 if r.pick is not None else 1


def run_stress(r: TuneResult, scene_file: str, cases: str, say, general: bool = False) -> dict:
    """``stress`` at the pick on the first scene: counts by status and the failing cases
    (each case rendered by its scene's variant, or with ``general`` the general build)."""
    from pipegen.scene.load import load_scene
    from pipegen.tools.stress import DEFAULT_SIZE, stress
    try:
        results = stress(r.compiled_pick, load_scene(scene_file), cases=cases, progress=say,
                         general=general, path=r.file)
    except RuntimeError as exc:          # a backend that cannot build the pick: said, and the
        first = str(exc).splitlines()[0]  # answer above stands
        return dict(cases=cases, counts={}, failed=[], error=first,
                    line=f"stress at the pick ({cases}) could not run: {first}")
    counts: dict = {}
    for x in results:
        counts[x.status] = counts.get(x.status, 0) + 1
    failed = [x.case for x in results if x.failed]
    line = (f"stress at the pick ({cases}, {len(results)} case{'s' * (len(results) != 1)} at "
            f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}): "
            + ", ".join(f"{n} {s}" for s, n in counts.items())
            + (f"; bound broken in {', '.join(failed)} (pipegen stress {r.file} "
               f"{_params_flags(r.pick.params)} --cases {','.join(failed)}"
               f"{' --general' if general else ''})" if failed else ""))
    return dict(cases=cases, counts=counts, failed=failed, line=line)


def _params_flags(params: dict) -> str:
    return " ".join(f"-p {k}={show(v)}" for k, v in params.items())


def _num(x, digits=3) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if float(x).is_integer() and abs(x) < 1e9:
        return str(int(x))
    return f"{x:.{digits}g}" if isinstance(x, float) else str(x)


def _time(m) -> str:
    if m.time_ms is None:
        return "-"
    return f"{m.time_ms:.2f}"


def figures(m, budget) -> str:
    f = m.figures
    keys = ["p99", "max", "rmse", "flip"]
    if f.get("lights_dropped") or "lights_dropped" in budget.metrics:
        keys.append("lights_dropped")
    parts = [f"{k} {_num(f[k], 4)}" for k in keys
             if k in f and not (isinstance(f[k], float) and math.isnan(f[k]))]
    parts.append(format_bytes(m.memory, "KiB"))
    if m.time_ms is not None:
        parts.append(f"{m.time_ms:.2f} ms (IQR {m.time_q[0]:.2f}-{m.time_q[1]:.2f}, "
                     f"{m.frames} frames)")
    return ", ".join(parts)


def label(params: dict) -> str:
    return " ".join(f"{k}={show(v)}" for k, v in params.items())


def report(r: TuneResult) -> str:
    head = (f"{r.technique}: tune on {', '.join(r.scenes)} against {r.reference}, budget "
            f"{r.budget.text}, minimising {r.minimise} ({r.backend})")
    names = [a.name for a in r.axes]
    shown = r.tried + r.analytic
    dropped = "lights_dropped" in r.budget.metrics or any(
        m.figures.get("lights_dropped") for m in shown)
    rows = [["#", *names, "p99", "max", "rmse", "flip", *(["dropped"] if dropped else []),
             "KiB", "ms", "budget"]]
    for m in shown:
        f = m.figures
        rows.append([str(m.order) if m.rendered else "-", *(show(v) for v in m.key),
                     _num(f.get("p99")), _num(f.get("max")), _num(f.get("rmse")),
                     _num(f.get("flip")),
                     *([_num(f.get("lights_dropped"))] if dropped else []),
                     f"{m.memory / 1024:.1f}", _time(m),
                     "within" if within(r.budget, m) else "out"])
    widths = [max(len(x[i]) for x in rows) for i in range(len(rows[0]))]
    table = ["  ".join(c.ljust(w) for c, w in zip(x, widths)).rstrip() for x in rows]
    lines = [head, f"tried ({len(r.tried)} rendered"
                   + (f", {len(r.analytic)} judged without rendering" if r.analytic else "")
                   + f", # = render order):", *("  " + t for t in table)]
    sweep = r.total * len(r.scenes)
    lines.append(f"renders: {r.renders} (the exhaustive sweep: {sweep}, {r.total} "
                 f"configurations x {len(r.scenes)} scene{'s' if len(r.scenes) > 1 else ''}); "
                 f"{r.pruned} ruled out by monotonicity without rendering, "
                 f"{r.total - len(r.tried) - len(r.analytic) - r.pruned} not needed (costlier "
                 f"than the answer); {r.timed_frames} frames timed")
    if r.pick is not None:
        lines.append(f"pick: {label(r.pick.params)}")
        lines.append(f"  {figures(r.pick, r.budget)}")
        if r.runner_up is not None:
            lines.append(f"runner-up: {label(r.runner_up.params)}")
            lines.append(f"  {figures(r.runner_up, r.budget)}")
            if r.minimise == "time" and overlap(r.pick, r.runner_up):
                lines.append("  their frame times overlap (interquartile ranges): a tie, "
                             "resolved by memory")
        else:
            lines.append("runner-up: none within budget")
    else:
        c = r.closest
        miss = "; ".join(f"{t.text}: {_num(float(v), 4)}, over by {_num(float(d), 4)}"
                         for t, v, d in r.budget.misses(c.figures))
        lines.append(f"no configuration meets the budget {r.budget.text}")
        lines.append(f"closest: {label(c.params)} ({miss})")
        lines.append(f"  {figures(c, r.budget)}")
    lines.append(f"how: {r.how}")
    if r.violations:
        lines += [f"monotonicity: {v}" for v in r.violations]
    elif r.pairs_checked:
        lines.append(f"monotonicity: held on the {r.pairs_checked} ordered pairs of rendered "
                     f"configurations")
    lines += [f"note: {n}" for n in r.notes]
    for m in ([r.pick] if r.pick else []):
        lines += [f"note: the pick: {n}" for n in m.notes]
    return "\n".join(lines)
