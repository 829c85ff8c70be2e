"""The search of ``pipegen tune``: the cheapest configuration of a technique's declared
parameter values whose error stays within the budget, without rendering every combination.

The configurations are the cartesian product of the declared values (``sweep``'s axes,
``variants.declared_axes``).  The search assumes **monotonicity**: each axis has an order of
accuracy, and a configuration no more accurate than a failing one on every axis fails too.  The
order is measured, not assumed, and the assumption is checked on every pair of rendered
configurations it relates:

1. **screen**: the defaults, then each axis's other values one at a time (1 + sum(n - 1)
   renders); each axis's values are ranked by their error there (ties: equal rank, e.g. two
   normal encodings that give the same image);
2. **corner**: the most accurate value of every axis.  If even it misses the budget, no
   configuration meets it (under monotonicity): the answer names the closest;
3. **floors**: per axis, a bisection over its ranks with the other axes at the corner finds the
   least accurate value that can still pass: every configuration below a failing probe is out;
4. **walk**: the remaining configurations in order of cost, each group of equal cost rendered
   (unless a failure already rules a configuration out) until two within budget are found:
   the pick and the runner-up.  Equal cost: lower error wins (the budget's metrics, then rmse),
   then the declared order.

A pair of rendered configurations that contradicts an order (the less accurate one passes, the
more accurate fails) is reported, the axes where they differ lose their order (pruning then
needs equal values there) and the walk starts again: more renders, the same exact answer.

Cost: ``memory`` is exact before any render; ``time`` is measured (median frame time over
``frames``, interquartile spread).  For ``time`` the walk follows an additive model of frame
time fitted on the screen and stops when the model, less its largest error so far, says every
remaining configuration is slower than the best found; the finalists are then timed again
together (successive halving, interleaved frames) and times whose spreads overlap are ties,
resolved by memory.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Callable, Optional

from pipegen.tools.tune.budget import RENDERED, Budget
from pipegen.tools.tune.measure import Evaluator, Measured, overlap


@dataclass
class Axis:
    name: str
    values: list                         # declared order
    rank: dict = field(default_factory=dict)      # value -> rank (0: least accurate)
    ordered: bool = True                 # False once a pair of renders contradicts the order
    scores: dict = field(default_factory=dict)    # value -> [error score per screen, latest first]

    def top(self):
        """The most accurate value (declared first among equals)."""
        best = max(self.rank.values())
        return next(v for v in self.values if self.rank[v] == best)

    def at_rank(self, r: int):
        return next(v for v in self.values if self.rank[v] == r)

    def order_text(self) -> str:
        if not self.ordered:
            return f"{self.name}: unordered (a pair of renders contradicted its order)"
        groups = sorted({r for r in self.rank.values()})
        parts = ["=".join(show(v) for v in self.values if self.rank[v] == r) for r in groups]
        return f"{self.name}: " + " < ".join(parts)


@dataclass
class TuneResult:
    axes: list
    budget: Budget
    minimise: str
    pick: Optional[Measured]
    runner_up: Optional[Measured]
    closest: Optional[Measured]          # when nothing meets the budget
    tried: list                          # Measured, rendered, in render order
    analytic: list                       # Measured whose budget verdict needed no render
    pruned: int                          # configurations ruled out by monotonicity
    total: int                           # configurations in the grid
    renders: int
    timed_frames: int
    how: str
    violations: list
    pairs_checked: int
    notes: list = field(default_factory=list)
    technique: str = ""                  # filled in by run.tune
    file: str = ""
    reference: str = ""
    scenes: list = field(default_factory=list)
    backend: str = "gl"
    compiled_pick: object = None


def show(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return f"{v:g}" if isinstance(v, float) else str(v)


def within(budget: Budget, m: Measured) -> bool:
    return budget.holds(m.figures)


def fails_rendered(budget: Budget, m: Measured) -> bool:
    """A rendered configuration missing a term on a rendered metric: what pruning uses."""
    return m.rendered and any(not t.holds(m.figures.get(t.metric, math.nan))
                              for t in budget.terms if t.metric in RENDERED)


def error_score(budget: Budget, m: Measured) -> tuple:
    """Lower is more accurate: the budget's metrics in order, then rmse when rendered."""
    out = tuple(m.figures.get(x, math.inf) for x in budget.metrics)
    return out + ((m.figures.get("rmse", math.inf),) if budget.needs_render else ())


def order_key(budget: Budget, minimise: str, m: Measured, index: int) -> tuple:
    """How configurations within budget are ranked: cost, then error, then declared order."""
    cost = m.memory if minimise == "memory" else (m.time_ms if m.time_ms is not None
                                                  else math.inf)
    return (cost, error_score(budget, m), index)


