"""cull_empty_draws: remove passes whose draw is empty for the scene (scene specialisation).

With ``tech.scene`` set, a pass draws nothing when it draws ``scene.translucent`` and the
scene has no translucent objects (or ``scene.opaque`` and no opaque ones), when its light
draw takes only light types the scene lacks, when it repeats per light for types the scene
lacks, or when it draws shadow maps or shadow volumes and no light of the scene casts.  Such a pass changes no target, so removing it changes no image: except for a pass
outside a repeat group that clears a target (its clears run even when it draws nothing),
which is kept.  Each removal is an ``ir.Cut`` with the scene fact behind it.
"""

from __future__ import annotations

import dataclasses
from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.ir.access import reads


def run(tech: ir.Technique) -> ir.Technique:
    facts = tech.scene
    if facts is None:
        return tech
    kept, cuts = [], []
    for p in tech.passes:
        why = _empty(p, facts)
        if why is None or (p.clears and not p.repeat_per_light):
            kept.append(p)
        else:
            cuts.append(ir.Cut("pass", p.name, why, tuple(sorted(reads(p)))))
    return dataclasses.replace(tech, passes=tuple(kept), cuts=tech.cuts + tuple(cuts))


def _lights(types: tuple[str, ...]) -> str:
    return " and ".join(types) + " lights"


def _empty(p: ir.Pass, facts: ir.SceneFacts) -> Optional[str]:
    """Why the pass draws nothing in every scene with these facts (None: it may draw)."""
    present = set(facts.light_types)
    if p.repeat_per_light:
        if not present:
            return "it repeats per light and the scene has no lights"
        if p.repeat_types and not present & set(p.repeat_types):
            return (f"it repeats per light for {_lights(p.repeat_types)} and the scene has "
                    f"none")
    d = p.draw
    if d.kind is ir.DrawKind.SCENE:
        material = set(d.material)
        if "translucent" in material and not facts.translucent:
            return f"it draws {d.describe()} and the scene has no translucent objects"
        if "opaque" in material and not facts.opaque:
            return f"it draws {d.describe()} and the scene has no opaque objects"
        if not material and not (facts.opaque or facts.translucent):
            return "it draws the scene and the scene has no objects"
    if d.shadow:
        if not facts.shadows:
            return f"it draws {d.describe()} and no light of the scene casts a shadow"
        if not present & set(d.light_types):
            return f"it draws {d.describe()} and the scene has no {_lights(d.light_types)}"
    if d.shadow_volumes and not facts.shadows:
        return f"it draws {d.describe()} and no light of the scene casts a shadow"
    if d.kind is ir.DrawKind.LIGHTS:
        if not present:
            return f"it draws {d.describe()} and the scene has no lights"
        if d.light_types and not present & set(d.light_types):
            return f"it draws {d.describe()} and the scene has no {_lights(d.light_types)}"
    return None
