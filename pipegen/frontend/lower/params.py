"""Technique parameters: the type, default and allowed set of a ``param`` declaration,
and a caller's override of its value."""

from __future__ import annotations

from typing import Iterable

from pipegen.frontend import ast
from pipegen.ir import nodes as ir
from pipegen.core.formats import FORMATS
from pipegen.packing.base import SCHEMES
from pipegen.frontend.lower.names import PARAM_TYPES, a_or_an, error

class ParamBuilder:
    """Types, default, allowed set and override of one ``param`` declaration."""

    def __init__(self, decl: ast.ParamDecl):
        self.decl = decl

    def build(self) -> ir.Param:
        d = self.decl
        t = self._type()
        # A word parameter with `in {…}` may hold any word listed there (`param hdr_accumulate
        # = blend in {blend, copy_back}`: a choice read by pass and target conditions); without
        # the list only formats and packing schemes.
        self.words = {v.name for v in d.allowed or () if isinstance(v, ast.Name)} \
            if t == ir.VOID else set()
        default = self._coerce(d.value, t)
        allowed = tuple(self._coerce(v, t) for v in d.allowed or ())
        if allowed and default not in allowed:
            raise error(d.value.span, f"the default of '{d.name.name}' ({_show(default)}) is "
                        f"not one of its allowed values", f"allowed: {_show_all(allowed)}")
        accurate = None
        if d.accurate is not None:
            accurate = self._coerce(d.accurate, t)
            if allowed and accurate not in allowed:
                raise error(d.accurate.span, f"the accurate value of '{d.name.name}' "
                            f"({_show(accurate)}) is not one of its allowed values",
                            f"allowed: {_show_all(allowed)}")
        return ir.Param(d.name.name, t, default, allowed, d.span, accurate)

    def _type(self) -> ir.Type:
        d = self.decl
        if d.type is not None:
            if d.type.name not in PARAM_TYPES:
                raise error(d.type.span, f"a parameter cannot have type '{d.type.name}'",
                            f"parameter types: {', '.join(PARAM_TYPES)}")
            return PARAM_TYPES[d.type.name]
        v = d.value
        if isinstance(v, ast.Number):
            return PARAM_TYPES[v.kind]
        if isinstance(v, ast.Bool):
            return ir.BOOL
        if isinstance(v, ast.Name):
            return ir.VOID
        raise error(v.span, "a parameter's value is a number, true/false, a format name or a "
                           "packing scheme", "e.g. `param scale = 0.5`, `param fmt = rgba16f` or "
                                             "`param encoding = octahedral`")

    def _coerce(self, v: ast.Expr, t: ir.Type):
        value = v.value if isinstance(v, (ast.Number, ast.Bool)) else \
            v.name if isinstance(v, ast.Name) else None
        kind = v.kind if isinstance(v, ast.Number) else \
            "bool" if isinstance(v, ast.Bool) else "name" if isinstance(v, ast.Name) else "?"
        result = _convert_param_value(value, kind, t, self.words)
        if result is None:
            raise error(v.span, f"parameter '{self.decl.name.name}' is "
                        f"{a_or_an(_type_word(t))}; {_show_literal(v)} is not", _param_hint(t))
        return result

    def override(self, p: ir.Param, value) -> ir.Param:
        kind, raw = _classify_override(value)
        words = set(p.allowed) if p.type == ir.VOID else set()
        converted = _convert_param_value(raw, kind, p.type, words)
        if converted is None and words and kind == "name":
            converted = raw       # a word it cannot hold: refused below, with its words
        if converted is None:
            raise error(self.decl.name.span,
                        f"parameter '{p.name}' is {a_or_an(_type_word(p.type))}; "
                        f"the value {value!r} given for it is not", _param_hint(p.type))
        if p.allowed and converted not in p.allowed:
            raise error(self.decl.name.span, f"{_show(converted)} is not an allowed value of "
                        f"parameter '{p.name}'", f"allowed: {_show_all(p.allowed)}")
        return ir.Param(p.name, p.type, converted, p.allowed, p.span, p.accurate)


def _convert_param_value(value, kind: str, t: ir.Type, words: set = frozenset()):
    """A literal of ``kind`` ("float", "int", "uint", "bool", "name") as a value of parameter
    type ``t``; None when it does not fit.  Integer literals serve float and (when not
    negative) uint parameters; names serve word parameters: a format, a packing scheme
    (``pack NAME = PARAM(…)`` then packs with the scheme the parameter holds), or one of
    ``words``, the parameter's own allowed words."""
    if t == ir.FLOAT and kind in ("float", "int", "uint"):
        return float(value)
    if t == ir.INT and kind == "int":
        return int(value)
    if t == ir.UINT and kind in ("uint", "int") and value >= 0:
        return int(value)
    if t == ir.BOOL and kind == "bool":
        return bool(value)
    if t == ir.VOID and kind == "name" and (value in FORMATS or value in SCHEMES
                                            or value in words):
        return value
    return None


def _classify_override(value) -> tuple[str, object]:
    """A caller's override (a Python value, or its spelling from a command line)."""
    if isinstance(value, bool):
        return "bool", value
    if isinstance(value, int):
        return "int", value
    if isinstance(value, float):
        return "float", value
    text = str(value).strip()
    if text in ("true", "false"):
        return "bool", text == "true"
    try:
        if text.lower().endswith("u"):
            return "uint", int(text[:-1], 0)
        return "int", int(text, 0)
    except ValueError:
        pass
    try:
        return "float", float(text)
    except ValueError:
        return "name", text


def _type_word(t: ir.Type) -> str:
    return "format or packing scheme" if t == ir.VOID else str(t)


def _param_hint(t: ir.Type) -> str:
    return {ir.FLOAT: "write a number like 0.5", ir.INT: "write an integer like 3",
            ir.UINT: "write a non-negative integer like 3u", ir.BOOL: "write true or false"}.get(
        t, f"write a format name ({' '.join(FORMATS)}), a packing scheme "
           f"({' '.join(SCHEMES)}), or list the words it may hold: `in {{a, b}}`")


def _show(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _show_all(values: Iterable) -> str:
    return "{" + ", ".join(_show(v) for v in values) + "}"


def _show_literal(v: ast.Expr) -> str:
    s = v.span
    if s.line == s.end_line and s.end_column > s.column:
        return f"'{s.source_line[s.column - 1:s.end_column - 1]}'"
    return "this value"
