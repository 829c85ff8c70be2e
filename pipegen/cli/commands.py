"""The ``pipegen`` subcommands built in (``compile``, ``run``, ``check``, ``specialise``,
``graph``, ``info``, ``test``): each takes the parsed arguments and returns the exit status.
The work itself is in ``compiler/``, ``proof/``, ``views/`` and ``testing/``, imported inside
the commands so that a compile loads none of the render and check code
(tests/test_compile_imports.py)."""

from __future__ import annotations

import sys
from pathlib import Path

from pipegen.backends import registry
from pipegen.core.defaults import DEFAULT_SIZE
from pipegen.core.diagnostics import PipegenError
from pipegen.cli.scene_args import load_scene_arg, mismatch_error, report_mismatches, scene_label
from pipegen.cli.technique_args import (compile_from_args, dump_watch, rendered_build,
                                        specialise_from_args)


def cmd_compile(args) -> int:
    from pipegen.core.outdir import OutputDir
    if args.strict and not args.scene:
        args.parser.error("--strict needs --scene: a scene to check the technique against")
    watch = dump_watch(args)
    out = OutputDir(args.out, "compile", args.force)          # before any work
    compiled = compile_from_args(args, watch)
    for warning in compiled.warnings():
        print(warning, file=sys.stderr)
    if args.scene:
        scene = load_scene_arg(args, size=False)
        compiled = specialise_from_args(args, compiled, scene, watch=watch)
        report_mismatches(compiled, scene, args.strict, scene_label(args))
    backends = tuple(registry.BACKENDS) if args.backend == "all" else (args.backend,)
    compiled.write(out, backends, args.size)
    print(compiled.report(args.size), end="")
    print(f"wrote {out}/")
    return 0


def cmd_run(args) -> int:
    from pipegen.core.outdir import OutputDir
    out = OutputDir(args.out, "run", args.force)              # before any work
    compiled = compile_from_args(args)
    scene = load_scene_arg(args)
    general = compiled
    report_mismatches(general, scene, args.strict, scene_label(args), note=args.general)
    compiled = rendered_build(args, general, scene, cuts=True)
    from pipegen.views.outputs import file_name, write_render
    pipeline = compiled.pipeline(args.backend, precision=args.precision)
    print(f"rendering {compiled.name} on {args.backend} at {scene.width}x{scene.height} "
          f"({len(scene.objects)} objects, {len(scene.lights)} lights)", file=sys.stderr)
    print(f"  device: {registry.get(args.backend).describe_device()}", file=sys.stderr)
    targets = _counting_clamps(compiled, lambda: pipeline.render(scene))
    if args.precision != "f32":      # float64 values: written as the codes they quantise to
        from pipegen.proof.precision import quantize_targets
        targets = quantize_targets(compiled.technique, targets)
    write_render(compiled, scene, targets, out)
    from pipegen.views.visualize import contact_sheet_name
    for name in sorted(targets):
        print(f"  {out.path / file_name(name, '.png')}")
    print(f"  {out.path / contact_sheet_name(targets)}   (every target on one sheet)")
    return 0


def cmd_check(args) -> int:
    from pipegen.core.outdir import OutputDir
    reference = None
    if args.reference is not None or args.reference_samples != 1:
        if args.precision != "f64":
            args.parser.error("--reference and --reference-samples measure the output with "
                              "--precision f64: add it")
        from pipegen.proof.references import check_samples, parse_reference
        check_samples(args.reference_samples)
        if args.reference is not None:     # the text checked before any work
            parse_reference(args.reference, args.reference_samples)
    out = OutputDir(args.out, "check", args.force) if args.out else None
    compiled = compile_from_args(args)
    scene = load_scene_arg(args)
    if out is None:
        out = OutputDir(Path("build/check") / compiled.name, "check", args.force)
    found = report_mismatches(compiled, scene, args.strict, scene_label(args),
                              note=args.general)
    compiled = rendered_build(args, compiled, scene)
    if args.precision != "f32":      # the float32 backends against the float64 evaluation
        from pipegen.proof.precision import main_precision_check
        if args.reference is not None or args.reference_samples != 1:
            from pipegen.proof.references import choose_reference
            reference = choose_reference(args.reference, compiled, args.reference_samples)
        return _counting_clamps(compiled, lambda: main_precision_check(
            compiled, scene, out, reference))
    from pipegen.proof.check import main_check
    return _counting_clamps(compiled, lambda: main_check(
        compiled, scene, out, mismatches=found, max_discontinuities=args.max_discontinuities))


