"""Run stress cases: each scene on GL, CL and the float64 evaluation, every target of both
float32 backends against the float64 values within the bound of the tolerance model
(``pipegen.proof``: ``f64_bound.py``, ``f64_compare.py``; docs/tolerances.md).

``Stress(compiled)`` renders each case with the variant compiled for the case's scene (as
``pipegen run`` would render that scene; ``general=True``: the general build), one per set
of facts (``ir.SceneFacts``), each with one pipeline per backend and its float64 bound, built
once and reused by every case with those facts; ``Stress.run_case(case) -> CaseResult``.  A case the technique cannot render as the scene asks
(``features.mismatches``: light types, translucency, light-index capacity, the light table) is
rendered where possible and reported with its mismatches and dropped lights, its bounds not
counted (``status == "unsupported"``).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from pipegen.core.diagnostics import PipegenError
from pipegen.proof.f64_bound import F64Bound
from pipegen.proof.f64_compare import TargetResult, finite_counts
from pipegen.proof.precision import compare_with_f64
from pipegen.tools.stress.cases import Case

BACKENDS = ("gl", "cl")


@dataclass
class CaseResult:
    case: str
    description: str
    technique: str
    size: tuple[int, int]
    status: str                   # ok | warn | FAIL | unsupported | not rendered
    targets: list[TargetResult] = field(default_factory=list)
    nonfinite: dict = field(default_factory=dict)        # backend -> (nan, inf)
    agree: Optional[bool] = None                          # GL vs CL within §7's tolerance
    disagree: list[str] = field(default_factory=list)
    mismatches: list[str] = field(default_factory=list)
    dropped: str = "-"
    seconds: float = 0.0
    images: dict = field(default_factory=dict, repr=False)   # for the report's PNGs
    scene: object = field(default=None, repr=False)
    # with a reference (--reference): backend -> the output's figures against it
    # (accuracy.codes_vs_reference), or {"error": why it could not be evaluated}
    vs_reference: dict = field(default_factory=dict)
    # one line per target over its bound: where, by how much, what the bound was made of
    # there (``proof.why.why_over``)
    why: list[str] = field(default_factory=list)

    @property
    def worst(self) -> Optional[TargetResult]:
        rows = [t for t in self.targets if not t.exact]
        return max(rows, key=lambda t: t.worst_ratio) if rows else None

    @property
    def failed(self) -> bool:
        return self.status == "FAIL"


@dataclass
class Build:
    """One build a case renders: the compiled technique, its bound (``F64Bound``, with the
    float64 pipeline) and a pipeline per float32 backend."""
    compiled: object
    bound: F64Bound
    pipes: dict

    @property
    def info(self):
        return self.bound.info

    @property
    def f64(self):
        return self.bound.f64


class Stress:
    def __init__(self, compiled, per_channel: bool = True, reference=None,
                 general: bool = False, path=None):
        """``per_channel``: perturb each channel of the read targets in turn (2 renders per
        channel and level of reads); False: all channels at once (2 renders per level).
        ``reference`` (``proof.references.Reference``): also measure each case's output
        against it (``CaseResult.vs_reference``); the bounds stay the technique's own
        float64 evaluation's.  ``general``: render every case with ``compiled`` itself
        instead of the variant compiled for its scene; ``path``: the ``.pipe`` file, so
        that the variants' light tables shrink (``driver.for_scene``)."""
        from pipegen.compiler.capabilities import capabilities
        self.compiled = compiled          # the general build: names, mismatches, capacities
        self.reference = reference
        self.per_channel, self.general, self.path = per_channel, general, path
        self.caps = capabilities(compiled.technique)
        self._builds: dict = {}           # facts (None: the general build) -> Build

    def facts(self, scene):
        """The key of the build that renders ``scene``: its facts (None: the general build)."""
        from pipegen.scene.features import scene_features
        return None if self.general else scene_features(scene).facts()

    def build_key(self, scene) -> str:
        """``facts`` as text (the stress journal keeps it: how many builds a run made)."""
        return repr(self.facts(scene))

    def build(self, scene) -> Build:
        """The build that renders ``scene``: the variant compiled for it (one per facts), or
        with ``general`` the general build."""
        from pipegen.compiler.driver import for_scene
        key = self.facts(scene)
        if key not in self._builds:
            compiled = for_scene(self.compiled, scene, self.general, self.path)
            self._builds[key] = Build(compiled, F64Bound(compiled, self.per_channel),
                                      {b: compiled.pipeline(b) for b in BACKENDS})
        return self._builds[key]

    def builds(self) -> list:
        """The builds (``Compiled``) that rendered the cases so far, one per set of facts."""
        return [b.compiled for b in self._builds.values()]

    def builds_text(self, n: Optional[int] = None) -> str:
        """Which builds rendered the cases so far (``n`` of them; None: those this runner
        made), for the report's first line."""
        if self.general:
            return "the general build (--general)"
        n = len(self._builds) if n is None else n
        return (f"each case rendered by the variant compiled for its scene: {n} variant"
                f"{'s' * (n != 1)}; --general renders the general build")

    # -- lights dropped ----------------------------------------------------------------------
    def dropped(self, scene, build: Build) -> str:
        caps = self.caps
        if not caps.index_packings and not caps.slot_packings:
            return "-"
        from pipegen.reference.lighting import lights_per_pixel
        from pipegen.reference.raster import rasterize
        g = rasterize(scene)
        out = []
        rules = {r[0]: r[1:] for r in caps.index_rules}
        for pack, scheme, capacity, types in caps.index_packings:
            faces, bank = rules.get(pack, ("back", None))      # features.capabilities
            sub = dataclasses.replace(scene, lights=tuple(
                l for i, l in enumerate(scene.lights) if l.type in types and
                (bank is None or i % bank[0] == bank[1])))
            if not sub.lights:
                continue
            n = lights_per_pixel(g, sub, conservative=True, faces=faces,
                                 sky=faces == "front" and scene.has_translucent) - capacity
            n = np.maximum(n, 0)
            out.append(f"{pack}: <={int(n.max())}/px on {int((n > 0).sum())} px")
        for pack, slots, types in caps.slot_packings:
            lost = build.pipes["cl"].dropped_lights.get(pack, [])
            if lost:
                sub = dataclasses.replace(scene, lights=tuple(scene.lights[i] for i in lost))
                n = lights_per_pixel(g, sub)
                out.append(f"{pack}: {len(lost)} lights, <={int(n.max())}/px on "
                           f"{int((n > 0).sum())} px")
            else:
                out.append(f"{pack}: 0")
        return "; ".join(out) or "0"

    # -- against the chosen reference ----------------------------------------------------------
    def vs_reference(self, scene, renders: dict, compiled) -> dict:
        """backend -> the output's error figures against the reference on ``scene`` (the
        worst pixel located); ``{"error": message}`` when the reference cannot render it."""
        from pipegen.proof.accuracy import codes_vs_reference, output_codes
        try:
            return {b: codes_vs_reference(output_codes(compiled, renders[b]),
                                          self.reference, scene, worst=1) for b in BACKENDS}
        except PipegenError as e:
            return {"error": e.message}

    # -- one case ----------------------------------------------------------------------------
    def run_case(self, case: Case, keep_images: bool = True) -> CaseResult:
        t0 = time.perf_counter()
        scene = case.scene
        res = CaseResult(case.name, case.description, self.compiled.name,
                         (scene.width, scene.height), "ok", scene=scene)
        res.mismatches = [m.message for m in self.compiled.mismatches(scene)]
        try:
            build = self.build(scene)
            compiled = build.compiled
            renders = {b: build.pipes[b].render(scene) for b in BACKENDS}
            f64 = build.f64.render(scene)
        except PipegenError as e:
            res.status = "not rendered"
            res.mismatches.append(e.message if hasattr(e, "message") else str(e))
            res.seconds = time.perf_counter() - t0
            return res
        blends = getattr(build.pipes["cl"], "last_blend_counts", {}) or {}
        res.nonfinite = {b: finite_counts(renders[b], False) for b in BACKENDS}
        res.nonfinite["f64"] = finite_counts(f64, True)
        from pipegen.proof.check import compare_targets, explain_disagreements
        rows = compare_targets(compiled, renders["gl"], renders["cl"], len(scene.lights),
                               counts=blends)
        if not all(r.passed for r in rows):
            rows = explain_disagreements(compiled, scene, renders["gl"], renders["cl"],
                                         rows, blends, f64)
        res.agree = all(r.passed for r in rows)
        res.disagree = [r.name for r in rows if not r.passed]
        res.dropped = self.dropped(scene, build)
        if self.reference is not None:
            res.vs_reference = self.vs_reference(scene, renders, compiled)
        bound, parts = build.bound.bounds(scene, f64, blends)
        rows = compare_with_f64(compiled, scene, renders, f64, bound, blends)
        res.targets = [row for b in BACKENDS for row in rows[b]]
        from pipegen.proof.why import why_over
        said = f"{case.name} ({case.description})" if case.description else case.name
        res.why = [w for w in (why_over(t, build.bound.part_maps, build.info, said)
                               for t in res.targets) if w]
        if keep_images:
            res.images = {"gl": renders["gl"], "f64": f64, "bound": bound, "parts": parts}
        if res.mismatches:
            res.status = "unsupported"
        elif not res.agree or any(not t.passed and t.output for t in res.targets):
            res.status = "FAIL"
        elif any(not t.passed for t in res.targets):
            res.status = "warn"
        res.seconds = time.perf_counter() - t0
        return res
