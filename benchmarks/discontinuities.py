"""What finding discontinuities costs: ``precision_check`` (``pipegen check --precision f64``)
with and without the search (proof/discontinuity.py), per technique, in one run.

The search renders the float64 evaluation with the technique's steps nudged; each variant is a
recompile.  Cold: a fresh PoCL kernel cache (the first check of a technique on a machine);
warm: the same calls again (every program cached).  Prints seconds and the ratio.

    python benchmarks/discontinuities.py [--size 64x36] [--threads 2] [TECHNIQUE.pipe ...]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import ROOT, set_threads  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="*", default=[str(ROOT / "examples/techniques/toon_deferred.pipe"),
                                                 str(ROOT / "pipelines/deferred.pipe"),
                                                 str(ROOT / "pipelines/deferred_calver.pipe")])
    ap.add_argument("--size", default="64x36")
    ap.add_argument("--threads", default="2")
    args = ap.parse_args()
    set_threads(args.threads)
    os.environ["POCL_CACHE_DIR"] = tempfile.mkdtemp(prefix="pocl-bench-")   # cold
    import warnings
    warnings.simplefilter("ignore")
    import pipegen
    from pipegen.proof.precision import precision_check
    w, h = (int(x) for x in args.size.split("x"))
    scene = pipegen.default_scene().with_size(w, h)
    print(f"precision_check at {w}x{h}, {args.threads} threads; seconds "
          f"(cold: fresh PoCL cache; warm: again)")
    print(f"{'technique':18s} {'sites':>5s} {'cold no search':>15s} {'cold search':>12s} "
          f"{'warm no search':>15s} {'warm search':>12s} {'found':>6s}")
    from pipegen.proof.discontinuity import sites
    for f in args.files:
        c = pipegen.compile_file(f)
        row = []
        for _ in range(2):
            for explain in (False, True):
                t0 = time.perf_counter()
                r = precision_check(c, scene, explain=explain)
                row.append(time.perf_counter() - t0)
        found = max(sum(x.discontinuity_count for x in rows) for rows in r.rows.values())
        print(f"{c.name:18s} {len(sites(c.technique)):5d} {row[0]:15.1f} {row[1]:12.1f} "
              f"{row[2]:15.1f} {row[3]:12.1f} {found:6d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
