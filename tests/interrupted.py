"""Helpers of the tests that stop a long pipegen command and resume it (test_sweep_resume.py,
test_stress_resume.py): the command in a subprocess from the repository root, its end, and a
wait until its journal holds something."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def start(command: str, *args, **kw) -> subprocess.Popen:
    """``pipegen COMMAND ARGS...`` running, its output captured."""
    return subprocess.Popen([sys.executable, "-m", "pipegen", command, *map(str, args)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kw)


def finish(proc, timeout=120):
    """(exit status, stdout, stderr) once ``proc`` ends."""
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err


def wait_until(proc, done, what: str, seconds: float = 60) -> None:
    """Poll ``done()`` until true, failing if ``proc`` ends first or ``seconds`` pass."""
    deadline = time.monotonic() + seconds
    while not done():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, f"no {what} committed in {seconds:.0f} s"
        time.sleep(0.02)
