"""``walk.child_exprs`` keeps each node's operands once worked out (issue 26 item 7: the
verifier, the code facts and the passes ask for the same nodes' children): the same
expressions in field order as before, the kept tuple per node, and a node made by
``records.replace`` works its own out (the fields only are copied)."""

from pipegen.core.records import replace
from pipegen.ir import nodes as ir
from pipegen.ir.walk import child_exprs, walk_exprs


def test_child_exprs_lists_the_operands_in_field_order_once_per_node():
    a, b, c = ir.Var("a", ir.FLOAT), ir.Var("b", ir.FLOAT), ir.Const(ir.FLOAT, 2.0)
    v = ir.Construct(ir.parse_type("vec3"), (a, b, c))
    s = ir.Binary("*", v, ir.Var("k", ir.FLOAT), ir.parse_type("vec3"))
    assert child_exprs(s) == (v, s.right) and child_exprs(v) == (a, b, c)
    assert child_exprs(s) is child_exprs(s) and child_exprs(a) == ()
    t = replace(s, left=ir.Construct(ir.parse_type("vec3"), (c, c, c)))
    assert child_exprs(t)[0] is t.left and child_exprs(t)[1] is s.right
    assert [type(e).__name__ for e in walk_exprs((ir.ExprStmt(t),))] == \
        ["Binary", "Construct", "Const", "Const", "Const", "Var"]
    assert t == replace(t) and repr(t) == repr(replace(t))      # the kept tuple is not a field


def _every_field_scanned(node) -> tuple:
    """What child_exprs held before it read the declared fields only: every field's value
    (and every item of a tuple field) that is an expression."""
    import dataclasses
    from pipegen.ir.walk import _EXPR_TYPES
    out = []
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if isinstance(value, _EXPR_TYPES):
            out.append(value)
        elif isinstance(value, tuple):
            out.extend(v for v in value if isinstance(v, _EXPR_TYPES))
    return tuple(out)


def test_the_declared_expression_fields_hold_every_operand_of_the_shipped_techniques():
    from pathlib import Path
    from pipegen.compiler.driver import compile_file
    from pipegen.ir.walk import walk_stmts
    root = Path(__file__).resolve().parents[1] / "pipelines"
    seen = 0
    for path in sorted(root.glob("*.pipe")):
        tech = compile_file(path).technique
        bodies = [p.body for p in tech.passes] + [f.body for f in tech.all_functions()]
        for body in bodies:
            for s in walk_stmts(body):
                assert child_exprs(s) == _every_field_scanned(s), s
                for e in walk_exprs((s,)):
                    assert child_exprs(e) == _every_field_scanned(e), e
                    seen += 1
    assert seen > 10_000
