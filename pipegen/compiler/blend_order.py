"""Blends whose result depends on the order of the fragments (issue 27): a pass that draws
translucent objects in scene order through such a blend renders a different image when the
scene lists its objects in another order, silently.

A blend equation ``op(src * sf, dst * df)`` per colour target is *order-independent* when
applying it for fragments a then b gives what b then a gives:

- ``min`` and ``max`` (factors ignored);
- ``add`` with ``df = one`` and an ``sf`` that does not read the destination: a sum,
  dst + f(a) + f(b);
- ``add`` that multiplies: ``sf = zero`` with ``df`` a source factor (``src_color``,
  ``src_alpha``, ``one_minus_src_*``, constants), dst * g(a) * g(b); or ``sf = dst_color`` /
  ``dst_alpha`` with ``df = zero``, src * dst;
- one that keeps the destination (``add(zero, one)``): nothing changes.

Everything else, ``add(src_alpha, one_minus_src_alpha)`` (over) first among them, is
order-dependent.  A pass drawing ``scene`` or ``scene.translucent`` without ``back_to_front``
whose blend on a written target is order-dependent is listed by :func:`order_dependent_blends`;
``compile`` warns about it, and ``run``/``check``/the API report it as a mismatch when the
scene has two or more translucent objects (``mismatches.py``).  Without a blend, a pass that
writes colour but not depth keeps the last fragment: order-dependent too; with depth writes
the nearest wins (ties aside) and order does not matter.
"""

from __future__ import annotations

from pipegen.ir import nodes as ir

F = ir.BlendFactor
_READS_DST = {F.DST_COLOR, F.ONE_MINUS_DST_COLOR, F.DST_ALPHA, F.ONE_MINUS_DST_ALPHA,
              F.SRC_ALPHA_SATURATE}
_SOURCE_ONLY = {F.SRC_COLOR, F.ONE_MINUS_SRC_COLOR, F.SRC_ALPHA, F.ONE_MINUS_SRC_ALPHA,
                F.CONSTANT_COLOR, F.ONE_MINUS_CONSTANT_COLOR, F.CONSTANT_ALPHA,
                F.ONE_MINUS_CONSTANT_ALPHA, F.ONE}


def commutes(eq: ir.BlendEquation) -> bool:
    """Whether blending two fragments in either order gives the same result (the module
    docstring)."""
    if eq.op in (ir.BlendOp.MIN, ir.BlendOp.MAX):
        return True
    if eq.op is not ir.BlendOp.ADD:
        return eq.src is F.ZERO and eq.dst is F.ONE        # keeps the destination
    if eq.dst is F.ONE:
        return eq.src not in _READS_DST
    if eq.src is F.ZERO:
        return eq.dst in _SOURCE_ONLY or eq.dst is F.ZERO
    return eq.src in (F.DST_COLOR, F.DST_ALPHA) and eq.dst is F.ZERO


def draws_translucent_in_scene_order(p: ir.Pass) -> bool:
    d = p.draw
    return (d.kind is ir.DrawKind.SCENE and not d.shadow and d.order is ir.DrawOrder.SCENE
            and (not d.material or "translucent" in d.material))


def order_dependent_blends(tech: ir.Technique) -> list[tuple[ir.Pass, str, str]]:
    """(pass, target, what depends on order) for each colour target written by a pass that
    draws translucent objects in scene order, where the result depends on that order."""
    out = []
    for p in tech.passes:
        if not draws_translucent_in_scene_order(p):
            continue
        writes_depth = p.state.depth.write and p.state.depth.func is not ir.CompareFunc.ALWAYS
        for target in p.writes:
            b = p.state.blend_for(target)
            if not b.enabled:
                if not writes_depth:
                    out.append((p, target, "no blend and no depth write: the last fragment "
                                           "drawn wins"))
                continue
            from pipegen.ir.printer import blend_equation   # only to word a warning
            bad = [f"{part} {blend_equation(eq)}" for part, eq, mask in
                   (("rgb", b.rgb, any(b.write_mask[:3])), ("alpha", b.alpha, b.write_mask[3]))
                   if mask and not commutes(eq)]
            if bad:
                out.append((p, target, "blend " + " and ".join(bad) +
                             " (not order-independent)"))
    return out


def describe(p: ir.Pass, target: str, what: str) -> str:
    return (f"pass {p.name} draws translucent objects in scene order into {target} with "
            f"{what}: where they overlap, the image depends on the order the scene lists them")


HINT = ("draw them `back_to_front` (farthest first), or use an order-independent blend "
        "(add(one, one), min, max)")
