"""``pipegen tune`` against the exhaustive sweep: the same answer, and how many renders each
takes (issue 25 item 6; docs/accuracy.md, `pipegen tune`).

    python benchmarks/tune_vs_sweep.py               # both cases at 96x54 (about a minute)
    python benchmarks/tune_vs_sweep.py --size 192x108

For each case: ``tune`` (the search, tools/tune/search.py) and every configuration rendered
(``tools.tune.run.exhaustive``, ranked as tune ranks: memory, then error, then declared
order); prints both picks (or, when no configuration meets the budget, both closest), the
render counts and their ratio.  Exit 1 if an answer differs or tune renders more than a third
of the sweep.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pipegen.tools.tune.run import exhaustive, tune  # noqa: E402

CASES = [
    ("pipelines/inferred.pipe", "examples/scenes/edges.toml", "p99<=2"),
    ("pipelines/lidr_bitplanes.pipe", "examples/scenes/stress_overlap.toml",
     "lights_dropped==0"),
]


def answer(r) -> str:
    m = r.pick or r.closest
    params = " ".join(f"{k}={v}" for k, v in m.params.items())
    if r.pick is not None:
        return f"pick {params}"
    return f"none within budget; closest {params}"


def renders(n: int) -> str:
    return f"{n} render" + "s" * (n != 1)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="96x54", help="render size (default 96x54)")
    args = ap.parse_args()
    size = tuple(int(x) for x in args.size.split("x"))
    ok = True
    for file, scene, budget in CASES:
        t0 = time.perf_counter()
        t = tune(str(ROOT / file), [str(ROOT / scene)], budget, size=size, frames=0)
        t1 = time.perf_counter()
        e = exhaustive(str(ROOT / file), [str(ROOT / scene)], budget, size=size)
        t2 = time.perf_counter()
        same = (t.pick or t.closest).params == (e.pick or e.closest).params and \
            (t.pick is None) == (e.pick is None)
        ratio = t.renders / e.renders
        ok &= same and ratio <= 1 / 3
        print(f"{Path(file).name} on {Path(scene).stem} at {size[0]}x{size[1]}, budget "
              f"{budget} ({e.total} configurations)")
        print(f"  tune:       {answer(t)}  [{renders(t.renders)}, {t1 - t0:.1f}s]")
        print(f"  exhaustive: {answer(e)}  [{renders(e.renders)}, {t2 - t1:.1f}s]")
        print(f"  same answer: {'yes' if same else 'NO'}; tune's renders: {ratio:.0%} of the "
              f"sweep's")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
