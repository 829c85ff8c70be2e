"""Checks on the scene's lights shared by both runtimes."""

from __future__ import annotations

from ..diagnostics import PipegenError


def check_light_capacity(lights: int, capacity: int, plan: dict) -> None:
    """A scene with more lights than the technique's light table is a user error."""
    if lights <= capacity:
        return
    hint = (f"the technique declares lights[{capacity}]; compile it with a larger table"
            + (", e.g. -p max_lights=" + str(lights) if "max_lights" in plan.get("params", {})
               else "") + " or use a scene with fewer lights")
    raise PipegenError(None, f"the scene has {lights} lights but technique "
                             f"'{plan.get('technique', '?')}' holds {capacity}", hint=hint)
