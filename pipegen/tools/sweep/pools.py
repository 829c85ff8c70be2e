"""Where the render jobs run: a local pool of worker processes (``LocalPool``) or a Dask
distributed cluster (``DaskPool``).  Both hand results back as they finish and run one job
alone once the others are done (``run_alone``: the timing phase)."""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading

from pipegen.core.diagnostics import PipegenError
from pipegen.tools.sweep.jobs import RENDER_ENV
from pipegen.tools.sweep.worker import child_env, python_command, receive, reply_error, send


class LocalPool:
    """``jobs`` render processes of this machine (``worker.py``: they need no importable
    ``__main__``, so a sweep runs from a script on standard input or a notebook), each with one
    rasteriser thread; a thread here feeds each one its next job."""

    name = "local process pool"

    def __init__(self, jobs: int):
        self.jobs = jobs
        self.procs: list = []
        self.stop = threading.Event()           # set when closing: feeders take no new job
        self.where = f"a local process pool of {jobs} (separate processes, 1 render thread each)"

    def _start(self, n: int) -> None:
        env = child_env(**RENDER_ENV)
        while len(self.procs) < n:
            self.procs.append(subprocess.Popen(
                python_command("pipegen.tools.sweep.worker"), stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, env=env))

    def map_unordered(self, fn, items):
        items = list(items)
        self._start(min(self.jobs, len(items)))
        todo: queue.SimpleQueue = queue.SimpleQueue()
        for i, x in enumerate(items):
            todo.put((i, x))
        done: queue.SimpleQueue = queue.SimpleQueue()
        stop = self.stop

        def feed(proc):
            while not stop.is_set():
                try:
                    i, x = todo.get_nowait()
                except queue.Empty:
                    return
                try:
                    send(proc.stdin, (fn, x))
                    reply = receive(proc.stdout)
                except (EOFError, OSError):
                    done.put((i, ("died", proc.wait())))
                    return
                except Exception as e:          # a reply that does not unpickle: say so
                    done.put((i, ("error", e, "")))
                    return
                done.put((i, reply))

        threads = [threading.Thread(target=feed, args=(p,), daemon=True) for p in self.procs]
        for t in threads:
            t.start()
        try:
            for _ in items:
                i, reply = _get_interruptibly(done)
                if reply[0] == "ok":
                    yield i, reply[1]
                elif reply[0] == "died":
                    raise RuntimeError(f"a render process died (exit status {reply[1]}) on "
                                       f"job {i + 1} of {len(items)}")
                else:
                    error, text = reply_error(reply)
                    if not isinstance(error, PipegenError) and text:   # a bug: where it was
                        sys.stderr.write(f"in the render process:\n{text}")
                    raise error
        finally:
            stop.set()

    def run_alone(self, fn, arg):
        return fn(arg)                          # here, after the pool's jobs have all finished

    def close(self, now: bool = False) -> None:
        """Stop the render processes: after their current job, or, ``now`` (Ctrl-C), at
        once."""
        self.stop.set()
        if now:
            for p in self.procs:
                p.kill()
        for p in self.procs:
            try:
                send(p.stdin, None)
                p.stdin.close()
            except OSError:
                pass
        for p in self.procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:   # busy on a job nobody waits for any more
                p.kill()
                p.wait()
            p.stdout.close()
        self.procs = []


RETRIES = 2          # a Dask job that fails (its worker died, say) runs again up to this often


def _get_interruptibly(q: queue.SimpleQueue):
    """``q.get()`` in short waits, so that Ctrl-C reaches the main thread at once."""
    while True:
        try:
            return q.get(timeout=0.2)
        except queue.Empty:
            continue


class DaskPool:
    name = "dask"

    def __init__(self, address: str):
        try:
            from distributed import Client
        except ImportError:
            raise PipegenError(None, "--scheduler needs Dask distributed, which is not installed",
                               hint="pip install 'pipegen[dask]'") from None
        try:
            self.client = Client(address, timeout="20s")
        except OSError as e:
            raise PipegenError(None, f"cannot reach the Dask scheduler at {address}: {e}",
                               hint="start one with `dask scheduler` and workers with "
                                    "`dask worker ADDRESS`") from None
        self.futures: list = []
        n = len(self.client.scheduler_info().get("workers", {}))
        self.where = f"the Dask cluster at {address} ({n} workers)"

    def map_unordered(self, fn, items):
        from distributed import as_completed
        # a job is a pure function of its argument: run twice (a worker lost mid-job, its
        # job retried elsewhere), it gives the same result, handed back once
        futures = {self.client.submit(fn, x, pure=False, retries=RETRIES): i
                   for i, x in enumerate(items)}
        self.futures = list(futures)
        for f in as_completed(self.futures):
            yield futures[f], f.result()

    def run_alone(self, fn, arg):
        workers = sorted(self.client.scheduler_info().get("workers", {}))
        return self.client.submit(fn, arg, pure=False, workers=workers[:1],
                                  allow_other_workers=False).result()

    def close(self, now: bool = False) -> None:
        if self.client.status == "closed":
            return
        if now:
            self.client.cancel(self.futures, force=True)
        self.client.close()


def available_cpus() -> list:
    return sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
        else list(range(os.cpu_count() or 1))
