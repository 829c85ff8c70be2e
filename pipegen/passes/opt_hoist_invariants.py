"""opt_hoist_invariants: compute once per pixel what a loop recomputes every iteration.

forward's light loop calls ``shade_table_light(i, world_pos, …)``, which passes ``p`` down to
``blinn_phong_along``, which normalises ``camera_pos - p``: the same view vector for every
light.  A hand-written shader computes it once before the loop; no shader compiler can, since
llvmpipe and PoCL inline the calls but do not move code out of loops.  Two steps:

1. lift (repeated until nothing lifts): in a function called, directly or not, from inside a
   loop, a builtin call whose operands are only constants, stage inputs, technique parameters
   and the function's never-assigned parameters becomes a new parameter (``pg_invN``); every
   call site passes that call with the parameters replaced by its arguments.  Only where, at
   every call site, those arguments are of the same kind in the caller (else the function is
   left as it is).  So the call climbs the chain: ``blinn_phong_along`` -> ``light_any`` ->
   ``shade_table_light`` -> the pass body, as ``normalize(camera_pos - world_pos)``.
2. hoist: in a pass or function body, such a builtin call inside a loop (in the pass body:
   constants, stage inputs and technique parameters only; in a function, its never-assigned
   parameters too) is declared once before the outermost loop holding it and read there.

Builtins are pure and total (no traps, no side effects), so evaluating one earlier, once, or
where a branch would have skipped it gives the same value: every result is bit for bit what it
was (tests/test_hoist_invariants.py, tests/test_light_table_images.py).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Callable, Iterable, Optional

from pipegen.ir import nodes as ir, walk as irwalk

_ROUNDS = 16        # a call climbs one function per round; chains are a few functions deep


def run(tech: ir.Technique) -> ir.Technique:
    memo = _Memo()
    for _ in range(_ROUNDS):
        lifted = _lift(tech, memo)
        if lifted is tech:
            break
        tech = lifted
    return _hoist(tech)


# -- what is invariant -------------------------------------------------------------------------
def _invariant(e: ir.Expr, fixed: frozenset) -> bool:
    """Whether ``e`` is built from constants, stage inputs, technique parameters, the locals
    named in ``fixed`` (never assigned) and builtin calls only."""
    if isinstance(e, ir.Const):
        return True
    if isinstance(e, ir.Var):
        return e.kind in ("input", "param") or e.name in fixed
    if isinstance(e, ir.Call) and not e.builtin:
        return False
    if isinstance(e, (ir.Unary, ir.Binary, ir.Ternary, ir.Call, ir.Construct, ir.Swizzle,
                      ir.Index)):
        return all(_invariant(c, fixed) for c in irwalk.child_exprs(e))
    return False        # light and material fields, loads, samples, target sizes


def _invariant_calls(stmts: Iterable[ir.Stmt], fixed: frozenset) -> list:
    """The builtin calls in ``stmts`` that ``_invariant`` accepts (with ``fixed``), outermost
    first, in order, each as ``(call, the same list of the calls inside it)``: the tree
    ``_candidates`` picks from, so that a lift round walks only these calls."""
    def collect(e: ir.Expr, out: list) -> None:
        if isinstance(e, ir.Call) and e.builtin and _invariant(e, fixed):
            inner: list = []
            for c in irwalk.child_exprs(e):
                collect(c, inner)
            out.append((e, inner))
        else:
            for c in irwalk.child_exprs(e):
                collect(c, out)

    top: list = []
    for s in irwalk.walk_stmts(stmts):
        for e in irwalk.child_exprs(s):
            collect(e, top)
    return top


def _candidates(calls: list, accept: Callable[[ir.Call], bool]) -> list[ir.Call]:
    """The outermost of ``calls`` (an ``_invariant_calls`` tree) that ``accept`` accepts,
    each once, in order: where a call is refused, the calls inside it are offered."""
    found: dict[ir.Call, None] = {}

    def pick(tree: list) -> None:
        for call, inner in tree:
            if accept(call):
                found.setdefault(call)
            else:
                pick(inner)

    pick(calls)
    return list(found)


def _assigned(stmts: Iterable[ir.Stmt]) -> set[str]:
    out = set()
    for s in irwalk.walk_stmts(stmts):
        if isinstance(s, ir.Assign):
            root = s.target
            while not isinstance(root, ir.Var):
                root = root.base
            out.add(root.name)
        elif isinstance(s, ir.For):
            out.add(s.var)
    return out


def _fixed_params(f: ir.Function) -> frozenset:
    return frozenset(name for name, _ in f.params) - _assigned(f.body)


def _names(f_params, body) -> set[str]:
    names = {n for n, _ in f_params}
    for s in irwalk.walk_stmts(body):
        if isinstance(s, ir.Declare):
            names.add(s.name)
        elif isinstance(s, ir.For):
            names.add(s.var)
    return names


def _fresh(taken: set[str]) -> str:
    k = 0
    while f"pg_inv{k}" in taken:
        k += 1
    taken.add(f"pg_inv{k}")
    return f"pg_inv{k}"


# -- 1. lift -----------------------------------------------------------------------------------
def _calls(body: tuple) -> list[tuple[ir.Call, bool]]:
    """The user-function calls in ``body``, nested statements included, each with whether it
    sits in the body of a loop (a loop's bounds are outside it): one walk of the body, for
    ``_Chains``, which needs both for every body in every round."""
    found: list[tuple[ir.Call, bool]] = []

    def stmts(ss, looped: bool) -> None:
        for s in ss:
            stack = list(irwalk.child_exprs(s))
            while stack:
                e = stack.pop()
                if isinstance(e, ir.Call) and not e.builtin:
                    found.append((e, looped))
                stack.extend(irwalk.child_exprs(e))
            for nested in _nested_bodies(s):
                stmts(nested, looped or isinstance(s, ir.For))

    stmts(body, False)
    return found


@functools.cache
def _field_names(cls: type) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls))


def _nested_bodies(s: ir.Stmt) -> Iterable[tuple]:
    """The statement lists ``s`` holds (an if's branches, a loop's body), as
    ``irwalk.walk_stmts`` finds them."""
    for name in _field_names(type(s)):
        value = getattr(s, name)
        if isinstance(value, tuple) and value and all(isinstance(v, _STMTS) for v in value):
            yield value


_STMTS = (ir.Declare, ir.Assign, ir.Output, ir.If, ir.For, ir.Break, ir.Continue, ir.Return,
          ir.Discard, ir.ExprStmt)


def _substitute(e: ir.Expr, args: dict[str, ir.Expr]) -> ir.Expr:
    return irwalk.rewrite_expr(e, lambda x: args.get(x.name, x)
                               if isinstance(x, ir.Var) and x.kind == "local" else x)


class _Memo:
    """What the lift rounds find in a body, kept across rounds by the identity of the body
    (held, so that the id stays its own): a round changes few bodies, the others are not
    walked again."""

    def __init__(self):
        self._calls: dict[int, tuple] = {}
        self._invariant: dict[tuple[int, frozenset], tuple] = {}
        self._fixed: dict[int, tuple] = {}

    def calls(self, body: tuple) -> list[tuple[ir.Call, bool]]:
        kept = self._calls.get(id(body))
        if kept is None or kept[0] is not body:
            kept = self._calls[id(body)] = (body, _calls(body))
        return kept[1]

    def invariant_calls(self, body: tuple, fixed: frozenset) -> list:
        key = (id(body), fixed)
        kept = self._invariant.get(key)
        if kept is None or kept[0] is not body:
            kept = self._invariant[key] = (body, _invariant_calls(body, fixed))
        return kept[1]

    def fixed_params(self, f: ir.Function) -> frozenset:
        kept = self._fixed.get(id(f))
        if kept is None or kept[0] is not f:
            kept = self._fixed[id(f)] = (f, _fixed_params(f))
        return kept[1]


class _Chains:
    """Who calls whom, and which calls can climb to a loop they are invariant in."""

    def __init__(self, tech: ir.Technique, memo: _Memo):
        self.by_name = {f.name: f for f in tech.all_functions()}
        self.fixed = {name: memo.fixed_params(f) for name, f in self.by_name.items()}
        bodies = [(None, p.body) for p in tech.passes]
        bodies += [(f.name, f.body) for f in self.by_name.values()]
        self.calls = {}            # function -> the user functions its body calls
        # function -> [(call, caller function or None for a pass body, inside a loop there)]
        self.sites: dict[str, list[tuple[ir.Call, Optional[str], bool]]] = {}
        work = []                  # functions called from inside a loop
        for caller, body in bodies:
            found = memo.calls(body)
            # a call equal to one inside a loop counts as inside it
            looped = {c for c, in_loop in found if in_loop}
            for c, _ in found:
                self.sites.setdefault(c.name, []).append((c, caller, c in looped))
            work += [c.name for c in looped]
            if caller is not None:
                self.calls[caller] = [c.name for c, _ in found]
        self.in_loops = set()
        while work:
            name = work.pop()
            if name in self.in_loops or name not in self.by_name:
                continue
            self.in_loops.add(name)
            work.extend(self.calls[name])
        self.memo: dict[tuple[str, ir.Expr], bool] = {}

    def liftable(self, e: ir.Expr, fn: str) -> bool:
        """Whether ``e`` (invariant in function ``fn``) can become a parameter of ``fn``: at
        every call site the expression it becomes is invariant there and, unless the caller is
        a pass body, sits in a loop of the caller or can climb further."""
        key = (fn, e)
        if key not in self.memo:
            self.memo[key] = fn in self.in_loops and fn in self.sites and all(
                self._site_ok(_substitute(e, _bindings(self.by_name[fn], call)), caller, looped)
                for call, caller, looped in self.sites[fn])
        return self.memo[key]

    def _site_ok(self, e: ir.Expr, caller: Optional[str], looped: bool) -> bool:
        if caller is None:
            return _invariant(e, frozenset())
        return _invariant(e, self.fixed[caller]) and (looped or self.liftable(e, caller))


def _lift(tech: ir.Technique, memo: _Memo) -> ir.Technique:
    """One round: each function's calls that ``_Chains.liftable`` accepts become parameters
    and its call sites pass them.  ``tech`` itself when nothing lifts."""
    chains = _Chains(tech, memo)
    lifts: dict[str, list[tuple[str, ir.Call]]] = {}      # function -> (new param, call)
    for f in tech.functions:
        if f.name not in chains.in_loops or f.name not in chains.sites:
            continue        # nothing in it is liftable (_Chains.liftable)
        invariant = memo.invariant_calls(f.body, chains.fixed[f.name])
        found = _candidates(invariant, lambda e, f=f: chains.liftable(e, f.name))
        if found:
            taken = _names(f.params, f.body)
            lifts[f.name] = [(_fresh(taken), e) for e in found]
    if not lifts:
        return tech
    by_name = chains.by_name

    def pass_values(e: ir.Expr) -> ir.Expr:
        if isinstance(e, ir.Call) and not e.builtin and e.name in lifts:
            bound = _bindings(by_name[e.name], e)
            extra = tuple(_substitute(call, bound) for _, call in lifts[e.name])
            return dataclasses.replace(e, args=e.args + extra)
        return e

    def calls_lifted(body: tuple) -> bool:
        return any(c.name in lifts for c, _ in memo.calls(body))

    def fix(f: ir.Function) -> ir.Function:
        if f.name not in lifts and not calls_lifted(f.body):
            return f        # what the rewrite would give: no call site, no lifted call
        body = irwalk.rewrite_stmts(f.body, pass_values)
        new = lifts.get(f.name, ())
        if new:
            reads = {call: ir.Var(name, call.type) for name, call in new}
            body = irwalk.rewrite_stmts(body, lambda x: reads.get(x, x)
                                        if isinstance(x, ir.Call) else x)
        if body == f.body and not new:
            return f
        return dataclasses.replace(f, body=body,
                                   params=f.params + tuple((n, c.type) for n, c in new))

    # call sites are rewritten before the lifted calls are replaced: a site's arguments hold
    # the caller's expressions, not the callee's new parameters
    packings = tuple(dataclasses.replace(k, functions=tuple(fix(f) for f in k.functions))
                     for k in tech.packings)
    functions = tuple(fix(f) for f in tech.functions)
    passes = tuple(dataclasses.replace(p, body=irwalk.rewrite_stmts(p.body, pass_values))
                   if calls_lifted(p.body) else p for p in tech.passes)
    return dataclasses.replace(tech, packings=packings, functions=functions, passes=passes)


def _bindings(f: ir.Function, call: ir.Call) -> dict[str, ir.Expr]:
    return {name: arg for (name, _), arg in zip(f.params, call.args)}


# -- 2. hoist ----------------------------------------------------------------------------------
def _hoist(tech: ir.Technique) -> ir.Technique:
    def fix_fn(f: ir.Function) -> ir.Function:
        body = _hoist_body(f.body, _fixed_params(f), _names(f.params, f.body))
        return f if body is f.body else dataclasses.replace(f, body=body)

    packings = tuple(dataclasses.replace(k, functions=tuple(fix_fn(f) for f in k.functions))
                     for k in tech.packings)
    functions = tuple(fix_fn(f) for f in tech.functions)
    passes = tuple(p if (b := _hoist_body(p.body, frozenset(), _names((), p.body))) is p.body
                   else dataclasses.replace(p, body=b) for p in tech.passes)
    if all(a is b for a, b in zip(functions + passes, tech.functions + tech.passes)) and \
            all(a is b for k, j in zip(packings, tech.packings)
                for a, b in zip(k.functions, j.functions)):
        return tech
    return dataclasses.replace(tech, packings=packings, functions=functions, passes=passes)


def _hoist_body(body: tuple, fixed: frozenset, taken: set[str]) -> tuple:
    """``body`` with each outermost loop's invariant builtin calls declared before it."""
    out: list[ir.Stmt] = []
    changed = False
    for s in body:
        if isinstance(s, ir.For):
            calls = _candidates(_invariant_calls(s.body, fixed), lambda e: True)
            if calls:
                names = {c: _fresh(taken) for c in calls}
                out.extend(ir.Declare(names[c], c.type, c) for c in calls)
                reads = {c: ir.Var(n, c.type) for c, n in names.items()}
                s = dataclasses.replace(s, body=irwalk.rewrite_stmts(
                    s.body, lambda x: reads.get(x, x) if isinstance(x, ir.Call) else x))
                changed = True
        elif isinstance(s, ir.If):
            then = _hoist_body(s.then, fixed, taken)
            other = _hoist_body(s.other, fixed, taken)
            if then is not s.then or other is not s.other:
                s = dataclasses.replace(s, then=then, other=other)
                changed = True
        out.append(s)
    return tuple(out) if changed else body
