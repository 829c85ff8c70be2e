"""The lark half of parsing (``syntax.parse`` is the entry point): the LALR parser (built once
per grammar and kept in the user's cache folder), the parse tree turned into ``ast`` nodes
with spans, and syntax errors in the user's words.  Imported only when a text has to be
parsed; a compile whose syntax trees are all cached (``syntax._ast_cache_file``)
never imports it, nor lark.
"""

from __future__ import annotations

import functools
import os
import sys
from typing import Optional

import lark
from lark import Lark, Token, Transformer, Tree, v_args
from lark.exceptions import (UnexpectedCharacters, UnexpectedEOF, UnexpectedInput,
                             UnexpectedToken, VisitError)

from pipegen.frontend import ast
from pipegen.frontend.expect_syntax import parse_expect
from pipegen.core.diagnostics import PipegenError, Span
from pipegen.core.package_files import cache_dir, grammar_text, load_cached, save_cached


#: How deeply constructs may nest (parse-tree levels: statements, calls, operators; each operator
#: of a chain like a + b + c is a level; parentheses alone are not).  The shipped techniques use
#: at most 13; every later phase walks the tree recursively, so the limit keeps them far from
#: Python's recursion limit.
MAX_NESTING = 100


# ---------------------------------------------------------------------------------------------
# The parser, built once per grammar and cached on disk
# ---------------------------------------------------------------------------------------------

_OPTIONS = dict(parser="lalr", propagate_positions=True, maybe_placeholders=True)
_CACHE_FORMAT = "1"          # bump when what is written to the cache changes


class _WholeWords:
    """Lexes a name in every parser state, even where no name can follow.

    The contextual lexer offers each state only the terminals it can shift.  Where keywords
    are expected but no name (`depth ds less`), ``lesser`` would lex as the keyword ``less``
    followed by ``er``; with NAME always offered, a word lexes whole and keywords are
    recognised only as whole words (lark turns an exact keyword match of NAME into the
    keyword).  The stream itself passes through unchanged.
    """

    always_accept = ("NAME",)
    # ``expect`` is a keyword only at the top level (an expectation's line); inside braces or
    # parentheses (shader code, a function's parameters) it is a name.  The contextual lexer
    # cannot tell by itself: LALR merges the lookaheads of states with the same items, and a
    # target's trailing ``if COND`` is followed by any top-level keyword, ``expect`` included,
    # so after that grammar change ``float expect = 1.0;`` lexed ``expect`` as the keyword.
    _OPEN, _CLOSE = ("LBRACE", "LPAR"), ("RBRACE", "RPAR")

    def process(self, stream):
        from lark import Token
        depth = 0
        for tok in stream:
            if tok.type in self._OPEN:
                depth += 1
            elif tok.type in self._CLOSE:
                depth = max(0, depth - 1)
            elif tok.type == "EXPECT" and depth:
                tok = Token.new_borrow_pos("NAME", tok.value, tok)
            yield tok


@functools.cache
def lalr_parser() -> Lark:
    """The LALR parser.  Building its tables takes 0.15-0.6 s, so the built parser is kept in
    the user's cache folder (``package_files.cache_dir()``) and loaded from there (about
    20 ms) by every later process with the same grammar, lark and Python.  A missing, unreadable,
    unsafe or stale cache file only means the parser is built again; a read-only install or
    cache folder only means it is not saved."""
    grammar = grammar_text()
    folder = cache_dir()
    path = _cache_file(folder, grammar) if folder is not None else None
    if path is not None:
        parser = load_cached(path, _load_parser)
        if parser is not None:
            return parser
    parser = Lark(grammar, postlex=_WholeWords(), **_OPTIONS)
    if path is not None:
        save_cached(parser, path, _save_parser)
    return parser


def _cache_file(folder: str, grammar: str) -> str:
    import hashlib
    key = "\0".join([_CACHE_FORMAT, grammar, repr(sorted(_OPTIONS.items())),
                      repr(_WholeWords.always_accept), lark.__version__,
                      "%d.%d" % sys.version_info[:2]])
    return os.path.join(folder, f"parser-{hashlib.sha256(key.encode()).hexdigest()[:32]}.pickle")


