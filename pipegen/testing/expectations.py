"""The ``expect`` lines of a ``.pipe`` file, checked (``pipegen test``, and the pytest plugin
through ``pipe_items.py``): ``check(compiled, expectation)`` -> an ``Outcome`` with the numbers.

Through ``pipegen.testing``'s functions, so that an expectation holds a target to the same
tolerance model as a test written in Python (docs/tolerances.md):

- ``expect T agrees gl cl``: ``assert_backends_agree`` for target T (no discontinuity);
- ``expect T vs f64``: ``assert_close_to_f64`` for T on both float32 backends;
- ``expect T agrees gl cl STAT OP N`` / ``expect T vs f64 STAT OP N``: the statistic of
  |a - b| per pixel (the largest channel) in T's units -- codes for fixed point (unorm, snorm,
  d24), values for float formats, codes for integers and stencil -- on each backend compared;
  ``over`` and ``discontinuities`` are the pixels the tolerance model counts beyond its bound
  (not explained, explained by a step of the technique's code);
- ``expect lights_dropped OP N``, ``expect mismatches OP N``: counts, without rendering.

An expectation on a target renders what ``pipegen run`` renders: the variant compiled for the
scene (``api.for_scene``; the general build with ``pytest --pipegen-general``), or the
general build when the variant culled the target (the scene does not call for it, but the
file asks about it).  Counts are of the general build.

Each check records a ``records.Comparison(kind="expect")`` (beside the ones the functions
record) for the plugin's report.  The scene is the built-in default scene at 64x36
(``api.TEST_SIZE``) unless the line says ``on "scene"`` and/or ``at WxH``.
"""

from __future__ import annotations

import operator
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, Optional

from pipegen.core.diagnostics import PipegenError
from pipegen.ir import nodes as ir
from pipegen.testing import records

_OPS: dict[str, Callable[[float, float], bool]] = {
    "<=": operator.le, "<": operator.lt, "==": operator.eq, "!=": operator.ne,
    ">=": operator.ge, ">": operator.gt}
_PERCENTILES = {"p50": 50.0, "p90": 90.0, "p95": 95.0, "p99": 99.0, "p99.9": 99.9}


@dataclass
class Outcome:
    """One expectation checked: whether it holds, and ``detail``, the numbers (for a
    failure, the reason with them)."""
    expectation: ir.Expectation
    passed: bool
    detail: str

    @property
    def where(self) -> str:
        """``file:line``, the file relative to the current folder when it is inside it."""
        s = self.expectation.span
        if s is None:
            return "?"
        rel = os.path.relpath(s.file)
        return f"{s.file if rel.startswith('..') else rel}:{s.line}"

    def line(self) -> str:
        """``file:line: expect ... ok (numbers)`` or ``... FAILED: reason``."""
        verdict = f"ok ({self.detail})" if self.passed else f"FAILED: {self.detail}"
        return f"{self.where}: expect {self.expectation.text} ... {verdict}"


def backends_needed(e: ir.Expectation) -> tuple[str, ...]:
    """What checking ``e`` renders with: GL and/or CL (the float64 evaluation runs on CL)."""
    if e.check == "count":
        return ()
    return ("gl", "cl")


def load(path, params: Optional[dict] = None):
    """The technique at ``path`` compiled; its messages name the file as ``path`` does."""
    from pipegen.compiler.inputs import compile_technique
    return compile_technique(path, list((params or {}).items()))


def check_file(path, params: Optional[dict] = None) -> Iterator[Outcome]:
    """Every expectation of the ``.pipe`` file at ``path``, checked in the order written."""
    compiled = load(path, params)
    for e in compiled.technique.expectations:
        yield check(compiled, e)


def check(compiled, e: ir.Expectation) -> Outcome:
    """``e`` checked on ``compiled``.  A scene that cannot be loaded or rendered fails this
    expectation with pipegen's message (the others are still checked)."""
    from pipegen.testing.api import for_scene, load_test_scene
    try:
        scene = load_test_scene(e.scene, e.size)     # None: the built-in scene at TEST_SIZE
        if e.check == "count":
            outcome = _count(compiled, e, scene)
        elif not _rendered(compiled, e.subject):
            outcome = Outcome(e, False, f"target '{e.subject}' is not rendered: compiling "
                                        f"removed it (does a pass write it?)")
        else:
            variant = for_scene(compiled, scene)
            build = variant if _rendered(variant, e.subject) else compiled
            outcome = (_verdict if e.statistic is None else _statistic)(build, e, scene)
    except PipegenError as err:      # the scene cannot be loaded or rendered: this one fails
        s = err.span
        where = (f"{s.file}:{s.line}:{s.column}: " if s is not None else
                 f"{os.path.relpath(e.scene)}: " if e.scene else "")
        outcome = Outcome(e, False, f"{where}error: {err.message}"
                                    + (f" (hint: {err.hint})" if err.hint else ""))
    _record(compiled, e, outcome)
    return outcome


