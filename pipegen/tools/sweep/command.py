"""``pipegen sweep`` on the command line: the subcommand's arguments (``add_parser``, called by
the ``pipegen`` parser) and ``cmd_sweep``, which runs the sweep and writes its folder."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pipegen.core.diagnostics import PipegenError
from pipegen.proof.references import REFERENCE_HELP, SAMPLES_HELP
from pipegen.tools.sweep.journal import Journal, SweepInterrupted
from pipegen.tools.sweep.outputs import write_outputs
from pipegen.tools.sweep.run import BACKEND_ORDER, DEFAULT_THREADS, run_sweep
from pipegen.tools.sweep.variants import parse_axes

EXAMPLES = """\
  pipegen sweep pipelines/inferred.pipe --scene examples/scenes/edges.toml -p lbuffer_scale=0.5,0.625,0.75,1.0 -p dsf=false,true -o out/sweep-inferred
      lbuffer_scale x dsf, GL and CL, Pareto plot and error maps
  pipegen sweep pipelines/lidr_cpu_sort.pipe pipelines/lidr_max_stencil.pipe pipelines/lidr_bitplanes.pipe --scene examples/scenes/many_lights.toml -o out/sweep-lidr
      three techniques side by side on one scene (lidr_bitplanes over its index_bits)
  pipegen sweep pipelines/inferred.pipe -p lbuffer_scale=0.5,1.0 -p dsf=true --size 640x360 --frames 9 -o out/s
  pipegen sweep pipelines/inferred.pipe --scheduler tcp://scheduler-host:8786 -o out/s
      renders on a Dask cluster (pip install 'pipegen[dask]'); timings on one of its workers
  pipegen sweep examples/techniques/toon_deferred.pipe -p bands=2,3,4 --reference examples/techniques/toon_deferred.pipe:bands=8 -o out/s-toon
      a technique of your own against a reference .pipe (here: itself with more bands) in
      float64; --reference self: against its parameters' `accurate` values
