"""The words of an ``expect`` statement (the grammar hands over the rest of its line).

``expect SUBJECT agrees BACKEND BACKEND [BOUND]``, ``expect SUBJECT vs f64 [BOUND]`` or
``expect COUNT OP NUMBER``, then ``on "scene"`` and/or ``at W x H`` in either order, where
BOUND is ``STATISTIC OP NUMBER`` (``p99 <= 2``).  Read here rather than by the LALR grammar:
``p99.9`` and ``96x64`` are one word each here but not tokens of the language, and which words
are targets, backends or statistics is the lowering's to check (frontend/lower/expectations.py),
with a did-you-mean.  Every error is a ``PipegenError`` at the word.
"""

from __future__ import annotations

import re
from typing import NamedTuple, Optional

from pipegen.frontend import ast
from pipegen.core.diagnostics import PipegenError, Span

_TOKENS = re.compile(r"""
    (?P<space>[ \t]+)
  | (?P<string>"([^"\\\n]|\\.)*")
  | (?P<size>\d+[ \t]*x[ \t]*\d+(?![\w.]))
  | (?P<number>(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?(?![\w.]))
  | (?P<op><=|>=|==|!=|<|>)
  | (?P<word>[A-Za-z_][\w./-]*)
""", re.VERBOSE)

EXAMPLES = ("`expect color agrees gl cl`, `expect color vs f64 p99 <= 2` or "
            "`expect lights_dropped == 0`")


class _Tok(NamedTuple):
    kind: str
    text: str
    span: Span


def parse_expect(text: str, line: int, column: int, source: str, filename: str,
                 keyword: Span) -> ast.Expect:
    """The ``expect`` statement whose words are ``text`` (starting at ``line:column`` of
    ``source``); ``keyword`` spans the word ``expect``."""
    return _Reader(_tokens(text.rstrip(), line, column, source, filename), keyword).expect()


def _tokens(text: str, line: int, column: int, source: str, filename: str) -> list[_Tok]:
    out, pos = [], 0
    while pos < len(text):
        m = _TOKENS.match(text, pos)
        col = column + pos
        if m is None:
            bad = text[pos]
            raise PipegenError(Span(filename, line, col, line, col + 1, source),
                               f"unexpected {_quoted(bad)} in an expectation",
                               f"write {EXAMPLES}; a scene path is a string in double quotes")
        if m.lastgroup != "space":
            span = Span(filename, line, col, line, column + m.end(), source)
            out.append(_Tok(m.lastgroup, m.group(), span))
        pos = m.end()
    return out


def _quoted(c: str) -> str:
    return "'\"'" if c == '"' else repr(c)


def _unquote(s: str) -> str:
    return re.sub(r"\\(.)", r"\1", s[1:-1])


