"""benchmarks/common.py's timing helpers: call order and per-pass aggregation (no timings)."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _common():
    spec = importlib.util.spec_from_file_location("bench_common",
                                                  ROOT / "benchmarks" / "common.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_interleaved_order_warmup_and_cpu():
    calls = []
    fns = {"a": lambda: calls.append("a"), "b": lambda: calls.append("b")}
    common = _common()
    out = common.interleaved(fns, 3)
    assert calls == ["a", "b", "a", "b", "b", "a", "a", "b"]     # warm-up, then ABBA
    assert sorted(out) == ["a", "b"] and all(len(v) == 3 for v in out.values())
    calls.clear()
    ticks = iter(range(100))
    out = common.interleaved(fns, 2, alternate=False, cpu=lambda: float(next(ticks)),
                             warmup=False)
    assert calls == ["a", "b", "a", "b"]
    assert out["a_cpu"] == out["b_cpu"] == [1.0, 1.0]


def test_pass_profile_sums_runs_and_takes_medians():
    frames = iter([None,                                          # the warm-up
                   [("p", {"t": 1.0, "n": 5}), ("q", {"t": 2.0}), ("p", {"t": 1.0, "n": 5})],
                   [("p", {"t": 4.0, "n": 7}), ("q", {"t": 3.0}), ("p", {"t": 4.0, "n": 7})],
                   [("p", {"t": 3.0, "n": 9}), ("q", {"t": 9.0}), ("p", {"t": 3.0, "n": 9})]])
    current = []
    before = []
    prof = _common().pass_profile(lambda: current.append(next(frames)), lambda: current[-1], 3,
                                  ("t",), counts=("n",), before=lambda: before.append(1))
    assert len(before) == 3 and prof["wall"] >= 0.0
    assert prof["passes"] == [{"pass": "p", "runs": 2, "n": 10, "t": 6.0},
                              {"pass": "q", "runs": 1, "n": 0, "t": 3.0}]


def test_in_blocks_order_settle_calls_and_counts():
    calls = []
    fns = {"a": lambda: calls.append("a"), "b": lambda: calls.append("b")}
    out = _common().in_blocks(fns, 5, 2)
    # warm-up; then turns (ABBA) each opening with an untimed call, two timed calls a turn,
    # the last turn cut to what is left
    assert calls == ["a", "b",
                     "a", "a", "a", "b", "b", "b",
                     "b", "b", "b", "a", "a", "a",
                     "a", "a", "b", "b"]
    assert [len(out["a"]), len(out["b"])] == [5, 5]
    assert all(t >= 0.0 for v in out.values() for t in v)