def _rendered(compiled, target: str) -> bool:
    return any(t.name == target for t in compiled.technique.targets)


# -- counts ------------------------------------------------------------------------------------

def _count(compiled, e: ir.Expectation, scene) -> Outcome:
    if e.subject == "mismatches":
        found = [m.message for m in compiled.mismatches(scene)]
        n, what = len(found), "; ".join(found)
    else:
        dropped = lights_dropped(compiled, scene)
        n = sum(len(v) for v in dropped.values())
        what = "; ".join(f"{pack}: lights {', '.join(map(str, v))}"
                         for pack, v in dropped.items() if v)
    ok = _OPS[e.op](n, e.value)
    detail = f"{e.subject} = {n}" + (f" ({what})" if what else "")
    return Outcome(e, ok, detail if ok else f"{detail}, expected {e.op} {_num(e.value)}")


def lights_dropped(compiled, scene) -> dict[str, list[int]]:
    """The lights no light set takes, per packing (``in PACK[k]`` draws): unlit, whole.  The
    host-side selection both runtimes draw with (``runtime/draws.py``), without rendering."""
    from pipegen.runtime.draws import LightSelection
    plan = compiled.plan("cl")
    selection = LightSelection(plan, scene.lights)
    for p in plan.passes:
        if p.draw.light_set:
            selection.of(p.draw)
    return dict(selection.dropped)


# -- the derived tolerance ---------------------------------------------------------------------

def _compare(compiled, e: ir.Expectation, scene):
    """``assert_backends_agree`` or ``assert_close_to_f64`` for ``e``'s target, any number of
    discontinuities allowed (they are counted here, for this target alone): (the result, or
    None when a pixel broke the bound; the failure's messages; the records made for it)."""
    from pipegen.testing.api import (ComparisonFailure, assert_backends_agree,
                                     assert_close_to_f64)
    compare = assert_backends_agree if e.check == "agrees" else assert_close_to_f64
    before = len(records.RECORDED)
    result, failures = None, []
    try:
        result = compare(compiled, scene, only={e.subject}, max_discontinuities=_ANY,
                         general=True)                  # ``compiled``: the build chosen
    except ComparisonFailure as failure:
        failures = [c.message or c.summary for c in failure.comparisons if not c.passed]
    made = [c for c in records.RECORDED[before:] if _target_of(c) == e.subject]
    return result, failures, made


_ANY = 1 << 62


def _target_of(c: records.Comparison) -> str:
    """The target a comparison is about (``color``, ``ds.depth``, ``color (gl)`` -> color)."""
    return c.target.split(" (")[0].partition(".")[0]


def _label(c: records.Comparison) -> str:
    """Which comparison a record is: gl-cl, gl (against f64), cl; with the aspect of a
    depth-stencil target (``ds.depth``)."""
    key = c.target.split(" (")[0]
    which = c.numbers.get("backend", "gl-cl")
    return which + (f" {key}" if "." in key else "")


def _verdict(compiled, e: ir.Expectation, scene) -> Outcome:
    result, failures, made = _compare(compiled, e, scene)
    if failures:
        return Outcome(e, False, " | ".join(failures))
    found: dict[str, list[str]] = {}          # a discontinuity -> the comparisons with it
    rows = ([("gl-cl", r) for r in result.rows] if e.check == "agrees" else
            [(b, r) for b, rs in result.rows.items() for r in rs])
    for which, row in rows:
        key = getattr(row, "name", None) or row.key
        if key.partition(".")[0] == e.subject:
            for d in row.discontinuities:
                found.setdefault(d.describe(), []).append(which)
    if found:
        counts = ", ".join(f"{_label(c)} {c.numbers.get('discontinuities', '0')} px"
                           for c in made)
        return Outcome(e, False, f"discontinuities ({counts}), none allowed without "
                                 f"`discontinuities <= N`: " + "; ".join(
                                     f"{', '.join(w)}: {d}" for d, w in found.items()))
    return Outcome(e, True, "; ".join(_brief(c) for c in made) or "within the derived bound")


def _brief(c: records.Comparison) -> str:
    n = c.numbers
    if "bound there" in n:
        return f"{_label(c)}: max {n.get('max error')}, bound there {n['bound there']}"
    return f"{_label(c)}: max {n.get('max error')}, limit {n.get('limit')}"


def _against(e: ir.Expectation) -> tuple[str, ...]:
    """The float32 backends a check renders with."""
    return e.against if e.check == "agrees" else ("gl", "cl")


