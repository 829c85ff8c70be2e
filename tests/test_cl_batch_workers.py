"""The CPU device's worker threads run under ``SCHED_BATCH`` (``runtime/cl/context.batch_schedule``:
woken by a launch they no longer preempt the host thread preparing the next pass), exactly
those threads, and ``$PIPEGEN_CL_BATCH_WORKERS=0`` leaves them alone.

Each case opens the device in a fresh interpreter: which threads are the device's is learnt
when the context is made, once per process.  Linux only (SCHED_BATCH, /proc/self/task)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

pytestmark = [pytest.mark.cl,
              pytest.mark.skipif(not hasattr(os, "SCHED_BATCH")
                                 or not os.path.isdir("/proc/self/task"),
                                 reason="Linux scheduling policies")]

OPEN = """
import json, os
threads = set(os.listdir("/proc/self/task"))
from pipegen.runtime.cl import context
ctx, queue = context.get_context()
new = sorted(int(t) for t in set(os.listdir("/proc/self/task")) - threads)
print(json.dumps({
    "moved": context.batch_workers(),
    "new": new,
    "policy": {t: os.sched_getscheduler(t) for t in new},
    "main": os.sched_getscheduler(0),
    "cpu": bool(ctx.devices[0].type & 2),       # CL_DEVICE_TYPE_CPU
}))
"""


def _open(**env) -> dict:
    proc = subprocess.run([sys.executable, "-c", OPEN], capture_output=True, text=True,
                          env={**os.environ, "POCL_MAX_PTHREAD_COUNT": "2", **env}, timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["policy"] = {int(k): v for k, v in out["policy"].items()}
    return out


def test_the_device_workers_and_only_they_are_batch_scheduled():
    out = _open()
    if not out["cpu"]:
        pytest.skip("not a CPU OpenCL device")
    if not out["new"]:
        pytest.skip("this CPU device started no thread while it was opened: nothing to move")
    # PoCL 3.0's pthread device starts one worker per allowed core when it is opened
    assert len(out["moved"]) >= 1
    assert set(out["moved"]) <= set(out["new"])
    assert all(out["policy"][t] == os.SCHED_BATCH for t in out["moved"])
    assert out["main"] == os.SCHED_OTHER           # the host thread keeps its policy
    assert all(out["policy"][t] == os.SCHED_OTHER
               for t in set(out["new"]) - set(out["moved"]))


def test_switched_off_by_the_environment():
    out = _open(PIPEGEN_CL_BATCH_WORKERS="0")
    assert out["moved"] == []
    assert all(p == os.SCHED_OTHER for p in out["policy"].values())