def _load_parser(f) -> Lark:
    return Lark.__new__(Lark)._load(f, postlex=_WholeWords())


def _save_parser(parser: Lark, f) -> None:
    parser.save(f, exclude_options={"postlex"})


def parse_tree(text: str, filename: str) -> ast.Module:
    """``text`` parsed with the LALR parser and turned into ``ast`` nodes; a syntax error, or
    nesting deeper than ``MAX_NESTING``, is a ``PipegenError`` at its place."""
    try:
        tree = lalr_parser().parse(text)
    except UnexpectedInput as e:
        raise _syntax_error(e, text, filename) from None
    _check_nesting(tree, text, filename)
    try:
        return _ToAst(text, filename).transform(tree)
    except VisitError as e:   # lark wraps exceptions raised inside transformer callbacks
        if isinstance(e.orig_exc, PipegenError):
            raise e.orig_exc from None
        raise


def _check_nesting(tree: Tree, text: str, filename: str) -> None:
    """Reject trees deeper than ``MAX_NESTING`` (iteratively: the tree may be arbitrarily
    deep), pointing at the construct that goes one level too deep."""
    stack = [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_NESTING:
            meta = node.meta
            line, col = (meta.line, meta.column) if not getattr(meta, "empty", True) else (1, 1)
            raise PipegenError(
                Span(filename, line, col, line, col + 1, text),
                f"nested too deeply: more than {MAX_NESTING} levels of statements, calls "
                f"and operators (each operator of a chain like a + b + c is a level)",
                "split it up: compute parts into local variables or helper functions")
        for child in node.children:
            if isinstance(child, Tree):
                stack.append((child, depth + 1))


# ---------------------------------------------------------------------------------------------
# Parse tree -> AST
# ---------------------------------------------------------------------------------------------


class _StencilTail(ast.Node):
    """``stencil VALUE`` after a pass-level ``clear T depth D`` (see the grammar's comment)."""

    def __init__(self, value: ast.Expr, span: Span):
        self.value = value
        self.span = span


class _DepthInside:
    def __init__(self, func: ast.Word, span: Span):
        self.func, self.span = func, span


class _LightSet:
    def __init__(self, pack: ast.Name, index: ast.Expr):
        self.pack, self.index = pack, index


def _present(children: list) -> list:
    """Drop the ``None`` placeholders lark leaves for absent ``[optional]`` parts."""
    return [c for c in children if c is not None]


def _as_body(x) -> list:
    """An if/for body: a block (already a list), a declaration (a list) or one statement."""
    return x if isinstance(x, list) else [x]


def _flatten(stmts: list) -> list:
    """Block contents: a declaration of several names arrives as a list of ``VarDecl``."""
    out = []
    for s in stmts:
        out.extend(s if isinstance(s, list) else [s])
    return out


@v_args(meta=True)
class _ToAst(Transformer):
    def __init__(self, text: str, filename: str):
        super().__init__(visit_tokens=False)
        self.text = text
        self.filename = filename

    # -- spans -------------------------------------------------------------------------------
    def _span(self, meta) -> Span:
        if getattr(meta, "empty", True):
            return Span(self.filename, 1, 1, 1, 1, self.text)
        return Span(self.filename, meta.line, meta.column, meta.end_line, meta.end_column,
                    self.text)

    def _tok_span(self, tok: Token) -> Span:
        return Span(self.filename, tok.line, tok.column, tok.end_line, tok.end_column, self.text)

    def _name(self, tok: Token) -> ast.Name:
        return ast.Name(str(tok), span=self._tok_span(tok))

    def _error(self, span: Span, message: str, hint: str) -> PipegenError:
        return PipegenError(span, message, hint)

    # -- top level ---------------------------------------------------------------------------
    def start(self, meta, items):
        return ast.Module(items, self.filename, span=self._span(meta))

    def technique(self, meta, ch):
        title = _unquote(ch[1]) if len(ch) > 1 else ""
        return ast.TechniqueDecl(self._name(ch[0]), title, span=self._span(meta))

    def include(self, meta, ch):
        return ast.Include(_unquote(ch[0]), span=self._span(meta))

    def param(self, meta, ch):
        name, type_tok, value, allowed, accurate = ch
        type_name = self._name(type_tok) if type_tok is not None else None
        return ast.ParamDecl(self._name(name), type_name, value, allowed, accurate,
                             span=self._span(meta))

    def allowed(self, meta, values):
        return values

    def accurate(self, meta, ch):
        return ch[0]

    def lights(self, meta, ch):
        ch = _present(ch)
        return ast.LightsDecl(ch[0], ch[1:], span=self._span(meta))

    def light_field(self, meta, ch):
        return ast.LightFieldDecl(self._name(ch[0]), self._name(ch[1]), span=self._span(meta))

    def material(self, meta, ch):
        return ast.MaterialDecl(_present(ch), span=self._span(meta))

    def material_field(self, meta, ch):
        return ast.MaterialFieldDecl(self._name(ch[0]), self._name(ch[1]), ch[2],
                                     span=self._span(meta))

    def target(self, meta, ch):
        *options, condition = ch[2:]      # [condition] leaves a None placeholder when absent
        return ast.TargetDecl(self._name(ch[0]), self._name(ch[1]), options,
                              condition=condition, span=self._span(meta))

    def size_abs(self, meta, ch):
        return ast.SizeAbs(ch[0], ch[1], span=self._span(meta))

    def size_rel(self, meta, ch):
        return ast.SizeRel(ch[0], span=self._span(meta))

    def samples(self, meta, ch):
        return ast.Samples(ch[0], span=self._span(meta))

    def target_clear(self, meta, ch):
        ch[0].span = self._span(meta)   # point at `clear …`, not just at its value
        return ch[0]

    def clear_color(self, meta, ch):
        return ast.ClearSpec(color=ch[0], span=self._span(meta))

    def clear_all(self, meta, ch):
        return ast.ClearSpec(all=ch[0], span=self._span(meta))

    def clear_depth(self, meta, ch):
        stencil = ch[1] if len(ch) > 1 else None
        return ast.ClearSpec(depth=ch[0], stencil=stencil, span=self._span(meta))

    def clear_stencil(self, meta, ch):
        return ast.ClearSpec(stencil=ch[0], span=self._span(meta))

    def output(self, meta, ch):
        return ast.OutputDecl(self._name(ch[0]), span=self._span(meta))

    def expect(self, meta, ch):
        tok = ch[0]
        keyword = Span(self.filename, meta.line, meta.column, meta.line, meta.column + 6,
                       self.text)
        return parse_expect(str(tok), tok.line, tok.column, self.text, self.filename, keyword)

    def pack(self, meta, ch):
        ch = _present(ch)
        return ast.PackDecl(self._name(ch[0]), self._name(ch[1]), ch[2:], span=self._span(meta))

    def option(self, meta, ch):
        key, value = ch
        if isinstance(value, Token):       # a STRING
            value = _unquote(value)
        return ast.Option(self._name(key), value, span=self._span(meta))

    def record(self, meta, options):
        return ast.Record(options, span=self._span(meta))

    # -- declaration values ------------------------------------------------------------------
    def signed_number(self, meta, ch):
        sign, tok = ch
        number = self._number(tok)
        if sign is not None:
            number.value = -number.value
            number.span = self._span(meta)
        return number

    def flag(self, meta, ch):
        return ast.Bool(ch[0] == "true", span=self._span(meta))

    def member(self, meta, ch):
        return ast.Field(ch[0], self._name(ch[1]), span=self._span(meta))

    def ident(self, meta, ch):
        return self._name(ch[0])

    def tuple(self, meta, items):
        return ast.TupleLit(items, span=self._span(meta))

    # -- passes ------------------------------------------------------------------------------
    def pass_decl(self, meta, ch):
        return ast.PassDecl(self._name(ch[0]), self._merge_stencil_tails(ch[2:]),
                            condition=ch[1], span=self._span(meta))

    def condition(self, meta, ch):
        return ast.Condition(ch[0], span=self._span(meta))

    def _merge_stencil_tails(self, stmts: list) -> list:
        out = []
        for s in stmts:
            if not isinstance(s, _StencilTail):
                out.append(s)
                continue
            prev = out[-1] if out else None
            if not (isinstance(prev, ast.PassClear) and prev.clear.depth is not None
                    and prev.clear.stencil is None):
                raise self._error(
                    s.span, "`stencil VALUE` may only follow `clear TARGET depth VALUE`",
                    "stencil state is written `stencil { func … ref … }`")
            prev.clear.stencil = s.value
            prev.span = _join(prev.span, s.span)
        return out

    def repeat_block(self, meta, ch):
        types = [c for c in ch if isinstance(c, ast.Word)]
        conditions = [c for c in ch if isinstance(c, ast.Condition)]
        passes = [c for c in ch if isinstance(c, ast.PassDecl)]
        return ast.RepeatBlock(passes, types, conditions[0] if conditions else None,
                               span=self._span(meta))

    def draw(self, meta, ch):
        span = self._span(meta)
        kind = ch[0]
        if kind.type == "SCENE":
            material = self._name(ch[1]) if ch[1] is not None else None
            # `from lights …`, `shadow_volumes` or `within light radius`
            last = ch[3] if len(ch) > 3 else None
            return ast.Draw("scene", material=material, span=span,
                            back_to_front=len(ch) > 2 and ch[2] is not None,
                            from_lights=last if isinstance(last, ast.DrawFrom) else None,
                            shadow_volumes=last if isinstance(last, ast.DrawVolumes) else None,
                            within=last if isinstance(last, ast.DrawWithin) else None)
        if kind.type == "FULLSCREEN":
            return ast.Draw("fullscreen", span=span)
        draw = ast.Draw("lights", volume=ch[1], span=span)
        for m in ch[2:]:
            if isinstance(m, ast.Word):
                draw.light_types.append(m)
            elif isinstance(m, _LightSet):
                if draw.light_set is not None:
                    raise self._error(m.pack.span, "a light draw names one light set",
                                      "write `in PACK[k]` once")
                draw.light_set = (m.pack, m.index)
            else:  # SCISSOR
                draw.scissor = True
        return draw

    def draw_from(self, meta, ch):
        types = [c for c in ch if isinstance(c, ast.Word)]
        first, tiles = ch[-2:]          # the optional clauses' placeholders (None: absent)
        return ast.DrawFrom(types, tiles, first, span=self._span(meta))

    def draw_volumes(self, meta, ch):
        return ast.DrawVolumes(span=self._span(meta))

    def draw_within(self, meta, ch):
        return ast.DrawWithin(span=self._span(meta))

    def light_set(self, meta, ch):
        return _LightSet(self._name(ch[0]), ch[1])

    def writes(self, meta, names):
        return ast.Writes([self._name(n) for n in names], span=self._span(meta))

    def reads(self, meta, names):
        return ast.Reads([self._name(n) for n in names], span=self._span(meta))

    def depth(self, meta, ch):
        target, rest = self._name(ch[0]), ch[1:]
        if isinstance(rest[0], Token):   # OFF
            return ast.Depth(target, None, [], span=self._span(meta))
        flags = [f for f in rest[1:] if not isinstance(f, _DepthInside)]
        inside = [f for f in rest[1:] if isinstance(f, _DepthInside)]
        if len(inside) > 1:
            raise self._error(inside[1].span, "`inside` is given twice", "give it once")
        return ast.Depth(target, rest[0], flags, inside[0].func if inside else None,
                         span=self._span(meta))

    def depth_inside(self, meta, ch):
        return _DepthInside(ch[0], self._span(meta))

    def stencil(self, meta, ch):
        return ast.Stencil(ch[0], ch[1:], span=self._span(meta))

    def stencil_item(self, meta, ch):
        key = "pass" if ch[0] == "zpass" else str(ch[0])
        return ast.StencilItem(key, ch[1], span=self._span(meta))

    def stencil_clear_tail(self, meta, ch):
        return _StencilTail(ch[0], self._span(meta))

    def blend(self, meta, ch):
        target, rest = self._name(ch[0]), ch[1:]
        span = self._span(meta)
        if len(rest) == 1 and isinstance(rest[0], Token):   # OFF
            return ast.Blend(target, None, None, span=span)
        if len(rest) == 1:
            return ast.Blend(target, rest[0], rest[0], span=span)
        return ast.Blend(target, rest[1], rest[2], span=span)   # RGB eq alpha eq

    def blend_eq(self, meta, ch):
        return ast.BlendEq(ch[0], ch[1], ch[2], span=self._span(meta))

    def blend_constant(self, meta, ch):
        return ast.BlendConstant(ch[0], span=self._span(meta))

    def mask(self, meta, ch):
        return ast.Mask(self._name(ch[0]), self._name(ch[1]), span=self._span(meta))

    def cull(self, meta, ch):
        return ast.Cull(ch[0], span=self._span(meta))

    def offset(self, meta, ch):
        return ast.Offset(ch[0], ch[1], span=self._span(meta))

    def pass_clear(self, meta, ch):
        return ast.PassClear(self._name(ch[0]), ch[1], span=self._span(meta))

    def repeat_stmt(self, meta, ch):
        return ast.RepeatPerLight(list(ch), span=self._span(meta))

    def fragment(self, meta, stmts):
        return ast.Fragment(_flatten(stmts), span=self._span(meta))

    def _word(self, meta, ch):
        return ast.Word(str(ch[0]), span=self._span(meta))

    word_volume = word_light_type = word_compare = word_depth_flag = word_face = _word
    word_stencil_op = word_blend_op = word_factor = word_cull = _word

    # -- shader code -------------------------------------------------------------------------
    def function(self, meta, ch):
        ch = _present(ch)
        params = [c for c in ch[2:] if isinstance(c, ast.ParamDef)]
        body = _flatten(ch[2 + len(params):])
        return ast.FunctionDef(ch[0], ch[1], params, body, span=self._span(meta))

    def param_def(self, meta, ch):
        return ast.ParamDef(ch[0], ch[1], span=self._span(meta))

    def block(self, meta, stmts):
        return _flatten(stmts)

    def declaration(self, meta, ch):
        type_name, declarators = ch[0], ch[1:]
        return [ast.VarDecl(type_name, name, init, span=span)
                for name, init, span in declarators]

    def declarator(self, meta, ch):
        return ch[0], ch[1], self._span(meta)

    def assignment(self, meta, ch):
        return ast.Assign(ch[0], ch[1], ch[2], span=self._span(meta))

    def assign_op(self, meta, ch):
        return str(ch[0])

    def expr_stmt(self, meta, ch):
        return ast.ExprStmt(ch[0], span=self._span(meta))

    def if_stmt(self, meta, ch):
        cond, then, *rest = ch           # no placeholder for an absent else: _body is inlined
        other = rest[0] if rest else None
        return ast.If(cond, _as_body(then), _as_body(other) if other is not None else None,
                      span=self._span(meta))

    def for_stmt(self, meta, ch):
        var_type, var, start, cond, (step_var, step), body = ch
        return ast.For(var_type, var, start, cond, step_var, step, _as_body(body),
                       span=self._span(meta))

    def for_step(self, meta, ch):
        if len(ch) == 3:                                  # i += STEP
            return ch[0], ch[2]
        var = ch[0] if isinstance(ch[0], ast.Name) else ch[1]   # i++ / ++i
        return var, ast.Number(1, "int", span=self._span(meta))

    def break_stmt(self, meta, ch):
        return ast.Break(span=self._span(meta))

    def continue_stmt(self, meta, ch):
        return ast.Continue(span=self._span(meta))

    def return_stmt(self, meta, ch):
        return ast.Return(ch[0], span=self._span(meta))

    def discard_stmt(self, meta, ch):
        return ast.Discard(span=self._span(meta))

    def conditional(self, meta, ch):
        return ast.Conditional(ch[0], ch[1], ch[2], span=self._span(meta))

    def binary(self, meta, ch):
        return ast.BinaryOp(str(ch[1]), ch[0], ch[2], span=self._span(meta))

    def unary(self, meta, ch):
        return ast.UnaryOp(str(ch[0]), ch[1], span=self._span(meta))

    def field(self, meta, ch):
        return ast.Field(ch[0], ch[1], span=self._span(meta))

    def index(self, meta, ch):
        return ast.Subscript(ch[0], ch[1], span=self._span(meta))

    def method_call(self, meta, ch):
        return ast.MethodCall(ch[0], ch[1], _present(ch[2:]), span=self._span(meta))

    def call(self, meta, ch):
        return ast.Call(ch[0], _present(ch[1:]), span=self._span(meta))

    def name(self, meta, ch):
        return self._name(ch[0])

    def number(self, meta, ch):
        return self._number(ch[0])

    def bool(self, meta, ch):
        return ast.Bool(ch[0] == "true", span=self._span(meta))

    def _number(self, tok: Token) -> ast.Number:
        span = self._tok_span(tok)
        text = str(tok)
        unsigned = text[-1] in "uU"
        digits = text[:-1] if unsigned else text
        is_hex = digits[:2].lower() == "0x"
        if not is_hex and any(c in digits for c in ".eE"):
            if unsigned:
                raise self._error(span, f"'{text}' is not a valid literal",
                                  "a 'u' suffix makes an unsigned integer: write 2u, not 2.0u")
            value = float(digits)
            if value > _FLT_MAX:
                raise self._error(span, f"float literal '{text}' is too large for a float",
                                  "a float holds up to about 3.4e38")
            return ast.Number(value, "float", span=span)
        significant = (digits[2:] if is_hex else digits).lstrip("0")
        # (a bound on the digits first: int() refuses thousands of them)
        value = int(significant[:12] or "0", 16 if is_hex else 10)
        if len(significant) > 12:
            value = 1 << 40
        limit = 0xFFFFFFFF if unsigned or is_hex else 0x7FFFFFFF
        if value > limit:
            kind = "uint" if unsigned else "int"
            raise self._error(span, f"integer literal '{text}' does not fit in {kind}",
                              "int holds up to 2147483647 and uint (the u suffix) 4294967295")
        if is_hex and not unsigned and value > 0x7FFFFFFF:
            value -= 1 << 32        # GLSL: a hex int literal is a 32-bit pattern (0xFFFFFFFF == -1)
        return ast.Number(value, "uint" if unsigned else "int", span=span)


_FLT_MAX = 3.4028234663852886e38


def _unquote(tok: Token) -> str:
    """A string literal's text, with the escapes Python knows decoded (\\n, \\", \\xHH,
    \\uXXXX, octal…); an escape that is not one (\\q, a truncated \\x4, a surrogate) stays as
    written, backslash included."""
    body = str(tok)[1:-1]
    if "\\" not in body:
        return body
    import re
    return re.sub(r"\\(x[0-9a-fA-F]{2}|u[0-9a-fA-F]{4}|U[0-9a-fA-F]{8}|[0-7]{1,3}|.)",
                  _escape, body, flags=re.S)


_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "a": "\a", "b": "\b", "f": "\f", "v": "\v",
            "\\": "\\", '"': '"', "'": "'", "\n": ""}


