"""User-facing errors: ``file:line:col``, the source line, a caret, and a hint.

A ``PipegenError`` is raised for anything wrong with the user's input; internal invariants are
plain ``assert``s.  The CLI prints ``err.render()`` and exits with status 1.
"""

from __future__ import annotations

from typing import Optional

from pipegen.core.records import record


@record(frozen=True)
class Span:
    file: str
    line: int          # 1-based
    column: int        # 1-based
    end_line: int = 0
    end_column: int = 0
    text: str = ""     # the whole source text (so errors can quote the line); not compared

    def __eq__(self, other: object) -> bool:  # spans compare by position, not by source text
        return isinstance(other, Span) and (self.file, self.line, self.column) == (
            other.file, other.line, other.column)

    def __hash__(self) -> int:
        return hash((self.file, self.line, self.column))

    def __repr__(self) -> str:
        return f"Span({self.file}:{self.line}:{self.column})"

    @property
    def source_line(self) -> str:
        """The line the span starts on, counted as the lexer counts lines: at '\\n' only (not at
        '\\f', '\\v' or U+2028, where ``str.splitlines`` would also split), without a '\\r'."""
        lines = self.text.split("\n")
        line = lines[self.line - 1] if 0 < self.line <= len(lines) else ""
        return line[:-1] if line.endswith("\r") else line

    @staticmethod
    def at_offset(file: str, text: str, offset: int) -> "Span":
        """The one-character span at character ``offset`` of ``text``."""
        offset = max(0, min(offset, len(text)))
        line = text.count("\n", 0, offset) + 1
        column = offset - (text.rfind("\n", 0, offset) + 1) + 1
        return Span(file, line, column, line, column + 1, text)


class PipegenError(Exception):
    """An error in the user's input, located in the source."""

    def __init__(self, span: Optional[Span], message: str, hint: str = ""):
        super().__init__(message)
        self.span = span
        self.message = message
        self.hint = hint

    def render(self, kind: str = "error") -> str:
        """``file:line:col: error: message``, the line, a caret, the hint; ``kind``
        "warning" for a located warning (``warning_text``)."""
        out = []
        if self.span is None:
            out.append(f"{kind}: {self.message}")
        else:
            s = self.span
            out.append(f"{s.file}:{s.line}:{s.column}: {kind}: {self.message}")
            line = _printable(s.source_line)
            if line:
                width = 1
                if s.end_line == s.line and s.end_column > s.column:
                    width = s.end_column - s.column
                line, column = _window(line, s.column)
                width = max(1, min(width, len(line) + 1 - column))
                gutter = f"{s.line:>5} | "
                out.append(gutter + line)
                out.append(" " * (len(gutter) - 2) + "| " + " " * (column - 1) + "^" * width)
        if self.hint:
            out.append(f"hint: {self.hint}")
        return "\n".join(out)

    def __str__(self) -> str:
        return self.render()


def warning_text(span: Optional[Span], message: str, hint: str = "") -> str:
    """A warning located in the source, laid out as an error is."""
    return PipegenError(span, message, hint).render("warning")


def _printable(line: str) -> str:
    """The quoted line with control characters (an escape sequence, a NUL…) shown as '?', one
    character each so the caret stays under its column."""
    if line.isprintable():
        return line
    return "".join(c if c.isprintable() or c == "\t" else "?" for c in line)


_WIDTH = 120


def _window(line: str, column: int) -> tuple[str, int]:
    """A long line cut to about ``_WIDTH`` characters around ``column`` ('…' where cut), and
    the column in what is shown."""
    if len(line) <= _WIDTH:
        return line, column
    start = max(0, min(column - 1 - _WIDTH // 2, len(line) - _WIDTH))
    shown = line[start:start + _WIDTH]
    prefix = "…" if start > 0 else ""
    suffix = "…" if start + _WIDTH < len(line) else ""
    return prefix + shown + suffix, column - start + len(prefix)
