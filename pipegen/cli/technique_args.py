"""The technique a command names (``file``, ``-p``), compiled, shown pass by pass
(``--dump-after``) and specialised for a scene, shared by the commands."""

from __future__ import annotations

import sys

from pipegen.compiler.inputs import compile_technique


def dump_watch(args):
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


def compile_from_args(args, watch=None):
    """Compile ``args.file`` with ``args.param``; a scene file given instead says so."""
    return compile_technique(args.file, args.param, watch=watch)


def specialise_from_args(args, compiled, scene, watch=None):
    """``compiled`` specialised for ``scene`` (the light table recompiled smaller, as
    ``compile_file(..., scene=)`` does).  ``watch``: what to show of the passes."""
    from pipegen.compiler.driver import compile_file
    from pipegen.compiler.specialise import specialise
    return specialise(compiled, scene, watch=watch,
                      recompile=lambda ps: compile_file(args.file, ps, watch=watch))


def rendered_build(args, compiled, scene, cuts: bool = False):
    """What ``run`` and ``check`` render: the variant compiled for ``scene`` (the light table
    shrunk), or with ``--general`` the general build.  On stderr, whether the variant was
    compiled or reused from this process's cache, and with ``cuts`` what the scene let it cut,
    one line per cut with its reason."""
    from pipegen.compiler.driver import for_scene
    special = for_scene(compiled, scene, args.general, args.file)
    spec = special.specialisation
    if spec is None:
        return special
    print(f"variant: {'reused' if spec.reused else 'compiled'} (specialised for "
          f"{spec.facts.describe()}; {len(spec.cuts)} cuts, passes "
          f"{len(spec.general.passes)} -> {len(special.technique.passes)}; --general renders "
          f"the general build)", file=sys.stderr)
    if cuts:
        for line in cut_lines(spec):
            print(line, file=sys.stderr)
    return special


def cut_lines(spec) -> list[str]:
    """What the scene let the variant cut, one indented line per cut (its reason), or a line
    saying nothing was."""
    return [f"  {c.describe()}" for c in spec.cuts] or \
        ["  nothing cut: the scene calls for every pass, target and branch"]
