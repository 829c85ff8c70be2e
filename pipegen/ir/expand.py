"""The evaluation order of the builtins whose float32 result depends on it: ``dot``, ``length``,
``distance``, ``cross``, ``mix`` and the matrix-vector products, as expression trees over the
operands' components.  llvmpipe's order (measured bit-exact on Mesa 22.3): ``dot`` =
``x + (y + (z + w))`` of unfused products, ``length`` = ``sqrt(dot(v, v))``, ``mix`` =
``a + (b - a) t``, ``cross`` of unfused products, ``m * v`` = ``((c0 v.x + c1 v.y) + c2 v.z)
+ c3 v.w``, ``v * m`` the dots of ``v`` with the columns.

One definition for every path that spells these out: the OpenCL prelude's functions
(``templates/cl_prelude.cl.j2``, rendered from these trees by ``backends/opencl/expansions``)
and the wide path, which expands them component by component.  A leaf is whatever the caller
passes for a component (the backends pass C expressions); ``Op`` nodes are the operations,
an infix operator (``+``, ``-``, ``*``) or a call (any other name).
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Optional, Sequence


class Op(NamedTuple):
    op: str             # "+", "-", "*", or the name of a function called
    args: tuple         # operands: Op nodes or leaves


INFIX = ("+", "-", "*")


def add(a, b) -> Op:
    return Op("+", (a, b))


def sub(a, b) -> Op:
    return Op("-", (a, b))


def mul(a, b) -> Op:
    return Op("*", (a, b))


def call(name: str, *args) -> Op:
    return Op(name, args)


def dot(a: Sequence, b: Sequence) -> Op:
    """``x + (y + (z + w))`` of the unfused products of the components (one product for a
    scalar)."""
    products = [mul(x, y) for x, y in zip(a, b, strict=True)]
    acc = products[-1]
    for p in reversed(products[:-1]):
        acc = add(p, acc)
    return acc


def length(v: Sequence, dot_of: Optional[Callable[[Sequence, Sequence], object]] = None) -> Op:
    """``sqrt(dot(v, v))``; ``dot_of``: how the caller spells the dot (the prelude calls its
    own ``pg_dot``, which is ``dot`` above), by default ``dot``."""
    return call("sqrt", (dot_of or dot)(v, v))


def distance(a: Sequence, b: Sequence, length_of: Optional[Callable[[list], object]] = None):
    """``length(a - b)``, the difference per component (``length_of``: how the caller spells
    the length, by default ``length``)."""
    return (length_of or length)([sub(x, y) for x, y in zip(a, b, strict=True)])


def cross(a: Sequence, b: Sequence) -> tuple[Op, Op, Op]:
    """The three components of ``cross(a, b)``: differences of unfused products."""
    (a0, a1, a2), (b0, b1, b2) = a, b
    return (sub(mul(a1, b2), mul(a2, b1)), sub(mul(a2, b0), mul(a0, b2)),
            sub(mul(a0, b1), mul(a1, b0)))


def mix(a, b, t) -> Op:
    """One component of ``mix(a, b, t)`` = ``a + (b - a) t`` (a constant ``t`` is split
    before this: ``passes/lower_mix_constant``)."""
    return add(a, mul(sub(b, a), t))


def matrix_vector(columns: Sequence, v: Sequence) -> Op:
    """``m * v`` (one component, or whole columns): ``((c0 v.x + c1 v.y) + c2 v.z) + c3 v.w``."""
    terms = [mul(c, x) for c, x in zip(columns, v, strict=True)]
    acc = terms[0]
    for t in terms[1:]:
        acc = add(acc, t)
    return acc


def vector_matrix(v: Sequence, columns: Sequence[Sequence],
                  dot_of: Optional[Callable[[Sequence, Sequence], object]] = None) -> list:
    """``v * m``: the dot of ``v`` with each column (``columns[k]``: column k's components, or
    the column itself as a one-element list for a caller that spells the dot as a call)."""
    return [(dot_of or dot)(v, c) for c in columns]
