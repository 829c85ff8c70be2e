"""Journals of long runs that survive being stopped (issue 29): ``pipegen sweep``'s
``rows.jsonl`` (``tools/sweep/journal.py``) and ``pipegen stress``'s ``cases.jsonl``
(``tools/stress/journal.py``).

A journal is a JSON-lines file in an output folder: a first line ``{KIND: identity}`` (what
makes the run's results the same results: its files and their SHA-256, its options), then one
line per finished piece of work.  Each piece is committed with ``OutputDir.commit_files``
(every file replaced atomically, the journal last) inside ``interrupts_deferred``, so the
folder is valid after any piece and a ``kill -9`` loses only the work in flight.  ``--resume``
reads the journal back (``read_journal``), refuses a run whose identity differs
(``check_identity``: a ``PipegenError`` naming what differs) and skips the pieces it holds.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import signal
import threading
from pathlib import Path
from typing import Optional

from pipegen.core.diagnostics import PipegenError


def file_sha256(path) -> Optional[str]:
    """The file's SHA-256 (hex), or None when it cannot be read."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def absolute(path) -> str:
    return str(Path(path).resolve())


def read_journal(path: Path, kind: str, command: str) -> tuple[dict, list[str], list[dict]]:
    """``(identity, lines, entries)`` of the journal at ``path`` (one entry per line after the
    first); a ``PipegenError`` when it is not a ``kind`` journal (``command``: what to run
    again, for the hint)."""
    lines = path.read_text().splitlines()
    try:
        entries = [json.loads(line) for line in lines]
        identity = entries[0][kind]
        if not isinstance(identity, dict) or not all(isinstance(e, dict) for e in entries):
            raise TypeError
    except (ValueError, KeyError, IndexError, TypeError):
        raise PipegenError(None, f"--resume: '{path}' is not a {kind} journal pipegen can "
                                 f"read", hint=f"run the {command} again without --resume")
    return identity, lines[1:], entries[1:]


def check_identity(identity: dict, before: dict, folder, what: dict, kind: str,
                   hint: str) -> None:
    """Refuse to resume when ``identity`` is not the journal's (``before``): a
    ``PipegenError`` naming each key that differs in words (``what``: key -> words)."""
    differ = [k for k in sorted(set(identity) | set(before)) if identity.get(k) != before.get(k)]
    if differ:
        raise PipegenError(None, f"--resume: this {kind} is not the one in '{folder}': "
                                 f"{', '.join(what.get(k, k) for k in differ)} "
                                 f"differ{'s' if len(differ) == 1 else ''}", hint=hint)


def read_back(folder, rel: str, kind: str, what: str) -> bytes:
    """A file an earlier run committed (``what``: whose, for the error)."""
    try:
        return (Path(folder) / rel).read_bytes()
    except OSError:
        raise PipegenError(None, f"--resume: '{rel}' of {what} is missing from '{folder}'",
                           hint=f"run the {kind} again without --resume") from None


@contextlib.contextmanager
def interrupts_deferred():
    """Hold back SIGINT (Ctrl-C) in the block and raise KeyboardInterrupt after it, so that a
    commit is never cut short by this process's own handler (in the main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda *a: caught.append(a))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt
