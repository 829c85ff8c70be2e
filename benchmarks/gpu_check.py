"""Every shipped technique on the GL backend's device (a GPU when EGL offers one) against CL,
through `pipegen check`'s tolerances, on three scenes; with frame times.  Issue 26 item 8.

    python benchmarks/gpu_check.py [--size 640x360] [--frames 5] [--scenes A.toml,B.toml,C.toml]
    PIPEGEN_GL_DEVICE=1 python benchmarks/gpu_check.py        # another EGL device

Prints the GL device (``runtime.gl.context.describe``: renderer, EGL device and why it was
chosen), then per technique and scene whether GL and CL agree (`check`'s verdict: every target
within the tolerance model, discontinuities counted apart), the targets that do not, and the
median GL and CL frame times (``render()``, read-back included, after a warm-up).  Exit 1 when
any technique disagrees.  Where EGL lists only Mesa's llvmpipe this measures the software
rasteriser, and says so on its first line.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from common import ROOT, TECHNIQUES, median_time, scene_at

SCENES = ("examples/scenes/many_lights.toml", "examples/scenes/mixed_lights.toml",
          "examples/scenes/street_lamps.toml")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--scenes", default=",".join(SCENES))
    args = ap.parse_args(argv)
    from pipegen.compiler.driver import compile_file
    from pipegen.proof.check import check
    from pipegen.runtime.gl import context
    gl_device = context.describe()
    soft = context.is_software(context.device()["renderer"])
    print(f"GL device: {gl_device}" + ("  [software: no GPU here]" if soft else ""))
    failed = 0
    print(f"{'technique':18} {'scene':16} {'agree':6} {'GL ms':>8} {'CL ms':>8}  disagreeing")
    for name in TECHNIQUES:
        compiled = compile_file(str(ROOT / "pipelines" / f"{name}.pipe"))
        for path in args.scenes.split(","):
            scene = scene_at(str(ROOT / path) if not Path(path).is_absolute() else path,
                             args.size)
            variant = compiled.specialise(scene) if not compiled.mismatches(scene) else compiled
            result = check(variant, scene)
            bad = [r.name for r in result.rows if not r.passed]
            failed += not result.passed
            ms = {}
            for b in ("gl", "cl"):
                pipe = variant.pipeline(b)
                ms[b] = median_time(lambda: pipe.render(scene), args.frames) * 1e3
            print(f"{name:18} {Path(path).stem:16} {'yes' if result.passed else 'NO':6} "
                  f"{ms['gl']:8.1f} {ms['cl']:8.1f}  {', '.join(bad) or '-'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
