"""GL (llvmpipe) vs CL (PoCL) frame time per technique, measured in one run.

    python benchmarks/backends.py [--scene examples/scenes/many_lights.toml] [--size 640x360]
        [--frames 3] [--block 1] [--threads 2] [--general] [--profile] [--png FILE]
        [technique[:param=value,...] ...]

By default each technique is compiled for the scene (the variant `pipegen run` renders);
``--general`` times the general build.

e.g. ``inferred:lbuffer_scale=0.625 inferred:lbuffer_scale=1.0 light_prepass deferred forward``.

Both backends run the full ``render()`` (all passes, then read-back of every target), so the
ratio compares like with like.  ``LP_NUM_THREADS`` and ``POCL_MAX_PTHREAD_COUNT`` are set to
``--threads`` before either runtime loads.  The frames are interleaved, GL CL CL GL GL CL ...
(``common.interleaved``: drift in a shared machine's load hits both alike, and neither always
runs first), after one warm-up render of each (which compiles shaders and kernels); each
figure is the median of ``--frames`` renders.  ``--block N`` times each backend in turns of N
renders back to back instead (ABBA, each turn after one untimed render: ``common.in_blocks``),
the steady state of one backend rendering frame after frame.  The two differ at small sizes: a
CL frame right after a GL frame is slower than one after a CL frame (light_prepass at 160x90
10.5 against 8.6 ms, the host thread's CPU time 4.9 against 3.8 ms and PoCL's threads' 11.0
against 10.3, llvmpipe's threads idle meanwhile, so no contention; a CL frame after 20 ms of
sleep is slower still: cold caches, most likely), while a GL frame after a CL one loses 0.1-0.6
ms; frame by frame, half the CL frames pay it.

``--profile`` adds, per technique and backend, where the frame goes, pass by pass (summed
over the lights of a repeat group, medians over ``--frames`` frames), largest first:

* GL: ``setup`` is host time from the start of a pass to its first draw call (clears,
  uniforms, texture/framebuffer bindings, state transitions), ``draw`` is from there until
  ``glFinish`` returns after its last draw (llvmpipe's rasterisation and shading, plus the
  host's per-light draw calls).  The GPU is drained before every pass, so the profiled frame
  is slower than an unprofiled one (printed too), but each pass is charged its own work.
* CL: ``benchmarks/cl_profile.py``: host stages (vertex, set-up, binning) against the raster
  kernel's device time (OpenCL profiling events); then both backends side by side, each pass
  drained the same way (``CLPipeline.profile``: host time to the raster kernel's launch,
  then until the queue is empty), so that a pass where CL loses stands out.

``--png FILE`` also draws the GL profile as horizontal stacked bars (matplotlib, if installed).

Small frames (issue 26 item 3, target CL/GL <= 1.0 at 160x90 and 320x180), measured on a
shared 2-core machine (load 3-5; ``python benchmarks/backends.py --size 160x90 --frames 7``,
LP_NUM_THREADS = POCL_MAX_PTHREAD_COUNT = 2).  CL/GL before (dee6b84) and after (7b93f47 and
3f957fa, with other helpers' changes to both runtimes since) in runs a minute apart; two
after-runs show how far one run is from the next:

    160x90            before   after   after (2nd run)   320x180 after
    forward            0.12x   0.23x   0.20x             0.16x
    forward_multipass  0.19x   0.29x   0.30x             0.31x
    deferred           1.79x   1.29x   1.84x             1.39x
    lidr_cpu_sort      1.08x   1.21x   0.87x             0.66x
    lidr_max_stencil   0.85x   0.79x   0.81x             0.56x
    lidr_bitplanes     1.11x   0.93x   1.05x             0.76x
    lidr_transparent   0.70x   0.62x   0.67x             0.64x
    light_prepass      0.91x   1.34x   1.33x             1.16x
    inferred           1.10x   1.39x   1.44x             0.86x
    deferred_calver    0.94x   1.21x   0.95x             1.03x

Runs this far apart rank nothing but deferred (>1 in every run: 81 lights, two passes each,
165 raster launches a frame; its host work, not its device time, is the frame: 18 ms of
kernels in a 54 ms frame).  The changes' own effects, in one process with frames
interleaved: multi-pass forward's lights in one launch (160x90 0.65x, 320x180 0.59x, 255
lights at 640x360 0.69x of the frame), vector kernel arguments declared (deferred's light
pass 47.8 -> ~5 us a set_args), raster keys and light lists once a frame (deferred 0.96x).
A later round ran deferred's light volumes as one launch (a repeat group fused on CL:
``benchmarks/cl_fused_groups.py``), which brought deferred to 0.92-1.01x at 160x90; the
README's small-frame table gives all 15 techniques after it, two runs of each size.

Where a small CL frame still goes (417d8d4, many_lights), a part of it: clipping.  Two
triangles cross a frustum plane in each scene pass (llvmpipe clips without a guard band, so
CL clips too).  In inferred's frame at 160x90 (11.1 ms) the clip step takes 0.6 ms of host time
beyond its wait for the set-up, reading its results back 0.17 ms, and copying every varying
slot (42,834 vertices each) into the clipper's output buffer, so that its new vertices can
follow the inputs, about 0.5 ms (frames with and without the copies alternated, medians of
41); lidr_cpu_sort's clip step 0.3 ms.  Dropping the two triangles altogether (timing only)
saves more, 1.5 ms at 160x90 and 3.2 ms at 320x180, but that includes rasterising them: they
cross the near plane and cover much of the screen.

Each pass's host work in turn (2026-12-04).  A CL frame used to prepare every pass's host work
(set-up read-backs, queuing the binning) before it queued the first raster kernel, and the
device sat idle meanwhile: light_prepass at 320x180, 3 ms of a 12.6 ms frame between its
last set-up kernel and its first raster kernel (every command's OpenCL profiling times).  It
now prepares pass k + 1 while the device rasterises pass k (``$PIPEGEN_CL_HOST_FIRST=1``:
the old order).  The gain is small, since the host's work then shares the 2 cores with
PoCL's threads and the next kernel still waits for it: ``python benchmarks/cl_host_ab.py
BEFORE AFTER --size WxH --blocks 6 --frames 5`` (a worker process per tree, CL only, blocks
alternated; load 0.8-1.9), wall after/before: at 320x180 0.89-1.05x (light_prepass 0.92,
lidr_cpu_sort 0.89, lidr_shadow_indexed 0.90, inferred 0.94, deferred_calver 0.95,
lidr_msaa_texture 1.05), at 160x90 0.93-1.10x (lidr_cpu_sort 0.93, deferred_calver 1.10,
most within 0.04 of 1).  Both pipelines in one process, frames alternated ABBA, 40 each:
320x180 0.95-1.00x (deferred_calver 0.946, inferred 0.960), 160x90 0.97-1.02x.

The clipper's vertices appended in place (same day): the copy of every varying slot above is
gone from the second frame on (a draw that clipped last frame leaves room after each slot's
vertices, ``setup_device.clip_room``; tests/test_cl_clip_room.py).  ``cl_host_ab.py BEFORE
AFTER --size 160x90 --blocks 6 --frames 5`` (load 1.3-1.5), process CPU after/before: 0.92x
lidr_cpu_sort, 0.94x deferred_calver, 0.95x light_prepass, 0.96-0.98x inferred, deferred and
lidr_shadow_prepass; wall 0.93-1.03x.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from common import (DEFAULT_SCENE, TECHNIQUES, compile_spec, in_blocks, interleaved,
                    median_time, pass_profile, scene_at, set_threads)


def drained_profile(pipe, frame, frames: int = 3) -> dict:
    """Per-pass times (ms) of either runtime, drained around every pass: its ``profile`` rows
    ``(pass, light, host_s, draw_s)`` (``GLPipeline.profile``, ``CLPipeline.profile``) as
    ``setup`` and ``draw``, summed per pass, medians of ``frames`` calls of ``frame()``."""
    def start():
        pipe.profile = []

    prof = pass_profile(frame,
                        lambda: ((name, {"setup": setup * 1e3, "draw": draw * 1e3})
                                 for name, _light, setup, draw in pipe.profile),
                        frames, ("setup", "draw"), before=start)
    pipe.profile = None
    return prof


def gl_profile(pipe, scene, frames: int = 3) -> dict:
    """Per-pass host set-up and draw time (ms) of a ``GLPipeline`` (``--profile``), largest
    first, with the unprofiled frame time."""
    prof = drained_profile(pipe, lambda: pipe.frame(scene), frames)
    prof["passes"].sort(key=lambda r: -(r["setup"] + r["draw"]))
    return {"wall": prof["wall"], "plain": median_time(lambda: pipe.frame(scene), frames),
            "passes": prof["passes"]}


def format_side_by_side(name: str, gl: dict, cl: dict) -> str:
    """Both backends' drained per-pass times, in the CL pass order."""
    g = {r["pass"]: r for r in gl["passes"]}
    lines = [f"{name}, drained per pass (ms): GL frame {gl['wall']:.1f}, CL frame "
             f"{cl['wall']:.1f}",
             f"  {'pass':<24} {'GL host':>8} {'GL draw':>8} {'CL host':>8} {'CL dev':>8} "
             f"{'CL/GL':>6}"]
    tg = tc = 0.0
    for r in cl["passes"]:
        q = g.get(r["pass"], {"setup": 0.0, "draw": 0.0})
        a, b = q["setup"] + q["draw"], r["setup"] + r["draw"]
        tg, tc = tg + a, tc + b
        lines.append(f"  {r['pass']:<24} {q['setup']:>8.2f} {q['draw']:>8.2f} "
                     f"{r['setup']:>8.2f} {r['draw']:>8.2f} "
                     f"{(b / a if a > 0.05 else float('nan')):>6.2f}")
    lines.append(f"  {'sum':<24} {tg:>17.2f} {tc:>17.2f} {tc / tg if tg else float('nan'):>6.2f}")
    return "\n".join(lines)


