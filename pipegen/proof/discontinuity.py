"""Discontinuities: pixels where two evaluations of a technique fall on different sides of a
step in its own code, told apart from precision errors (docs/tolerances.md, "Discontinuities").

A technique whose code has a step (a comparison ``x < t`` in a branch or a ``?:``, ``step``,
``floor``/``ceil``/``round``/``fract``/``mod``/``sign``, a float-to-integer conversion, a
packing's quantisation) renders a different value wherever its input lands on the other side of
the step, however small the input's error.  At such a pixel float32 and float64 (or GL and CL)
may differ by a whole toon band or a whole packed code: not an error of precision, and no bound
on precision can hold it.

How a pixel is recognised: the float64 evaluation is rendered again with the step *nudged*,
its input moved by ``delta * (|operands| + 1)`` up and down (``delta`` in ``LEVELS``, smallest
first).  A candidate pixel (the two evaluations differ there by more than a continuous
computation could) is a discontinuity of a site when nudging that one site makes the float64
evaluation jump there (a choice flipped, not a value moved) and one evaluation is closer to the
jumped value than to the unnudged one: it took the other side.  All sites upstream of the
target are nudged at once first (two renders per level); only when that explains something are
the sites split in halves, and each half that still flips something split again, down to the
one site that names the pixel (about 4 log2(n) renders per site found among n, where trying each
site in turn cost 2 n).  Every render is of one program: the technique compiled once for the
float64 evaluation with each step's move a run-time input (``nudged_at_run_time``; 0 leaves a
site exactly as it was), made only when some pixel is a candidate.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence

import numpy as np

from pipegen.core.diagnostics import Span
from pipegen.ir import nodes as ir
from pipegen.ir import printer, walk
from pipegen.ir.builtins import nudge_input
from pipegen.proof.f64_compare import error

# the nudges tried, relative to the operands' magnitude (and absolute below 1): 2^-12 is
# arithmetic error, 2^-6 an input read from an 8-bit target (half a code is 2^-9 of 1, and a
# shading input is a few such values combined)
LEVELS = (2.0 ** -12, 2.0 ** -6)
COMPARISONS = {"<", "<=", ">", ">="}
STEP_CALLS = {"floor", "ceil", "round", "fract", "mod", "sign", "step"}
MAX_LOCATIONS = 20            # pixel locations kept per site (the count is exact)


@dataclass(frozen=True)
class Site:
    """One step in the technique's code."""
    index: int                 # its place in the walk (``nudged(..., only=index)``)
    text: str                  # the expression, as the IR printer spells it
    span: Optional[Span]       # where the user wrote it (None: generated code)
    where: str                 # "function toon", "pass shade", "packing ids"
    passes: frozenset = frozenset()   # the passes whose code runs it (directly or by a call)

    def describe(self) -> str:
        at = f"{self.span.file}:{self.span.line}:{self.span.column}" if self.span else \
            "generated code"
        return f"`{self.text}` ({at}, {self.where})"


@dataclass
class Discontinuity:
    """The pixels of one target where a site (None: several sites together) made the choice."""
    site: Optional[Site]
    count: int
    locations: list[tuple[int, int]] = field(default_factory=list)   # (x, y), y from the top

    def describe(self) -> str:
        what = self.site.describe() if self.site else "several steps at once"
        at = ", ".join(f"({x}, {y})" for x, y in self.locations[:5])
        more = ", …" if self.count > 5 else ""
        return f"{self.count} px at {what}: {at}{more}"


def _float(t: ir.Type) -> bool:
    return t.scalar is ir.Scalar.FLOAT and not t.mat


def _nudge(x: ir.Expr, scale: ir.Expr, delta) -> ir.Expr:
    """``x + delta * (scale + 1)``; ``delta`` a number, or the name of a run-time nudge
    (``nudge[k]``): then ``nudge[k] != 0 ? x + nudge[k] * (scale + 1) : x``, exactly ``x``
    wherever the site is left alone (even where ``scale`` is infinite)."""
    t = x.type
    grow = ir.Binary("+", scale, ir.Const(ir.FLOAT, 1.0), scale.type)
    amount = ir.Var(delta, ir.FLOAT, "input") if isinstance(delta, str) \
        else ir.Const(ir.FLOAT, delta)
    moved = ir.Binary("+", x, ir.Binary("*", amount, grow, grow.type), t)
    if isinstance(delta, str):
        return ir.Ternary(ir.Binary("!=", amount, ir.Const(ir.FLOAT, 0.0), ir.BOOL), moved, x, t)
    return moved


