"""spec_light_types: fold tests of light types the scene does not have (scene specialisation).

With ``tech.scene`` set, every light's ``type`` field holds one of the scene's type codes
(0 point, 1 spot, 2 directional).  So does a function parameter that every call site feeds
from a ``type`` field, a constant, or another such parameter (found by a fixpoint over the
call graph; a parameter that is ever assigned is not followed).  A comparison ``t == c`` or
``t != c`` of such a value with a constant outside its set folds to ``false`` / ``true``;
``opt_fold_constants`` then removes the dead branch.  Every fold is recorded as an
``ir.Cut`` naming the function or pass it happened in and the scene fact behind it.
"""

from __future__ import annotations

import dataclasses
from typing import Optional

from pipegen.ir import nodes as ir, walk as irwalk

TYPE_CODES = {"point": 0, "spot": 1, "directional": 2}
TYPE_NAMES = {v: k for k, v in TYPE_CODES.items()}
TOP = None                  # not known to be a light type


def run(tech: ir.Technique) -> ir.Technique:
    if tech.scene is None:
        return tech
    present = frozenset(TYPE_CODES[t] for t in tech.scene.light_types)
    params = _parameter_sets(tech, present)
    cuts: list[ir.Cut] = []

    def rewrite(where: str, scope: dict, body):
        def fold(e: ir.Expr) -> ir.Expr:
            if not (isinstance(e, ir.Binary) and e.op in ("==", "!=")):
                return e
            for value, const in ((e.left, e.right), (e.right, e.left)):
                values = _value_set(value, present, scope)
                if values is TOP or not isinstance(const, ir.Const) or \
                        not isinstance(const.value, int) or const.value in values:
                    continue
                name = TYPE_NAMES.get(const.value, f"type {const.value}")
                cuts.append(ir.Cut("branch", f"{_spell(value)} {e.op} {name}", (
                    f"in {where}: always {'false' if e.op == '==' else 'true'}, the scene has "
                    f"no {name} lights")))
                return ir.Const(ir.BOOL, e.op == "!=")
            return e
        return irwalk.rewrite_stmts(body, fold)

    def fix_fn(f: ir.Function) -> ir.Function:
        scope = {p: params.get((f.name, p)) for p, _ in f.params}
        return dataclasses.replace(f, body=rewrite(f"function `{f.name}`", scope, f.body))

    packings = tuple(dataclasses.replace(k, functions=tuple(fix_fn(f) for f in k.functions))
                     for k in tech.packings)
    functions = tuple(fix_fn(f) for f in tech.functions)
    passes = tuple(dataclasses.replace(p, body=rewrite(f"pass `{p.name}`", {}, p.body))
                   for p in tech.passes)
    return dataclasses.replace(tech, packings=packings, functions=functions, passes=passes,
                               cuts=tech.cuts + tuple(dict.fromkeys(cuts)))


def _spell(e: ir.Expr) -> str:
    if isinstance(e, ir.LightField):
        return "light.type" if e.index is None else "lights[…].type"
    return e.name if isinstance(e, ir.Var) else "type"


def _value_set(e: ir.Expr, present: frozenset, scope: dict) -> Optional[frozenset]:
    if isinstance(e, ir.LightField) and e.field == "type":
        return present
    if isinstance(e, ir.Const) and isinstance(e.value, int) and not isinstance(e.value, bool):
        return frozenset({e.value})
    if isinstance(e, ir.Var) and e.kind == "local" and e.name in scope:
        return scope[e.name]
    return TOP


def _assigned(f: ir.Function) -> set[str]:
    """Names a function body assigns or redeclares (its parameters among them lose their
    call-site values)."""
    out = set()
    for s in irwalk.walk_stmts(f.body):
        if isinstance(s, ir.Declare):
            out.add(s.name)
        elif isinstance(s, ir.Assign):
            target = s.target
            while not isinstance(target, ir.Var) and hasattr(target, "base"):
                target = target.base
            if isinstance(target, ir.Var):
                out.add(target.name)
    return out


def _parameter_sets(tech: ir.Technique, present: frozenset) -> dict:
    """(function, parameter) -> the light-type codes it can hold (TOP: unknown)."""
    fns = {f.name: f for f in tech.all_functions()}
    blocked = {name: _assigned(f) for name, f in fns.items()}
    bottom = frozenset()
    sets: dict = {(f.name, p): bottom for f in fns.values() for p, _ in f.params}
    sites: list = []        # (enclosing function or None, call)
    for f in fns.values():
        sites += [(f.name, e) for e in irwalk.walk_exprs(f.body) if _user_call(e, fns)]
    for p in tech.passes:
        sites += [(None, e) for e in irwalk.walk_exprs(p.body) if _user_call(e, fns)]
    called = {call.name for _, call in sites}
    for key in sets:        # never called: nothing is known of its arguments
        if key[0] not in called:
            sets[key] = TOP
    changed = True
    while changed:
        changed = False
        for enclosing, call in sites:
            scope = {} if enclosing is None else {
                p: sets[(enclosing, p)] for p, _ in fns[enclosing].params}
            for (param, _), arg in zip(fns[call.name].params, call.args):
                key = (call.name, param)
                old = sets[key]
                if old is TOP:
                    continue
                got = TOP if param in blocked[call.name] else _value_set(arg, present, scope)
                new = TOP if got is TOP else old | got
                if new != old:
                    sets[key] = new
                    changed = True
    return sets


def _user_call(e, fns) -> bool:
    return isinstance(e, ir.Call) and not e.builtin and e.name in fns
