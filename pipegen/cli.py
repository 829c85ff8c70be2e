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

from . import DEFAULT_SIZE
from .backends import registry
from .diagnostics import PipegenError

MAX_SIZE = 16384          # per side: GL_MAX_TEXTURE_SIZE of llvmpipe
DEFAULT_SIZE_TEXT = f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}"

EXAMPLES = {
    "compile": """\
  pipegen compile pipelines/lidr_bitplanes.pipe -o build/lidr
      GLSL + pipeline_gl.py, OpenCL C + pipeline_cl.py, and report.txt in build/lidr/
  pipegen compile pipelines/inferred.pipe -p lbuffer_scale=0.5 --size 1920x1080 -o build/inferred
      with a parameter overridden; the report's memory figures at 1920x1080
""",
    "run": """\
  pipegen run pipelines/forward.pipe -o out/forward
      render the built-in default scene: one PNG and one .npy per target
  pipegen run pipelines/deferred.pipe --scene examples/scenes/many_lights.toml --size 640x360 -o out/deferred
  pipegen run pipelines/forward.pipe --backend cl -o out/forward-cl
      the same technique on the PoCL software reference
  pipegen run pipelines/inferred.pipe -p lbuffer_scale=0.5 -o out/inferred
""",
    "check": """\
  pipegen check pipelines/lidr_bitplanes.pipe
      GL vs CL on the built-in scene, one row per target; error images in build/check/lidr_bitplanes/
  pipegen check pipelines/lidr_max_stencil.pipe --scene examples/scenes/stress_overlap.toml
      exit 1 and the first divergent pass on disagreement
""",
    "info": """\
  pipegen info pipelines/inferred.pipe
      parameters, targets (bytes at 1280x720), passes and packing schemes
  pipegen info pipelines/inferred.pipe -p lbuffer_scale=0.5 --size 1920x1080
""",
}

OUTPUT_NOTE = """\
output folders (-o): created if missing; pipegen writes a manifest (.pipegen-manifest.json) of
the files it wrote, replaces only those on the next run, and never deletes or overwrites a file
it did not write.  A non-empty folder it did not write is refused unless --force.
"""


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(_join_negative_sizes(sys.argv[1:] if argv is None else argv))
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


def build_parser() -> argparse.ArgumentParser:
    from . import __version__
    fmt = argparse.RawDescriptionHelpFormatter
    everything = "".join(EXAMPLES[c] for c in ("compile", "run", "check", "info"))
    parser = argparse.ArgumentParser(
        prog="pipegen",
        description="Compile real-time rendering techniques (.pipe files) to GLSL + moderngl "
                    "and OpenCL C + PoCL pipelines, run them, and check one against the other.",
        epilog="examples:\n" + everything + "\n" + OUTPUT_NOTE, formatter_class=fmt)
    parser.add_argument("--version", action="version", version=f"pipegen {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    def command(name: str, summary: str, func, output_note: bool = True):
        p = sub.add_parser(name, help=summary, description=summary[0].upper() + summary[1:] + ".",
                           epilog="examples:\n" + EXAMPLES[name]
                           + ("\n" + OUTPUT_NOTE if output_note else ""),
                           formatter_class=fmt)
        p.add_argument("file", help="the technique, a .pipe file")
        p.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                       type=param_arg,
                       help="override a parameter, checked against its allowed values "
                            "(repeatable; default: the values the file declares)")
        p.set_defaults(func=func)
        return p

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
    force(c)

    r = command("run", "render a scene, one PNG + .npy per target", cmd_run)
    r.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="output folder (required; only files pipegen wrote are replaced)")
    r.add_argument("--scene", metavar="FILE",
                   help="scene .toml (default: the built-in default scene)")
    r.add_argument("--size", type=size_arg, metavar="WxH",
                   help=f"output size (default: the scene file's width x height, "
                        f"{DEFAULT_SIZE_TEXT} for the built-in scene; each side 1..{MAX_SIZE})")
    r.add_argument("--backend", choices=list(registry.BACKENDS), default="gl",
                   help="; ".join(f"{b.name}: {b.description}" for b in registry.BACKENDS.values())
                   + " (default: gl)")
    force(r)

    k = command("check", "render on GL and CL, compare every target", cmd_check)
    k.add_argument("--scene", metavar="FILE",
                   help="scene .toml (default: the built-in default scene)")
    k.add_argument("--size", type=size_arg, metavar="WxH",
                   help=f"output size (default: the scene file's width x height, "
                        f"{DEFAULT_SIZE_TEXT} for the built-in scene; each side 1..{MAX_SIZE})")
    k.add_argument("-o", "--out", metavar="DIR",
                   help="folder for the error images (default: build/check/<technique>)")
    force(k)

    i = command("info", "list parameters, targets, passes and packing schemes", cmd_info,
                output_note=False)
    i.add_argument("--size", type=size_arg, default=DEFAULT_SIZE, metavar="WxH",
                   help=f"output size the target sizes and bytes assume "
                        f"(default: {DEFAULT_SIZE_TEXT}; each side 1..{MAX_SIZE})")

    from .sweep import add_parser as add_sweep          # `pipegen sweep`: pipegen/sweep.py
    add_sweep(sub, size_arg, OUTPUT_NOTE, DEFAULT_SIZE_TEXT, MAX_SIZE)
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