"""



def add_parser(sub, size_arg, output_note: str, default_size_text: str, max_size: int,
               count_arg):
    """Add ``sweep`` to the ``pipegen`` subcommands (``cli.build_parser``, which gives the
    argument types: ``size_arg``, ``count_arg``)."""
    p = sub.add_parser(
        "sweep", help="render parameter variants, measure frame time and error",
        description="Render every combination of parameter values of one or more techniques "
                    "on each backend; measure frame time (median and interquartile range), "
                    "target memory, error against a float64 reference (--reference) and the "
                    "f64 evaluation, and GL/CL agreement; write the results, a Pareto plot "
                    "and an HTML report (DIR/index.html).",
        epilog="examples:\n" + EXAMPLES + "\n" + output_note,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", nargs="+", metavar="FILE", help="techniques (.pipe files)")
    p.add_argument("-p", "--param", action="append", default=[], metavar="NAME=V1,V2,...",
                   help="an axis: values of a parameter to sweep (repeatable; default: every "
                        "parameter with declared allowed values, and every bool parameter)")
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="output folder (required; only files pipegen wrote are replaced)")
    p.add_argument("--scene", metavar="FILE",
                   help="scene .toml (default: the built-in default scene)")
    p.add_argument("--size", type=size_arg, metavar="WxH",
                   help=f"output size (default: the scene file's width x height, "
                        f"{default_size_text} for the built-in scene; each side 1..{max_size})")
    p.add_argument("--reference", metavar="R", help=REFERENCE_HELP)
    p.add_argument("--reference-samples", type=count_arg, default=1, metavar="N",
                   help=SAMPLES_HELP)
    p.add_argument("--backend", type=_backends_arg, default=BACKEND_ORDER, metavar="gl,cl",
                   help="backends, comma-separated (default: gl,cl; agreement needs both)")
    p.add_argument("--frames", type=count_arg, default=5, metavar="N",
                   help="timed frames per variant and backend, median taken after one warm-up "
                        "(default: 5; 0: no timing)")
    p.add_argument("--jobs", type=count_arg, default=None, metavar="N",
                   help="render processes in the local pool (default: the CPUs available)")
    p.add_argument("--threads", type=count_arg, default=DEFAULT_THREADS, metavar="T",
                   help=f"rasteriser threads while timing (LP_NUM_THREADS, "
                        f"POCL_MAX_PTHREAD_COUNT; the timing process is pinned to T CPUs; "
                        f"default: {DEFAULT_THREADS})")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run renders on a Dask distributed cluster, e.g. tcp://HOST:8786 "
                        "(pip install 'pipegen[dask]')")
    from pipegen.compiler.driver import GENERAL_HELP
    p.add_argument("--general", action="store_true", help=GENERAL_HELP)
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--resume", action="store_true",
                   help="finish a sweep that was stopped (Ctrl-C, kill, a crash): render only "
                        "the variants DIR/rows.jsonl lacks, then time them all; the files, "
                        "options and scene must be the stopped sweep's")
    p.add_argument("--force", action="store_true",
                   help="write into an output folder that holds files pipegen did not write")
    p.set_defaults(func=cmd_sweep)
    return p


def _backends_arg(text: str) -> tuple:
    from pipegen.backends import registry
    names = tuple(dict.fromkeys(b.strip() for b in text.split(",") if b.strip()))
    bad = [b for b in names if b not in registry.BACKENDS]
    if not names or bad:
        raise argparse.ArgumentTypeError(
            f"bad backend list {text!r}: choose from {', '.join(registry.BACKENDS)}, "
            f"comma-separated")
    return names


def command_line(args) -> str:
    """The sweep's command line, rebuilt from its arguments (not sys.argv: ``main([...])``
    may be called from Python)."""
    import shlex
    words = ["pipegen", "sweep", *args.files]
    for p in args.param:
        words += ["-p", p]
    if args.scene:
        words += ["--scene", args.scene]
    if args.size:
        words += ["--size", f"{args.size[0]}x{args.size[1]}"]
    words += ["--backend", ",".join(args.backend), "--frames", str(args.frames)]
    for flag in ("reference", "reference_samples", "jobs", "scheduler"):
        value = getattr(args, flag, None)
        if value is not None and not (flag == "reference_samples" and value == 1):
            words += ["--" + flag.replace("_", "-"), str(value)]
    if getattr(args, "general", False):
        words += ["--general"]
    words += ["-o", str(args.out)]
    return " ".join(shlex.quote(w) for w in words)


def cmd_sweep(args) -> int:
    from pipegen.compiler.inputs import looks_like_scene
    from pipegen.core.outdir import OutputDir
    out = OutputDir(args.out, "sweep", args.force)          # before any work
    for f in args.files:
        if Path(f).suffix.lower() == ".toml" or looks_like_scene(Path(f)):
            raise PipegenError(None, f"{f}: this looks like a scene file (.toml), not a "
                                     f"technique (.pipe)",
                               hint="give the scene with --scene")
    if args.scene and Path(args.scene).suffix.lower() == ".pipe":
        raise PipegenError(None, f"{args.scene}: this looks like a technique (.pipe), not a "
                                 f"scene file (.toml)", hint="--scene takes a scene .toml")
    if args.jobs == 0:
        raise PipegenError(None, "--jobs must be at least 1")
    if args.reference is not None:          # its text checked before any variant compiles
        from pipegen.proof.references import parse_reference
        parse_reference(args.reference, args.reference_samples)
    axes = parse_axes(args.param) if args.param else None
    journal = Journal(out, resume=args.resume, command=command_line(args))
    try:
        result = run_sweep(args.files, args.scene, args.size, axes, args.backend, args.frames,
                           args.jobs, args.scheduler, max(1, args.threads),
                           progress=not args.no_progress, reference=args.reference,
                           reference_samples=args.reference_samples, general=args.general,
                           journal=journal)
    except SweepInterrupted as e:
        what = "rendered, frame times not measured" if e.timing else "done"
        print(f"\ninterrupted: {e.rows} of {e.total} rows {what} ({out}/results.csv, "
              f"results.json); resume with: {journal.command} --resume", file=sys.stderr)
        return 130
    result.command = journal.command
    write_outputs(result, out, journal=journal.text())
    print(result.summary(), end="")
    print(f"wrote {out}/: index.html, results.csv, results.json, table.txt, pareto.png, "
          f"errors/ ({len(result.maps)} maps), images/")
    return 0

