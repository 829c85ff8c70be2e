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


def specialise_from_args(args, compiled, scene, say_variant: bool = False, watch=None):
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
