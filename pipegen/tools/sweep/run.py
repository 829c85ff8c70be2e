"""A sweep from start to finish in memory: plan the variants, run the render jobs on a pool,
then time them alone (the package docstring); ``run_sweep`` returns a ``SweepResult`` and
writes nothing."""

from __future__ import annotations

import json
import math
import os
import sys
from typing import Optional

from pipegen.core.outdir import safe_name
from pipegen.ir.lifetimes import Sharing, technique_memory
from pipegen.ir.memory import technique_bytes
from pipegen.ir.traffic import frame_traffic
from pipegen.tools.sweep.commands import row_command
from pipegen.tools.sweep.journal import SweepInterrupted, sweep_identity, variant_key
from pipegen.tools.sweep.jobs import (load_spec_scene, reference_data, render_job, scene_spec,
                                      spec_name, time_job)
from pipegen.tools.sweep.pareto import mark_front_and_ties
from pipegen.tools.sweep.pools import DaskPool, LocalPool, available_cpus
from pipegen.tools.sweep.progress import progress_bar
from pipegen.tools.sweep.outputs import csv_text, json_text
from pipegen.tools.sweep.result import SweepResult, backend_title
from pipegen.tools.sweep.variants import plan_variants

BACKEND_ORDER = ("gl", "cl")
DEFAULT_THREADS = 2
F64_NOTE = ("f64 columns are empty: this compiler's Compiled.pipeline does not take "
            "precision='f64' yet")


PARTIAL_TIMING = ("frame times: not measured yet (a partial sweep: the rows rendered so far; "
                  "pipegen sweep ... --resume finishes it)")

UNTIMED = dict(frame_ms=math.nan, cpu_ms=math.nan, frame_ms_q1=math.nan, frame_ms_q3=math.nan)

BUILD_NOTE = {
    False: "every variant rendered and timed as compiled for the scene (culled passes, "
           "targets and branches never run, as pipegen run renders it; --general: the general "
           "builds)",
    True: "every variant rendered and timed as its general build (--general), not as "
          "compiled for the scene"}


def f64_supported() -> bool:
    """Does ``Compiled.pipeline`` take ``precision`` (the f64 evaluation)?"""
    import inspect
    from pipegen.compiler.driver import Compiled
    return "precision" in inspect.signature(Compiled.pipeline).parameters


