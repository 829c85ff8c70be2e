"""What both runtimes decide the same way: the light-capacity check, which lights a light
draw instances, and parameter overrides at render time."""

from __future__ import annotations

from typing import Optional

import numpy as np

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


def light_type(light) -> str:
    """A scene light's type name (``point``, ``spot``, ``directional``; ints as the table
    codes them)."""
    t = getattr(light, "type", "point")
    if isinstance(t, (int, np.integer)):
        return {0: "point", 1: "spot", 2: "directional"}.get(int(t), str(t))
    return str(t)


def light_filter(draw: dict) -> bool:
    """Whether a light draw instances only some lights (a type filter or a light set)."""
    return bool(draw.get("light_types") or draw.get("light_set"))


def light_list(draw: dict, lights: list, plan: dict, light_sets: dict,
               dropped: Optional[dict] = None) -> list[int]:
    """The lights (table indices, in table order) a light draw instances: all of them, those
    of the draw's ``light_types``, and/or those of its CPU-sorted ``light_set`` ``(pack, k)``
    (``packing.sort_lights_into_slots`` into ``plan["light_sets"][pack]`` slots, default 4).

    ``light_sets`` caches the sorted sets per pack for the scene (the caller clears it when
    the scene changes); ``dropped`` receives, per pack, the lights no set could take."""
    idx = list(range(len(lights)))
    types = draw.get("light_types") or []
    if types:
        idx = [i for i in idx if light_type(lights[i]) in types]
    light_set = draw.get("light_set")
    if light_set:
        pack, k = light_set[0], int(light_set[1])
        if pack not in light_sets:
            from ..packing import sort_lights_into_slots
            slots = int((plan.get("light_sets") or {}).get(pack, 4))
            centers = [tuple(getattr(l, "position", (0.0, 0.0, 0.0))) for l in lights]
            radii = [float(getattr(l, "radius", 0.0)) for l in lights]
            sets, dropped_ = sort_lights_into_slots(centers, radii, slots)
            light_sets[pack] = [list(map(int, s)) for s in sets]
            if dropped is not None:
                dropped[pack] = [int(i) for i in dropped_]
        chosen = set(light_sets[pack][k]) if k < len(light_sets[pack]) else set()
        idx = [i for i in idx if i in chosen]
    return idx


def check_param_overrides(plan: dict, params) -> None:
    """``render(scene, params)``: parameters are compile-time constants (the specialise phase
    folds them into the shaders), so a value other than the compiled one needs a recompile."""
    if not params:
        return
    compiled = plan.get("params") or {}
    for name, value in params.items():
        if name not in compiled:
            raise ValueError(f"unknown parameter '{name}' (the technique has: "
                             f"{', '.join(compiled) or 'none'})")
        if value != compiled[name]:
            raise ValueError(f"parameter '{name}' was compiled in as {compiled[name]!r}; "
                             f"recompile with {name}={value!r} to change it")
