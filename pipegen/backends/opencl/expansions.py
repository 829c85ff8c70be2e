"""The evaluation orders of ``pipegen.ir.expand`` as OpenCL C: ``c_text`` renders a tree, and
``prelude_forms`` gives the expressions the prelude's ``pg_dot``, ``pg_length``, ``pg_distance``,
``pg_mix``, ``pg_cross`` and matrix products are made of (``templates/cl_prelude.cl.j2``).
The wide path renders the same trees component by component (``wide/expressions.py``), so
the two paths cannot drift apart in their operation order."""

from __future__ import annotations

import functools
from typing import Callable, NamedTuple, Optional

from pipegen.ir import expand
from pipegen.ir.expand import Op

XYZW = "xyzw"
_PRECEDENCE = {"+": 1, "-": 1, "*": 2}


def c_text(e, tight: bool = False, call: Optional[Callable[[str, list], str]] = None) -> str:
    """``e`` (a tree of ``expand``, leaves C expressions) as C.  Each operation in parentheses
    (the wide path's spelling), or with ``tight`` only those C's precedence and
    left-to-right grouping need (the prelude's); ``call(name, args)`` spells a call (default
    ``name(args)``)."""
    if not isinstance(e, Op):
        return str(e)
    if e.op not in expand.INFIX:
        args = [c_text(a, tight, call) for a in e.args]
        return call(e.op, args) if call else f"{e.op}({', '.join(args)})"
    left, right = (c_text(a, tight, call) for a in e.args)
    if not tight:
        return f"({left} {e.op} {right})"
    mine = _PRECEDENCE[e.op]
    if _precedence(e.args[0]) < mine:
        left = f"({left})"
    if _precedence(e.args[1]) <= mine:        # a + (b + c): the grouping is the order
        right = f"({right})"
    return f"{left} {e.op} {right}"


def _precedence(e) -> int:
    return _PRECEDENCE.get(e.op, 3) if isinstance(e, Op) else 3


def _pg_dot(a, b) -> Op:
    """The prelude's own dot of two whole vectors, a call of its ``pg_dot``."""
    return expand.call("pg_dot", *a, *b)


class _Component(NamedTuple):
    vector: str         # "a" or "b"
    k: int


def _dot_of_products(n: int) -> str:
    """The sum ``pg_dot`` returns for n components: the products are ``p = a * b`` (one vector
    multiplication), summed in ``expand.dot``'s order over ``p``'s components."""
    def over_p(e):
        if not isinstance(e, Op):
            raise AssertionError(f"dot: a term {e!r} outside the products")
        x, y = e.args
        if e.op == "*" and isinstance(x, _Component) and isinstance(y, _Component) \
                and (x.vector, y.vector) == ("a", "b") and x.k == y.k:
            return f"p.{XYZW[x.k]}"
        return Op(e.op, (over_p(x), over_p(y)))
    tree = expand.dot([_Component("a", k) for k in range(n)],
                      [_Component("b", k) for k in range(n)])
    return c_text(over_p(tree), tight=True)


@functools.cache            # the same for every program: built once a process
def prelude_forms() -> dict:
    """The prelude's expressions in ``expand``'s orders (the template's ``order``): ``dot[n]``
    (n = 1: the product ``a * b``; else the sum over ``p = a * b``), ``length``, ``distance``,
    ``mix`` and ``cross`` over the macro or function parameters, ``matrix_vector[n]`` and
    ``vector_matrix[n]`` over the matrix ``m`` and the vector ``v``."""
    tight = {"tight": True}
    return {
        "dot": {1: c_text(expand.dot(["a"], ["b"]), **tight),
                **{n: _dot_of_products(n) for n in (2, 3, 4)}},
        "length": c_text(expand.length(["(v)"], dot_of=_pg_dot), **tight),
        "distance": c_text(expand.distance(["(a)"], ["(b)"], length_of=lambda v: expand.call(
            "pg_length", *v)), **tight),
        "mix": c_text(expand.mix("(a)", "(b)", "(t)"), **tight),
        "cross": ", ".join(c_text(c, **tight) for c in expand.cross(
            [f"a.{c}" for c in "xyz"], [f"b.{c}" for c in "xyz"])),
        "matrix_vector": {n: c_text(expand.matrix_vector(
            [f"m.c[{k}]" for k in range(n)], [f"v.{c}" for c in XYZW[:n]]), **tight)
            for n in (3, 4)},
        "vector_matrix": {n: ", ".join(c_text(d, **tight) for d in expand.vector_matrix(
            ["v"], [[f"m.c[{k}]"] for k in range(n)], dot_of=_pg_dot)) for n in (3, 4)},
    }
