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
