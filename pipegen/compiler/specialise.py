"""Scene specialisation: compile a technique for what a scene calls for, say why each cut was
made, and refuse scenes that break the assumptions.

``specialise(compiled, scene)`` (or ``compile_file(path, scene=scene)``) turns the scene's
features (``features.scene_features``) into compile-time facts (``ir.SceneFacts``) and runs
the scene phases, ``passes/pipelines.SCENE`` run by the pass manager, verified after each in
tests:

    assume_scene → spec_light_types → spec_shadows → fold → dead_code → unread_reads →
    prune → cull_empty_draws → cull_unread

and, before them, shrinks the light table: the parameter that sizes it is set to the smallest
power of two (within its allowed values) that holds the scene's lights, so similar scenes
share a variant.  Every cut is an ``ir.Cut`` with its reason, chained to the scene fact or the
earlier cut behind it.  Variants are cached by (source, parameters, facts): rendering a
sequence of scenes compiles each variant once (``Specialisation.reused``).
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from pipegen.core.units import format_bytes
from pipegen.ir import nodes as ir
from pipegen.ir.memory import specialisation_bytes
from pipegen.scene.features import SceneFeatures, scene_features
from pipegen.passes import pipelines
from pipegen.passes.manager import Watch, run_pipeline

SCENE_PHASES = pipelines.SCENE  # read when a variant compiles: a test may put another in its place


@dataclass(frozen=True)
class Specialisation:
    features: SceneFeatures
    facts: ir.SceneFacts
    cuts: tuple[ir.Cut, ...]
    general: ir.Technique            # the technique before specialisation
    special: ir.Technique            # the technique after specialisation
    params: tuple[tuple[str, object], ...]   # parameters the specialisation set
    reused: bool = False             # this variant came from the cache

    # The pieces below are what ``pipegen specialise`` (``report``) and the compile report
    # (``summary``) say about a specialisation; both are built from them.

    def pass_names(self) -> tuple[list[str], list[str]]:
        """The pass names before and after specialisation."""
        return [p.name for p in self.general.passes], [p.name for p in self.special.passes]

    def target_names(self) -> tuple[list[str], list[str]]:
        """The target names before and after specialisation."""
        return ([t.name for t in self.general.targets],
                [t.name for t in self.special.targets])

    def memory(self, w: int, h: int) -> tuple[int, int]:
        """Bytes of all targets at output size ``w`` x ``h``, before and after."""
        return specialisation_bytes(self.general, self.special, w, h)

    def cut_lines(self, params: bool = False) -> list[str]:
        """The facts specialised for, then each cut with its reason (and, with ``params``,
        the parameters the specialisation set)."""
        lines = [f"specialised for: {self.facts.describe()}"]
        lines += [f"  {c.describe()}" for c in self.cuts] or ["  nothing to cut"]
        if params:
            lines += [f"  parameter {k} = {v}" for k, v in self.params]
        return lines

    def summary(self) -> list[str]:
        """What was cut and why, and the passes and targets before and after, compactly (the
        compile report)."""
        (before_p, after_p), (before_t, after_t) = self.pass_names(), self.target_names()
        return [*self.cut_lines(),
                f"passes: {len(before_p)} -> {len(after_p)} ({', '.join(after_p)})",
                f"targets: {len(before_t)} -> {len(after_t)} ({', '.join(after_t)})"]

    def report(self, w: int, h: int) -> list[str]:
        """What was cut and why, the parameters set, the passes and targets before and after
        in full and the target memory at ``w`` x ``h`` (``pipegen specialise``)."""
        (before_p, after_p), (before_t, after_t) = self.pass_names(), self.target_names()
        before_m, after_m = self.memory(w, h)
        return [*self.cut_lines(params=True), "",
                f"passes   before ({len(before_p)}): {', '.join(before_p)}",
                f"         after  ({len(after_p)}): {', '.join(after_p)}",
                f"targets  before ({len(before_t)}): {', '.join(before_t)}",
                f"         after  ({len(after_t)}): {', '.join(after_t)}",
                f"target memory at {w}x{h}: {format_bytes(before_m, 'MiB', exact=True)} -> "
                f"{format_bytes(after_m, 'MiB', exact=True)} "
                f"({format_bytes(before_m - after_m, 'MiB')} saved)"]


_CACHE: dict = {}


def clear_cache() -> None:
    _CACHE.clear()


def _key(compiled, facts: ir.SceneFacts, shrinks: bool) -> tuple:
    """The variant's cache key.  ``shrinks``: whether the light table may be shrunk (only
    with ``recompile``): ``Compiled.specialise`` keeps the table, ``compile_file(scene=)``
    shrinks it, so the two make different variants of the same technique and facts."""
    tech = compiled.technique
    digest = hashlib.sha256(repr(tech).encode()).hexdigest()
    return (tech.source, digest, tuple(sorted(compiled.params.items())), facts, shrinks)


def specialise(compiled, scene, features: Optional[SceneFeatures] = None,
               recompile: Optional[Callable[[dict], object]] = None,
               verify_each: bool = False, watch: Optional[Watch] = None):
    """``compiled`` specialised for ``scene``: a new ``Compiled`` whose ``specialisation``
    lists the cuts.  ``recompile(params)`` compiles the same source with other parameters
    (used to shrink the light table); without it the table keeps its size.  ``watch``: what
    to show of the scene passes as they run (``manager.Watch``; a cached variant runs none)."""
    features = features or scene_features(scene)
    facts = features.facts()
    key = _key(compiled, facts, recompile is not None)
    hit = _CACHE.get(key)
    if hit is not None:
        return dataclasses.replace(hit, specialisation=dataclasses.replace(
            hit.specialisation, reused=True))
    general = compiled.technique
    base, set_params, cuts = compiled, {}, []
    if recompile is not None:
        base, set_params, cuts = _shrink_light_table(compiled, facts, recompile)
    tech = dataclasses.replace(base.technique, scene=facts, cuts=tuple(cuts))
    watch = watch or Watch()
    tech, ran = run_pipeline(SCENE_PHASES, tech, verify_each, watch.progress, watch.dump_after,
                             watch.dump)
    phases = [*base.phases_run, "assume_scene", *ran]
    spec = Specialisation(features, facts, tech.cuts, general, tech,
                          tuple(set_params.items()))
    # the compiled technique ``base`` with the scene's IR (and no plans emitted yet): the
    # compiler's record, without importing the compiler that calls this
    out = dataclasses.replace(base, technique=tech, params=dict(base.params),
                              phases_run=phases, specialisation=spec, _plans={})
    _CACHE[key] = out
    return out


def _shrink_light_table(compiled, facts: ir.SceneFacts, recompile):
    """Recompile with the light table's sizing parameter at the smallest power of two (within
    its allowed values) that holds the scene's lights.  The parameter is the integer one,
    not set by the user, whose value is the table's capacity; the recompiled capacity is
    checked, so a parameter that only happens to share the value is left alone."""
    tech = compiled.technique
    capacity = tech.lights.capacity
    if not tech.lights.fields or facts.lights >= capacity:
        return compiled, {}, []
    for p in tech.params:
        if p.name in compiled.params or p.type != ir.INT or p.default != capacity:
            continue
        allowed = sorted(v for v in (p.allowed or ()) if v >= facts.lights)
        size = allowed[0] if p.allowed and allowed else (facts.lights if not p.allowed
                                                          else capacity)
        if size >= capacity:
            continue
        params = {**compiled.params, p.name: size}
        smaller = recompile(params)
        if smaller.technique.lights.capacity != size:
            continue
        why = (f"{capacity} -> {size} entries ({p.name} = {size}): the scene has "
               f"at most {facts.lights} lights (rounded up to a power of two)")
        return smaller, {p.name: size}, [ir.Cut("table", "lights", why)]
    return compiled, {}, []


# ---- proof -------------------------------------------------------------------------------------


@dataclass
class Verification:
    """``specialise --verify``: per backend, the targets compared bit for bit and the first
    pass (with its light) after which a specialised target differs from the general one."""
    compared: dict                    # backend -> target names compared
    differences: dict                 # backend -> [target names that differ]
    first_difference: dict            # backend -> "pass (light k): targets" or None

    @property
    def identical(self) -> bool:
        return not any(self.differences.values())


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def verify(general, special, scene, backends=("gl", "cl"), size=None) -> Verification:
    """Render ``scene`` with the general and the specialised technique on each backend and
    compare every target the specialised pipeline produces, bit for bit (NaNs by their bits).
    On a difference both are replayed pass by pass to name the first pass that differs."""
    compared, differences, first = {}, {}, {}
    for backend in backends:
        g = general.pipeline(backend, size).render(scene)
        s = special.pipeline(backend, size).render(scene)
        names = sorted(s)
        compared[backend] = names
        differences[backend] = [n for n in names if n not in g or not _same(g[n], s[n])]
        first[backend] = (_first_difference(general, special, scene, backend, size)
                          if differences[backend] else None)
    return Verification(compared, differences, first)


def _first_difference(general, special, scene, backend, size) -> Optional[str]:
    _, gcaps = general.pipeline(backend, size).render(scene, capture_passes=True)
    _, scaps = special.pipeline(backend, size).render(scene, capture_passes=True)
    latest = {}
    order = iter(gcaps)
    for cap in scaps:
        key = (cap["pass"], cap["light"])
        skipped = []                          # general executions the variant does not run
        for g in order:                       # the general run's same execution, in order
            latest[(g["pass"], g["light"])] = g
            if (g["pass"], g["light"]) == key:
                break
            skipped.append(_where(g))
        g = latest.get(key)
        bad = sorted(n for n, v in cap["targets"].items()
                     if g is None or n not in g["targets"] or not _same(g["targets"][n], v))
        if bad:
            before = (f" (after the general pipeline's {', '.join(skipped[:4])}"
                      f"{' …' if len(skipped) > 4 else ''}, which the variant does not run)"
                      if skipped else "")
            return f"{_where(cap)}: {', '.join(bad)}{before}"
    rest = [_where(g) for g in order]         # what the general pipeline runs after that
    if rest:
        return (f"after {_where(scaps[-1]) if scaps else 'the clears'}: the general pipeline "
                f"goes on with {', '.join(rest[:4])}{' …' if len(rest) > 4 else ''}")
    return None


def _where(cap) -> str:
    return cap["pass"] if cap["light"] is None else f"{cap['pass']} (light {cap['light']})"
