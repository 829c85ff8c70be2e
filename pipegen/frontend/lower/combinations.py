"""Technique-wide rules about passes that combine: stencil shadow volumes with the light-volume
front-face technique.

Trebilco, "Shadows" / "Shadow volumes": "Shadow volumes work easily with LIDR lights. Once the
shadow volume has marked the stencil buffer to indicate where the shadowed areas are, the light
volumes can be rendered to ignore these areas.  However this will not work if using the Light
Volume Front Faces technique for MSAA / Transparency support."

Why: the stencil a shadow-volume pass leaves holds one answer per pixel, for the opaque surface
there.  The front-face technique ("Light Volume Front Faces", lidr_transparent.pipe) writes a
light's index for the whole view ray, so that the translucent surfaces in front of the opaque
one, and the pixel's other samples, find every light that may reach them.  A light volume that
tests the shadow stencil would drop the light for all of those whenever the opaque surface
behind them is shadowed, although they may be lit.

In the language, combining means: a pass that draws light volumes' front faces (``cull back``,
or ``cull auto``, which draws them for lights the camera is outside of) with a stencil test, on
a depth/stencil target that a ``draw scene… shadow_volumes`` pass of the technique counts into.
That is a positioned error at the pass's ``cull`` statement.
"""

from __future__ import annotations

from pipegen.frontend import ast
from pipegen.ir import nodes as ir
from pipegen.frontend.lower.collect import PassItem
from pipegen.frontend.lower.names import error

_FRONT_FACES = (ir.CullMode.BACK, ir.CullMode.AUTO)


def _tests_stencil(p: ir.Pass) -> bool:
    s = p.state.stencil
    return any(f.func is not ir.CompareFunc.ALWAYS for f in (s.front, s.back))


def check_shadow_volume_combinations(passes: list[ir.Pass], items: list[PassItem]) -> None:
    """Refuse a light-volume pass drawing front faces that tests a shadow-volume stencil
    (the module docstring); ``passes`` lowered from ``items``, in the same order."""
    counted = {p.depth_target: p for p in passes if p.draw.shadow_volumes}
    if not counted:
        return
    for p, item in zip(passes, items):
        if (p.draw.kind is not ir.DrawKind.LIGHTS or p.state.cull not in _FRONT_FACES
                or p.depth_target not in counted or not _tests_stencil(p)):
            continue
        cull = next(s for s in item.decl.stmts if isinstance(s, ast.Cull))
        volumes = counted[p.depth_target]
        raise error(
            cull.span,
            f"pass '{p.name}' draws light-volume front faces (`cull {p.state.cull.value}`, "
            f"Trebilco's \"Light Volume Front Faces\" technique for MSAA and transparency) and "
            f"tests the stencil that pass '{volumes.name}' counts shadow volumes into: \"this "
            f"will not work if using the Light Volume Front Faces technique for MSAA / "
            f"Transparency support\" (Trebilco, \"Shadows\"). The stencil says whether the "
            f"opaque surface at the pixel is shadowed, but a front-face index serves every "
            f"surface along the view ray (translucent ones in front, the pixel's other "
            f"samples), which may be lit where the opaque surface is not",
            "draw the light volumes' back faces behind the surface (`cull front`, `depth … "
            "gequal`) as lidr_shadow_volumes.pipe does, or shadow these lights with shadow "
            "maps (lidr_shadow_prepass.pipe, lidr_shadow_indexed.pipe)")
