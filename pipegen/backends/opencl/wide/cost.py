"""How much work a pixel of a pass does, for the wide path's choice (``MIN_COST``): a rough
count of operations, and of the ``load``/``sample`` gathers."""

from __future__ import annotations

from pipegen.ir import nodes as ir
from pipegen.ir.walk import child_exprs
from pipegen.backends import plan as planlib


# What a builtin call counts beyond its node, where its expansion is long: the prelude's
# exp2 and log2 are minimax polynomials of some 10 operations each (llvmpipe's), pow is the
# two, and the wide form evaluates each for W lanes at once where the scalar path runs the
# whole polynomial per pixel.  Counted as one node, multi-pass forward's specialised light
# pass (Blinn-Phong's specular pow) came to 97 and stayed scalar, where its raster kernel
# measured 530 ms scalar against 301 ms wide (``benchmarks/cl_wide_passes.py --size 640x360
# --frames 5 forward_multipass``, many_lights); a light pass of cost 39 without them measured
# the same either way, and one of 16 4 % slower wide
BUILTIN_WORK = {"pow": 20, "exp": 10, "exp2": 10, "log": 10, "log2": 10}


def cost(body, functions: dict) -> int:
    """A rough count of the operations a pixel runs (expression nodes, calls of user functions
    counted with their bodies, builtins with long expansions with ``BUILTIN_WORK``, bounded
    loops times their bound): the wide form pays its batching only when the shading does
    enough work per pixel (``MIN_COST``)."""
    memo: dict = {}

    def fcost(name: str) -> int:
        if name not in memo:
            memo[name] = 0
            f = functions.get(name)
            memo[name] = stmts(f.body) if f is not None else 0
        return memo[name]

    def expr(e) -> int:
        n = 1
        if isinstance(e, ir.Call):
            n += BUILTIN_WORK.get(e.name, 0) if e.builtin else fcost(e.name)
        for sub in child_exprs(e):
            n += expr(sub)
        return n

    def stmts(body) -> int:
        n = 0
        for s in body:
            if isinstance(s, ir.For):
                n += iterations(s) * stmts(s.body)
            elif isinstance(s, ir.If):
                n += expr(s.cond) + stmts(s.then) + stmts(s.other)
            else:
                for e in child_exprs(s):
                    n += expr(e)
        return n

    return stmts(body)


def iterations(s: ir.For) -> int:
    """The iterations a loop is counted with (its constant bounds', 8 for others)."""
    b = s.bound.value if isinstance(s.bound, ir.Const) else 8
    a = s.start.value if isinstance(s.start, ir.Const) else 0
    return max(1, int(b) - int(a))


def gathers(body, functions: dict) -> int:
    """How many ``load``/``sample`` calls the code holds (functions counted with theirs), for
    ``GATHER_COST`` (0 since the gathers are wide: lane by lane they measured slower than the
    scalar code where they were a large share of the work, deferred_calver's point lights)."""
    return _gathers(body, functions, {})


def _gathers(body, functions: dict, memo: dict) -> int:
    facts = planlib.code_facts(body)      # one walk per body (memoised in ir/facts.py)
    n = facts.loads
    for name in facts.call_list:
        if name in functions:
            if name not in memo:
                memo[name] = _gathers(functions[name].body, functions, memo)
            n += memo[name]
    return n
