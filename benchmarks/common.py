"""What the benchmark scripts share: the technique list, timing, technique specs, scenes."""

from __future__ import annotations

import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Every shipped technique (pipelines/*.pipe), the default of the benchmarks that take a list.
TECHNIQUES = ["forward", "forward_multipass", "deferred", "lidr_cpu_sort", "lidr_max_stencil",
              "lidr_bitplanes", "lidr_transparent", "light_prepass", "inferred", "deferred_calver"]


def median_time(fn, repeat: int, warmup: bool = True) -> float:
    """Median wall time of ``repeat`` calls of ``fn`` (after one untimed call if ``warmup``:
    shader/kernel compilation and buffer creation are not frame time)."""
    if warmup:
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def parse_spec(spec: str) -> tuple[str, dict]:
    """``name:a=1,b=x`` -> ("name", {"a": "1", "b": "x"}) (the compiler parses the values)."""
    name, _, rest = spec.partition(":")
    return name, dict(kv.split("=", 1) for kv in rest.split(",") if kv)


def compile_spec(spec: str):
    from pipegen.compiler import compile_file
    name, params = parse_spec(spec)
    return compile_file(ROOT / f"pipelines/{name}.pipe", params=params or None)


def scene_at(path: str, size: str):
    from pipegen.scene import load_scene
    w, h = (int(v) for v in size.split("x"))
    return load_scene(path).with_size(w, h)
