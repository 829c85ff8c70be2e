"""What both runtimes check the same way: a new scene (``check_scene``: a specialised
pipeline's scene assumptions, the light capacity, the shadow tiles) and parameter overrides at
render time.  (Which lights and passes a frame draws is ``draws.py``.)"""

from __future__ import annotations

import math

from pipegen.backends.plan import Plan
from pipegen.core.diagnostics import PipegenError
from pipegen.scene.shadows import shadow_lights, tiles_needed


def check_light_capacity(lights: int, plan: Plan) -> None:
    """A scene with more lights than the technique's light table is a user error."""
    capacity = plan.lights.capacity
    if not plan.lights.fields or lights <= capacity:
        return
    hint = (f"the technique declares lights[{capacity}]; compile it with a larger table"
            + (", e.g. -p max_lights=" + str(lights) if "max_lights" in plan.params else "")
            + " or use a scene with fewer lights")
    raise PipegenError(None, f"the scene has {lights} lights but technique "
                             f"'{plan.technique or '?'}' holds {capacity}", hint=hint)


def check_shadow_capacity(plan: Plan, scene) -> None:
    """A scene whose shadow-casting lights need more tiles than a shadow-map pass's atlas has
    is a user error (its lights would be drawn unshadowed): each light takes consecutive tiles,
    six for a point light (``shadows.first_tiles``)."""
    n = tiles_needed(scene.lights)
    lights = len(shadow_lights(scene.lights))
    for p in plan.passes:
        tiles = p.draw.shadow_tiles
        if n and p.draw.shadow and n > tiles * tiles:
            raise PipegenError(None, f"the scene's {lights} shadow-casting "
                               f"{'light needs' if lights == 1 else 'lights need'} {n} atlas "
                               f"tiles (six per point light, one per spot or directional) but "
                               f"pass '{p.name}' of technique '{plan.technique or '?'}' draws an "
                               f"atlas of {tiles} x {tiles} tiles",
                               hint="compile it with more tiles (e.g. -p shadow_tiles="
                                    f"{math.isqrt(n - 1) + 1} where the technique declares it), or "
                                    "cast fewer shadows (`shadows = false`)")


def check_scene_facts(plan: Plan, scene) -> None:
    """A pipeline specialised for a scene's features refuses a scene that breaks one of them:
    a light type it was specialised without, more lights, translucency (never a silently
    wrong image)."""
    facts = plan.scene
    if facts is None:
        return
    counts: dict[str, int] = {}
    for light in scene.lights:
        counts[light.type] = counts.get(light.type, 0) + 1
    broken = [f"specialised for 0 {t} lights; this scene has {n}"
              for t, n in counts.items() if t not in facts.light_types]
    if len(scene.lights) > facts.lights:
        broken.append(f"specialised for at most {facts.lights} lights; this scene has "
                      f"{len(scene.lights)}")
    translucent = sum(o.material.translucent for o in scene.objects)
    if translucent and not facts.translucent:
        broken.append(f"specialised for no translucent objects; this scene has {translucent}")
    casting = len(shadow_lights(scene.lights))
    if casting and not facts.shadows:
        broken.append(f"specialised for no shadow-casting lights; this scene has {casting}")
    opaque = len(scene.objects) - translucent
    if opaque and not facts.opaque:
        broken.append(f"specialised for no opaque objects; this scene has {opaque}")
    if broken:
        raise PipegenError(None, f"technique '{plan.technique}' " + "; ".join(broken),
                           hint="compile it for this scene (--scene), or without a scene")


def shadow_first(plan: Plan) -> int:
    """The light indices a plan's shadow maps take: the smallest ``first K`` of its shadow-map
    draws (0: every index may cast)."""
    return min((p.draw.shadow_first for p in plan.passes
                if p.draw.shadow and p.draw.shadow_first), default=0)


def scene_as_drawn(plan: Plan, scene):
    """``scene`` as the plan draws it: lights at or after its ``shadow_first`` cast no shadow
    (no atlas tile, ``shadow_tile`` -1: lit unshadowed; ``compiler/mismatches`` warns of them).
    ``scene`` itself when nothing changes."""
    from pipegen.scene.shadows import casting_below
    return casting_below(scene, shadow_first(plan))


def check_scene(plan: Plan, scene) -> None:
    """Everything a pipeline checks before it takes a new scene, the same on both runtimes: the
    specialised scene facts, the light table's capacity and the shadow atlas's tiles (each a
    user error with a hint, raised before anything is uploaded)."""
    check_scene_facts(plan, scene)
    check_light_capacity(len(scene.lights), plan)
    check_shadow_capacity(plan, scene)


def check_param_overrides(plan: Plan, params) -> None:
    """``render(scene, params)``: parameters are compile-time constants (the specialise phase
    folds them into the shaders), so a value other than the compiled one needs a recompile."""
    if not params:
        return
    compiled = plan.params
    for name, value in params.items():
        if name not in compiled:
            raise ValueError(f"unknown parameter '{name}' (the technique has: "
                             f"{', '.join(compiled) or 'none'})")
        if value != compiled[name]:
            raise ValueError(f"parameter '{name}' was compiled in as {compiled[name]!r}; "
                             f"recompile with {name}={value!r} to change it")