def _counting_clamps(compiled, work):
    """``work()``, then one warning per pass and target whose values the format clamped in
    the CL frames it rendered (runtime/cl/clamps.py; GL never shows them)."""
    from pipegen.proof.clamps import warning_lines
    from pipegen.runtime.cl.clamps import collect
    with collect() as log:
        result = work()
    for line in warning_lines(log.clamps, compiled.technique.output):
        print(line, file=sys.stderr)
    return result


def cmd_specialise(args) -> int:
    compiled = compile_from_args(args)
    scene = load_scene_arg(args)
    special = specialise_from_args(args, compiled, scene)
    found = special.mismatches(scene)
    if found and args.strict:
        raise mismatch_error(special, found, scene_label(args))
    print("\n".join(_specialisation_lines(args, compiled, special, scene, found)))
    if not args.verify:
        return 0
    return _verify(args, compiled, special, scene)


def _specialisation_lines(args, compiled, special, scene, found) -> list[str]:
    """``pipegen specialise``'s report: the scene's features, what the technique will not
    render of it, and the specialisation's cuts and figures."""
    spec = special.specialisation
    return [f"{compiled.name} on {scene_label(args)} ({len(scene.objects)} objects, "
            f"{len(scene.lights)} lights)", "", "scene features",
            *[f"  {x}" for x in spec.features.describe()], "",
            "not rendered for this scene" + (" (--strict makes this an error)" if found else ""),
            *([f"  {m.message}" for m in found]
              or ["  nothing: the technique renders everything this scene has"]), "",
            *spec.report(scene.width, scene.height)]


def _verify(args, compiled, special, scene) -> int:
    """``pipegen specialise --verify``: render general and specialised on the backends asked
    for, print a line per backend; exit status 1 naming the first differing pass."""
    from pipegen.compiler.specialise import verify
    w, h = scene.width, scene.height
    backends = tuple(registry.BACKENDS) if args.backend == "all" else (args.backend,)
    print(f"  … rendering general and specialised on {', '.join(backends)} at {w}x{h}",
          file=sys.stderr)
    result = verify(compiled, special, scene, backends)
    print("", f"verify at {w}x{h}: every target the specialised pipeline produces, bit for bit",
          sep="\n")
    for b in backends:
        names, bad = result.compared[b], result.differences[b]
        title = registry.get(b).label()
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
    compiled = compile_from_args(args)
    size = args.size or DEFAULT_SIZE
    if args.scene:
        scene = load_scene_arg(args, size=False)
        compiled = specialise_from_args(args, compiled, scene)
        size = args.size or (scene.width, scene.height)     # the size run renders it at
    path, rendered = write_graph(build_dot(compiled, size), args.out)
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
    compiled = compile_from_args(args)
    defaults = None
    if args.param:
        from pipegen.compiler.driver import compile_file
        defaults = {p.name: p.default for p in compile_file(args.file).technique.params}
    print(describe(compiled, args.size, defaults), end="")
    return 0



def cmd_test(args) -> int:
    """``pipegen test FILE…``: every expectation of each file, one line each as it is checked;
    exit 1 naming the failed ones (file:line), or when a file has an error or none of the
    files has an expectation (``help_text.TEST_NOTE``)."""
    from pipegen.compiler.inputs import parse_params
    from pipegen.testing.expectations import check_file
    params = parse_params(args.param)
    failed, broken, checked = [], [], 0
    for path in args.files:
        before = checked
        try:
            for outcome in check_file(path, params):
                checked += 1
                print(outcome.line(), flush=True)
                if not outcome.passed:
                    failed.append(outcome.where)
        except PipegenError as e:
            print(e.render(), file=sys.stderr, flush=True)
            broken.append(path)
            continue
        if checked == before:
            print(f"{path}: no expectations (write e.g. `expect color agrees gl cl`; "
                  f"docs/language.md, Expectations)", flush=True)
    if failed or broken:
        what = [f"{len(failed)} of {checked} expectations failed ({', '.join(failed)})"] \
            if failed else []
        what += [f"{len(broken)} file{'s' if len(broken) > 1 else ''} with errors "
                 f"({', '.join(broken)})"] if broken else []
        print(f"error: {'; '.join(what)}", file=sys.stderr)
        return 1
    if not checked:
        print(f"error: no expectations in {', '.join(args.files)}: nothing was tested",
              file=sys.stderr)
        print("hint: an expectation is a line like `expect color agrees gl cl` in the "
              ".pipe file (docs/language.md, Expectations)", file=sys.stderr)
        return 1
    print(f"{checked} expectation{'s' if checked > 1 else ''} hold"
          f"{'s' if checked == 1 else ''}")
    return 0
