"""The scene a command renders (``--scene``, ``--size``) and what the technique will not render
of it, shared by the commands: warnings on stderr, or with ``--strict`` an error (exit 1)."""

from __future__ import annotations

import sys
from pathlib import Path

from pipegen.core.defaults import DEFAULT_SIZE
from pipegen.core.diagnostics import PipegenError


def scene_label(args) -> str:
    return args.scene if args.scene else "the built-in default scene"


def load_scene_arg(args, size: bool = True):
    """The scene of ``args.scene`` (the built-in default scene without it), its load notes
    printed on stderr; resized to ``args.size`` when ``size`` and the command has one."""
    from pipegen.scene.load import default_scene, load_scene_noting
    if args.scene:
        if Path(args.scene).suffix.lower() == ".pipe":
            raise PipegenError(None, f"{args.scene}: this looks like a technique (.pipe), not a "
                                     f"scene file (.toml)",
                               hint="the technique is the first argument; --scene takes a "
                                    "scene .toml, e.g. examples/scenes/small.toml")
        scene = load_scene_noting(args.scene)      # notes printed once, not as warnings
    else:
        scene = default_scene().with_size(*DEFAULT_SIZE)
    if size and getattr(args, "size", None):
        scene = scene.with_size(*args.size)
    return scene


def mismatch_error(compiled, found, label: str) -> PipegenError:
    return PipegenError(None, f"{compiled.name} will not render all of {label} (--strict):\n"
                        + "\n".join(f"  {m.message}" for m in found),
                        hint="without --strict these are warnings and the scene is rendered "
                             "anyway; or choose a technique that renders what the scene has")


def report_mismatches(compiled, scene, strict: bool, label: str, note: bool = True) -> list:
    """What ``compiled`` will not render of ``scene``: a warning line each on stderr, or with
    ``strict`` a ``PipegenError`` listing them all (never a silently wrong image).  Asked of
    the general technique (a variant's culled passes would change the wording).  ``note``:
    also say what ``compiled`` computes that the scene does not call for (when it renders:
    ``--general``)."""
    found = compiled.mismatches(scene)
    if found and strict:
        raise mismatch_error(compiled, found, label)
    for m in found:
        print(f"warning: part of {label} will not be rendered: {m.message}", file=sys.stderr)
    said = unused_cost_note(compiled, scene) if note else None
    if said:
        print(f"note: {said}", file=sys.stderr)
    return found


def unused_cost_note(compiled, scene) -> str | None:
    """What the general build computes that ``scene`` does not call for, when it costs frame
    time: shadow-map passes and lookups with no shadow-casting light (llvmpipe runs the
    untaken lookup under a mask: forward on many_lights 1.6x slower): said only of a general
    build (``--general``).  None when specialised or when there is nothing to say."""
    if compiled.specialisation is not None:
        return None
    if not any(p.draw.shadow for p in compiled.technique.passes):
        return None
    from pipegen.scene.shadows import shadow_lights
    if shadow_lights(scene.lights):
        return None
    return ("no light in this scene casts shadows, but this build still clears the shadow "
            "atlas and runs the shadow lookup for every light; without --general the "
            "variant compiled for the scene removes both (docs/specialise.md)")
