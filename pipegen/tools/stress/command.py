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
                   help="folder for the table (table.txt), the cases' journal "
                        "(cases.jsonl), worst-pixel PNGs and failing scenes, each case written "
                        "as it finishes (default: build/stress/<technique>)")
    p.add_argument("--resume", action="store_true",
                   help="finish a run that was stopped (Ctrl-C, kill, a crash): render only "
                        "the cases DIR/cases.jsonl lacks; the technique, options and scene "
                        "must be the stopped run's")
    p.add_argument("--force", action="store_true",
                   help="write into an output folder that holds files pipegen did not write")
    p.set_defaults(func=cmd_stress, parser=p)
    return p


def cmd_stress(args) -> int:
    from pipegen.compiler.inputs import compile_technique
    from pipegen.core.diagnostics import PipegenError
    from pipegen.core.outdir import OutputDir
    from pipegen.tools.stress.cases import build, case_names, random_scene_toml
    from pipegen.tools.stress.journal import (JOURNAL, TABLE, JournaledRunner, StressJournal,
                                              stress_identity)
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
    stress = Stress(compiled, reference=reference, general=args.general, path=args.file)
    journal = StressJournal(out, resume=args.resume)
    done = journal.start(stress_identity(args.file, args.param, args.scene, size, names,
                                         args.random, args.seed, args.reference,
                                         args.reference_samples, args.general))

    def report_text(records: list) -> str:
        builds = stress.builds_text(len({r.build for r in journal.records.values()}))
        return "\n".join(report_lines(compiled.name, base.name, size, records, builds,
                                       reference)) + "\n"

    runner = JournaledRunner(stress, journal, done, reference, report_text)
    results = []
    failing_random = None
    try:
        for case in build(base, names) if names else []:
            say(case.name + (" (done)" if case.name in done else ""))
            results.append(runner.run_case(case))
        if args.random:
            from pipegen.tools.stress.search import random_search
            randoms, failing_random = random_search(runner, args.random, size, args.seed, say)
            results += randoms
    except KeyboardInterrupt:
        total = len(names) + args.random      # shrinking steps of --random come after these
        print(f"\ninterrupted: {min(len(journal.records), total)} of {total} cases done "
              f"({out}/{TABLE}); resume with: {command_line(args)} --resume", file=sys.stderr)
        return 130
    text = report_text(results)
    counts = {}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    summary = ", ".join(f"{n} {s}" for s, n in counts.items())
    failed = [r for r in results if r.failed]
    with out.staging() as tmp:       # the final folder: files of cases no longer run go
        for r in failed:
            for name, data in journal.files_of(r).items():
                (tmp / name).write_bytes(data)
        if failing_random is not None:
            params, res = failing_random
            (tmp / "random_minimal.toml").write_text(
                random_scene_toml(params, *size) + "\n")
        (tmp / TABLE).write_text(text + summary + "\n")
        (tmp / JOURNAL).write_text(journal.text())
    print(text, end="")
    print(f"{summary}; {time.perf_counter() - t_start:.1f}s")
    if failing_random is not None:
        print(f"random search: minimal failing scene ({failing_random[1].case}) saved as "
              f"{out.path / 'random_minimal.toml'}")
    if failed:
        print("BOUND BROKEN: " + ", ".join(r.case for r in failed)
              + f"; scenes and worst-pixel PNGs in {out.path}/")
        return 1
    return 0


def report_lines(technique: str, base: str, size: tuple, records: list, builds: str,
                 reference) -> list[str]:
    """What stress prints (and writes as table.txt) for ``records`` (``CaseRecord``): the
    title, the table, the notes and the table against the reference."""
    from pipegen.tools.stress import report
    lines = [f"{technique}: stress on {base} at {size[0]}x{size[1]} ({len(records)} cases; "
             f"error of each float32 target against the float64 evaluation, divided by its "
             f"bound; {builds})", report.table_of_rows([r.row for r in records])]
    lines += [f"note: {line}" for r in records for line in r.notes]
    if reference is not None:
        notes = {n for r in records for n in r.ref_notes}
        lines += [""] + report.reference_lines(reference, [r.ref_row for r in records], notes)
    return lines


def command_line(args) -> str:
    """The run's command line, rebuilt from its arguments (for the resume hint)."""
    import shlex
    words = ["pipegen", "stress", args.file]
    for p in args.param:
        words += ["-p", p]
    if args.scene:
        words += ["--scene", args.scene]
    words += ["--size", f"{args.size[0]}x{args.size[1]}", "--cases", args.cases]
    if args.random:
        words += ["--random", str(args.random), "--seed", str(args.seed)]
    if args.reference is not None:
        words += ["--reference", args.reference]
    if args.reference_samples != 1:
        words += ["--reference-samples", str(args.reference_samples)]
    if args.general:
        words.append("--general")
    if args.out:
        words += ["-o", args.out]
    return " ".join(shlex.quote(w) for w in words)


def reference_table(results, reference) -> list[str]:
    """Each case's output against the chosen reference, in rgba8 codes: rmse, ``vs ref p99``
    and max of the worse float32 backend, and its worst pixel (y from the top)."""
    from pipegen.tools.stress.report import reference_lines, reference_row
    notes = {n for r in results if r.scene is not None for n in reference.notes(r.scene)}
    return reference_lines(reference, [reference_row(r) for r in results], notes)


def _base_scene(args):
    from pipegen.scene.load import default_scene, load_scene_noting
    if args.scene:
        return load_scene_noting(args.scene)
    return default_scene()