def param_arg(text: str) -> tuple[str, object]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(
            f"bad parameter override {text!r}: write NAME=VALUE, e.g. -p lbuffer_scale=0.5")
    return name.strip(), _literal(value.strip())


def parse_size(text: str) -> tuple[int, int]:
    """``WxH`` -> (w, h); a ``PipegenError`` when malformed or out of range."""
    try:
        return size_arg(text)
    except argparse.ArgumentTypeError as e:
        raise PipegenError(None, str(e)) from None


def parse_params(items: list) -> dict:
    """``["NAME=VALUE", ...]`` (or already-parsed pairs) -> ``{name: value}``."""
    params = {}
    for item in items:
        if isinstance(item, str):
            try:
                item = param_arg(item)
            except argparse.ArgumentTypeError as e:
                raise PipegenError(None, str(e)) from None
        params[item[0]] = item[1]
    return params


def _literal(text: str):
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    if text in ("true", "false"):
        return text == "true"
    return text


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
    from .outdir import OutputDir
    out = OutputDir(args.out, "compile", args.force)          # before any work
    compiled = _compile(args)
    backends = tuple(registry.BACKENDS) if args.backend == "all" else (args.backend,)
    compiled.write(out, backends, args.size)
    print(compiled.report(args.size), end="")
    print(f"wrote {out}/")
    return 0


def cmd_run(args) -> int:
    from .outdir import OutputDir
    out = OutputDir(args.out, "run", args.force)              # before any work
    compiled = _compile(args)
    scene = _scene(args)
    from .outputs import file_name, write_render
    pipeline = compiled.pipeline(args.backend)
    print(f"rendering {compiled.name} on {args.backend} at {scene.width}x{scene.height} "
          f"({len(scene.objects)} objects, {len(scene.lights)} lights)", file=sys.stderr)
    targets = pipeline.render(scene)
    write_render(compiled, scene, targets, out)
    for name in sorted(targets):
        print(f"  {out.path / file_name(name, '.png')}")
    return 0


def cmd_check(args) -> int:
    from .outdir import OutputDir
    out = OutputDir(args.out, "check", args.force) if args.out else None
    compiled = _compile(args)
    scene = _scene(args)
    if out is None:
        out = OutputDir(Path("build/check") / compiled.name, "check", args.force)
    from .check import main_check
    return main_check(compiled, scene, out)


def cmd_info(args) -> int:
    from .info import describe
    compiled = _compile(args)
    defaults = None
    if args.param:
        from .compiler import compile_file
        defaults = {p.name: p.default for p in compile_file(args.file).technique.params}
    print(describe(compiled, args.size, defaults), end="")
    return 0


def _compile(args):
    """Compile ``args.file`` with ``args.param``; a scene file given instead says so."""
    from .compiler import compile_file
    path = Path(args.file)
    if path.suffix.lower() == ".toml":
        raise _scene_not_technique(path)
    try:
        return compile_file(path, parse_params(args.param))
    except PipegenError:
        if _looks_like_scene(path):
            raise _scene_not_technique(path) from None
        raise


def _scene(args):
    from .scene import default_scene, load_scene
    if args.scene:
        if Path(args.scene).suffix.lower() == ".pipe":
            raise PipegenError(None, f"{args.scene}: this looks like a technique (.pipe), not a "
                                     f"scene file (.toml)",
                               hint="the technique is the first argument; --scene takes a "
                                    "scene .toml, e.g. examples/scenes/small.toml")
        scene = load_scene(args.scene)
    else:
        scene = default_scene().with_size(*DEFAULT_SIZE)
    if args.size:
        scene = scene.with_size(*args.size)
    return scene


def _looks_like_scene(path: Path) -> bool:
    import tomllib
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return bool({"camera", "objects", "lights"} & set(data))


def _scene_not_technique(path: Path) -> PipegenError:
    return PipegenError(None, f"{path}: this looks like a scene file (.toml), not a technique "
                              f"(.pipe)",
                        hint=f"the first argument is the technique; give the scene with "
                             f"--scene, e.g. pipegen run pipelines/forward.pipe --scene {path} "
                             f"-o out/forward")


if __name__ == "__main__":
    sys.exit(main())