def _abs(x: ir.Expr) -> ir.Expr:
    return ir.Call("abs", (x,), x.type)


def _step_input(e: ir.Expr) -> Optional[int]:
    """The argument of a step site that its nudge moves, or None if ``e`` is not a site."""
    if isinstance(e, ir.Binary) and e.op in COMPARISONS and _float(e.left.type) \
            and _float(e.right.type):
        return 0
    if isinstance(e, ir.Call) and e.builtin and e.name in STEP_CALLS and e.args \
            and _float(e.args[0].type):
        return 1 if e.name == "step" else 0
    if isinstance(e, ir.Construct) and e.type.scalar in (ir.Scalar.INT, ir.Scalar.UINT) \
            and len(e.args) == 1 and _float(e.args[0].type):
        return 0
    return None


def _nudged_site(e: ir.Expr, delta) -> ir.Expr:
    if isinstance(e, ir.Binary):            # a < b  ->  a + delta * (|a| + |b| + 1) < b
        a, b = e.left, e.right
        scale = ir.Binary("+", _abs(a), _abs(b), a.type if a.type.size >= b.type.size
                          else b.type)
        return dataclasses.replace(e, left=_nudge(a, scale, delta))
    k = _step_input(e)
    args = list(e.args)
    x = args[k]
    scale = _abs(x)
    if isinstance(e, ir.Call) and e.name == "step":      # step(edge, x): x against edge
        scale = ir.Binary("+", _abs(args[0]), _abs(x), x.type if x.type.size >= args[0].type.size
                          else args[0].type)
    args[k] = _nudge(x, scale, delta)
    return dataclasses.replace(e, args=tuple(args))


def _bodies(tech: ir.Technique):
    """(where, statements) in the order ``walk.map_technique_code`` rewrites them."""
    for p in tech.packings:
        for f in p.functions:
            yield f"packing {p.name}", f.body
    for f in tech.functions:
        yield f"function {f.name}", f.body
    for p in tech.passes:
        yield f"pass {p.name}", p.body


def _callers(tech: ir.Technique) -> dict[str, frozenset]:
    """Function name -> the passes that call it, directly or through other functions."""
    calls: dict[str, set] = {}
    for where, body in _bodies(tech):
        calls[where] = {e.name for e in walk.walk_exprs(body)
                        if isinstance(e, ir.Call) and not e.builtin}
    out: dict[str, set] = {}
    for p in tech.passes:
        seen, todo = set(), list(calls.get(f"pass {p.name}", ()))
        while todo:
            f = todo.pop()
            if f in seen:
                continue
            seen.add(f)
            out.setdefault(f, set()).add(p.name)
            todo += [g for where, called in calls.items() if where.endswith(f" {f}")
                     and not where.startswith("pass ") for g in called]
    return {f: frozenset(ps) for f, ps in out.items()}


def sites(tech: ir.Technique) -> list[Site]:
    """Every step of the technique's code, in walk order."""
    out: list[Site] = []
    callers = _callers(tech)
    for where, body in _bodies(tech):
        kind, _, name = where.partition(" ")
        passes = frozenset({name}) if kind == "pass" else callers.get(name, frozenset())

        def visit(e, where=where, passes=passes):
            if _step_input(e) is not None:
                out.append(Site(len(out), _source(e), getattr(e, "span", None), where, passes))
            return e
        walk.rewrite_stmts(body, visit)
    return out


