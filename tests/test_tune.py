"""``pipegen tune`` (issue 25 item 6): the budget's grammar and its errors, the search against
rendering every configuration (a synthetic technique without a backend, then inferred and
lidr_bitplanes on GL), the command line's report, exit statuses and ``tune.json``.

The whole grids (inferred's 192 configurations, against which tune must render at most a
third) are in benchmarks/tune_vs_sweep.py and in the ``exhaustive`` test at the end; the
default run checks the same answers on a 16-configuration slice of inferred's grid."""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipegen.core.diagnostics import PipegenError
from pipegen.tools.tune.budget import parse_budget
from pipegen.tools.tune.measure import Evaluator, Measured
from pipegen.tools.tune.search import Search, order_key, within

ROOT = Path(__file__).resolve().parents[1]
INFERRED = str(ROOT / "pipelines/inferred.pipe")
LIDR = str(ROOT / "pipelines/lidr_bitplanes.pipe")
EDGES = str(ROOT / "examples/scenes/edges.toml")
OVERLAP = str(ROOT / "examples/scenes/stress_overlap.toml")
SMALL = str(ROOT / "examples/scenes/small.toml")
# a slice of inferred's grid: 16 configurations where the full one has 192
SLICE = {"lbuffer_scale": [0.75, 1.0], "normal_encoding": ["kircher", "octahedral"],
         "normal_format": ["rg8", "rg16f"], "lbuffer_format": ["rgba16f"]}


def pipegen(*args, timeout=300):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "pipegen", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, env=env, timeout=timeout)


# -- the budget --------------------------------------------------------------------------------


def test_budget_terms_and_verdicts():
    b = parse_budget(" p99<=2 , max < 40,lights_dropped==0")
    assert [t.text for t in b.terms] == ["p99<=2", "max<40", "lights_dropped==0"]
    assert b.holds(dict(p99=2.0, max=39.0, lights_dropped=0))
    assert not b.holds(dict(p99=2.0, max=40.0, lights_dropped=0))
    assert not b.holds(dict(p99=2.0, max=39.0))                # a figure not known: not held
    misses = b.misses(dict(p99=5.0, max=10.0, lights_dropped=3))
    assert [(t.text, v, d) for t, v, d in misses] == [("p99<=2", 5.0, 3.0),
                                                       ("lights_dropped==0", 3, 3.0)]
    assert b.needs_render and not parse_budget("lights_dropped==0").needs_render


@pytest.mark.parametrize("text, column, width, message", [
    ("", 1, 1, "the budget is empty"),
    ("p98<=2", 1, 3, "unknown budget metric 'p98'"),
    ("p99<=2, mse<=1", 9, 3, "unknown budget metric 'mse'"),
    ("p99>=2", 4, 2, "bounds p99 from above: use <=, < or ==, not >="),
    ("p99 2", 4, 1, "bounds p99 from above"),
    ("p99<=abc", 6, 3, "must be a number >= 0, not 'abc'"),
    ("p99<=-1", 6, 2, "must be a number >= 0"),
    ("p99<=2,,max<=3", 8, 1, "an empty term"),
    ("p99<=2, p99<=3", 9, 6, "p99 is bounded twice"),
])
def test_bad_budgets_point_at_the_text(text, column, width, message):
    with pytest.raises(PipegenError) as e:
        parse_budget(text)
    err = e.value
    assert message in err.message
    assert (err.span.column, err.span.end_column - err.span.column) == (column, width)
    shown = err.render()
    assert shown.startswith(f"--budget:1:{column}: error:")
    if text:
        assert shown.splitlines()[2].endswith("| " + " " * (column - 1) + "^" * width)


# -- the search on a synthetic technique (no backend) ------------------------------------------


