"""Generic traversal and rewriting of shader IR, shared by the compiler passes.

``rewrite_expr(e, fn)`` rebuilds an expression bottom-up, calling ``fn`` on every node after its
children were rewritten (``fn`` returns the node itself to keep it).  ``rewrite_stmts`` does the
same over statement lists with an optional statement hook that may return a list (to delete or
splice statements).  ``walk_*`` visit without rebuilding; ``child_exprs`` lists one node's
expressions, for walkers that treat some statements their own way.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from typing import Callable, Iterable, Iterator, Optional

from pipegen.core.records import replace
from pipegen.ir import nodes as ir

ExprFn = Callable[[ir.Expr], ir.Expr]
StmtFn = Callable[[ir.Stmt], Optional[list]]

_EXPR_TYPES = (ir.Const, ir.Var, ir.Unary, ir.Binary, ir.Ternary, ir.Call, ir.Construct,
               ir.Swizzle, ir.Index, ir.LightField, ir.MaterialField, ir.Load, ir.Sample, ir.TargetSize)


def is_expr(x: object) -> bool:
    return isinstance(x, _EXPR_TYPES)


@functools.cache
def _field_names(cls: type) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls))


def _children(node) -> Iterator[tuple[str, object]]:
    for name in _field_names(type(node)):
        yield name, getattr(node, name)


def rewrite_expr(e: Optional[ir.Expr], fn: ExprFn) -> Optional[ir.Expr]:
    # the compiler's hottest loop (every pass rewrites every expression): the fields declared
    # to hold expressions (``_expr_fields``, as ``child_exprs`` reads them) read directly, no
    # generator
    if e is None:
        return None
    changes = None
    for name, many in _expr_fields(type(e)):
        value = getattr(e, name)
        if value is None:
            continue
        if many:
            new_t = tuple([rewrite_expr(v, fn) for v in value])
            if any(a is not b for a, b in zip(new_t, value)):
                changes = changes or {}
                changes[name] = new_t
        else:
            new = rewrite_expr(value, fn)
            if new is not value:
                changes = changes or {}
                changes[name] = new
    return fn(replace(e, **changes) if changes else e)


def rewrite_stmts(stmts: Iterable[ir.Stmt], expr_fn: ExprFn,
                  stmt_fn: Optional[StmtFn] = None) -> tuple[ir.Stmt, ...]:
    """Rewrite every expression in ``stmts`` with ``expr_fn``; then offer each rebuilt statement
    to ``stmt_fn``, which returns None to keep it or a list of statements to replace it."""
    out: list[ir.Stmt] = []
    for s in stmts:
        s = _rewrite_stmt(s, expr_fn, stmt_fn)
        replacement = stmt_fn(s) if stmt_fn else None
        if replacement is None:
            out.append(s)
        else:
            out.extend(replacement)
    return tuple(out)


def _rewrite_stmt(s: ir.Stmt, expr_fn: ExprFn, stmt_fn: Optional[StmtFn]) -> ir.Stmt:
    changes = {}
    for name in _field_names(type(s)):
        value = getattr(s, name)
        if isinstance(value, _EXPR_TYPES):
            changes[name] = rewrite_expr(value, expr_fn)
        elif isinstance(value, tuple) and value \
                and not all(isinstance(v, _EXPR_TYPES) for v in value) \
                and all(isinstance(v, _STMT_TYPES) for v in value):
            changes[name] = rewrite_stmts(value, expr_fn, stmt_fn)
    return replace(s, **changes) if changes else s


_STMT_TYPES = (ir.Declare, ir.Assign, ir.Output, ir.If, ir.For, ir.Break, ir.Continue, ir.Return,
               ir.Discard, ir.ExprStmt)


def _is_stmt(x: object) -> bool:
    return isinstance(x, _STMT_TYPES)


def walk_exprs(stmts: Iterable[ir.Stmt]) -> Iterator[ir.Expr]:
    """Every expression node (pre-order) in a statement list, nested statements included."""
    for s in stmts:
        for _, value in _children(s):
            if is_expr(value):
                yield from _walk_expr(value)
            elif isinstance(value, tuple):
                for v in value:
                    if is_expr(v):
                        yield from _walk_expr(v)
                    elif _is_stmt(v):
                        yield from walk_exprs((v,))


# ``exprs_of``'s tuples by the identity of the statement tuple (held, so that the id stays its
# own).  Unchanged bodies keep their identity through the passes (``passes/bodies.py``), so the
# passes that first ask whether a body holds anything to rewrite, and ``facts.code_facts``
# after them, share one walk of it.  Bounded as ``facts._FACTS`` is, for long-lived processes.
_FLAT: dict[int, tuple] = {}
_FLAT_MAX = 1024


def exprs_of(stmts) -> tuple[ir.Expr, ...]:
    """``walk_exprs(stmts)`` as a tuple, walked once per statement tuple (a list is walked each
    time: it may change)."""
    hit = _FLAT.get(id(stmts))
    if hit is not None and hit[0] is stmts:
        return hit[1]
    flat = tuple(walk_exprs(stmts))
    if isinstance(stmts, tuple):
        if len(_FLAT) >= _FLAT_MAX:
            _FLAT.clear()
        _FLAT[id(stmts)] = (stmts, flat)
    return flat


def _walk_expr(e: ir.Expr) -> Iterator[ir.Expr]:
    yield e
    for c in child_exprs(e):
        yield from _walk_expr(c)


@functools.cache
def _expr_fields(cls: type) -> tuple[tuple[str, bool], ...]:
    """``(name, is a tuple)`` of the fields of ``cls`` declared to hold expressions (their
    annotation names ``Expr``: ``Expr``, ``Optional[Expr]``, ``tuple[Expr, ...]``), in order."""
    return tuple((f.name, str(f.type).startswith("tuple")) for f in dataclasses.fields(cls)
                 if _NAMES_EXPR.search(str(f.type)))


_NAMES_EXPR = re.compile(r"\bExpr\b")       # Expr itself, not ExprStmt


def child_exprs(node) -> tuple[ir.Expr, ...]:
    """The expressions ``node``'s own fields hold: an expression's operands, a statement's
    expressions (not those of its nested statements).  Read from the fields declared to hold
    expressions, so a walker built on it sees a field added to the IR
    (tests/test_walk_children.py checks them against every field's values).

    Worked out once per node and kept in its ``__dict__`` (IR nodes are frozen records, so
    what their fields hold never changes; ``records.replace`` copies fields only): the
    verifier, the code facts, the hoisting pass, the light-row plans and the wide emitter's
    cost model walk the same nodes, some 15,000 calls a compile."""
    kept = node.__dict__.get("_child_exprs")
    if kept is not None:
        return kept
    found = []
    for name, many in _expr_fields(type(node)):
        value = getattr(node, name)
        if many:
            found.extend(value)
        elif value is not None:
            found.append(value)
    kept = node.__dict__["_child_exprs"] = tuple(found)
    return kept


def walk_stmts(stmts: Iterable[ir.Stmt]) -> Iterator[ir.Stmt]:
    """Every statement (pre-order), nested bodies included."""
    for s in stmts:
        yield s
        for _, value in _children(s):
            if isinstance(value, tuple) and value and all(_is_stmt(v) for v in value):
                yield from walk_stmts(value)


def map_technique_code(tech: ir.Technique, expr_fn: ExprFn,
                       stmt_fn: Optional[StmtFn] = None) -> ir.Technique:
    """Apply a rewrite to every function body and pass body of a technique."""
    def fix_fn(f: ir.Function) -> ir.Function:
        return dataclasses.replace(f, body=rewrite_stmts(f.body, expr_fn, stmt_fn))

    packings = tuple(dataclasses.replace(p, functions=tuple(fix_fn(f) for f in p.functions))
                     for p in tech.packings)
    functions = tuple(fix_fn(f) for f in tech.functions)
    passes = tuple(dataclasses.replace(p, body=rewrite_stmts(p.body, expr_fn, stmt_fn))
                   for p in tech.passes)
    return dataclasses.replace(tech, packings=packings, functions=functions, passes=passes)
