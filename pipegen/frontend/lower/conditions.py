"""Conditions on declarations: ``pass NAME if COND { … }``, ``repeat per light … if COND
{ … }`` and ``target T : F … if COND``, present only where COND holds.

COND is written like shader code but reads only parameters, so it is decided while lowering,
with the values the technique is compiled with (overrides included), as parameters in
declarations are: a sweep compiles one variant per value and each variant holds just its own
passes and targets.  What a condition may contain: parameters, literals (numbers, true,
false), a word parameter's words (``hdr_accumulate == copy_back``), comparisons (``==`` and
``!=`` for words and booleans, all six for numbers), ``!``, ``&&``, ``||`` and parentheses.
Anything else is an error at the place it is written.
"""

from __future__ import annotations

from typing import Union

from pipegen.frontend import ast
from pipegen.ir import nodes as ir
from pipegen.frontend.lower.names import did_you_mean, error, listing, reserved_meaning

Value = Union[bool, int, float, str]

_COMPARISONS = {"==": lambda a, b: a == b, "!=": lambda a, b: a != b,
                "<": lambda a, b: a < b, "<=": lambda a, b: a <= b,
                ">": lambda a, b: a > b, ">=": lambda a, b: a >= b}
_HINT = ("a condition compares parameters with values, e.g. `if hdr_accumulate == copy_back` "
         "or `if samples > 1 && !tonemap`")


def holds(cond: ast.Condition, params: dict[str, ir.Param]) -> bool:
    """Whether ``cond`` is true for the parameters' values; an error at the part of it that is
    not a condition over parameters."""
    value = _Evaluator(params).value(cond.expr)
    if not isinstance(value, bool):
        raise error(cond.expr.span, f"a condition must be true or false, not "
                    f"{_describe(value)}", _HINT)
    return value


def parameter_value(expr: ast.Expr, params: dict[str, ir.Param]):
    """The value of an expression over parameters (``WORD_PARAM == WORD`` in shader code is a
    constant once the technique is compiled); an error where it is not one."""
    return _Evaluator(params).value(expr)


def spelling(cond: ast.Condition) -> str:
    """The condition as written (one line), for messages."""
    s = cond.expr.span
    if s.line == s.end_line:
        return s.source_line[s.column - 1:s.end_column - 1]
    return "its condition"


class _Evaluator:
    def __init__(self, params: dict[str, ir.Param]):
        self.params = params

    def value(self, e: ast.Expr) -> Value:
        if isinstance(e, (ast.Number, ast.Bool)):
            return e.value
        if isinstance(e, ast.Name):
            return self._param(e).default
        if isinstance(e, ast.UnaryOp):
            return self._unary(e)
        if isinstance(e, ast.BinaryOp):
            return self._binary(e)
        raise error(e.span, f"{_construct(e)} cannot appear in a condition: it is decided "
                    f"at compile time, from parameters only", _HINT)

    def _param(self, name: ast.Name) -> ir.Param:
        p = self.params.get(name.name)
        if p is not None:
            return p
        reserved = reserved_meaning(name.name)
        if reserved is not None:
            raise error(name.span, f"'{name.name}' is {reserved}: a condition reads only "
                        f"parameters (it is decided at compile time)", _HINT)
        raise error(name.span, f"unknown parameter '{name.name}' in a condition",
                    did_you_mean(name.name, self.params,
                                 f"parameters: {listing(self.params)}"))

    def _unary(self, e: ast.UnaryOp) -> Value:
        v = self.value(e.operand)
        if e.op == "!":
            if not isinstance(v, bool):
                raise error(e.operand.span, f"`!` needs true or false, not {_describe(v)}",
                            _HINT)
            return not v
        if e.op in "-+" and _is_number(v):
            return -v if e.op == "-" else v
        raise error(e.span, f"`{e.op}` cannot appear in a condition", _HINT)

    def _binary(self, e: ast.BinaryOp) -> Value:
        if e.op in ("&&", "||"):
            left, right = self._truth(e.left), self._truth(e.right)  # both checked, always
            return (left and right) if e.op == "&&" else (left or right)
        if e.op not in _COMPARISONS:
            raise error(e.span, f"operator `{e.op}` cannot appear in a condition", _HINT)
        left, right = self._operands(e)
        if isinstance(left, str) or isinstance(left, bool) or isinstance(right, bool):
            if e.op not in ("==", "!="):
                raise error(e.span, f"`{e.op}` compares numbers; {_describe(left)} and "
                            f"{_describe(right)} are compared with == or !=", _HINT)
            if isinstance(left, bool) != isinstance(right, bool):
                raise error(e.span, f"cannot compare {_describe(left)} with "
                            f"{_describe(right)}", _HINT)
        elif not (_is_number(left) and _is_number(right)):
            raise error(e.span, f"cannot compare {_describe(left)} with {_describe(right)}",
                        _HINT)
        return _COMPARISONS[e.op](left, right)

    def _truth(self, e: ast.Expr) -> bool:
        v = self.value(e)
        if not isinstance(v, bool):
            raise error(e.span, f"`&&` and `||` join true or false, not {_describe(v)}", _HINT)
        return v

    def _operands(self, e: ast.BinaryOp) -> tuple[Value, Value]:
        """Both sides; a word parameter's other side may be a bare word it can hold."""
        word_param = next((self.params[s.name] for s in (e.left, e.right)
                           if isinstance(s, ast.Name) and s.name in self.params
                           and self.params[s.name].type == ir.VOID), None)
        sides = []
        for s in (e.left, e.right):
            if word_param is not None and isinstance(s, ast.Name) and s.name not in self.params:
                sides.append(self._word(s, word_param))
            else:
                sides.append(self.value(s))
        if word_param is not None and not all(isinstance(v, str) for v in sides):
            other = next(v for v in sides if not isinstance(v, str))
            raise error(e.span, f"parameter '{word_param.name}' holds a word; it cannot be "
                        f"compared with {_describe(other)}",
                        f"compare it with one of its words: {_words(word_param)}")
        return sides[0], sides[1]

    def _word(self, word: ast.Name, p: ir.Param) -> str:
        if p.allowed and word.name not in p.allowed:
            raise error(word.span, f"'{word.name}' is not a value parameter '{p.name}' can "
                        f"hold", did_you_mean(word.name, map(str, p.allowed),
                                              f"its values: {_words(p)}"))
        return word.name


def _words(p: ir.Param) -> str:
    return ", ".join(map(str, p.allowed)) if p.allowed else "a format or a packing scheme"


def _is_number(v: Value) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _describe(v: Value) -> str:
    if isinstance(v, bool):
        return "true or false"
    if isinstance(v, str):
        return f"the word '{v}'"
    return f"the number {v:g}" if isinstance(v, float) else f"the number {v}"


def _construct(e: ast.Expr) -> str:
    return {ast.Call: "a call", ast.MethodCall: "a call", ast.Field: "a field or swizzle",
            ast.Subscript: "an index", ast.Conditional: "`?:`"}.get(type(e), "this")
