"""``pipegen``: compile, run and check rendering techniques.

Every user error is printed as ``file:line:col``, the line, a caret and a hint, and exits with
status 1 (bad usage of the command line itself exits with 2, argparse's convention).  A
traceback reaching the user for bad input is a bug.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .diagnostics import PipegenError

EXAMPLES = """\
examples:
  pipegen compile pipelines/lidr_bitplanes.pipe -o build/lidr
      GLSL + pipeline_gl.py, OpenCL C + pipeline_cl.py, and report.txt in build/lidr/
  pipegen run pipelines/forward.pipe -o out/forward
      render the built-in default scene: one PNG and one .npy per target
  pipegen run pipelines/deferred.pipe --scene examples/scenes/many_lights.toml --size 640x360 -o out/
  pipegen run pipelines/forward.pipe --backend cl -o out/forward-cl
      the same technique on the PoCL software reference
  pipegen check pipelines/lidr_max_stencil.pipe --scene examples/scenes/stress_overlap.toml
      GL vs CL, one row per target; exit 1 and the first divergent pass on disagreement
"""


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        return args.func(args)
    except PipegenError as e:
        print(e.render(), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pipegen",
        description="Compile real-time rendering techniques (.pipe files) to GLSL + moderngl "
                    "and OpenCL C + PoCL pipelines, run them, and check one against the other.",
        epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    def common(p: argparse.ArgumentParser) -> None:
        p.add_argument("file", help="the technique, a .pipe file")
        p.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                       help="override a parameter (repeatable)")

    c = sub.add_parser("compile", help="emit shaders, pipeline modules and a report",
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    common(c)
    c.add_argument("-o", "--out", required=True, help="output folder (replaced atomically)")
    c.add_argument("--size", default="1280x720", help="output size the report assumes")
    c.add_argument("--backend", choices=["gl", "cl", "all"], default="all")
    c.set_defaults(func=cmd_compile)

    r = sub.add_parser("run", help="render a scene, one PNG + .npy per target",
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    common(r)
    r.add_argument("-o", "--out", required=True, help="output folder (replaced atomically)")
    r.add_argument("--scene", help="scene .toml (default: the built-in default scene)")
    r.add_argument("--size", help="output size WxH (default: the scene's)")
    r.add_argument("--backend", choices=["gl", "cl"], default="gl")
    r.set_defaults(func=cmd_run)

    k = sub.add_parser("check", help="render on GL and CL, compare every target",
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    common(k)
    k.add_argument("--scene", help="scene .toml (default: the built-in default scene)")
    k.add_argument("--size", help="output size WxH (default: the scene's)")
    k.add_argument("-o", "--out", help="folder for the error images "
                                       "(default: build/check/<technique>)")
    k.set_defaults(func=cmd_check)
    return parser


def parse_params(items: list[str]) -> dict:
    params = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise PipegenError(None, f"bad parameter override {item!r}",
                               hint="write NAME=VALUE, e.g. -p lbuffer_scale=0.5")
        params[name.strip()] = _literal(value.strip())
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


def parse_size(text: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    try:
        size = (int(w), int(h))
    except ValueError:
        size = (0, 0)
    if not sep or min(size) < 1 or max(size) > 16384:
        raise PipegenError(None, f"bad size {text!r}", hint="write WIDTHxHEIGHT, e.g. 640x360")
    return size


def cmd_compile(args) -> int:
    from .compiler import compile_file
    compiled = compile_file(args.file, parse_params(args.param))
    backends = ("gl", "cl") if args.backend == "all" else (args.backend,)
    out = compiled.write(args.out, backends)
    print(compiled.report(parse_size(args.size)), end="")
    print(f"wrote {out}/")
    return 0


def cmd_run(args) -> int:
    from .compiler import compile_file
    from .outputs import write_render
    compiled = compile_file(args.file, parse_params(args.param))
    scene = _scene(args)
    pipeline = compiled.pipeline(args.backend)
    print(f"rendering {compiled.name} on {args.backend} at {scene.width}x{scene.height} "
          f"({len(scene.objects)} objects, {len(scene.lights)} lights)", file=sys.stderr)
    targets = pipeline.render(scene)
    out = write_render(compiled, scene, targets, Path(args.out))
    for name in sorted(targets):
        print(f"  {out / (name + '.png')}")
    return 0


def cmd_check(args) -> int:
    from .check import main_check
    from .compiler import compile_file
    compiled = compile_file(args.file, parse_params(args.param))
    scene = _scene(args)
    out = Path(args.out) if args.out else Path("build/check") / compiled.name
    return main_check(compiled, scene, out)


def _scene(args):
    from .scene import default_scene, load_scene
    scene = load_scene(args.scene) if args.scene else default_scene()
    if args.size:
        scene = scene.with_size(*parse_size(args.size))
    return scene


if __name__ == "__main__":
    sys.exit(main())