def _escape(m) -> str:
    e = m.group(1)
    if e[0] in "xuU" and len(e) > 1 or e[0] in "01234567":
        code = int(e, 8) if e[0] in "01234567" else int(e[1:], 16)
        if code <= 0x10FFFF and not 0xD800 <= code <= 0xDFFF:
            return chr(code)
        return m.group(0)
    return _ESCAPES.get(e, m.group(0))


def _join(a: Span, b: Span) -> Span:
    return Span(a.file, a.line, a.column, b.end_line, b.end_column, a.text)


# ---------------------------------------------------------------------------------------------
# Syntax errors in the user's words
# ---------------------------------------------------------------------------------------------

# Terminals that stand for a class of tokens rather than one spelling.
_TOKEN_CLASSES = {"NAME": "a name", "NUMBER": "a number", "STRING": "a string in double quotes",
                  "$END": "the end of the file",
                  "EXPECT_TEXT": "an expectation on the same line (e.g. `color agrees gl cl`)"}
_OPERATORS = {"OROR", "ANDAND", "PIPE", "CARET", "AMP", "EQ_OP", "REL_OP", "SHIFT_OP", "PLUS",
              "MINUS", "MUL_OP", "QMARK"}
_SHADER_STATEMENTS = {"if", "for", "return", "break", "continue", "discard"}
_PASS_STATEMENTS = {"draw", "writes", "reads", "depth", "stencil", "blend", "mask", "cull",
                    "offset", "clear", "repeat", "fragment"}
