"""``pipegen``: compile, run, check and describe rendering techniques.

Every user error is printed as ``file:line:col``, the line, a caret and a hint (or ``error: …``
and a hint when it is not about a place in a file), and exits with status 1; misuse of the
command line itself (an unknown option, a malformed ``--size`` or ``-p``) exits with 2,
argparse's convention.  A traceback reaching the user for bad input is a bug.

Output folders (``-o``) are checked before any work and written through ``outdir.OutputDir``:
pipegen never deletes or overwrites a file it did not write.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from pipegen.core.defaults import DEFAULT_SIZE
from pipegen.backends import registry
from pipegen.core.diagnostics import PipegenError
from pipegen.compiler.inputs import compile_technique, param_pair

MAX_SIZE = 16384          # per side: GL_MAX_TEXTURE_SIZE of llvmpipe
DEFAULT_SIZE_TEXT = f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}"

EXAMPLES = {
    "compile": """\
  pipegen compile pipelines/lidr_bitplanes.pipe -o build/lidr
      GLSL + pipeline_gl.py, OpenCL C + pipeline_cl.py, and report.txt in build/lidr/
  pipegen compile pipelines/inferred.pipe -p lbuffer_scale=0.5 --size 1920x1080 -o build/inferred
      with a parameter overridden; the report's memory figures at 1920x1080
  pipegen compile pipelines/inferred.pipe --scene examples/scenes/small.toml -o build/inferred-small
      specialised for the scene's features; report.txt says what was culled and why
  pipegen compile pipelines/forward.pipe --dump-after fold -o build/forward
      the IR after the fold pass, in .pipe spelling, on stdout (all: after every pass)
""",
    "run": """\
  pipegen run pipelines/forward.pipe -o out/forward
      render the built-in default scene: one PNG and one .npy per target
  pipegen run pipelines/deferred.pipe --scene examples/scenes/many_lights.toml --size 640x360 -o out/deferred
  pipegen run pipelines/forward.pipe --backend cl -o out/forward-cl
      the same technique on the PoCL software reference
  pipegen run pipelines/inferred.pipe -p lbuffer_scale=0.5 -o out/inferred
  pipegen run pipelines/lidr_bitplanes.pipe --scene examples/scenes/mixed_lights.toml --strict -o out/lidr
      exit 1, listing what the technique will not render of this scene (a warning without --strict)
  pipegen run pipelines/deferred_calver.pipe --scene examples/scenes/small.toml --specialise -o out/calver
      render the variant specialised for the scene (culled passes and targets never run)
""",
    "check": """\
  pipegen check pipelines/lidr_bitplanes.pipe
      GL vs CL on the built-in scene, one row per target; error images in build/check/lidr_bitplanes/
  pipegen check pipelines/lidr_max_stencil.pipe --scene examples/scenes/stress_overlap.toml
      exit 1 and the first divergent pass on disagreement
  pipegen check pipelines/inferred.pipe --scene examples/scenes/small.toml --specialise
      GL vs CL on the variant specialised for the scene
""",
    "info": """\
  pipegen info pipelines/inferred.pipe
      parameters, targets (bytes at 1280x720), passes and packing schemes
  pipegen info pipelines/inferred.pipe -p lbuffer_scale=0.5 --size 1920x1080
""",
    "specialise": """\
  pipegen specialise pipelines/inferred.pipe --scene examples/scenes/small.toml
      the scene's features, what is culled and why, passes and targets before and after
  pipegen specialise pipelines/deferred_calver.pipe --scene examples/scenes/small.toml --verify
      render general and specialised on GL and CL, compare bit for bit (exit 1 if they differ)
""",
    "graph": """\
  pipegen graph pipelines/deferred.pipe -o deferred.svg
      passes, targets and their read/write/depth edges (an SVG with Graphviz, else DOT text)
  pipegen graph pipelines/inferred.pipe --scene examples/scenes/small.toml -o inferred.svg
      culled passes and targets greyed, each with its reason
