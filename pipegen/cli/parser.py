"""The ``pipegen`` argument parser: one function per built-in subcommand adds its options (each
names its run function in ``commands``), a few more add the options several share; ``sweep``,
``stress`` and ``tune`` add themselves (``tools/``)."""

from __future__ import annotations

import argparse

from pipegen.backends import registry
from pipegen.cli import commands
from pipegen.cli.arguments import (DEFAULT_SIZE_TEXT, MAX_SIZE, count_arg, dump_after_arg,
                                   graph_path_arg, param_arg, size_arg)
from pipegen.cli.help_text import EXAMPLES, MISMATCH_NOTE, OUTPUT_NOTE, TEST_NOTE
from pipegen.core.defaults import DEFAULT_SIZE

COMMANDS = ("compile", "run", "check", "specialise", "graph", "info", "test")

FORMATTER = argparse.RawDescriptionHelpFormatter


class _Version(argparse.Action):
    """``--version``: the installed version, looked up only when asked for (importlib.metadata
    costs every other command tens of milliseconds)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, help="show the version and exit")

    def __call__(self, parser, namespace, values, option_string=None):
        from pipegen.core.defaults import version
        print(f"pipegen {version()}")
        parser.exit()


def build_parser(command_word: str | None = None) -> argparse.ArgumentParser:
    """The ``pipegen`` argument parser.  ``command_word``: the first word of the command line,
    when known; if it names one of ``COMMANDS``, only that subcommand is added (the others,
    and above all ``sweep``, ``stress`` and ``tune``, whose modules import numpy and the scene
    code, tens of milliseconds, change nothing for that command's parse, help or errors).
    ``--version`` leaves them out too (it prints and exits while parsing).  Without it
    (``--help``, an unknown word, ``sweep`` itself) every subcommand is added."""
    everything = "".join(EXAMPLES[c] for c in COMMANDS)
    parser = argparse.ArgumentParser(
        prog="pipegen",
        description="Compile real-time rendering techniques (.pipe files) to GLSL + moderngl "
                    "and OpenCL C + PoCL pipelines, run them, and check one against the other.",
        epilog="examples:\n" + everything + "\n" + OUTPUT_NOTE, formatter_class=FORMATTER)
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    built_in = dict(zip(COMMANDS, (add_compile, add_run, add_check, add_specialise, add_graph,
                                   add_info, add_test)))
    if command_word in COMMANDS:
        # the subcommand the command line names is all its parse, help and errors read: the
        # others' options (tens of help strings each) are not built
        built_in[command_word](sub)
        return parser
    for add in built_in.values():
        add(sub)
    if command_word == "--version":
        return parser
    from pipegen.tools.sweep.command import add_parser as add_sweep  # `pipegen sweep`: tools/sweep/
    add_sweep(sub, size_arg, OUTPUT_NOTE, DEFAULT_SIZE_TEXT, MAX_SIZE, count_arg)
    from pipegen.tools.stress.command import add_parser as add_stress  # `pipegen stress`: tools/stress/
    add_stress(sub, size_arg, OUTPUT_NOTE)
    from pipegen.tools.tune.command import add_parser as add_tune  # `pipegen tune`: tools/tune/
    add_tune(sub, size_arg, OUTPUT_NOTE)
    return parser


# -- the built-in subcommands, in the order --help lists them ----------------------------------


def add_compile(sub) -> None:
    c = add_command(sub, "compile", "emit shaders, pipeline modules and a report",
                    commands.cmd_compile)
    add_required_out(c)
    add_fixed_size(c, "the report's memory figures assume")
    c.add_argument("--backend", choices=[*registry.BACKENDS, "all"], default="all",
                   help="which backends to emit (default: all)")
    c.add_argument("--scene", metavar="FILE",
                   help="specialise for this scene's features: light types, light count, "
                        "translucent objects; report.txt lists every cut and its reason "
                        "(default: the general technique)")
    c.add_argument("--dump-after", metavar="PASS|all", type=dump_after_arg,
                   help="print the IR after this compiler pass (several: comma-separated; "
                        "all: after every pass) to stdout, each headed // after PASS, then "
                        "compile as usual; with --scene also the scene passes "
                        "(default: print no IR)")
    add_strict(c, needs_scene=True)
    add_force(c)


def add_run(sub) -> None:
    r = add_command(sub, "run", "render a scene, one PNG + .npy per target", commands.cmd_run,
                    mismatch_note=True)
    add_required_out(r)
    add_scene_and_size(r)
    r.add_argument("--backend", choices=list(registry.BACKENDS), default="gl",
                   help="; ".join(f"{b.name}: {b.description}" for b in registry.BACKENDS.values())
                   + " (default: gl)")
    r.add_argument("--precision", choices=("f32", "f64"), default="f32",
                   help="f64: the float64 evaluation of the technique (with --backend cl): "
                        "its arithmetic in double, targets unquantised; the PNGs and .npy "
                        "files hold it quantised to each target's format (default: f32)")
    add_specialise_flag(r)
    add_strict(r)
    add_force(r)


def add_check(sub) -> None:
    k = add_command(sub, "check", "render on GL and CL, compare every target", commands.cmd_check,
                    mismatch_note=True)
    add_scene_and_size(k)
    k.add_argument("-o", "--out", metavar="DIR",
                   help="folder for the error images (default: build/check/<technique>)")
    k.add_argument("--precision", choices=("f32", "f64"), default="f32",
                   help="f64: instead of GL against CL, each float32 backend against the "
                        "technique's float64 evaluation (CL), within the bound of the "
                        "tolerance model (docs/tolerances.md; a measurement: exit status 0) "
                        "(default: f32)")
    from pipegen.proof.references import REFERENCE_HELP, SAMPLES_HELP
    k.add_argument("--reference", metavar="R",
                   help="with --precision f64, also measure the output's error against the "
                        "reference R: " + REFERENCE_HELP)
    k.add_argument("--reference-samples", type=count_arg, default=1, metavar="N",
                   help=SAMPLES_HELP)
    k.add_argument("--max-discontinuities", type=count_arg, default=0, metavar="N",
                   help="pixels where GL and CL may take different sides of a step in the "
                        "technique's code (a comparison, floor, step, ...), listed with the "
                        "expression (default: 0)")
    add_specialise_flag(k)
    add_strict(k)
    add_force(k)


def add_specialise(sub) -> None:
    sp = add_command(sub, "specialise", "show what a scene lets a technique cut, and why",
                     commands.cmd_specialise, output_note=False, mismatch_note=True)
    sp.add_argument("--scene", metavar="FILE", required=True,
                    help="scene .toml whose features the technique is specialised for "
                         "(required)")
    sp.add_argument("--size", type=size_arg, metavar="WxH",
                    help=f"output size for the memory figures and --verify's renders "
                         f"(default: the scene file's width x height; each side 1..{MAX_SIZE})")
    sp.add_argument("--verify", action="store_true",
                    help="render general and specialised and compare every target the "
                         "specialised pipeline produces, bit for bit; exit 1 naming the first "
                         "differing pass (default: no rendering)")
    sp.add_argument("--backend", choices=[*registry.BACKENDS, "all"], default="all",
                    help="backends --verify renders on (default: all)")
    add_strict(sp)


def add_graph(sub) -> None:
    g = add_command(sub, "graph", "draw passes and targets as a graph (SVG, PNG or DOT)",
                    commands.cmd_graph, output_note=False)
    g.add_argument("-o", "--out", required=True, metavar="G.svg", type=graph_path_arg,
                   help="the graph file: .svg, .png or .pdf rendered with Graphviz's dot "
                        "when installed (otherwise the DOT text is written beside, as .dot), "
                        ".dot or .gv for the DOT text (required)")
    g.add_argument("--scene", metavar="FILE",
                   help="specialise for this scene and grey out what is culled, with the "
                        "reason (default: the general technique)")
    g.add_argument("--size", type=size_arg, metavar="WxH",
                   help=f"output size the target sizes and memory assume (default: the "
                        f"scene's width x height with --scene, as run uses, else "
                        f"{DEFAULT_SIZE_TEXT}; each side 1..{MAX_SIZE})")


def add_info(sub) -> None:
    i = add_command(sub, "info", "list parameters, targets, passes and packing schemes",
                    commands.cmd_info, output_note=False)
    add_fixed_size(i, "the target sizes and bytes assume")


def add_test(sub) -> None:
    summary = "check the expectations written in .pipe files (expect …)"
    t = sub.add_parser("test", help=summary, description=summary[0].upper() + summary[1:] + ".",
                       epilog="examples:\n" + EXAMPLES["test"] + "\n" + TEST_NOTE,
                       formatter_class=FORMATTER)
    t.add_argument("files", nargs="+", metavar="FILE",
                   help="techniques (.pipe files); each one's expectations are checked in the "
                        "order written")
    t.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                   type=param_arg,
                   help="override a parameter of every FILE, checked against its allowed "
                        "values (repeatable; default: the values each file declares)")
    t.set_defaults(func=commands.cmd_test, parser=t)


# -- what several subcommands share ------------------------------------------------------------


def add_command(sub, name: str, summary: str, func, output_note: bool = True,
                mismatch_note: bool = False) -> argparse.ArgumentParser:
    """Subcommand ``name`` run by ``func``, with its examples and notes, the technique file and
    ``-p``; the parser is kept in the arguments (``args.parser.error``: a usage error)."""
    p = sub.add_parser(name, help=summary, description=summary[0].upper() + summary[1:] + ".",
                       epilog="examples:\n" + EXAMPLES[name]
                       + ("\n" + OUTPUT_NOTE if output_note else "")
                       + ("\n" + MISMATCH_NOTE if mismatch_note else ""),
                       formatter_class=FORMATTER)
    p.add_argument("file", help="the technique, a .pipe file")
    p.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                   type=param_arg,
                   help="override a parameter, checked against its allowed values "
                        "(repeatable; default: the values the file declares)")
    p.set_defaults(func=func, parser=p)
    return p


def add_required_out(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="output folder (required; only files pipegen wrote are replaced)")


def add_fixed_size(p: argparse.ArgumentParser, assumed_by: str) -> None:
    """``--size`` when no scene sets it (compile, graph, info): the default size."""
    p.add_argument("--size", type=size_arg, default=DEFAULT_SIZE, metavar="WxH",
                   help=f"output size {assumed_by} "
                        f"(default: {DEFAULT_SIZE_TEXT}; each side 1..{MAX_SIZE})")


def add_scene_and_size(p: argparse.ArgumentParser) -> None:
    """The scene a command renders and its size (run, check)."""
    p.add_argument("--scene", metavar="FILE",
                   help="scene .toml, or a glTF file (.gltf, .glb) (default: the built-in "
                        "default scene)")
    p.add_argument("--size", type=size_arg, metavar="WxH",
                   help=f"output size (default: the scene file's width x height, "
                        f"{DEFAULT_SIZE_TEXT} for the built-in scene; each side 1..{MAX_SIZE})")


def add_strict(p: argparse.ArgumentParser, needs_scene: bool = False) -> None:
    p.add_argument("--strict", action="store_true",
                   help="what the technique will not render of the scene is an error "
                        "(exit 1) instead of a warning"
                        + (" (needs --scene)" if needs_scene else "")
                        + " (default: warn)")


def add_specialise_flag(p: argparse.ArgumentParser) -> None:
    """``--general`` (the general build) and ``--specialise``, the default kept as a no-op for
    the command lines written before it was one (run, check)."""
    from pipegen.compiler.driver import GENERAL_HELP, SPECIALISE_HELP
    build = p.add_mutually_exclusive_group()
    build.add_argument("--general", action="store_true", help=GENERAL_HELP)
    build.add_argument("--specialise", action="store_true", help=SPECIALISE_HELP)


def add_force(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true",
                   help="write into an output folder that holds files pipegen did not "
                        "write (they are kept, unless an output has the same name; "
                        "default: refuse)")