_TOP_LEVEL = {"technique", "include", "param", "lights", "material", "target", "output", "pack",
              "pass"}
# Words that start a declaration, a target option or a pass statement: the likely intent
# behind an unknown word at the start of one.
_STARTERS = _PASS_STATEMENTS | _TOP_LEVEL | {"size", "samples"}
_COMPARE = {"never", "less", "equal", "lequal", "greater", "notequal", "gequal", "always"}
_MAX_LISTED = 8


def _syntax_error(e: UnexpectedInput, text: str, filename: str) -> PipegenError:
    if isinstance(e, UnexpectedCharacters):
        return _bad_character(e, text, filename)
    expected = {_spelling(t) for t in _expected_terminals(e)}
    if isinstance(e, UnexpectedEOF) or (isinstance(e, UnexpectedToken)
                                        and e.token.type == "$END"):
        line, col = _end_position(text)
        span = Span(filename, line, col, line, col + 1, text)
        return PipegenError(span, f"unexpected end of file; expected {_describe(expected)}",
                            _hint(expected, None))
    tok = e.token
    span = Span(filename, tok.line, tok.column, tok.end_line, tok.end_column, text)
    if text.startswith("/*", tok.start_pos):
        return PipegenError(span, "unterminated comment", "close it with */")
    if "';'" in expected and not expected & {"'}'", "the end of the file"}:
        prev = _end_of_previous_token(text, tok.line, tok.column)
        if prev is not None and prev[0] < tok.line:
            # A forgotten ';' at the end of a line: point there, not at the next line.
            span = Span(filename, prev[0], prev[1], prev[0], prev[1] + 1, text)
            return PipegenError(span, "expected ';' at the end of this statement",
                                "statements in shader code end with ';'")
    found = _found(tok, expected)
    return PipegenError(span, f"unexpected {found}; expected {_describe(expected)}",
                        _misspelling_hint(expected, tok, text) or _hint(expected, tok))