def run_sweep(files: list, scene=None, size: Optional[tuple] = None,
              axes: Optional[dict] = None, backends=BACKEND_ORDER, frames: int = 5,
              jobs: Optional[int] = None, scheduler: Optional[str] = None,
              threads: int = DEFAULT_THREADS, progress: bool = True,
              reference: Optional[str] = None, reference_samples: int = 1,
              general: bool = False, journal=None) -> SweepResult:
    """Sweep ``files`` (the package docstring) and return the rows; nothing is written.

    ``files``: technique paths (str or Path); ``scene``: a scene path, a loaded ``Scene``
    (``pipegen.scene.load_scene``) or None for the built-in scene; ``size``: (width, height)
    or None for the scene's; ``axes``: {name: [values]} (``variants.parse_axes``) or None for
    the declared ones; ``reference``: what the errors are measured against, ``scene``,
    ``self`` or ``FILE.pipe[:name=value,...]`` (``proof.references``; None: each technique's
    default), evaluated at ``reference_samples`` x ``reference_samples`` per pixel;
    ``general``: render and time the general builds (else, as ``pipegen run``, each variant
    compiled for the scene, in the render and timing processes); ``journal``: a
    ``journal.Journal`` that commits each variant's rows as it finishes (and, resuming, gives
    those already rendered).  Ctrl-C raises ``journal.SweepInterrupted``.  Works
    from a notebook or a script on standard input: the render processes import only pipegen
    (``worker.py``)."""
    backends = tuple(backends)
    if isinstance(files, (str, os.PathLike)):
        files = [files]
    variants, compiled = plan_variants([str(f) for f in files], axes)
    refs = plan_references(variants, compiled, reference, reference_samples)
    spec = scene_spec(scene, size)
    s = load_spec_scene(spec, say=lambda text: print(text, file=sys.stderr))
    use_f64 = f64_supported()
    notes = [BUILD_NOTE[general]]
    if not use_f64:
        notes.append(F64_NOTE)
    if 0 < frames < 3:
        notes.append(f"{frames} timed frame{'s' if frames > 1 else ''} per variant: the "
                     f"interquartile ranges say little about the noise, so few ties are found "
                     f"(--frames 5 or more to rank frame times you can believe)")
    from pipegen.proof.accuracy import FLIP_NOTE
    if FLIP_NOTE:
        notes.append(FLIP_NOTE)
    job_list = [dict(file=v.file, params=dict(v.params), scene=spec, backends=list(backends),
                     f64=use_f64, reference=reference_data(refs[v.technique].spec),
                     general=general)
                for v in variants]
    described = {t: dict(label=r.label, text=r.describe(), why=r.spec.why)
                 for t, r in refs.items()}
    done = journal.start(sweep_identity(variants, spec, (s.width, s.height), backends,
                                        reference, reference_samples, general, use_f64)) \
        if journal else {}
    # per variant: (rows without frame times or command, error maps, images); from the
    # journal when resuming, else as its render job finishes
    rendered = [done.get(variant_key(v)) for v in variants]
    todo = [v.index for v in variants if rendered[v.index] is None]
    pool = DaskPool(scheduler) if scheduler else \
        LocalPool(max(1, jobs or len(available_cpus())))

    def partial_results() -> dict:
        rows = [dict(r, **UNTIMED) for part in rendered if part for r in part[0]]
        mark_front_and_ties(rows)
        partial = SweepResult(rows, spec_name(spec, s), s.width, s.height, len(s.lights),
                              backends, pool.where, PARTIAL_TIMING, notes,
                              references=described, command=journal.command,
                              warnings=clamp_warnings(rows))
        return {"results.csv": csv_text(rows), "results.json": json_text(partial)}

    timing_phase = False
    try:
        bar = progress_bar(len(todo), "renders", progress)
        for k, res in pool.map_unordered(render_job, [job_list[i] for i in todo]):
            v = variants[todo[k]]
            rendered[v.index] = variant_rows(v, res, s, backends, refs, compiled)
            if journal:
                journal.record(v, *rendered[v.index], partial_results())
            bar.update(1)
        bar.close()
        timing_phase = True
        if frames > 0:
            timing = pool.run_alone(time_job, dict(
                variants=[dict(file=v.file, params=dict(v.params)) for v in variants],
                scene=spec, backends=list(backends), frames=frames, threads=threads,
                progress=progress, general=general))
            ms, cpu_ms, how = timing["ms"], timing["cpu_ms"], timing["how"]
            q1, q3 = timing["q1"], timing["q3"]
            how = how.replace("in one fresh process", "after every render job had finished, "
                              "in one fresh process alone" + (" on one Dask worker"
                                                              if scheduler else ""), 1)
        else:
            ms, how = [{} for _ in variants], "frame times: not measured (--frames 0)"
            cpu_ms = q1 = q3 = ms
    except KeyboardInterrupt:
        pool.close(now=True)
        raise SweepInterrupted(sum(len(part[0]) for part in rendered if part),
                               len(variants) * len(backends), timing_phase) from None
    finally:
        pool.close()

    rows, maps, images = [], {}, {}
    for v, (part_rows, part_maps, part_images) in zip(variants, rendered):
        for r in part_rows:
            b = r["backend"]
            rows.append(dict(r, frame_ms=ms[v.index].get(b, math.nan),
                             cpu_ms=cpu_ms[v.index].get(b, math.nan),
                             frame_ms_q1=q1[v.index].get(b, math.nan),
                             frame_ms_q3=q3[v.index].get(b, math.nan),
                             command=row_command(v.file, v.params, b, spec,
                                                 (s.width, s.height), frames, reference,
                                                 reference_samples, general)))
        maps.update(part_maps)
        images.update(part_images)
    mark_front_and_ties(rows)
    warnings = clamp_warnings(rows)
    return SweepResult(rows, spec_name(spec, s), s.width, s.height, len(s.lights), backends,
                       pool.where, how, notes, maps, images, described, warnings=warnings)


