"""Memory over many compile + pipeline + render cycles in one process (issue 29 item 2): does a
long-lived process that builds many pipelines (a sweep, a test suite, a tool) stay flat?

    python benchmarks/soak.py [--cycles 250] [--size 96x54] [--backends gl,cl] [--no-close]
        [--png soak.png]

Each cycle compiles ``lidr_bitplanes`` and ``deferred`` afresh (the compile caches cleared, as
a new technique would be), makes a pipeline per backend, renders ``examples/scenes/small.toml``
once and closes it (``pipeline.close()``; ``--no-close`` drops it instead and leaves the cleanup
to the garbage collector).  After every 10 cycles: ``gc.collect()``, then the resident set
size (``/proc/self/statm``).  Prints the curve and the growth after warm-up (the first 20
cycles), total and per cycle; ``--png`` draws it (matplotlib).  The issue's target: at most 2
MiB growth over 1,000 renders (250 cycles x two techniques x two backends) after warm-up.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
import time
from pathlib import Path

from common import ROOT, scene_at

TECHNIQUES = ("lidr_bitplanes", "deferred")
WARMUP = 50     # cycles: the IR facts cache (ir/facts.py) fills over the first ~40


def rss_mib() -> float:
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def clear_compile_caches() -> None:
    """Drop what pipegen caches per technique, so each cycle compiles and builds anew."""
    from pipegen.compiler import specialise
    specialise.clear_cache()


def cycle(backends, scene, close: bool) -> None:
    from pipegen.compiler.driver import compile_file
    for name in TECHNIQUES:
        compiled = compile_file(str(ROOT / "pipelines" / f"{name}.pipe"))
        for b in backends:
            pipe = compiled.pipeline(b)
            pipe.render(scene)
            if close:
                (getattr(pipe, "close", None) or pipe.release)()
            del pipe
    clear_compile_caches()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=250)
    ap.add_argument("--size", default="96x54")
    ap.add_argument("--backends", default="gl,cl")
    ap.add_argument("--no-close", action="store_true")
    ap.add_argument("--png")
    args = ap.parse_args(argv)
    scene = scene_at(str(ROOT / "examples/scenes/small.toml"), args.size)
    backends = args.backends.split(",")
    curve = []
    t0 = time.perf_counter()
    for i in range(1, args.cycles + 1):
        cycle(backends, scene, not args.no_close)
        if i % 10 == 0 or i == 1:
            gc.collect()
            curve.append((i, rss_mib()))
            print(f"cycle {i:5d}: {curve[-1][1]:8.1f} MiB  ({time.perf_counter() - t0:.0f} s)",
                  flush=True)
    after = [m for i, m in curve if i >= WARMUP]
    grow = after[-1] - after[0] if len(after) > 1 else 0.0
    cycles = curve[-1][0] - next(i for i, _ in curve if i >= WARMUP)
    renders = cycles * len(TECHNIQUES) * len(backends)
    print(f"after warm-up ({WARMUP} cycles): {after[0]:.1f} -> {after[-1]:.1f} MiB over "
          f"{cycles} cycles ({renders} renders): {grow:+.2f} MiB, "
          f"{grow * 1024 / max(cycles, 1):+.1f} KiB per cycle")
    if args.png:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 3.2))
        ax.plot([i for i, _ in curve], [m for _, m in curve], marker=".")
        ax.axvline(WARMUP, color="#999", ls=":")
        ax.set_xlabel("cycle (compile + pipeline + render, " + ", ".join(TECHNIQUES) + " x "
                      + ", ".join(backends) + ")")
        ax.set_ylabel("RSS after gc (MiB)")
        ax.set_title(f"pipegen soak at {args.size}: {grow:+.2f} MiB after warm-up")
        fig.tight_layout()
        fig.savefig(args.png, dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