""",
}

COMMANDS = ("compile", "run", "check", "specialise", "graph", "info")

OUTPUT_NOTE = """\
output folders (-o): created if missing; pipegen writes a manifest (.pipegen-manifest.json) of
the files it wrote, replaces only those on the next run, and never deletes or overwrites a file
it did not write.  A non-empty folder it did not write is refused unless --force.
"""

MISMATCH_NOTE = """\
what a technique will not render of a scene (a light type it cannot draw, translucent objects
it never draws, more lights per pixel than its packing holds) is printed as a warning before
rendering; --strict makes it an error (exit 1).
"""


def main(argv: list[str] | None = None) -> int:
    argv = _join_negative_sizes(sys.argv[1:] if argv is None else argv)
    parser = build_parser(argv[0] if argv else None)
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        return args.func(args)
    except PipegenError as e:
        print(e.render(), file=sys.stderr)
        return 1
    except OSError as e:
        where = f": '{e.filename}'" if e.filename else ""
        print(f"error: {e.strerror or e}{where}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


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
    when known; if it names one of ``COMMANDS``, the subcommands implemented elsewhere
    (``sweep``, ``stress``: their modules import numpy and the scene code, tens of
    milliseconds) are left out, which changes nothing for that command's parse, help or errors.
    Without it (``--help``, an unknown word, ``sweep`` itself) every subcommand is added."""
    fmt = argparse.RawDescriptionHelpFormatter
    everything = "".join(EXAMPLES[c] for c in COMMANDS)
    parser = argparse.ArgumentParser(
        prog="pipegen",
        description="Compile real-time rendering techniques (.pipe files) to GLSL + moderngl "
                    "and OpenCL C + PoCL pipelines, run them, and check one against the other.",
        epilog="examples:\n" + everything + "\n" + OUTPUT_NOTE, formatter_class=fmt)
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    def command(name: str, summary: str, func, output_note: bool = True,
                mismatch_note: bool = False):
        p = sub.add_parser(name, help=summary, description=summary[0].upper() + summary[1:] + ".",
                           epilog="examples:\n" + EXAMPLES[name]
                           + ("\n" + OUTPUT_NOTE if output_note else "")
                           + ("\n" + MISMATCH_NOTE if mismatch_note else ""),
                           formatter_class=fmt)
        p.add_argument("file", help="the technique, a .pipe file")
        p.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                       type=param_arg,
                       help="override a parameter, checked against its allowed values "
                            "(repeatable; default: the values the file declares)")
        p.set_defaults(func=func, parser=p)
        return p

    def strict(p: argparse.ArgumentParser, needs_scene: bool = False) -> None:
        p.add_argument("--strict", action="store_true",
                       help="what the technique will not render of the scene is an error "
                            "(exit 1) instead of a warning"
                            + (" (needs --scene)" if needs_scene else "")
                            + " (default: warn)")

    def specialise(p: argparse.ArgumentParser) -> None:
        p.add_argument("--specialise", action="store_true",
                       help="render the variant compiled for this scene's features (culled "
                            "passes and targets never run; see pipegen specialise) "
                            "(default: the general technique)")

    def scene_and_size(p: argparse.ArgumentParser) -> None:
        """The scene a command renders and its size (run, check)."""
        p.add_argument("--scene", metavar="FILE",
                       help="scene .toml, or a glTF file (.gltf, .glb) (default: the built-in "
                            "default scene)")
        p.add_argument("--size", type=size_arg, metavar="WxH",
                       help=f"output size (default: the scene file's width x height, "
                            f"{DEFAULT_SIZE_TEXT} for the built-in scene; each side 1..{MAX_SIZE})")

    def force(p: argparse.ArgumentParser) -> None:
        p.add_argument("--force", action="store_true",
                       help="write into an output folder that holds files pipegen did not "
                            "write (they are kept, unless an output has the same name; "
                            "default: refuse)")

    c = command("compile", "emit shaders, pipeline modules and a report", cmd_compile)
    c.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="output folder (required; only files pipegen wrote are replaced)")
    c.add_argument("--size", type=size_arg, default=DEFAULT_SIZE, metavar="WxH",
                   help=f"output size the report's memory figures assume "
                        f"(default: {DEFAULT_SIZE_TEXT}; each side 1..{MAX_SIZE})")
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
    strict(c, needs_scene=True)
    force(c)

    r = command("run", "render a scene, one PNG + .npy per target", cmd_run,
                mismatch_note=True)
    r.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="output folder (required; only files pipegen wrote are replaced)")
    scene_and_size(r)
    r.add_argument("--backend", choices=list(registry.BACKENDS), default="gl",
                   help="; ".join(f"{b.name}: {b.description}" for b in registry.BACKENDS.values())
                   + " (default: gl)")
    r.add_argument("--precision", choices=("f32", "f64"), default="f32",
                   help="f64: the float64 evaluation of the technique (with --backend cl): "
                        "its arithmetic in double, targets unquantised; the PNGs and .npy "
                        "files hold it quantised to each target's format (default: f32)")
    specialise(r)
    strict(r)
    force(r)

    k = command("check", "render on GL and CL, compare every target", cmd_check,
                mismatch_note=True)
    scene_and_size(k)
    k.add_argument("-o", "--out", metavar="DIR",
                   help="folder for the error images (default: build/check/<technique>)")
    k.add_argument("--precision", choices=("f32", "f64"), default="f32",
                   help="f64: instead of GL against CL, each float32 backend against the "
                        "technique's float64 evaluation (CL), the precision error per target "
                        "in codes/ulps (a measurement: exit status 0) (default: f32)")
    specialise(k)
    strict(k)
    force(k)

    sp = command("specialise", "show what a scene lets a technique cut, and why", cmd_specialise,
                 output_note=False, mismatch_note=True)
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
    strict(sp)

    g = command("graph", "draw passes and targets as a graph (SVG, PNG or DOT)", cmd_graph,
                output_note=False)
    g.add_argument("-o", "--out", required=True, metavar="G.svg", type=graph_path_arg,
                   help="the graph file: .svg, .png or .pdf rendered with Graphviz's dot "
                        "when installed (otherwise the DOT text is written beside, as .dot), "
                        ".dot or .gv for the DOT text (required)")
    g.add_argument("--scene", metavar="FILE",
                   help="specialise for this scene and grey out what is culled, with the "
                        "reason (default: the general technique)")
    g.add_argument("--size", type=size_arg, default=DEFAULT_SIZE, metavar="WxH",
                   help=f"output size the target sizes and memory assume "
                        f"(default: {DEFAULT_SIZE_TEXT}; each side 1..{MAX_SIZE})")

    i = command("info", "list parameters, targets, passes and packing schemes", cmd_info,
                output_note=False)
    i.add_argument("--size", type=size_arg, default=DEFAULT_SIZE, metavar="WxH",
                   help=f"output size the target sizes and bytes assume "
                        f"(default: {DEFAULT_SIZE_TEXT}; each side 1..{MAX_SIZE})")

    if command_word in COMMANDS:
        return parser
    from pipegen.tools.sweep.command import add_parser as add_sweep  # `pipegen sweep`: tools/sweep/
    add_sweep(sub, size_arg, OUTPUT_NOTE, DEFAULT_SIZE_TEXT, MAX_SIZE)
    from pipegen.tools.stress.command import add_parser as add_stress  # `pipegen stress`: pipegen/stress/
    add_stress(sub, size_arg, OUTPUT_NOTE)
    return parser


