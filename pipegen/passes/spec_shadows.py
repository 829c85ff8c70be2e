"""spec_shadows: a scene without shadow-casting lights reads no shadow map (scene
specialisation).

With ``tech.scene`` set and ``tech.scene.shadows`` false, every light's ``shadow_tile`` field
holds -1 (``pipegen/scene/shadows.py``: no light casts a shadow), so each read of it becomes
the constant -1.0, and each function or pass where one did gets an ``ir.Cut`` naming the
scene fact.  The rest is the scene pipeline's later passes (``pipelines.SCENE``): folding turns
``common/shadows.pipe``'s ``shadow_factor`` into ``return 1.0`` and the lookup after it,
``opt_dead_code`` drops, ``opt_unread_reads`` takes the atlas out of the ``reads`` of the
passes that called it, and ``cull_empty_draws`` / ``cull_unread`` remove the shadow-map passes
and the atlas.
"""

from __future__ import annotations

import dataclasses

from pipegen.ir import nodes as ir, walk as irwalk


def run(tech: ir.Technique) -> ir.Technique:
    if tech.scene is None or tech.scene.shadows:
        return tech
    cuts: list[ir.Cut] = []

    def rewrite(where: str, body):
        hit = []

        def fold(e: ir.Expr) -> ir.Expr:
            if isinstance(e, ir.LightField) and e.field == "shadow_tile":
                hit.append(e)
                return ir.Const(ir.FLOAT, -1.0)
            return e
        out = irwalk.rewrite_stmts(body, fold)
        if hit:
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
    return dataclasses.replace(tech, packings=packings, functions=functions, passes=passes,
                               cuts=tech.cuts + tuple(cuts))