def _expected_terminals(e: UnexpectedInput) -> set[str]:
    """The terminals the parser could really have shifted.  ``e.expected`` is the raw LALR
    lookahead set of the failing state, which after a name also lists what may follow that name
    in unrelated contexts; replaying the parser gives the exact set."""
    interactive = getattr(e, "interactive_parser", None)
    if interactive is not None:
        return set(interactive.accepts())
    return set(getattr(e, "expected", None) or ())


def _bad_character(e: UnexpectedCharacters, text: str, filename: str) -> PipegenError:
    span = Span(filename, e.line, e.column, e.line, e.column + 1, text)
    rest = text[e.pos_in_stream:]
    if rest.startswith("/*"):
        return PipegenError(span, "unterminated comment", "close it with */")
    if rest.startswith('"'):
        return PipegenError(span, "unterminated string", 'close it with " on the same line')
    return PipegenError(span, f"unexpected character {rest[:1]!r}",
                        "names are letters, digits and '_'; see docs/language.md for the syntax")


def _spelling(terminal: str) -> str:
    """How a terminal reads in a message: "'pass'", "a name", "an operator"…"""
    if terminal in _TOKEN_CLASSES:
        return _TOKEN_CLASSES[terminal]
    if terminal in _OPERATORS:
        return "an operator"
    for t in lalr_parser().terminals:
        if t.name == terminal:
            value = t.pattern.value
            if t.pattern.type == "str":
                return f"'{value}'"
            return f"'{value.split('|')[0].strip('()?:')}'"
    return terminal.lower()


