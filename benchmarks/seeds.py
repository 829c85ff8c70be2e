"""The papers' figures next to the ones measured here, on llvmpipe (GL) and PoCL (CL), in one run.

    python benchmarks/seeds.py [--frames 3] [--threads 2] [--scale 1.0] [--skip-forward]

- **Trebilco 2007** (light-indexed deferred rendering, ShaderX6): 255 lights at 1024x768, LIDR
  at 1/2/4 lights per pixel 82/62/37 FPS against multi-pass forward 12 FPS.  Here: the
  many-lights geometry (``examples/scenes/many_lights.toml``) with its lights replaced by 255
  point lights on a 17 x 15 grid, 1.4 apart, of radius 0.63, 0.91 or 1.33 (at most 1, 2 or 4
  light spheres contain a point: the measured lights-per-pixel are printed), rendered by the
  three LIDR techniques and by ``forward_multipass`` (``max_lights = 256``, at the 4-lights
  scene: its cost hardly depends on the radius, one full-scene pass per light).
- **Kircher & Lawrance 2009** (inferred lighting): an 800x450 L-buffer with DSF 25 ms against a
  1280x720 one without DSF 32 ms; 81 lights: inferred 29.4 ms against forward 167 ms.  Here:
  ``inferred`` at ``lbuffer_scale`` 0.625 (800x450 for 1280x720) with ``dsf = true`` against
  1.0 with ``dsf = false``, and the default inferred against single-pass ``forward``, all on
  ``examples/scenes/many_lights.toml`` (81 lights) at 1280x720.

Timings come from ``pipegen.sweep.time_job``, as ``pipegen sweep`` takes them: per scene one
fresh process, pinned to ``--threads`` CPUs with ``LP_NUM_THREADS = POCL_MAX_PTHREAD_COUNT =
--threads``, one untimed warm-up render per variant and backend, then ``--frames`` rounds
timing every variant once each, in alternating order; the median.  GL: ``frame()`` to
``glFinish`` (no read-back); CL: ``render()`` (with the read-back of every target).

Only ratios can match: the papers ran GPUs of 2007-2009 with fixed-function rasterisers and
blenders; here rasterisation, depth test and blending are software.  ``--scale`` shrinks every
size (0.5: 512x384 and 640x360) for a quicker run.
"""

from __future__ import annotations

import argparse
import colorsys
import random
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TREBILCO_GRID = (17, 15)            # 255 lights
TREBILCO_SPACING = 1.4
TREBILCO_RADII = {1: 0.63, 2: 0.91, 4: 1.33}     # < s/2, < s/sqrt(2), < s
TREBILCO_PAPER_FPS = {1: 82, 2: 62, 4: 37}
TREBILCO_FORWARD_FPS = 12
KL_PAPER = dict(dsf_800=25.0, full_720=32.0, inferred_81=29.4, forward_81=167.0)
LIDRS = ("lidr_cpu_sort", "lidr_max_stencil", "lidr_bitplanes")


def trebilco_scene(path: Path, radius: float) -> Path:
    """many_lights.toml's camera and objects with 255 grid lights of ``radius``."""
    text = (ROOT / "examples/scenes/many_lights.toml").read_text()
    head = text[:text.index("[[lights]]")]
    head = head.replace('name = "many_lights"', 'name = "trebilco_255"')
    rng = random.Random(2007)
    nx, nz = TREBILCO_GRID
    s = TREBILCO_SPACING
    out = [head.rstrip(), ""]
    for j in range(nz):
        for i in range(nx):
            x = (i - (nx - 1) / 2) * s
            z = (j - (nz - 1) / 2) * s
            r, g, b = colorsys.hsv_to_rgb(rng.random(), 0.75, 1.0)
            out += ["[[lights]]", f"position = [{x:.4g}, 0.9, {z:.4g}]",
                    f"radius = {radius:.4g}",
                    f"color = [{1.2 * r:.4g}, {1.2 * g:.4g}, {1.2 * b:.4g}]", ""]
    path.write_text("\n".join(out))
    return path


def lights_per_pixel(scene_path: Path, size: tuple[int, int]) -> tuple[int, float]:
    """(max, mean over lit surface pixels) of the lights whose sphere contains the point."""
    from pipegen.reference.lighting import lights_per_pixel as lpp
    from pipegen.reference.raster import rasterize
    from pipegen.scene import load_scene
    scene = load_scene(scene_path).with_size(*size)
    gb = rasterize(scene, ("opaque",))
    n = lpp(gb, scene)[gb.coverage]
    lit = n[n > 0]
    return int(n.max()), float(lit.mean()) if lit.size else 0.0


def time_group(scene_path, size, variants, frames, threads) -> list[dict]:
    from pipegen.sweep import scene_spec, time_job
    job = dict(variants=[dict(file=str(ROOT / f"pipelines/{name}.pipe"), params=params)
                         for name, params in variants],
               scene=scene_spec(scene_path, size), backends=["gl", "cl"], frames=frames,
               threads=threads, progress=True)
    res = time_job(job)
    return res["ms"], res["how"]


