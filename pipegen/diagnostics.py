"""User-facing errors: ``file:line:col``, the source line, a caret, and a hint.

A ``PipegenError`` is raised for anything wrong with the user's input; internal invariants are
plain ``assert``s.  The CLI prints ``err.render()`` and exits with status 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
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
        lines = self.text.splitlines()
        return lines[self.line - 1] if 0 < self.line <= len(lines) else ""


class PipegenError(Exception):
    """An error in the user's input, located in the source."""

    def __init__(self, span: Optional[Span], message: str, hint: str = ""):
        super().__init__(message)
        self.span = span
        self.message = message
        self.hint = hint

    def render(self) -> str:
        out = []
        if self.span is None:
            out.append(f"error: {self.message}")
        else:
            s = self.span
            out.append(f"{s.file}:{s.line}:{s.column}: error: {self.message}")
            line = s.source_line
            if line:
                gutter = f"{s.line:>5} | "
                out.append(gutter + line)
                width = 1
                if s.end_line == s.line and s.end_column > s.column:
                    width = s.end_column - s.column
                out.append(" " * (len(gutter) - 2) + "| " + " " * (s.column - 1) + "^" * width)
        if self.hint:
            out.append(f"hint: {self.hint}")
        return "\n".join(out)

    def __str__(self) -> str:
        return self.render()