def _describe(expected: set[str]) -> str:
    """``{"'if'", "'for'", "a name", …}`` -> "a statement", "';' or an operator", …"""
    words = {w.strip("'") for w in expected}
    groups = []
    if _SHADER_STATEMENTS <= words:
        groups.append("a statement")
        expected = {w for w in expected if w.strip("'") not in _SHADER_STATEMENTS | {"else"}}
    if len(_PASS_STATEMENTS & words) >= 4:
        groups.append("a pass statement (draw, writes, reads, depth, stencil, blend, …)")
        expected = {w for w in expected if w.strip("'") not in _PASS_STATEMENTS}
    if len(_TOP_LEVEL & words) >= 4:
        groups.append("a declaration (target, param, pass, …)")
        expected = {w for w in expected if w.strip("'") not in _TOP_LEVEL | {"repeat"}}
    if groups:
        # Inside statement lists a name or literal merely starts one of the statements.
        expected = {w for w in expected if w not in ("a name", "a number", "'true'", "'false'",
                                                      "'('", "'-'", "'+'", "'!'", "'~'")}
    items = sorted(expected, key=_order) + groups
    if len(items) > _MAX_LISTED:
        items = items[:_MAX_LISTED - 1] + ["…"]
    if len(items) == 1:
        return items[0]
    return ", ".join(items[:-1]) + " or " + items[-1]