class Synthetic(Evaluator):
    """A technique of three axes whose error and memory are formulas: renders are counted
    as the real evaluator counts them, and nothing is drawn."""

    AXES = {"scale": [0.25, 0.5, 0.75, 1.0], "filter": [True, False],
            "fmt": ["r8", "r16", "r32"]}
    BYTES = {"r8": 1, "r16": 2, "r32": 4}

    def __init__(self, error):
        self.error = error                  # params -> p99
        self.known, self.renders, self.timed_frames, self.frames = {}, 0, 0, 0

    def compiled(self, params):
        class P:
            def __init__(self, name, default):
                self.name, self.default = name, default
        tech = type("T", (), {"params": [P("scale", 0.5), P("filter", True), P("fmt", "r16")]})
        return type("C", (), {"technique": tech})

    def measured(self, key, params):
        if key not in self.known:
            mem = int(1000 * params["scale"] ** 2 * (4 + self.BYTES[params["fmt"]]))
            self.known[key] = Measured(key, dict(params), mem)
        return self.known[key]

    def render(self, key, params):
        m = self.measured(key, params)
        if not m.rendered:
            e = self.error(params)
            m.figures.update(p99=e, max=e * 3, rmse=e / 2, flip=0.0, lights_dropped=0)
            m.rendered, self.renders = True, self.renders + 1
            m.order = self.renders
        return m

    def time(self, measured, frames=None):
        pass


def smooth(p) -> float:
    """Monotone: less scale, no filter, fewer bits each cost error."""
    return (40 * (1 - p["scale"]) * (1.0 if p["filter"] else 2.0)
            + {"r8": 3.0, "r16": 0.5, "r32": 0.0}[p["fmt"]])


def bumpy(p) -> float:
    """Not monotone: at full scale r32 is worse than r16 (the screen at the defaults ranks
    r32 best, so a pair of renders must contradict it)."""
    e = smooth(p)
    if p["scale"] == 1.0 and p["fmt"] == "r32":
        e += 4.0
    return e


def exhaustive_answer(error, budget_text):
    budget = parse_budget(budget_text)
    ev = Synthetic(error)
    axes = Synthetic.AXES
    keys = list(itertools.product(*axes.values()))
    rows = [ev.render(k, dict(zip(axes, k))) for k in keys]
    ok = sorted((order_key(budget, "memory", m, i), m.key) for i, m in enumerate(rows)
                if within(budget, m))
    return ok[0][1] if ok else None, len(keys)


@pytest.mark.parametrize("error", [smooth, bumpy])
@pytest.mark.parametrize("budget", ["p99<=1", "p99<=3", "p99<=6", "p99<=11", "p99<=20",
                                    "p99<=40", "rmse<=2", "p99<=0.1"])
def test_search_finds_what_rendering_everything_finds(error, budget):
    ev = Synthetic(error)
    result = Search(ev, Synthetic.AXES, parse_budget(budget)).run()
    want, total = exhaustive_answer(error, budget)
    got = result.pick.key if result.pick else None
    assert got == want, (budget, result.how, result.violations)
    assert result.renders == ev.renders < total
    if want is None:                                   # nothing passes: the closest is named
        assert result.closest is not None and result.closest.rendered


def test_a_contradicted_order_is_reported_and_unordered():
    ev = Synthetic(bumpy)
    search = Search(ev, Synthetic.AXES, parse_budget("p99<=1"))
    result = search.run()
    # the screen at the defaults ranks r32 best; at full scale r16 passes where r32 fails
    assert result.pick.params == {"scale": 1.0, "filter": True, "fmt": "r16"}
    assert any("fmt" in v for v in result.violations), result.violations
    assert "fmt: unordered" in result.how


def test_smooth_errors_prune_most_of_the_grid():
    ev = Synthetic(smooth)
    result = Search(ev, Synthetic.AXES, parse_budget("p99<=11")).run()
    assert result.violations == [] and result.pairs_checked > 0
    assert result.pruned > 0
    assert result.pick.params == {"scale": 0.75, "filter": True, "fmt": "r16"}
    # the runner-up is the next in cost order within budget
    assert result.runner_up.params == {"scale": 0.75, "filter": True, "fmt": "r32"}


# -- real techniques (GL) ----------------------------------------------------------------------