def _source(e: ir.Expr) -> str:
    """The expression as the user wrote it (its span's text on one line), else as the IR
    printer spells it (generated code, or parameters already substituted)."""
    span = getattr(e, "span", None)
    if span is not None and span.text and span.end_line == span.line and span.end_column:
        lines = span.text.splitlines()
        if 0 < span.line <= len(lines):
            return lines[span.line - 1][span.column - 1:span.end_column - 1]
    return printer.expr(e)


def _map_sites(tech: ir.Technique, rewrite) -> ir.Technique:
    """The technique with each step site ``e`` replaced by ``rewrite(k, e)``, ``k`` its index
    in walk order (``sites``)."""
    count = [0]

    def fn(e):
        if _step_input(e) is None:
            return e
        k = count[0]
        count[0] += 1
        return rewrite(k, e)
    return walk.map_technique_code(tech, fn)


def nudged(tech: ir.Technique, delta: float, only=None) -> ir.Technique:
    """The technique with every step (``only``: the one of that index, or those of a set of
    indices) nudged by ``delta``."""
    chosen = {only} if isinstance(only, int) else only
    return _map_sites(tech, lambda k, e: _nudged_site(e, delta)
                      if chosen is None or k in chosen else e)


def nudged_at_run_time(tech: ir.Technique) -> ir.Technique:
    """The technique with every step's input moved by a run-time amount, ``nudge[k]`` for
    site ``k`` (``builtins.nudge_input``; the float64 CL runtime's ``CLPipeline.nudge``
    sets them): one program for every nudge the search tries, where a constant per variant
    cost a compile and a PoCL build each (0.3-1 s a pass program)."""
    return _map_sites(tech, lambda k, e: _nudged_site(e, nudge_input(k)))


Convert = Callable[[str, np.ndarray], np.ndarray]


