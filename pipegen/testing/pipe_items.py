"""pytest collects a ``.pipe`` file's expectations as test items (the plugin's
``pytest_collect_file`` calls ``collect_pipe_file``): one item per ``expect`` line, named
``line N: expect ...``, checked by ``expectations.check``.

A failure is reported as ``file:line`` and the reason with its numbers, not a Python
traceback; a file that does not compile is a collection error showing pipegen's message.  An
item that renders is marked ``pipegen_requires("gl", "cl")`` (skipped, with the reason, where
a backend cannot run) and, where the project declares them, ``gl`` and ``cl``.

The only module of pipegen.testing that imports pytest (the plugin imports it when pytest
asks for a ``.pipe`` file).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Optional

import pytest

from pipegen.core.diagnostics import PipegenError

# a line starting with `expect` and a blank: the cheap test before compiling a .pipe file
_EXPECT_LINE = re.compile(rb"^[ \t]*expect[ \t]", re.M)


def collect_pipe_file(parent, file_path: Path) -> Optional["PipeFile"]:
    """A ``pytest.File`` node for ``file_path`` when it holds an ``expect`` line, else None
    (the file is not read further: a project's library of .pipe files costs nothing)."""
    try:
        data = Path(file_path).read_bytes()
    except OSError:
        return None
    if not _EXPECT_LINE.search(data):
        return None
    return PipeFile.from_parent(parent, path=Path(file_path))


class PipeFile(pytest.File):
    """A technique whose expectations are test items."""

    compiled = None

    def collect(self):
        from pipegen.testing.expectations import load
        here = os.path.relpath(self.path)           # messages name it as the summary does
        try:
            self.compiled = load(self.path if here.startswith("..") else here)
        except PipegenError as e:
            raise self.CollectError(e.render()) from None
        for e in self.compiled.technique.expectations:
            yield ExpectItem.from_parent(self, name=f"line {e.span.line}: expect {e.text}",
                                         expectation=e)


class ExpectationFailed(AssertionError):
    """An expectation that does not hold; the message is the reason with its numbers."""


class ExpectItem(pytest.Item):
    """One ``expect`` line of a technique."""

    def __init__(self, *, expectation, **kwargs):
        super().__init__(**kwargs)
        self.expectation = expectation
        from pipegen.testing.expectations import backends_needed
        needed = backends_needed(expectation)
        if needed:
            self.add_marker(pytest.mark.pipegen_requires(*needed))
            declared = {line.split(":")[0].split("(")[0].strip()
                        for line in self.config.getini("markers")}
            for backend in needed:
                if backend in declared:       # e.g. pipegen's own suite guards gl / cl
                    self.add_marker(getattr(pytest.mark, backend))

    def runtest(self) -> None:
        from pipegen.testing.expectations import check
        outcome = check(self.parent.compiled, self.expectation)
        if not outcome.passed:
            raise ExpectationFailed(outcome.line())

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, ExpectationFailed):
            return str(excinfo.value)
        if isinstance(excinfo.value, PipegenError):
            return excinfo.value.render()
        return super().repr_failure(excinfo, style)

    def reportinfo(self):
        return self.path, self.expectation.span.line - 1, self.name