@pytest.mark.gl
def test_inferred_slice_matches_exhaustive():
    from pipegen.tools.tune.run import exhaustive, tune
    t = tune(INFERRED, [EDGES], "p99<=2", size=(96, 54), frames=0, axes=SLICE)
    e = exhaustive(INFERRED, [EDGES], "p99<=2", size=(96, 54), axes=SLICE)
    assert e.renders == e.total == 16
    assert t.pick.params == e.pick.params == {
        "lbuffer_scale": 1.0, "dsf": True, "normal_encoding": "octahedral",
        "normal_format": "rg8", "lbuffer_format": "rgba16f"}
    assert t.pick.figures["p99"] == pytest.approx(2.0, abs=0.01)
    assert t.renders < e.renders and not t.violations
    assert t.runner_up.params == e.runner_up.params


@pytest.mark.gl
def test_lidr_no_light_dropped_on_stress_overlap_is_out_of_reach():
    """Up to 20 lights overlap there; index_bits 8 holds 4 a pixel, 16 two, 32 one: none
    meets the budget, and both tune and the exhaustive sweep name index_bits=8 closest."""
    from pipegen.tools.tune.run import exhaustive, tune
    t = tune(LIDR, [OVERLAP], "lights_dropped==0", size=(48, 27), frames=0)
    e = exhaustive(LIDR, [OVERLAP], "lights_dropped==0", size=(48, 27))
    assert t.pick is None and e.pick is None
    assert t.closest.params == e.closest.params == {"index_bits": 8}
    assert t.renders == 1 and e.renders == 3                 # a third
    drops = {m.params["index_bits"]: m.figures["lights_dropped"] for m in t.tried + t.analytic}
    assert drops[8] < drops[16] < drops[32]


@pytest.mark.gl
def test_cli_no_configuration_meets_the_budget():
    r = pipegen("tune", LIDR, "--scene", OVERLAP, "--budget", "lights_dropped==0",
                "--size", "48x27", "--stress", "none", "--frames", "0")
    assert r.returncode == 1, r.stderr
    assert "no configuration meets the budget lights_dropped==0" in r.stdout
    assert "closest: index_bits=8 (lights_dropped==0: " in r.stdout
    assert "renders: 1 (the exhaustive sweep: 3" in r.stdout
    assert "Traceback" not in r.stderr


def test_cli_bad_budget_is_a_usage_error():
    r = pipegen("tune", LIDR, "--scene", OVERLAP, "--budget", "p99=>2")
    assert r.returncode == 2
    assert "--budget:1:4: error: a budget bounds p99 from above" in r.stderr
    assert "usage: pipegen tune" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.gl