class Explainer:
    """Explains pixels over a bound as discontinuities of one technique on one scene.

    ``base``: the float64 evaluation's render of ``scene``; ``convert(key, values)``: a float64
    render's target in the units the sides are given in (the identity for value units; the
    format's codes for exact targets).  Nudged renders are made once and shared by every
    target and backend explained."""

    def __init__(self, compiled, scene, base: dict, convert: Optional[Convert] = None):
        self.compiled, self.scene, self.base = compiled, scene, base
        self.convert = convert or (lambda key, v: np.asarray(v, np.float64))
        self.sites = sites(compiled.technique)
        self._renders: dict = {}
        self._pipeline = None           # the float64 program with run-time nudges
        self.renders_made = 0

    def upstream(self, target: str) -> set:
        """The passes whose output can reach ``target``'s final value: its writers, and for
        each writer the passes before it that wrote what it reads, its depth/stencil target
        (which decides which of its fragments land) or the target itself (blending, and the
        pixels it does not cover), and so on.  A pass that runs after a writer cannot reach
        it: deferred_calver's light passes write the stencil of the depth target its G-buffer
        pass tests, but only later.  Every target starts the frame cleared (docs/language.md,
        Targets), so nothing reaches a pass from a later one through the last frame."""
        passes = self.compiled.plan("cl").passes
        writes = [set(p.writes) | ({p.depth_target} if p.depth_target else set())
                  for p in passes]
        found, seen, todo = set(), set(), [(target, len(passes))]
        while todo:
            t, before = todo.pop()
            if (t, before) in seen:
                continue
            seen.add((t, before))
            writers = [i for i in range(before) if t in writes[i]]
            for i in writers:
                found.add(passes[i].name)
                todo += [(r, i) for r in passes[i].reads] + [(t, i)]
                if passes[i].depth_target:
                    todo.append((passes[i].depth_target, i))
        return found

    def _render(self, delta: float, only) -> dict:
        if isinstance(only, frozenset) and len(only) == 1:
            only = next(iter(only))      # one site: the same render as nudging it alone
        key = (delta, only)
        if key not in self._renders:
            if self._pipeline is None:      # one float64 program for every nudge
                from pipegen.compiler.driver import Compiled
                variant = Compiled(nudged_at_run_time(self.compiled.technique),
                                   self.compiled.params)
                self._pipeline = variant.pipeline("cl", precision="f64")
            chosen = {only} if isinstance(only, int) else only
            self._pipeline.nudge({k: delta for k in chosen})
            self._renders[key] = self._pipeline.render(self.scene)
            self.renders_made += 1
        return self._renders[key]

    def explain(self, key: str, candidates: np.ndarray, sides: Sequence[np.ndarray],
                smooth: np.ndarray) -> tuple[list[Discontinuity], np.ndarray]:
        """``candidates``: (H, W) pixels where the two evaluations differ by more than
        ``smooth`` allows (the error a continuous computation could make there); ``sides``:
        their values of target ``key`` (a float32 render, or two), in ``convert``'s units.
        A candidate is a discontinuity when a nudge of the technique's steps makes the float64
        evaluation jump there (by more than 4x ``smooth``: a choice flipped, not a value
        moved) and a side is closer to the jumped value than to the unnudged one: it fell on
        the other side.  Returns the discontinuities (per site, largest first) and the
        candidates left unexplained."""
        remaining = np.asarray(candidates, bool).copy()
        found: dict[Optional[int], np.ndarray] = {}
        if not self.sites or not remaining.any():
            return [], remaining
        base = self.convert(key, self.base[key])
        smooth = np.asarray(smooth, np.float64)
        # only the steps in passes that write the target or what it reads, transitively: a
        # variant is a recompile of the float64 evaluation, not to be made for nothing
        upstream = self.upstream(key.partition(".")[0])
        candidates_sites = [s for s in self.sites if s.passes & upstream]
        relevant = frozenset(s.index for s in candidates_sites)
        if not relevant:
            return [], remaining
        for level in LEVELS:
            if not remaining.any():
                break

            def flips(group, pixels):
                only = frozenset(s.index for s in group)
                both = [self.convert(key, self._render(s * level, only)[key]) for s in (1, -1)]
                return pixels & _flipped(sides, base, both, smooth)

            def assign(group, pixels) -> np.ndarray:
                """The pixels (all flipped by nudging ``group`` together) that one site of the
                group flips alone, each given to the first such site in ``group``'s order:
                halves first, so k sites that explain something among n cost about 4 k
                log2(n) renders instead of 2 n."""
                if len(group) == 1:
                    found[group[0].index] = found.get(group[0].index, False) | pixels
                    return pixels
                explained = np.zeros_like(pixels)
                half = len(group) // 2
                for part in (group[:half], group[half:]):
                    rest = pixels & ~explained
                    if not rest.any():
                        break
                    flipped = flips(part, rest)
                    if flipped.any():
                        explained |= assign(part, flipped)
                return explained

            todo = flips(candidates_sites, remaining)
            if todo.any():
                alone = assign(candidates_sites, todo)
                if (todo & ~alone).any():    # flipped only with several sites nudged together
                    found[None] = found.get(None, False) | (todo & ~alone)
                remaining &= ~todo
        out = []
        h = remaining.shape[0]
        for index, mask in found.items():
            ys, xs = np.nonzero(mask)
            order = np.lexsort((xs, h - 1 - ys))          # reading order: top row first
            locs = [(int(xs[i]), int(h - 1 - ys[i])) for i in order[:MAX_LOCATIONS]]
            out.append(Discontinuity(self.sites[index] if index is not None else None,
                                     int(mask.sum()), locs))
        out.sort(key=lambda d: -d.count)
        return out, remaining


def distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(H, W): the largest channel difference (``f64_compare.error``: NaN matches only NaN)."""
    d = error(np.asarray(a, np.float64), np.asarray(b, np.float64))
    return d.max(axis=-1) if d.ndim == 3 else d


def _flipped(sides: Sequence[np.ndarray], base: np.ndarray, nudged: Sequence[np.ndarray],
             smooth: np.ndarray) -> np.ndarray:
    """Pixels where a nudged render jumps away from ``base`` and some side is closer to it."""
    s = smooth.max(axis=-1) if smooth.ndim == 3 else smooth
    out = np.zeros(np.shape(base)[:2], bool)
    for n in nudged:
        jump = distance(n, base) > 4 * s + 1e-12
        for side in sides:
            out |= jump & (distance(side, n) < distance(side, base))
    return out