# -- argument types (errors here are usage errors: exit status 2) ------------------------------


def size_arg(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(-?\d+)\s*[xX]\s*(-?\d+)\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(
            f"bad size {text!r}: write WIDTHxHEIGHT, e.g. 640x360 (each side 1..{MAX_SIZE})")
    w, h = int(m.group(1)), int(m.group(2))
    if not (1 <= w <= MAX_SIZE and 1 <= h <= MAX_SIZE):
        raise argparse.ArgumentTypeError(
            f"bad size {text!r}: width and height must each be 1..{MAX_SIZE} pixels")
    return w, h


def graph_path_arg(text: str) -> str:
    from pipegen.views.graph import SUFFIXES
    if Path(text).suffix.lower() not in SUFFIXES:
        raise argparse.ArgumentTypeError(
            f"bad graph file {text!r}: name it with one of {', '.join(SUFFIXES)}, "
            f"e.g. -o graph.svg")
    return text


def param_arg(text: str) -> tuple[str, object]:
    try:
        return param_pair(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def dump_after_arg(text: str) -> frozenset | str:
    """``--dump-after``: ``all`` or pass names (comma-separated), each one a compile may run."""
    from pipegen.passes.pipelines import all_pass_names
    if text.strip() == "all":
        return "all"
    names = frozenset(n.strip() for n in text.split(",") if n.strip())
    unknown = sorted(names - set(all_pass_names()))
    if unknown or not names:
        raise argparse.ArgumentTypeError(
            f"unknown pass {', '.join(map(repr, unknown)) or repr(text)}: the passes are "
            f"{', '.join(all_pass_names())} (or all)")
    return names


def parse_size(text: str) -> tuple[int, int]:
    """``WxH`` -> (w, h); a ``PipegenError`` when malformed or out of range."""
    try:
        return size_arg(text)
    except argparse.ArgumentTypeError as e:
        raise PipegenError(None, str(e)) from None


def _join_negative_sizes(argv: list[str]) -> list[str]:
    """``--size -5x10``: argparse would take ``-5x10`` for an option; pass it as the value so
    the size check can say what is wrong with it."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] == "--size" and i + 1 < len(argv) and re.match(r"-\d", argv[i + 1]):
            out.append("--size=" + argv[i + 1])
            i += 2
            continue
        out.append(argv[i])
        i += 1
    return out


# -- commands ----------------------------------------------------------------------------------


def cmd_compile(args) -> int:
    from pipegen.core.outdir import OutputDir
    if args.strict and not args.scene:
        args.parser.error("--strict needs --scene: a scene to check the technique against")
    watch = _dump_watch(args)
    out = OutputDir(args.out, "compile", args.force)          # before any work
    compiled = _compile(args, watch)
    if args.scene:
        scene = _scene(args, size=False)
        compiled = _specialise(args, compiled, scene, watch=watch)
        report_mismatches(compiled, scene, args.strict, _scene_label(args))
    backends = tuple(registry.BACKENDS) if args.backend == "all" else (args.backend,)
    compiled.write(out, backends, args.size)
    print(compiled.report(args.size), end="")
    print(f"wrote {out}/")
    return 0


def cmd_run(args) -> int:
    from pipegen.core.outdir import OutputDir
    out = OutputDir(args.out, "run", args.force)              # before any work
    compiled = _compile(args)
    scene = _scene(args)
    if args.specialise:
        compiled = _specialise(args, compiled, scene, say_variant=True)
    report_mismatches(compiled, scene, args.strict, _scene_label(args))
    from pipegen.views.outputs import file_name, write_render
    pipeline = compiled.pipeline(args.backend, precision=args.precision)
    print(f"rendering {compiled.name} on {args.backend} at {scene.width}x{scene.height} "
          f"({len(scene.objects)} objects, {len(scene.lights)} lights)", file=sys.stderr)
    targets = pipeline.render(scene)
    if args.precision != "f32":      # float64 values: written as the codes they quantise to
        from pipegen.proof.precision import quantize_targets
        targets = quantize_targets(compiled.technique, targets)
    write_render(compiled, scene, targets, out)
    for name in sorted(targets):
        print(f"  {out.path / file_name(name, '.png')}")
    return 0


def cmd_check(args) -> int:
    from pipegen.core.outdir import OutputDir
    out = OutputDir(args.out, "check", args.force) if args.out else None
    compiled = _compile(args)
    scene = _scene(args)
    if out is None:
        out = OutputDir(Path("build/check") / compiled.name, "check", args.force)
    if args.specialise:
        compiled = _specialise(args, compiled, scene, say_variant=True)
    found = report_mismatches(compiled, scene, args.strict, _scene_label(args))
    if args.precision != "f32":      # the float32 backends against the float64 evaluation
        from pipegen.proof.precision import main_precision_check
        return main_precision_check(compiled, scene, out)
    from pipegen.proof.check import main_check
    return main_check(compiled, scene, out, mismatches=found)


def cmd_specialise(args) -> int:
    compiled = _compile(args)
    scene = _scene(args)
    special = _specialise(args, compiled, scene)
    spec = special.specialisation
    w, h = scene.width, scene.height
    found = special.mismatches(scene)
    if found and args.strict:
        raise mismatch_error(special, found, _scene_label(args))
    lines = [f"{compiled.name} on {_scene_label(args)} ({len(scene.objects)} objects, "
             f"{len(scene.lights)} lights)", "", "scene features",
             *[f"  {x}" for x in spec.features.describe()], "",
             "not rendered for this scene" + (" (--strict makes this an error)" if found else ""),
             *([f"  {m.message}" for m in found]
               or ["  nothing: the technique renders everything this scene has"]), "",
             *spec.report(w, h)]
    print("\n".join(lines))
    if not args.verify:
        return 0
    from pipegen.compiler.specialise import verify
    backends = tuple(registry.BACKENDS) if args.backend == "all" else (args.backend,)
    print(f"  … rendering general and specialised on {', '.join(backends)} at {w}x{h}",
          file=sys.stderr)
    result = verify(compiled, special, scene, backends)
    print("", f"verify at {w}x{h}: every target the specialised pipeline produces, bit for bit",
          sep="\n")
    for b in backends:
        names, bad = result.compared[b], result.differences[b]
        title = registry.get(b).title
        if not bad:
            print(f"  {title}: {len(names)} targets identical ({', '.join(names)})")
        else:
            print(f"  {title}: {len(bad)} of {len(names)} targets differ ({', '.join(bad)}); "
                  f"first differing pass: {result.first_difference[b] or 'not localised'}")
    if result.identical:
        print("identical: the specialised pipeline renders what the general one renders")
        return 0
    first = next(result.first_difference[b] for b in backends if result.differences[b])
    print(f"error: the specialised pipeline differs from the general one; first differing "
          f"pass: {first or 'not localised'}", file=sys.stderr)
    return 1


def cmd_graph(args) -> int:
    from pipegen.views.graph import build_dot, write_graph
    compiled = _compile(args)
    if args.scene:
        compiled = _specialise(args, compiled, _scene(args, size=False))
    path, rendered = write_graph(build_dot(compiled, args.size), args.out)
    if rendered or Path(args.out).suffix.lower() == path.suffix.lower():
        print(f"wrote {path}")
    else:
        print(f"wrote {path} (the DOT text: Graphviz's dot is not installed, so no "
              f"{Path(args.out).suffix} was drawn)")
        print(f"hint: install Graphviz (apt-get install graphviz), or draw it with "
              f"dot -T{Path(args.out).suffix[1:].lower()} {path} -o {args.out}", file=sys.stderr)
    return 0


def cmd_info(args) -> int:
    from pipegen.views.info import describe
    compiled = _compile(args)
    defaults = None
    if args.param:
        from pipegen.compiler.driver import compile_file
        defaults = {p.name: p.default for p in compile_file(args.file).technique.params}
    print(describe(compiled, args.size, defaults), end="")
    return 0


def _dump_watch(args):
    """``--dump-after``: a ``Watch`` printing the IR after the passes named (None: none), a
    usage error (exit 2) for a scene pass without ``--scene``."""
    if not args.dump_after:
        return None
    from pipegen.passes.manager import Watch
    from pipegen.passes.pipelines import GENERAL, SCENE, pass_names
    if not args.scene and args.dump_after != "all":
        scene_only = sorted(args.dump_after - set(pass_names(GENERAL)))
        if scene_only:
            args.parser.error(f"--dump-after {', '.join(scene_only)}: runs only with --scene "
                              f"(the passes are {', '.join(pass_names(GENERAL))}; with --scene "
                              f"also {', '.join(pass_names(SCENE))})")

    def dump(name, tech) -> None:
        from pipegen.ir.printer import print_technique
        print(f"// after {name}\n{print_technique(tech)}", flush=True)
    return Watch(dump_after=args.dump_after, dump=dump)


def _compile(args, watch=None):
    """Compile ``args.file`` with ``args.param``; a scene file given instead says so."""
    return compile_technique(args.file, args.param, watch=watch)


def _specialise(args, compiled, scene, say_variant: bool = False, watch=None):
    """``compiled`` specialised for ``scene`` (the light table recompiled smaller, as
    ``compile_file(..., scene=)`` does); with ``say_variant``, whether the variant was compiled
    or reused from this process's cache, on stderr.  ``watch``: what to show of the passes."""
    from pipegen.compiler.driver import compile_file
    from pipegen.compiler.specialise import specialise
    special = specialise(compiled, scene, watch=watch,
                         recompile=lambda ps: compile_file(args.file, ps, watch=watch))
    if say_variant:
        spec = special.specialisation
        print(f"variant: {'reused' if spec.reused else 'compiled'} (specialised for "
              f"{spec.facts.describe()}; {len(spec.cuts)} cuts, passes "
              f"{len(spec.general.passes)} -> {len(special.technique.passes)})",
              file=sys.stderr)
    return special


def mismatch_error(compiled, found, label: str) -> PipegenError:
    return PipegenError(None, f"{compiled.name} will not render all of {label} (--strict):\n"
                        + "\n".join(f"  {m.message}" for m in found),
                        hint="without --strict these are warnings and the scene is rendered "
                             "anyway; or choose a technique that renders what the scene has")


def report_mismatches(compiled, scene, strict: bool, label: str) -> list:
    """What ``compiled`` will not render of ``scene``: a warning line each on stderr, or with
    ``strict`` a ``PipegenError`` listing them all (never a silently wrong image)."""
    found = compiled.mismatches(scene)
    if found and strict:
        raise mismatch_error(compiled, found, label)
    for m in found:
        print(f"warning: part of {label} will not be rendered: {m.message}", file=sys.stderr)
    note = unused_cost_note(compiled, scene)
    if note:
        print(f"note: {note}", file=sys.stderr)
    return found


def unused_cost_note(compiled, scene) -> str | None:
    """What the general build computes that ``scene`` does not call for, when it costs frame
    time: shadow-map passes and lookups with no shadow-casting light (llvmpipe runs the
    untaken lookup under a mask: forward on many_lights 1.6x slower).  None when specialised
    or when there is nothing to say."""
    if compiled.specialisation is not None:
        return None
    if not any(p.draw.shadow for p in compiled.technique.passes):
        return None
    from pipegen.scene.shadows import shadow_lights
    if shadow_lights(scene.lights):
        return None
    return ("no light in this scene casts shadows, but this build still clears the shadow "
            "atlas and runs the shadow lookup for every light; --specialise removes both "
            "(docs/specialise.md)")


def _scene_label(args) -> str:
    return args.scene if args.scene else "the built-in default scene"


def _scene(args, size: bool = True):
    from pipegen.scene.load import default_scene, load_scene
    if args.scene:
        if Path(args.scene).suffix.lower() == ".pipe":
            raise PipegenError(None, f"{args.scene}: this looks like a technique (.pipe), not a "
                                     f"scene file (.toml)",
                               hint="the technique is the first argument; --scene takes a "
                                    "scene .toml, e.g. examples/scenes/small.toml")
        import warnings
        from pipegen.scene.load import SceneLoadWarning
        with warnings.catch_warnings():        # printed below as notes, once, not as warnings
            warnings.simplefilter("ignore", SceneLoadWarning)
            scene = load_scene(args.scene)
        for note in getattr(scene, "notes", ()):
            print(f"note: {note}", file=sys.stderr)
    else:
        scene = default_scene().with_size(*DEFAULT_SIZE)
    if size and getattr(args, "size", None):
        scene = scene.with_size(*args.size)
    return scene