class _Reader:
    def __init__(self, toks: list[_Tok], keyword: Span):
        self.toks = toks
        self.k = 0
        self.keyword = keyword

    # -- the token stream ----------------------------------------------------------------------
    def peek(self, offset: int = 0) -> Optional[_Tok]:
        i = self.k + offset
        return self.toks[i] if i < len(self.toks) else None

    def take(self, kind: str, what: str, hint: str) -> _Tok:
        tok = self.peek()
        if tok is None or tok.kind != kind:
            raise self.unexpected(tok, what, hint)
        self.k += 1
        return tok

    def at_word(self, *words: str) -> bool:
        tok = self.peek()
        return tok is not None and tok.kind == "word" and (not words or tok.text in words)

    def unexpected(self, tok: Optional[_Tok], what: str, hint: str) -> PipegenError:
        if tok is None:
            last = self.toks[-1].span if self.toks else self.keyword
            span = Span(last.file, last.end_line, last.end_column, last.end_line,
                        last.end_column + 1, last.text)
            return PipegenError(span, f"the expectation ends here; expected {what}", hint)
        return PipegenError(tok.span, f"unexpected {_describe(tok)}; expected {what}", hint)

    # -- the statement -------------------------------------------------------------------------
    def expect(self) -> ast.Expect:
        subject = self.name(self.take("word", "a target or a count (e.g. lights_dropped)",
                                      f"write {EXAMPLES}"))
        against: list[ast.Name] = []
        statistic = op = value = None
        tok = self.peek()
        if self.at_word("agrees"):
            self.k += 1
            while self.at_word() and self.peek().text not in ("on", "at") and not (
                    self.peek(1) is not None and self.peek(1).kind == "op"):
                against.append(self.name(self.toks[self.k]))
                self.k += 1
            if not against:
                raise self.unexpected(self.peek(), "the backends that agree",
                                      "write e.g. `expect color agrees gl cl`")
            check = "agrees"
        elif self.at_word("vs"):
            self.k += 1
            against.append(self.name(self.take(
                "word", "what to compare with (f64)",
                "write e.g. `expect color vs f64`: the float32 backends against the "
                "float64 evaluation")))
            check = "vs"
        elif tok is not None and tok.kind == "op":
            check = "count"
            op, value = self.comparison()
        else:
            raise self.unexpected(tok, "'agrees', 'vs' or a comparison (==, <=, <, >=, >)",
                                  f"write {EXAMPLES}")
        if check != "count" and self.at_word() and self.peek().text not in ("on", "at"):
            statistic = self.name(self.toks[self.k])
            self.k += 1
            op, value = self.comparison()
        scene, size = self.where()
        text = " ".join(re.sub(r"[ \t]+", "", t.text) if t.kind == "size" else t.text
                        for t in self.toks)
        return ast.Expect(subject, check, against, statistic, op, value, scene, size, text,
                          span=_join(self.keyword, self.toks[-1].span))

    def comparison(self) -> tuple[ast.Word, ast.Number]:
        tok = self.take("op", "a comparison (<=, <, ==, >=, >)",
                        "a bound reads e.g. `p99 <= 2` or `lights_dropped == 0`")
        op = ast.Word(tok.text, span=tok.span)
        num = self.take("number", "a number", "a bound reads e.g. `p99 <= 2`")
        kind = "float" if any(c in num.text for c in ".eE") else "int"
        value = float(num.text) if kind == "float" else int(num.text)
        return op, ast.Number(value, kind, span=num.span)

    def where(self) -> tuple[Optional[ast.Word], Optional[ast.SizeAbs]]:
        """``on "scene"`` and ``at W x H``, each at most once, in either order."""
        scene = size = None
        while self.peek() is not None:
            tok = self.peek()
            if self.at_word("on") and scene is None:
                self.k += 1
                s = self.take("string", "the scene file, a string in double quotes",
                              'write e.g. `on "scenes/hard.toml"` (relative to this file)')
                scene = ast.Word(_unquote(s.text), span=s.span)
            elif self.at_word("at") and size is None:
                self.k += 1
                s = self.take("size", "a size W x H", "write e.g. `at 96x64`")
                w, h = (int(v) for v in re.split(r"[ \t]*x[ \t]*", s.text))
                size = ast.SizeAbs(ast.Number(w, "int", span=s.span),
                                   ast.Number(h, "int", span=s.span), span=s.span)
            else:
                given = [w for w, v in (("on", scene), ("at", size)) if v is not None]
                left = [f"'{w}'" for w in ("on", "at") if w not in given]
                if tok.kind == "word" and tok.text in given:
                    raise PipegenError(tok.span, f"'{tok.text}' is given twice",
                                       "an expectation has one scene and one size")
                raise self.unexpected(tok, " or ".join(left) or "the end of the line",
                                      'an expectation ends with `on "scene.toml"` and/or '
                                      '`at W x H`; write one expectation per line')
        return scene, size

    @staticmethod
    def name(tok: _Tok) -> ast.Name:
        return ast.Name(tok.text, span=tok.span)


def _describe(tok: _Tok) -> str:
    return {"word": f"word '{tok.text}'", "number": f"number '{tok.text}'",
            "string": f"string {tok.text}", "size": f"size '{tok.text}'",
            "op": f"'{tok.text}'"}[tok.kind]


def _join(a: Span, b: Span) -> Span:
    return Span(a.file, a.line, a.column, b.end_line, b.end_column, a.text)