@pytest.mark.cl
def test_cli_writes_tune_json_and_stresses_the_pick(tmp_path):
    out = tmp_path / "tune"
    r = pipegen("tune", LIDR, "--scene", SMALL, "--budget", "lights_dropped==0", "--size",
                "48x27", "--stress", "far_1e3", "--frames", "3", "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "pick: index_bits=8" in r.stdout
    assert "stress at the pick (far_1e3, 1 case at 96x64): 1 ok" in r.stdout
    data = json.loads((out / "tune.json").read_text())
    assert data["pick"]["params"] == {"index_bits": 8}
    assert data["pick"]["figures"]["lights_dropped"] == 0
    assert data["pick"]["time_ms"] > 0 and data["pick"]["frames"] == 3
    assert data["budget"] == "lights_dropped==0" and data["reference"] == "scene"
    assert data["renders"] == 1 and data["configurations"] == 3
    assert {m["params"]["index_bits"]: m["figures"]["lights_dropped"] > 0
            for m in data["free"]} == {16: True, 32: True}
    assert data["stress"]["counts"] == {"ok": 1}
    assert "search" in data and data["runner_up"] is None
    assert (out / ".pipegen-manifest.json").is_file()


@pytest.mark.gl
@pytest.mark.exhaustive
def test_inferred_whole_grid_within_a_third_of_the_sweep():
    from pipegen.tools.tune.run import exhaustive, tune
    t = tune(INFERRED, [EDGES], "p99<=2", size=(96, 54), frames=0)
    e = exhaustive(INFERRED, [EDGES], "p99<=2", size=(96, 54))
    assert t.pick.params == e.pick.params
    assert e.renders == 192 and t.renders * 3 <= e.renders


class TimedSynthetic(Synthetic):
    """Frame time a formula too: filtering and more bits cost time, scale most of all."""

    def time(self, measured, frames=None):
        for m in measured:
            p = m.params
            t = 10 * p["scale"] ** 2 + (1.0 if p["filter"] else 0.0) + \
                {"r8": 0.0, "r16": 0.2, "r32": 0.5}[p["fmt"]]
            m.time_ms, m.time_q, m.frames = t, (t - 0.01, t + 0.01), 5


@pytest.mark.parametrize("budget", ["p99<=3", "p99<=11", "p99<=25"])
def test_minimise_time_finds_the_fastest_within_budget(budget):
    ev = TimedSynthetic(smooth)
    result = Search(ev, Synthetic.AXES, parse_budget(budget), minimise="time").run()
    everything = TimedSynthetic(smooth)
    rows = [everything.render(k, dict(zip(Synthetic.AXES, k)))
            for k in itertools.product(*Synthetic.AXES.values())]
    everything.time(rows)
    b = parse_budget(budget)
    fastest = min((m for m in rows if within(b, m)), key=lambda m: m.time_ms)
    assert result.pick.params == fastest.params
    assert result.pick.time_ms == pytest.approx(fastest.time_ms)
    assert result.renders < len(rows)


@pytest.mark.gl
def test_every_scene_counts_and_the_worst_one_decides():
    from pipegen.tools.tune.run import tune
    axes = {"lbuffer_scale": [0.75, 1.0], "dsf": [True], "normal_encoding": ["kircher"],
            "normal_format": ["rg8", "rg16f"], "lbuffer_format": ["rgba16f"]}
    r = tune(INFERRED, [EDGES, SMALL], "p99<=2", size=(64, 36), frames=0, axes=axes)
    assert r.renders == 2 * len(r.tried)
    for m in r.tried:
        assert [e["scene"] for e in m.per_scene] == ["edges", "small"]
        for metric in ("p99", "max", "rmse"):
            assert m.figures[metric] == max(e[metric] for e in m.per_scene)
    assert r.scenes == ["edges (64x36)", "small (64x36)"]


@pytest.mark.gl
@pytest.mark.cl
def test_reference_self_is_the_technique_in_float64():
    """Against itself in float64 (at its defaults: no parameter declares `accurate`), the
    default index_bits=8 is exact on small.toml and the others drop lights."""
    from pipegen.tools.tune.run import tune
    r = tune(LIDR, [SMALL], "p99<=1", reference="self", size=(48, 27), frames=0)
    assert r.reference == "self"
    assert r.pick.params == {"index_bits": 8} and r.pick.figures["max"] == 0
    worse = {m.params["index_bits"]: m.figures["p99"] for m in r.tried if m is not r.pick}
    assert all(p99 > 1 for p99 in worse.values()) and set(worse) == {16, 32}
    assert any("self: lidr_bitplanes" in n for n in r.notes)


@pytest.mark.gl
def test_tune_measures_what_sweep_measures():
    """tools.tune.run.exhaustive (what the comparisons count as the sweep) and run_sweep give
    the same figures, row for row: p99/max/rmse against the scene reference, target bytes."""
    from pipegen.tools.sweep.run import run_sweep
    from pipegen.tools.tune.run import exhaustive
    axes = {"lbuffer_scale": [0.75, 1.0], "dsf": [True], "normal_encoding": ["octahedral"],
            "normal_format": ["rg8", "rg16f"], "lbuffer_format": ["rgba16f"]}
    s = run_sweep([INFERRED], EDGES, (96, 54), axes, backends=("gl",), frames=0, jobs=1,
                  progress=False)
    e = exhaustive(INFERRED, [EDGES], "p99<=2", size=(96, 54), axes=axes)
    assert len(s.rows) == len(e.tried) == 4
    for row, m in zip(s.rows, e.tried):
        assert row["params"] == " ".join(f"{k}={v:g}" if isinstance(v, float) else
                                         f"{k}={str(v).lower()}" for k, v in m.params.items())
        assert (row["p99_scene"], row["max_scene"], row["target_bytes"]) == \
            (m.figures["p99"], m.figures["max"], m.memory)
        assert row["rmse_scene"] == pytest.approx(m.figures["rmse"], abs=1e-12)
