"""Where the render jobs run: a local pool of spawned processes (``LocalPool``) or a Dask
distributed cluster (``DaskPool``).  Both hand results back as they finish and run one job
alone once the others are done (``run_alone``: the timing phase)."""

from __future__ import annotations

import os

from pipegen.core.diagnostics import PipegenError
from pipegen.tools.sweep.jobs import render_worker_init


class LocalPool:
    name = "local process pool"

    def __init__(self, jobs: int):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        self.jobs = jobs
        self.ex = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"),
                                      initializer=render_worker_init)
        self.where = f"a local process pool of {jobs} (spawned processes, 1 render thread each)"

    def map_unordered(self, fn, items):
        from concurrent.futures import as_completed
        futures = {self.ex.submit(fn, x): i for i, x in enumerate(items)}
        for f in as_completed(futures):
            yield futures[f], f.result()

    def run_alone(self, fn, arg):
        return fn(arg)                          # here, after the pool's jobs have all finished

    def close(self) -> None:
        self.ex.shutdown()


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
        n = len(self.client.scheduler_info().get("workers", {}))
        self.where = f"the Dask cluster at {address} ({n} workers)"

    def map_unordered(self, fn, items):
        from distributed import as_completed
        futures = {self.client.submit(fn, x, pure=False): i for i, x in enumerate(items)}
        for f in as_completed(list(futures)):
            yield futures[f], f.result()

    def run_alone(self, fn, arg):
        workers = sorted(self.client.scheduler_info().get("workers", {}))
        return self.client.submit(fn, arg, pure=False, workers=workers[:1],
                                  allow_other_workers=False).result()

    def close(self) -> None:
        self.client.close()


def available_cpus() -> list:
    return sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
        else list(range(os.cpu_count() or 1))