def format_gl_profile(name: str, prof: dict) -> str:
    total = sum(r["setup"] + r["draw"] for r in prof["passes"]) or 1.0
    lines = [f"{name} GL: profiled frame {prof['wall']:.1f} ms (unprofiled "
             f"{prof['plain'] * 1e3:.1f} ms)",
             f"  {'pass':<22} {'runs':>5} {'setup ms':>9} {'draw ms':>8} {'share':>6}"]
    for r in prof["passes"]:
        lines.append(f"  {r['pass']:<22} {r['runs']:>5} {r['setup']:>9.2f} {r['draw']:>8.2f} "
                     f"{(r['setup'] + r['draw']) / total:>6.1%}")
    setup = sum(r["setup"] for r in prof["passes"])
    draw = sum(r["draw"] for r in prof["passes"])
    lines.append(f"  {'total':<22} {'':>5} {setup:>9.2f} {draw:>8.2f}")
    return "\n".join(lines)


def plot_profiles(profiles: list[tuple[str, dict]], path: str) -> None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("--png: matplotlib is not installed; no chart", file=sys.stderr)
        return
    labels, setup, draw = [], [], []
    for tech, prof in profiles:
        for r in prof["passes"]:
            labels.append(f"{tech}: {r['pass']} x{r['runs']}")
            setup.append(r["setup"])
            draw.append(r["draw"])
    fig, ax = plt.subplots(figsize=(9, 0.28 * len(labels) + 1.2))
    y = range(len(labels))
    ax.barh(y, setup, color="tab:orange", label="host set-up")
    ax.barh(y, draw, left=setup, color="tab:blue", label="draw (to glFinish)")
    ax.set_yticks(list(y), labels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("ms per frame")
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"GL profile chart: {path}", file=sys.stderr)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=str(DEFAULT_SCENE))
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--threads", default="2")
    ap.add_argument("--profile", action="store_true",
                    help="per pass: host set-up vs draw/kernel time, both backends")
    ap.add_argument("--png", default=None, help="with --profile: the GL profile as a bar chart")
    ap.add_argument("--general", action="store_true",
                    help="time the general build (default: the variant compiled for the scene, "
                         "what pipegen run renders)")
    ap.add_argument("--block", type=int, default=1,
                    help="time each backend in turns of this many frames back to back (after "
                         "an untimed one), not frame by frame")
    ap.add_argument("techniques", nargs="*", default=TECHNIQUES)
    args = ap.parse_args()
    set_threads(args.threads)

    scene = scene_at(args.scene, args.size)
    w, h = scene.width, scene.height
    print(f"{Path(args.scene).name} at {w}x{h}: {len(scene.objects)} objects, "
          f"{len(scene.lights)} lights; LP_NUM_THREADS = POCL_MAX_PTHREAD_COUNT = {args.threads}",
          file=sys.stderr)
    rows, profiles = [], []
    for i, spec in enumerate(args.techniques, 1):
        compiled = compile_spec(spec)
        if not args.general:
            compiled = compiled.specialise(scene)
        name = spec
        gl, cl = compiled.pipeline("gl"), compiled.pipeline("cl")
        print(f"[{i}/{len(args.techniques)}] {name}", file=sys.stderr)
        fns = {"gl": lambda: gl.render(scene), "cl": lambda: cl.render(scene)}
        times = interleaved(fns, args.frames) if args.block <= 1 else \
            in_blocks(fns, args.frames, args.block)
        gl_s, cl_s = statistics.median(times["gl"]), statistics.median(times["cl"])
        if args.profile:
            from cl_profile import format_profile, profile
            prof = gl_profile(gl, scene, args.frames)
            profiles.append((name, prof))
            print(format_gl_profile(name, prof))
            print(format_profile(f"{name} CL", profile(cl, scene, args.frames)))
            print(format_side_by_side(name, prof, drained_profile(cl, lambda: cl.render(scene),
                                                                  args.frames)))
        gl.release()
        rows.append((name, gl_s, cl_s))
    width = max(20, *(len(r[0]) for r in rows))
    print(f"{'general build' if args.general else 'variant compiled for the scene'}, "
          f"{w}x{h}, median of {args.frames} frames"
          + (f" (in turns of {args.block})" if args.block > 1 else " (interleaved)"))
    print(f"{'technique':<{width}} {'GL ms':>8} {'CL ms':>8} {'CL/GL':>7}")
    for name, g, c in rows:
        print(f"{name:<{width}} {g * 1e3:>8.1f} {c * 1e3:>8.1f} {c / g:>6.2f}x")
    if args.png and profiles:
        plot_profiles(profiles, args.png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
