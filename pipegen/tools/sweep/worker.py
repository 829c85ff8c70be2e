"""The local pool's render processes: ``python -m pipegen.tools.sweep.worker``, one job at a time
over a pipe (``LocalPool`` in ``pools.py`` starts them).

Why not ``multiprocessing``: its spawn and forkserver children first re-create the parent's
``__main__`` (``runpy.run_path`` of the parent's script), which fails when that script was read
from standard input (``python - < script.py``: ``__main__.__file__`` is ``"<stdin>"``) and
re-runs a script without an ``if __name__ == "__main__"`` guard; fork is unsafe with GL and
OpenCL drivers loaded.  These workers import only pipegen: a job is a pickled
``(function, argument)`` whose function lives in an importable module (``jobs.render_job``).

The protocol, both ways: an 8-byte little-endian length, then a pickle.  In: ``(fn, arg)``, or
``None`` to stop.  Out: ``("ok", value)`` or an error (``error_reply``).  The
worker's own standard output goes to its standard error, so that nothing a driver prints can
corrupt a reply.
"""

from __future__ import annotations

import os
import pickle
import signal
import struct
import sys
import traceback
from pathlib import Path
from typing import BinaryIO, Optional

HEADER = struct.Struct("<Q")
# the folder holding the ``pipegen`` package: a worker must import the same pipegen as its
# parent, even where the parent found it through sys.path rather than an install
PACKAGE_ROOT = str(Path(__file__).resolve().parents[3])


def python_command(module: str) -> list[str]:
    """``python -P -m MODULE`` with this interpreter: ``-P`` keeps the current folder off the
    child's sys.path, so that a source checkout in the folder a user runs from (the repository
    root, say, where ``pipegen/`` has no built grammar) cannot stand in for the pipegen the
    parent imported; ``child_env`` puts that one first."""
    return [sys.executable, "-P", "-m", module]


def child_env(**extra: str) -> dict:
    """The environment of a child Python process that imports this pipegen (the render
    workers, the timing process)."""
    env = dict(os.environ, **extra)
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    env["PYTHONPATH"] = os.pathsep.join([PACKAGE_ROOT] + [p for p in paths
                                                          if p != PACKAGE_ROOT])
    return env


def send(stream: BinaryIO, obj) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(HEADER.pack(len(data)) + data)
    stream.flush()


def receive(stream: BinaryIO) -> Optional[object]:
    """The next message, or raises EOFError when the other end has closed the pipe."""
    head = _read_exactly(stream, HEADER.size)
    return pickle.loads(_read_exactly(stream, HEADER.unpack(head)[0]))


def _read_exactly(stream: BinaryIO, n: int) -> bytes:
    chunks, left = [], n
    while left:
        chunk = stream.read(left)
        if not chunk:
            raise EOFError("the pipe closed")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def main() -> int:
    # Ctrl-C in a terminal reaches the whole process group: the parent stops the sweep and
    # ends this process; on its own it would die with a traceback in the middle of a job
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # replies go on a private copy of stdout; fd 1 (print, C libraries) now writes to stderr
    replies = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    jobs = sys.stdin.buffer
    while True:
        try:
            message = receive(jobs)
        except EOFError:
            return 0
        if message is None:
            return 0
        fn, arg = message
        try:
            reply = ("ok", fn(arg))
        except BaseException as e:          # noqa: B902 - every failure goes back to the parent
            reply = error_reply(e, traceback.format_exc())
        send(replies, reply)


def error_reply(e: BaseException, text: str) -> tuple:
    """``("error", exception, traceback text)`` for an exception that survives a pickle round
    trip; a ``PipegenError`` (its __init__ takes more than the message) as its fields; any
    other as a RuntimeError naming it."""
    from pipegen.core.diagnostics import PipegenError
    if isinstance(e, PipegenError):
        return ("pipegen", e.span, e.message, e.hint, text)
    try:
        pickle.loads(pickle.dumps(e))
        return ("error", e, text)
    except Exception:
        return ("error", RuntimeError(f"{type(e).__name__}: {e}"), text)


def reply_error(reply: tuple) -> tuple[BaseException, str]:
    """The exception an error reply stands for, and the worker's traceback text."""
    if reply[0] == "pipegen":
        from pipegen.core.diagnostics import PipegenError
        return PipegenError(reply[1], reply[2], reply[3]), reply[4]
    return reply[1], reply[2]


if __name__ == "__main__":
    sys.exit(main())