def ratio(a: float, b: float) -> str:
    return f"{a / b:.2f}x" if b else "-"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scale", type=float, default=1.0,
                    help="multiply every size by this (default 1: the papers' sizes)")
    ap.add_argument("--skip-forward", action="store_true",
                    help="leave out multi-pass forward on 255 lights (the slowest part)")
    args = ap.parse_args()
    t_start = time.perf_counter()

    def sized(w, h):
        return max(8, round(w * args.scale)), max(8, round(h * args.scale))

    tre_size, kl_size = sized(1024, 768), sized(1280, 720)
    tmp = Path(tempfile.mkdtemp(prefix="pipegen-seeds-"))

    # -- Trebilco ------------------------------------------------------------------------------
    tre = {}                     # k -> {technique: {backend: ms}}
    overlap = {}
    how = ""
    for k, radius in TREBILCO_RADII.items():
        path = trebilco_scene(tmp / f"trebilco_{k}.toml", radius)
        overlap[k] = lights_per_pixel(path, tre_size)
        variants = [(name, {}) for name in LIDRS]
        if k == 4 and not args.skip_forward:
            variants.append(("forward_multipass", {"max_lights": 256}))
        print(f"Trebilco, {k} light(s) per pixel: timing {len(variants)} techniques at "
              f"{tre_size[0]}x{tre_size[1]}", file=sys.stderr)
        ms, how = time_group(path, tre_size, variants, args.frames, args.threads)
        tre[k] = {name: m for (name, _), m in zip(variants, ms)}

    # -- Kircher & Lawrance --------------------------------------------------------------------
    kl_scene = ROOT / "examples/scenes/many_lights.toml"
    kl_variants = [("inferred", {"lbuffer_scale": 0.625, "dsf": True}),
                   ("inferred", {"lbuffer_scale": 1.0, "dsf": False}),
                   ("forward", {})]
    print(f"Kircher & Lawrance: timing {len(kl_variants)} variants at {kl_size[0]}x{kl_size[1]}",
          file=sys.stderr)
    kl_ms, _ = time_group(kl_scene, kl_size, kl_variants, args.frames, args.threads)
    kl = dict(zip(("dsf_800", "full_720", "forward"), kl_ms))

    # -- report ----------------------------------------------------------------------------------
    W = 30
    print(f"Trebilco 2007: 255 lights at {tre_size[0]}x{tre_size[1]} (paper: 1024x768, a GPU); "
          f"frame time in ms (FPS), and the speed-up over multi-pass forward")
    for k in TREBILCO_RADII:
        print(f"  {k} light(s)/pixel: radius {TREBILCO_RADII[k]}, measured max {overlap[k][0]}, "
              f"mean {overlap[k][1]:.2f} over lit pixels")
    fwd = tre.get(4, {}).get("forward_multipass")
    print(f"{'':<{W}} {'paper':>16} {'llvmpipe (GL)':>24} {'PoCL (CL)':>24}")

    def cell(ms, base):
        if ms is None:
            return "-"
        s = f"{ms:.0f} ms ({1e3 / ms:.1f})"
        return s + (f" {base / ms:.1f}x" if base else "")

    for k in TREBILCO_RADII:
        for name in LIDRS:
            m = tre[k][name]
            paper = f"{TREBILCO_PAPER_FPS[k]} FPS {TREBILCO_PAPER_FPS[k] / TREBILCO_FORWARD_FPS:.1f}x"
            print(f"{f'{name}, {k}/px':<{W}} {paper:>16} "
                  f"{cell(m['gl'], fwd and fwd['gl']):>24} {cell(m['cl'], fwd and fwd['cl']):>24}")
    if fwd:
        print(f"{'forward_multipass, 4/px':<{W}} {f'{TREBILCO_FORWARD_FPS} FPS 1.0x':>16} "
              f"{cell(fwd['gl'], fwd['gl']):>24} {cell(fwd['cl'], fwd['cl']):>24}")
    print(f"{'LIDR 1/px over 4/px':<{W}} {ratio(TREBILCO_PAPER_FPS[1], TREBILCO_PAPER_FPS[4]):>16} "
          + " ".join(f"{ratio(tre[4]['lidr_bitplanes'][b], tre[1]['lidr_bitplanes'][b]):>24}"
                     for b in ("gl", "cl")) + "   (bit planes; FPS ratio = time ratio inverted)")
    print()
    p = KL_PAPER
    print(f"Kircher & Lawrance 2009: many_lights (81 lights) at {kl_size[0]}x{kl_size[1]}; "
          f"frame time in ms")
    print(f"{'':<{W}} {'paper':>16} {'llvmpipe (GL)':>24} {'PoCL (CL)':>24}")
    rows = [("L-buffer 0.625 + DSF", f"{p['dsf_800']:g} ms", "dsf_800"),
            ("L-buffer 1.0, no DSF", f"{p['full_720']:g} ms", "full_720"),
            ("forward (81 lights)", f"{p['forward_81']:g} ms", "forward")]
    for label, paper, key in rows:
        print(f"{label:<{W}} {paper:>16} " + " ".join(f"{kl[key][b]:>21.0f} ms" for b in ("gl", "cl")))
    print(f"{'0.625+DSF / 1.0 no DSF':<{W}} {ratio(p['dsf_800'], p['full_720']):>16} "
          + " ".join(f"{ratio(kl['dsf_800'][b], kl['full_720'][b]):>24}" for b in ("gl", "cl")))
    print(f"{'inferred / forward':<{W}} {ratio(p['inferred_81'], p['forward_81']):>16} "
          + " ".join(f"{ratio(kl['dsf_800'][b], kl['forward'][b]):>24}" for b in ("gl", "cl"))
          + "   (paper's inferred: 29.4 ms)")
    print()
    print(how)
    print(f"total {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