def _order(word: str) -> tuple:
    # Punctuation first (most often the fix), then keywords, then classes of tokens.
    if word.startswith("'") and not word[1:2].isalpha():
        return (0, word)
    if word.startswith("'"):
        return (1, word)
    return (2, word)


def _found(tok: Token, expected: set[str]) -> str:
    if tok.type == "NAME":
        return f"name '{tok}'"
    if tok.type == "NUMBER":
        return f"number '{tok}'"
    if tok.type == "STRING":
        return f"string {tok}"
    if str(tok).isidentifier() and "a name" in expected:
        return f"keyword '{tok}' (it cannot be used as a name here)"
    return f"'{tok}'"


def _misspelling_hint(expected: set[str], tok: Token, text: str) -> Optional[str]:
    """'did you mean …' for a misspelt keyword: the unexpected word itself, or an earlier word
    on its line that a declaration or pass statement was probably meant to start with
    (``targt x : rgba8`` fails only at the ':', read as a function ``targt x(…)``)."""
    keywords = {w.strip("'") for w in expected if w.startswith("'") and w[1:2].isalpha()}
    if tok.type == "NAME" and keywords:
        close = _close_matches(str(tok), sorted(keywords), cutoff=0.6)
        if close:
            return f"did you mean '{close[0]}'?"
    import re
    line = _lines(text)[tok.line - 1][:tok.column - 1]
    for word in re.findall(r"[A-Za-z_]\w*", line):
        if word in _STARTERS:
            continue
        close = _close_matches(word, sorted(_STARTERS), cutoff=0.75)
        if close:
            return f"'{word}' is not a keyword; did you mean '{close[0]}'?"
    return None


