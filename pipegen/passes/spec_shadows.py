"""spec_shadows: a scene without shadow-casting lights reads no shadow map (scene
specialisation).

With ``tech.scene`` set and ``tech.scene.shadows`` false, every light's ``shadow_tile`` field
holds -1 (``pipegen/scene/shadows.py``: no light casts a shadow), so each read of it folds to the
constant -1.0.  Then, in the functions and passes where a read folded, constants are folded
(``opt_fold_constants``) and the statements after a top-level ``return`` dropped, so
``common/shadows.pipe``'s ``shadow_factor`` becomes ``return 1.0``; a shadow-map pass's depth
target (the atlas) that no code reads any more leaves the ``reads`` of every pass, and
``cull_empty_draws`` / ``cull_unread`` remove the shadow-map passes and the atlas.  Each
function or pass where a read folded gets one ``ir.Cut`` naming the scene fact.
"""

from __future__ import annotations

import dataclasses

from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.passes import opt_fold_constants


def run(tech: ir.Technique) -> ir.Technique:
    if tech.scene is None or tech.scene.shadows:
        return tech
    cuts: list[ir.Cut] = []

    changed: set[str] = set()

    def rewrite(where: str, body):
        hit = []

        def fold(e: ir.Expr) -> ir.Expr:
            if isinstance(e, ir.LightField) and e.field == "shadow_tile":
                hit.append(e)
                return ir.Const(ir.FLOAT, -1.0)
            return e
        out = irwalk.rewrite_stmts(body, fold)
        if hit:
            changed.add(where)
            cuts.append(ir.Cut("branch", "shadow_tile", f"in {where}: always -1, no light of "
                                                        f"the scene casts a shadow"))
        return out

    def fix_fn(f: ir.Function) -> ir.Function:
        return dataclasses.replace(f, body=rewrite(f"function `{f.name}`", f.body))

    packings = tuple(dataclasses.replace(k, functions=tuple(fix_fn(f) for f in k.functions))
                     for k in tech.packings)
    functions = tuple(fix_fn(f) for f in tech.functions)
    passes = tuple(dataclasses.replace(p, body=rewrite(f"pass `{p.name}`", p.body))
                   for p in tech.passes)
    tech = dataclasses.replace(tech, packings=packings, functions=functions, passes=passes,
                               cuts=tech.cuts + tuple(cuts))
    if not changed:
        return tech
    folded = opt_fold_constants.run(tech)
    functions = tuple(dataclasses.replace(g, body=_until_return(g.body))
                      if f"function `{f.name}`" in changed else f
                      for f, g in zip(tech.functions, folded.functions))
    tech = dataclasses.replace(tech, functions=functions)
    atlases = {p.depth_target for p in tech.passes if p.draw.shadow and p.depth_target}
    passes = []
    for p in tech.passes:
        if p.draw.shadow or not atlases & set(p.reads):
            passes.append(p)
            continue
        used = _targets_read(tech, p)
        passes.append(dataclasses.replace(p, reads=tuple(
            r for r in p.reads if r not in atlases or r in used)))
    return dataclasses.replace(tech, passes=tuple(passes))


def _until_return(body: tuple) -> tuple:
    """``body`` without the statements after its first top-level ``return``."""
    for k, s in enumerate(body):
        if isinstance(s, ir.Return):
            return tuple(body[:k + 1])
    return tuple(body)


def _targets_read(tech: ir.Technique, p: ir.Pass) -> set[str]:
    """The targets the code of pass ``p`` (its body and the functions it reaches) reads."""
    from pipegen.ir.facts import pass_functions
    out: set[str] = set()
    for stmts in [p.body] + [f.body for f in pass_functions(tech, p.body)]:
        for e in irwalk.walk_exprs(stmts):
            if isinstance(e, (ir.Load, ir.Sample, ir.TargetSize)):
                out.add(e.target)
    return out
