"""The ``material { FIELD: TYPE = DEFAULT, … }`` block: the fields a scene object may set.

Defaults are constants (a number, ``-`` a number, or a constructor of numbers such as
``vec3(0)``): the runtime writes them into every record the scene does not set, so they are
evaluated here, not in shader code.  Fields are scalars or vectors of float, int or uint (one
row component each, like the light table's fields: ``ir/light_layout.py``).
"""

from __future__ import annotations

from typing import Optional

from pipegen.frontend import ast
from pipegen.frontend.lower.names import a_or_an, did_you_mean, error, listing
from pipegen.ir import nodes as ir

FIELD_TYPES = ("float", "int", "uint", "vec2", "vec3", "vec4",
               "ivec2", "ivec3", "ivec4", "uvec2", "uvec3", "uvec4")
# the names a material field may not take: the scene's own material keys
SCENE_KEYS = ("albedo", "specular", "shininess", "alpha", "translucent")


def lower_material_table(decls: list[ast.MaterialDecl],
                         lights: ir.LightTable) -> Optional[ir.MaterialTable]:
    if not decls:
        return None
    if not lights.fields:
        raise error(decls[0].span, "a material block needs a light table",
                    "the material records are stored after the lights: declare "
                    "`lights[N] { … }` (ir/material_layout.py)")
    if len(decls) > 1:
        raise error(decls[1].span, "the material block is declared twice",
                    f"the first `material {{ … }}` is on line {decls[0].span.line}; merge them")
    fields: list[ir.MaterialAttr] = []
    for f in decls[0].fields:
        name = f.name.name
        if any(a.name == name for a in fields):
            raise error(f.name.span, f"material field '{name}' is declared twice",
                        "list each field once")
        if name in SCENE_KEYS:
            raise error(f.name.span, f"'{name}' is a scene material key already",
                        f"read it as the stage input `{name}`, or name the field otherwise")
        if f.type.name not in FIELD_TYPES:
            raise error(f.type.span, f"a material field is a float, int or uint scalar or "
                        f"vector, not '{f.type.name}'",
                        did_you_mean(f.type.name, FIELD_TYPES, f"types: {listing(FIELD_TYPES)}"))
        t = ir.parse_type(f.type.name)
        fields.append(ir.MaterialAttr(name, t, default_value(f.default, t, name)))
    if not fields:
        raise error(decls[0].span, "the material block declares no field",
                    "e.g. `material { model: uint = 0 }`")
    return ir.MaterialTable(tuple(fields), decls[0].span)


def default_value(e: ast.Expr, t: ir.Type, name: str) -> tuple[float, ...]:
    """The default of field ``name`` of type ``t``, one float per component."""
    if isinstance(e, ast.Call):
        if e.func.name != str(t):
            raise error(e.func.span, f"material field '{name}' is {a_or_an(t)}, "
                        f"not {e.func.name}", f"write {t}(…)")
        values = [_number(a, t, name) for a in e.args]
        if len(values) == 1:
            values *= t.size
        if len(values) != t.size:
            raise error(e.span, f"{t} takes 1 or {t.size} values, not {len(values)}",
                        f"e.g. {t}({', '.join(['0'] * t.size)})")
        return tuple(values)
    if t.size != 1:
        raise error(e.span, f"material field '{name}' is {a_or_an(t)}: its default is a {t}",
                    f"e.g. {t}(0)")
    return (_number(e, t, name),)


def _number(e: ast.Expr, t: ir.Type, name: str) -> float:
    sign = 1
    if isinstance(e, ast.UnaryOp) and e.op in "-+" and isinstance(e.operand, ast.Number):
        sign, e = (-1 if e.op == "-" else 1), e.operand
    if not isinstance(e, ast.Number):
        raise error(e.span, f"the default of material field '{name}' is not a number",
                    "defaults are constants: a number, or a constructor such as vec3(0)")
    value = sign * e.value
    if t.scalar is not ir.Scalar.FLOAT:
        if e.kind == "float" or (t.scalar is ir.Scalar.UINT and value < 0):
            kind = "an unsigned integer" if t.scalar is ir.Scalar.UINT else "an integer"
            raise error(e.span, f"material field '{name}' is {a_or_an(t)}: its default must "
                        f"be {kind}, not {value}", "write a whole number")
    return float(value)

