"""cull_unread: remove passes whose outputs nothing reads, and targets no pass uses
(scene specialisation; reference counting as in Filament's frame graph).

Walking the passes backwards from the technique's output, a pass is live when it writes a
target that is needed: the output, or a target a later live pass reads (``reads``, its depth
target when it tests depth or stencil).  A pass writes its colour targets, its clears and its
depth target when it writes depth or stencil (``reads`` and ``writes`` are ``ir/access.py``'s,
the one definition).  A ``repeat per light`` group runs its passes in turn for every light, so
a group is walked until nothing changes (a pass may feed an earlier one of the group for the
next light).  Dead passes and the targets no live pass touches are removed, each with the
reason: the targets it writes, and the culled passes that were their only readers.  Runs only
on scene-specialised techniques (``tech.scene``): without a scene the technique's every target
is an output the user asked for.
"""

from __future__ import annotations

import dataclasses

from pipegen.ir import nodes as ir
from pipegen.ir.access import reads, writes


def _groups(passes) -> list[list[int]]:
    """Pass indices in blocks: a repeat group is one block, every other pass its own."""
    blocks: list[list[int]] = []
    for k, p in enumerate(passes):
        if p.repeat_per_light and blocks and passes[blocks[-1][0]].repeat_group == p.repeat_group:
            blocks[-1].append(k)
        else:
            blocks.append([k])
    return blocks


def live_passes(tech: ir.Technique) -> set[int]:
    needed = {tech.output}
    live: set[int] = set()
    for block in reversed(_groups(tech.passes)):
        while True:
            before = (len(live), len(needed))
            for k in reversed(block):
                p = tech.passes[k]
                if k in live or writes(tech, p) & needed:
                    live.add(k)
                    needed |= reads(p)
            if (len(live), len(needed)) == before:
                break
    return live


def run(tech: ir.Technique) -> ir.Technique:
    if tech.scene is None:
        return tech
    live = live_passes(tech)
    culled = [p for k, p in enumerate(tech.passes) if k not in live]
    earlier = {c.name: set(c.reads) for c in tech.cuts if c.kind == "pass"}
    cuts = []
    for p in culled:
        parts = []
        for t in sorted(writes(tech, p)):
            readers = [q.name for q in tech.passes if t in reads(q) and q.name != p.name]
            readers += [name for name, r in earlier.items() if t in r]
            if not readers:
                parts.append(f"`{t}`, which nothing reads")
            else:
                parts.append(f"`{t}`, read only by culled pass"
                             f"{'es' if len(readers) > 1 else ''} "
                             + ", ".join(f"`{r}`" for r in readers))
        cuts.append(ir.Cut("pass", p.name, "it writes " + "; ".join(parts),
                           tuple(sorted(reads(p)))))
    passes = tuple(p for k, p in enumerate(tech.passes) if k in live)
    used = {tech.output} | {t for p in passes for t in reads(p) | writes(tech, p)}
    used |= {p.depth_target for p in passes if p.depth_target}
    targets = []
    for t in tech.targets:
        if t.name in used:
            targets.append(t)
            continue
        users = [p.name for p in tech.passes if t.name in reads(p) | writes(tech, p)
                 or t.name == p.depth_target]
        users += [name for name, r in earlier.items() if t.name in r and name not in users]
        why = ("no pass uses it" if not users else "used only by culled pass"
               + ("es " if len(users) > 1 else " ") + ", ".join(f"`{u}`" for u in users))
        cuts.append(ir.Cut("target", t.name, why))
    return dataclasses.replace(tech, passes=passes, targets=tuple(targets),
                               cuts=tech.cuts + tuple(cuts))
