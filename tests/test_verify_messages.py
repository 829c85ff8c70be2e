"""The IR verifier formats a failed check's message only when it fails (``verify._check``
takes a ``lambda``): the messages must still name the values of the node that broke."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from pipegen.compiler.driver import compile_file
from pipegen.ir import nodes as ir, walk
from pipegen.ir.verify import verify

ROOT = Path(__file__).resolve().parents[1]


def _retype_first_binary(tech: ir.Technique) -> tuple[ir.Technique, ir.Binary]:
    """``tech`` with its first binary operator typed bool, and that operator as it was."""
    found = []

    def retype(e):
        if isinstance(e, ir.Binary) and not found and e.type != ir.BOOL:
            found.append(e)
            return dataclasses.replace(e, type=ir.BOOL)
        return e
    return walk.map_technique_code(tech, retype), found[0]


def test_a_mistyped_operator_is_named_with_its_operand_types():
    tech = compile_file(ROOT / "pipelines" / "forward.pipe").technique
    verify(tech)
    broken, op = _retype_first_binary(tech)
    with pytest.raises(AssertionError) as e:
        verify(broken)
    assert str(e.value).startswith("IR invariant violated in ")
    assert str(e.value).endswith(f": {op.left.type} {op.op} {op.right.type} is not a bool")


def test_a_parameter_of_the_wrong_value_is_named_with_its_value():
    tech = compile_file(ROOT / "pipelines" / "forward.pipe").technique
    p = next(p for p in tech.params if p.type == ir.FLOAT)
    broken = dataclasses.replace(tech, params=tuple(
        dataclasses.replace(q, default="x") if q is p else q for q in tech.params))
    with pytest.raises(AssertionError, match=rf"in parameter '{p.name}': value 'x' is not a "
                                             rf"float$"):
        verify(broken)