def _close_matches(word: str, candidates: list[str], cutoff: float) -> list[str]:
    import difflib
    return difflib.get_close_matches(word, candidates, n=1, cutoff=cutoff)


def _lines(text: str) -> list[str]:
    """The lines as the lexer counts them: split at '\\n' only (not at '\\f', '\\v', U+2028…,
    which ``str.splitlines`` also splits at)."""
    return text.split("\n")


def _hint(expected: set[str], tok: Optional[Token]) -> str:
    words = {w.strip("'") for w in expected}
    if tok is None and "}" in words:
        return "a '{' is not closed"
    if tok is None and ")" in words:
        return "a '(' is not closed"
    if len(_PASS_STATEMENTS & words) >= 4:
        return ("a pass holds draw, writes, reads, depth, stencil, blend, mask, cull, offset, "
                "clear, repeat per light and fragment { … } statements")
    if len(_TOP_LEVEL & words) >= 4:
        return ("top-level declarations are technique, include, param, lights, material, target, "
                "output, pack, pass, repeat per light { … } and functions like "
                "`float f(float x) { … }`")
    if _COMPARE <= words:
        return "comparison functions: " + " ".join(sorted(_COMPARE))
    if tok is not None and tok.type == "NAME" and words == {"x"}:
        return "write an absolute size as `size W x H`, with spaces around the x"
    if "," in words and ")" in words:
        return "separate arguments with ','"
    if ";" in words:
        return "statements in shader code end with ';'"
    return "see docs/language.md for the syntax"


def _end_position(text: str) -> tuple[int, int]:
    lines = _lines(text.rstrip())
    return len(lines), len(lines[-1]) + 1


def _end_of_previous_token(text: str, line: int, column: int) -> Optional[tuple[int, int]]:
    """(line, column just after) the last non-blank character before ``line:column``,
    skipping // comments."""
    lines = _lines(text)
    row, col = line - 1, column - 1
    while row >= 0:
        code = lines[row][:col] if row == line - 1 else lines[row]
        cut = code.find("//")
        code = (code[:cut] if cut >= 0 else code).rstrip()
        if code:
            return row + 1, len(code) + 1
        row -= 1
    return None