# -- statistics --------------------------------------------------------------------------------

def _statistic(compiled, e: ir.Expectation, scene) -> Outcome:
    if e.statistic in ("over", "discontinuities"):
        values = _counted(compiled, e, scene)
    else:
        values = {name: statistic(e.statistic, err) for name, err in _errors(compiled, e, scene)}
    unit = " px" if e.statistic in ("over", "discontinuities") else _unit(compiled, e.subject)
    ok = all(_OPS[e.op](v, e.value) for v in values.values())
    shown = ", ".join(f"{name} {_num(v)}" for name, v in values.items())
    detail = f"{e.statistic}: {shown}{unit}"
    if ok:
        return Outcome(e, True, detail)
    bad = [name for name, v in values.items() if not _OPS[e.op](v, e.value)]
    return Outcome(e, False, f"{detail}; expected {e.op} {_num(e.value)} "
                             f"(fails on {', '.join(bad)})")


def statistic(name: str, err) -> float:
    """``name`` (``Expectation.STATISTICS`` but over/discontinuities) of the per-pixel
    errors ``err`` (any shape; NaN against a number counts as infinite)."""
    import numpy as np
    a = np.asarray(err, np.float64).ravel()
    if a.size == 0:
        return 0.0
    if name == "max":
        return float(a.max())
    if name == "rmse":
        return float(np.sqrt(np.mean(np.square(a))))
    return float(np.percentile(a, _PERCENTILES[name], method="higher"))


def _errors(compiled, e: ir.Expectation, scene) -> Iterator[tuple[str, object]]:
    """(what was compared, |a - b| per pixel in the target's units), for each comparison."""
    from pipegen.testing.api import render
    f32 = {b: render(compiled, scene, backend=b, general=True) for b in _against(e)}
    keys = [k for k in f32[_against(e)[0]] if k.partition(".")[0] == e.subject]
    fmt = compiled.technique.target(e.subject).format
    if e.check == "agrees":
        a, b = _against(e)
        for k in keys:
            label = f"{a}-{b}" + (f" {k}" if len(keys) > 1 else "")
            yield label, _pixel_error(_in_units(fmt, k, f32[a][k].values),
                                      _in_units(fmt, k, f32[b][k].values))
        return
    f64 = compiled.pipeline("cl", precision="f64").render(scene)
    for backend, targets in f32.items():
        for k in keys:
            label = backend + (f" {k}" if len(keys) > 1 else "")
            yield label, _pixel_error(_in_units(fmt, k, targets[k].values),
                                      _in_units(fmt, k, f64[k], f64=True))


def _in_units(fmt, key: str, values, f64: bool = False):
    """A target's values in its units: codes for fixed point (the float64 evaluation's values
    times the largest code, unrounded), integers and stencil; values for float formats."""
    import numpy as np
    from pipegen.core.formats import Kind
    v = np.asarray(values, np.float64)
    if not f64 or key.endswith(".stencil"):
        return v
    if fmt.is_integer:
        return np.asarray(fmt.quantize(v), np.float64)
    if fmt.is_normalized or fmt.kind is Kind.DEPTH_STENCIL:
        top = np.asarray(fmt.max_codes, np.float64)
        return v * (top if v.ndim == 3 else top[0])
    return v


def _pixel_error(a, b):
    """|a - b| per pixel, its largest channel (NaN matches only NaN, inf only itself)."""
    from pipegen.proof.f64_compare import error
    err = error(a, b)
    return err.max(axis=-1) if err.ndim == 3 else err


def _counted(compiled, e: ir.Expectation, scene) -> dict[str, float]:
    """``over`` or ``discontinuities`` as the tolerance model counts them, per comparison."""
    _, _, made = _compare(compiled, e, scene)
    return {_label(c): float(c.numbers.get(e.statistic, "0")) for c in made}


def _unit(compiled, target: str) -> str:
    from pipegen.core.formats import Kind
    fmt = compiled.technique.target(target).format
    return "" if fmt.kind is Kind.FLOAT or fmt.kind is Kind.DEPTH else " codes"


# -- records -----------------------------------------------------------------------------------

def _record(compiled, e: ir.Expectation, outcome: Outcome) -> None:
    command = f"pipegen test {e.span.file}" if e.span is not None else "pipegen test"
    records.record(records.Comparison(
        "expect", compiled.name, e.subject if e.check != "count" else "-", outcome.passed,
        f"{outcome.where}: expect {e.text}", {"result": outcome.detail}, command=command,
        message="" if outcome.passed else outcome.line()))


def _num(x: float) -> str:
    return f"{x:.4g}" if isinstance(x, float) else str(x)