class Search:
    def __init__(self, ev: Evaluator, axes: dict, budget: Budget, minimise: str = "memory",
                 say: Callable[[str], None] = lambda text: None):
        self.ev, self.budget, self.minimise, self.say = ev, budget, minimise, say
        self.axes = [Axis(k, list(v)) for k, v in axes.items()]
        self.keys = list(itertools.product(*(a.values for a in self.axes)))
        self.index = {k: i for i, k in enumerate(self.keys)}
        self.violations: list[str] = []
        self.pairs: set = set()
        self.fails: list[tuple] = []         # keys failing a rendered term
        self.ranked = False                  # every axis ranked (after the screen)
        self.base: Optional[tuple] = None

    # -- helpers ---------------------------------------------------------------------------
    def params(self, key: tuple) -> dict:
        return {a.name: v for a, v in zip(self.axes, key)}

    def m(self, key: tuple) -> Measured:
        return self.ev.measured(key, self.params(key))

    def below(self, b: tuple, a: tuple) -> bool:
        """``b`` no more accurate than ``a`` on every axis (an unordered axis: equal)."""
        for ax, vb, va in zip(self.axes, b, a):
            if ax.ordered:
                if ax.rank[vb] > ax.rank[va]:
                    return False
            elif vb != va:
                return False
        return True

    def pruned(self, key: tuple) -> Optional[tuple]:
        """A failing rendered configuration that rules ``key`` out, if any."""
        if self.ev.known.get(key) is not None and self.ev.known[key].rendered:
            return None
        return next((f for f in self.fails if self.below(key, f)), None)

    def render(self, key: tuple, why: str) -> Measured:
        fresh = not (key in self.ev.known and self.ev.known[key].rendered)
        m = self.ev.render(key, self.params(key))
        if fresh:
            if self.minimise == "time":
                self.ev.time([m])
            verdict = "within" if within(self.budget, m) else "out"
            self.say(f"{why}: {self.label(key)}: {self.figures_text(m)} ({verdict})")
            if fails_rendered(self.budget, m):
                self.fails.append(key)
            if self.ranked:
                self.check(m)
        return m

    def label(self, key: tuple) -> str:
        return " ".join(f"{a.name}={show(v)}" for a, v in zip(self.axes, key))

    def figures_text(self, m: Measured) -> str:
        parts = [f"{x} {m.figures[x]:.4g}" for x in ("p99", "max", "rmse", "flip",
                                                      "lights_dropped")
                 if x in m.figures and not (isinstance(m.figures[x], float)
                                            and math.isnan(m.figures[x]))]
        return ", ".join(parts)

    # -- monotonicity ----------------------------------------------------------------------
    def check(self, m: Measured) -> bool:
        """Hold ``m`` against every rendered configuration it is ordered with; a contradiction
        of the budget verdict unorders the axes they differ on.  True when one was found."""
        found = False
        for other in [x for x in self.ev.known.values() if x.rendered and x.key != m.key]:
            for lo, hi in ((m, other), (other, m)):
                if not self.below(lo.key, hi.key):
                    continue
                self.pairs.add((lo.key, hi.key))
                if fails_rendered(self.budget, hi) and not fails_rendered(self.budget, lo):
                    differ = [a for a, x, y in zip(self.axes, lo.key, hi.key) if x != y]
                    text = (f"monotonicity violated: {self.label(lo.key)} is within budget but "
                            f"the more accurate {self.label(hi.key)} is not; "
                            f"{', '.join(a.name for a in differ)} "
                            f"{'lose their' if len(differ) > 1 else 'loses its'} order")
                    self.violations.append(text)
                    self.say(text)
                    for a in differ:
                        a.ordered = False
                    found = True
        return found

    # -- phases ----------------------------------------------------------------------------
    def screen(self, base: tuple, why: str) -> None:
        """``base``, then each axis's other values one at a time; ranks every axis's values
        by their error there (worst first; equal figures, equal rank)."""
        base_m = self.render(base, why)
        for i, a in enumerate(self.axes):
            for v in a.values:
                key = base[:i] + (v,) + base[i + 1:]
                mm = self.render(key, why) if key != base else base_m
                a.scores.setdefault(v, []).insert(
                    0, tuple(round(x, 9) for x in error_score(self.budget, mm)))
            # the latest screen first; a tie there is broken by the earlier one
            scores = {v: tuple(a.scores[v]) for v in a.values}
            distinct = sorted(set(scores.values()), reverse=True)      # worst first
            a.rank = {v: distinct.index(scores[v]) for v in a.values}
        self.ranked = True
        self.base = base
        for m in [x for x in self.ev.known.values() if x.rendered]:
            self.check(m)

    def default(self, a: Axis):
        for p in self.ev.compiled({}).technique.params:
            if p.name == a.name and p.default in a.values:
                return p.default
        return a.values[0]

    def corner(self) -> tuple:
        return tuple(a.top() for a in self.axes)

    def floors(self, corner: tuple) -> None:
        for i, a in enumerate(self.axes):
            if not a.ordered:
                continue
            lo, hi = 0, a.rank[corner[i]]
            while lo < hi:
                mid = (lo + hi) // 2
                key = corner[:i] + (a.at_rank(mid),) + corner[i + 1:]
                if self.pruned(key) is not None:
                    lo = mid + 1
                    continue
                m = self.render(key, f"floor of {a.name}")
                if fails_rendered(self.budget, m):
                    lo = mid + 1
                else:
                    hi = mid

    def candidates(self) -> list[tuple]:
        """Configurations the free figures do not rule out, cheapest first (time: by the
        model), equal cost by predicted error, then declared order."""
        free_out = {k for k in self.keys if self.free_fail(k)}
        keys = [k for k in self.keys if k not in free_out]
        if self.minimise == "memory":
            return sorted(keys, key=lambda k: (self.m(k).memory, self.predicted(k),
                                               self.index[k]))
        return sorted(keys, key=lambda k: (self.predicted_time(k), self.m(k).memory,
                                           self.index[k]))

    def free_fail(self, key: tuple) -> bool:
        m = self.m(key)
        return any(not t.holds(m.figures[t.metric]) for t in self.budget.terms
                   if t.metric not in RENDERED and t.metric in m.figures)

    def predicted(self, key: tuple) -> float:
        """An additive model of the budget's first rendered metric from the screen."""
        base = self.base
        b = self.ev.known.get(base)
        if b is None or not b.rendered:
            return 0.0
        metric = next((t.metric for t in self.budget.terms if t.metric in RENDERED), "rmse")
        total = b.figures[metric]
        for i, v in enumerate(key):
            k = base[:i] + (v,) + base[i + 1:]
            if k in self.ev.known and self.ev.known[k].rendered:
                total += self.ev.known[k].figures[metric] - b.figures[metric]
        return total

    def predicted_time(self, key: tuple) -> float:
        base = self.base
        b = self.ev.known.get(base)
        if b is None or b.time_ms is None:
            return 0.0
        total = b.time_ms
        for i, v in enumerate(key):
            k = base[:i] + (v,) + base[i + 1:]
            if k in self.ev.known and self.ev.known[k].time_ms is not None:
                total += self.ev.known[k].time_ms - b.time_ms
        return total

    def walk_memory(self) -> list[Measured]:
        """Groups of equal memory, cheapest first, until two configurations are within
        budget; restarted when a pair contradicts an order."""
        while True:
            found: list[Measured] = []
            restart = False
            cands = self.candidates()
            for _, group in itertools.groupby(cands, key=lambda k: self.m(k).memory):
                n_viol = len(self.violations)
                for key in group:
                    if self.pruned(key) is None:
                        self.render(key, "walk")
                    known = self.ev.known[key]
                    if known.rendered and within(self.budget, known):
                        found.append(known)
                if len(self.violations) > n_viol:
                    restart = True
                    break
                if len(found) >= 2 or (found and not self.budget.needs_render):
                    break
            if not restart:
                return sorted(found, key=lambda m: order_key(self.budget, "memory", m,
                                                              self.index[m.key]))

    def walk_time(self) -> list[Measured]:
        while True:
            n_viol = len(self.violations)
            for key in self.candidates():
                best = self.best_time()
                if best is not None and self.predicted_time(key) - self.margin() > best.time_ms:
                    break
                if self.pruned(key) is None:
                    self.render(key, "walk")
                if len(self.violations) > n_viol:
                    break
            if len(self.violations) == n_viol:
                return self.finalists()

    def passing(self) -> list[Measured]:
        return [m for m in self.ev.known.values() if m.rendered and within(self.budget, m)]

    def best_time(self) -> Optional[Measured]:
        ok = [m for m in self.passing() if m.time_ms is not None]
        return min(ok, key=lambda m: m.time_ms) if ok else None

    def margin(self) -> float:
        """The additive time model's largest error on the configurations timed so far."""
        res = [abs(m.time_ms - self.predicted_time(m.key)) for m in self.ev.known.values()
               if m.time_ms is not None]
        return max(res, default=0.0)

    def finalists(self) -> list[Measured]:
        """Successive halving over the passing configurations within the model's margin of
        the fastest: timed together, the slower half dropped, frames doubled, down to two."""
        best = self.best_time()
        if best is None:
            return []
        pool = sorted([m for m in self.passing() if m.time_ms is not None and
                       m.time_ms <= best.time_ms + self.margin()], key=lambda m: m.time_ms)
        frames = max(3, self.ev.frames)
        while True:
            self.ev.time(pool, frames)
            pool.sort(key=lambda m: m.time_ms)
            if len(pool) <= 2:
                break
            pool = pool[:max(2, len(pool) // 2)]
            frames *= 2
        # times whose spreads overlap are a tie: the one with less memory wins
        if len(pool) == 2 and overlap(pool[0], pool[1]) and pool[1].memory < pool[0].memory:
            pool.reverse()
        return pool

    # -- the whole search ------------------------------------------------------------------
    def run(self) -> TuneResult:
        free = all(t.metric in self.m(k).figures for k in self.keys for t in self.budget.terms)
        if free and self.minimise == "memory":
            return self.run_free()
        defaults = tuple(self.default(a) for a in self.axes)
        self.screen(defaults, "screen")
        corner = self.corner()
        self.render(corner, "corner")
        # the orders again around the corner, where the budget's boundary is: the defaults'
        # errors may be dominated by one axis and rank the others by noise
        self.screen(corner, "screen at the corner")
        corner = self.corner()
        c = self.render(corner, "corner")
        found: list[Measured] = []
        if self.passing():
            if within(self.budget, c):
                self.floors(corner)
            found = self.walk_memory() if self.minimise == "memory" else self.walk_time()
        how = self.how()
        return self.result(found, how)

    def run_free(self) -> TuneResult:
        """A budget on figures that need no render (lights_dropped) and memory as cost: every
        configuration is classified without rendering; the pick alone is rendered for its
        error figures."""
        self.base = None
        ordered = sorted(self.keys, key=lambda k: order_key(self.budget, "memory", self.m(k),
                                                            self.index[k]))
        found = [self.m(k) for k in ordered if within(self.budget, self.m(k))][:2]
        how = ("every configuration's budget figures computed without rendering (target "
               "memory, lights over each light-index packing's capacity), ranked by memory, "
               "then the budget's figures, then the declared order; only the pick is rendered "
               "for its error figures")
        return self.result(found, how)

    def result(self, found: list, how: str) -> TuneResult:
        pick = found[0] if found else None
        runner = found[1] if len(found) > 1 else None
        closest = None
        if pick is None:
            pool = [m for m in self.ev.known.values()
                    if m.rendered or not self.budget.needs_render]
            closest = min(pool, key=lambda m: (self.budget.shortfall(m.figures),
                                               m.memory, self.index[m.key]), default=None)
        for m in (pick, closest):
            if m is not None and not m.rendered:
                self.ev.render(m.key, m.params)
        # memory as cost: the pick and the runner-up timed together, for the report
        timed = [m for m in (pick, runner) if m is not None and m.time_ms is None]
        if self.minimise == "memory" and timed:
            self.ev.time(timed)
        tried = sorted([m for m in self.ev.known.values() if m.rendered], key=lambda m: m.order)
        # judged without rendering: every budget figure known, or one that needs no render
        # already out of budget
        analytic = [m for m in self.ev.known.values() if not m.rendered and (
            all(t.metric in m.figures for t in self.budget.terms) or self.free_fail(m.key))]
        judged = {m.key for m in analytic}
        pruned = sum(1 for k in self.keys if k not in judged and not (
            k in self.ev.known and self.ev.known[k].rendered) and self.pruned(k) is not None)
        return TuneResult(self.axes, self.budget, self.minimise, pick, runner, closest, tried,
                          analytic, pruned, len(self.keys), self.ev.renders,
                          self.ev.timed_frames, how, list(self.violations), len(self.pairs))

    def how(self) -> str:
        orders = "; ".join(a.order_text() for a in self.axes)
        cost = ("target memory (exact, from the formats)" if self.minimise == "memory" else
                "frame time (median, interquartile spread; an additive model from the screen "
                "orders the walk, successive halving times the finalists)")
        return (f"a screen (the defaults, then each axis's other values one at a time) and a "
                f"second screen around the most accurate corner rank each axis's values by "
                f"error [{orders}]; per axis a bisection for the least accurate value that can "
                f"still pass; then a walk in order of {cost}, skipping every configuration no "
                f"more accurate than a failing one on every axis (monotonicity, checked on "
                f"every ordered pair of renders)")