def variant_rows(v, res: dict, s, backends, refs: dict, compiled: dict) -> tuple:
    """A rendered variant's rows (one per backend: phase 1's columns, no frame times or
    command), error maps and images.  The rows pass through JSON, as the journal keeps them,
    so that a resumed sweep and an uninterrupted one give the same values."""
    tech = res.get("technique") or compiled[v.index].technique   # the build rendered
    tb = technique_bytes(tech, s.width, s.height)
    memory = {b: technique_memory(tech, s.width, s.height, SHARING[b]) for b in backends}
    bandwidth = frame_bandwidth(tech, s)
    rows, maps, images = [], {}, {}
    for b in backends:
        m = res["metrics"][b]
        name = safe_name(f"{v.slug}_{b}", ".png")
        row = dict(technique=v.technique, params=v.params_text, backend=b, target_bytes=tb,
                   peak_bytes=memory[b].peak_bytes, allocated_bytes=memory[b].allocated_bytes,
                   bandwidth_bytes=bandwidth, agree=res["agree"], file=v.file,
                   width=s.width, height=s.height, notes="; ".join(res["notes"]),
                   reference=refs[v.technique].label, error_map=f"errors/{name}",
                   device=res.get("devices", {}).get(b, backend_title(b)),
                   image=f"images/{name}", worst=[])
        row.update({k: m[k] for k in m})
        row["target_errors"] = target_errors_text(m.get("targets", []))
        if b == "cl":               # the CL backend counts what the formats clamp
            row["clamps"] = res.get("clamps", [])
            row["clamped"] = sum(c["count"] for c in row["clamps"] if c["warned"])
        rows.append(row)
        maps[name] = res["maps"][b]
        images[name] = res["images"][b]
    return json.loads(json.dumps(rows)), maps, images


# how each backend's runtime shares target storage when it aliases (docs/memory.md)
SHARING = {"cl": Sharing.BYTES, "gl": Sharing.DESCRIPTOR}


def frame_bandwidth(tech, scene) -> int:
    """The frame's estimated memory traffic (``ir/traffic.py``) on ``scene``, each pass counted
    as often as the frame runs it (repeat groups and shadow maps once per light they take)."""
    from pipegen.backends.plan import technique_plan
    from pipegen.runtime.draws import LightSelection
    runs = [0] * len(tech.passes)
    for k, _ in LightSelection(technique_plan(tech, ""), list(scene.lights)).schedule():
        runs[k] += 1
    return frame_traffic(tech.passes, tech.targets, scene.width, scene.height, runs)[1]


def plan_references(variants: list, compiled: dict, text: Optional[str], samples: int) -> dict:
    """{technique name: ``references.Reference``}: the one named (``text``) or each technique's
    default, made for its first variant (a bad ``text`` fails here, before any job)."""
    from pipegen.proof.references import choose_reference
    refs = {}
    for v in variants:
        if v.technique not in refs:
            refs[v.technique] = choose_reference(text, compiled[v.index], samples)
    return refs


def target_errors_text(errors: list) -> str:
    """The csv's ``target_errors``: ``attribute p99 units`` per intermediate attribute,
    ``;``-separated (results.json has the rest: rmse, max, worst pixels, what against)."""
    return "; ".join(f"{e['attribute']} p99 {e['p99']:.3g} {e['units']}" for e in errors)


def clamp_warnings(rows: list[dict]) -> list[str]:
    """One warning per technique, pass and target whose values a format clamped, in any
    variant (the CL rows' ``clamps``), with the variants it happened in."""
    from pipegen.proof.clamps import describe, from_record
    seen: dict = {}
    for n, r in enumerate(rows, 1):
        for c in r.get("clamps", []):
            if c["warned"]:
                key = (r["technique"], c["pass_name"], c["target"])
                worst, numbers = seen.get(key, (None, []))
                if worst is None or c["count"] > worst["count"]:
                    worst = c
                seen[key] = (worst, numbers + [n])
    out = []
    for (technique, _, _), (c, numbers) in seen.items():
        clamp = from_record(c)
        rows_text = ",".join(map(str, numbers[:8])) + ("..." if len(numbers) > 8 else "")
        out.append(f"warning: {technique}: {describe(clamp)} (rows {rows_text}; the most in "
                   f"one frame shown; counted on the CL backend)")
    return out
