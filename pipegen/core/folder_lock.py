"""One writer per output folder (issue 29): two ``pipegen run … -o DIR`` at once must not mix
their outputs.  ``OutputDir`` takes the folder's lock when it is checked, before any work, and
keeps it until its outputs are in place; a second process asking for the same folder meanwhile
gets a ``PipegenError`` naming the holder (its pid and command), at once rather than after its
own rendering.

The lock is an exclusive ``flock`` on a file named after the folder's resolved path in a
per-user folder under the system's temporary folder (``pipegen-locks-UID/``): not in the
output folder, which may not exist yet (and whose creation must wait for the outputs), and not
beside it (the user's folders hold nothing of pipegen's but its outputs).  The kernel drops
the lock when its holder exits, however it ends.  Within one process the same folder may be
claimed more than once (a command's ``OutputDir`` and a helper's ``as_output_dir`` on the same
path): the claims share the lock and it is released with the last.  Where ``fcntl`` does not
exist (Windows) there is no lock.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import threading
from pathlib import Path
from typing import Optional

from pipegen.core.diagnostics import PipegenError

try:
    import fcntl
except ImportError:              # pragma: no cover - Windows
    fcntl = None

_HELD: dict[str, list] = {}      # lock file -> [fd, claims] in this process
_GUARD = threading.Lock()


def lock_path(folder: Path) -> Path:
    """The lock file of an output folder (the module docstring)."""
    key = hashlib.sha1(os.fsencode(Path(folder).resolve())).hexdigest()[:20]
    uid = os.getuid() if hasattr(os, "getuid") else 0
    return Path(tempfile.gettempdir()) / f"pipegen-locks-{uid}" / f"{key}.lock"


class FolderLock:
    """A claim on an output folder's lock (taken on construction; ``release`` once)."""

    def __init__(self, folder: Path, command: str):
        self.folder = Path(folder)
        self.path = lock_path(folder)
        self.held = False
        if fcntl is None:
            return
        with _GUARD:
            entry = _HELD.get(str(self.path))
            if entry is not None:
                entry[1] += 1
            else:
                _HELD[str(self.path)] = [self._take(command), 1]
        self.held = True

    def _take(self, command: str) -> int:
        self.path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read(fd)
            os.close(fd)
            raise PipegenError(None, f"output folder '{self.folder}' is being written by "
                                     f"another pipegen ({holder or 'a process'})",
                               hint="wait for it to finish, or pass another folder with -o")
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()}, pipegen {command}\n".encode())
        return fd

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        with _GUARD:
            entry = _HELD.get(str(self.path))
            if entry is None:
                return
            entry[1] -= 1
            if entry[1] == 0:
                del _HELD[str(self.path)]
                os.close(entry[0])       # closing the descriptor drops the flock

    def __del__(self):
        if sys is not None and getattr(self, "held", False):   # not at interpreter exit
            self.release()


def _read(fd: int) -> Optional[str]:
    try:
        return os.pread(fd, 200, 0).decode(errors="replace").strip() or None
    except OSError:
        return None
