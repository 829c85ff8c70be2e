"""One configuration of a technique measured for ``pipegen tune``: compiled once, rendered on
each scene (every render counted), its output's error against the reference, the lights its
light-index packings drop, its target memory and, when asked, its frame time.

Each scene is rendered, as ``pipegen run`` renders it, by the variant compiled for it
(``driver.for_scene``; the general build with ``general``).  Target memory (``ir.memory.
technique_bytes`` of the build rendered on the first scene, at its size) and the lights dropped
by a light-index packing (a float64 rasterisation of the scene: how many lights reach each
pixel against what the packing holds) need no render; the error figures do.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from pipegen.core.diagnostics import PipegenError


@dataclass
class Measured:
    """What is known of one configuration.  ``figures``: metric -> value, the worst over the
    scenes (``lights_dropped``: the sum); rendered metrics are absent until it is rendered."""

    key: tuple                       # one value per axis, in axis order
    params: dict
    memory: int
    figures: dict = field(default_factory=dict)
    per_scene: list = field(default_factory=list)     # [{scene, p99, max, rmse, flip, ...}]
    rendered: bool = False
    time_ms: Optional[float] = None                   # median frame time
    time_q: Optional[tuple] = None                    # (first quartile, third quartile)
    frames: int = 0
    notes: list = field(default_factory=list)
    order: int = 0                                    # when it was rendered (1, 2, ...)


class Reference:
    """The reference the error is measured against: ``pipegen.proof.references`` when it is
    there (``scene``, ``self``, ``FILE.pipe[:k=v]``), else the scene reference alone."""

    def __init__(self, text: Optional[str], base, samples: int = 1):
        try:
            from pipegen.proof import references as R
        except ImportError:          # before issue 25's references land: the scene reference
            R = None
        self.scene_refs: dict = {}
        if R is None:
            if text not in (None, "scene") or samples != 1:
                raise PipegenError(None, f"--reference {text}: only the scene reference is "
                                         f"available in this version", hint="--reference scene")
            self.ref, self.label = None, "scene"
            self.describe = "scene: pipegen's float64 scene evaluation (the shipped lighting)"
            self.why = ""
            return
        spec = R.parse_reference(text, samples) if text else R.default_reference(base)
        if not text and samples != 1:
            spec = dataclasses.replace(spec, samples=samples)
        # one reference for every configuration: for `self`, the technique at its defaults
        # with the `accurate` values (not each configuration's own values)
        self.ref = R.Reference(spec, base)
        self.label, self.describe, self.why = spec.label, self.ref.describe(), spec.why

    def errors(self, codes, scene) -> dict:
        from pipegen.proof import accuracy
        if self.ref is not None and hasattr(accuracy, "codes_vs_reference"):
            try:
                rgb = self.ref.output_rgb(scene)     # evaluated once per scene, then cached
            except RuntimeError as exc:              # e.g. its float64 program fails to build
                raise PipegenError(None, f"the reference ({self.label}) could not be evaluated "
                                         f"on {scene.name}: {str(exc).splitlines()[0]}",
                                   hint="try --reference scene, or pipegen run --backend cl "
                                        "--precision f64 on the reference technique") from None
            e = accuracy.codes_vs_reference(codes, self.ref, scene)
        else:
            if id(scene) not in self.scene_refs:
                self.scene_refs[id(scene)] = accuracy.scene_reference(scene)
            sref = self.scene_refs[id(scene)]
            e, rgb = accuracy.scene_error(codes, sref), sref.rgb
        return dict(p99=float(e["p99"]), max=float(e["max"]), rmse=float(e["rmse"]),
                    flip=accuracy.flip_mean(codes, rgb))


class Evaluator:
    """Measures configurations of ``file`` on ``scenes`` (loaded, sized) on one backend;
    ``renders`` counts every render (one per configuration and scene), ``timed_frames`` the
    frames timed."""

    def __init__(self, file: str, scenes: list, reference: Reference, backend: str = "gl",
                 frames: int = 5, general: bool = False):
        from pipegen.compiler.driver import compile_file
        self.file, self.scenes, self.reference = file, scenes, reference
        self.backend, self.frames, self.general = backend, frames, general
        self.compile = compile_file
        self.renders = 0
        self.timed_frames = 0
        self._compiled: dict = {}
        self._raster: dict = {}
        self.known: dict = {}        # key -> Measured

    def compiled(self, params: dict):
        k = tuple(sorted(params.items(), key=lambda kv: kv[0]))
        if k not in self._compiled:
            self._compiled[k] = self.compile(self.file, dict(params) or None)
        return self._compiled[k]

    def rendered(self, params: dict, scene):
        """The build that renders ``scene``: the variant compiled for it (cached per process
        by facts), or the general build with ``general``."""
        from pipegen.compiler.driver import for_scene
        return for_scene(self.compiled(params), scene, self.general, self.file)

    # -- free figures ----------------------------------------------------------------------
    def measured(self, key: tuple, params: dict) -> Measured:
        """The configuration with what needs no render: memory and (index packings) lights
        dropped."""
        if key not in self.known:
            from pipegen.ir.memory import technique_bytes
            c = self.compiled(params)
            s0 = self.scenes[0]
            m = Measured(key, dict(params), technique_bytes(self.rendered(params, s0).technique,
                                                            s0.width, s0.height))
            dropped = self.index_dropped(c)
            if dropped is not None:
                m.figures["lights_dropped"] = dropped
            self.known[key] = m
        return self.known[key]

    def index_dropped(self, compiled) -> Optional[int]:
        """Light-pixel pairs over capacity of the light-index packings, summed over pixels and
        scenes (as ``stress`` computes them: conservative light volumes, float64); None when
        the technique has slot packings (known only after a render), 0 without packings."""
        from pipegen.compiler.capabilities import capabilities
        from pipegen.reference.lighting import lights_per_pixel
        caps = capabilities(compiled.technique)
        if caps.slot_packings:
            return None
        total = 0
        rules = {r[0]: r[1:] for r in caps.index_rules}
        for scene in self.scenes:
            for pack, _scheme, capacity, types in caps.index_packings:
                faces, bank = rules.get(pack, ("back", None))
                sub = dataclasses.replace(scene, lights=tuple(
                    l for i, l in enumerate(scene.lights) if l.type in types and
                    (bank is None or i % bank[0] == bank[1])))
                if not sub.lights:
                    continue
                n = lights_per_pixel(self.raster(scene), sub, conservative=True, faces=faces,
                                     sky=faces == "front" and scene.has_translucent)
                total += int(np.maximum(n - capacity, 0).sum())
        return total

    def raster(self, scene):
        if id(scene) not in self._raster:
            from pipegen.reference.raster import rasterize
            self._raster[id(scene)] = rasterize(scene)
        return self._raster[id(scene)]

    # -- rendering -------------------------------------------------------------------------
    def render(self, key: tuple, params: dict) -> Measured:
        """Render the configuration on every scene (once: cached) and fill its figures."""
        m = self.measured(key, params)
        if m.rendered:
            return m
        from pipegen.proof import accuracy
        slot_lost = 0
        for scene in self.scenes:
            notes = [x.message for x in self.compiled(params).mismatches(scene)]
            c = self.rendered(params, scene)
            pipe = c.pipeline(self.backend)
            try:
                targets = pipe.render(scene)
                self.renders += 1
                lost = getattr(pipe, "dropped_lights", None) or {}
                if lost:
                    slot_lost += self._slot_pairs(scene, lost)
            finally:
                getattr(pipe, "release", lambda: None)()
            e = self.reference.errors(accuracy.output_codes(c, targets), scene)
            e["scene"] = scene.name
            m.per_scene.append(e)
            m.notes += [n for n in notes if n not in m.notes]
        for metric in ("p99", "max", "rmse", "flip"):
            m.figures[metric] = max(e[metric] for e in m.per_scene)
        if "lights_dropped" not in m.figures:
            m.figures["lights_dropped"] = slot_lost
        m.rendered = True
        m.order = sum(1 for x in self.known.values() if x.rendered)
        return m

    def _slot_pairs(self, scene, lost: dict) -> int:
        from pipegen.reference.lighting import lights_per_pixel
        total = 0
        for indices in lost.values():
            if indices:
                sub = dataclasses.replace(scene, lights=tuple(scene.lights[i] for i in indices))
                total += int(lights_per_pixel(self.raster(scene), sub).sum())
        return total

    # -- timing ----------------------------------------------------------------------------
    def time(self, measured: list, frames: Optional[int] = None) -> None:
        """Time the configurations on the first scene, interleaved frame by frame
        (``tools.timing.interleave``) after one warm-up each: median and quartiles in ms."""
        from pipegen.tools.timing import interleave
        frames = self.frames if frames is None else frames
        if frames <= 0 or not measured:
            return
        scene = self.scenes[0]
        pipes, fns = [], {}
        try:
            for m in measured:
                p = self.rendered(m.params, scene).pipeline(self.backend)
                pipes.append(p)
                fns[m.key] = (lambda p=p: p.frame(scene)) if hasattr(p, "frame") else \
                    (lambda p=p: p.render(scene))
            samples = interleave(fns, frames, warmup=True)
        finally:
            for p in pipes:
                getattr(p, "release", lambda: None)()
        for m in measured:
            wall = sorted(x * 1e3 for x in samples[m.key].wall)
            m.time_ms = statistics.median(wall)
            q = statistics.quantiles(wall, n=4) if len(wall) > 1 else [wall[0]] * 3
            m.time_q = (q[0], q[2])
            m.frames = len(wall)
            self.timed_frames += len(wall)


def overlap(a: Measured, b: Measured) -> bool:
    """Do two frame times' interquartile ranges overlap (a tie within the spread)?"""
    if a.time_q is None or b.time_q is None:
        return False
    return a.time_q[0] <= b.time_q[1] and b.time_q[0] <= a.time_q[1]


def finite(x) -> Optional[float]:
    return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else x
