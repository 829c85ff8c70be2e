"""``pipegen stress --random N``: N scenes drawn by hypothesis strategies (seeded, no example
database), each run like a named case; the first whose bound breaks is shrunk by hypothesis to
a minimal failing scene (fewer objects and lights, simpler numbers), written as TOML.

The scene parameters are plain data (``cases.random_scene_toml`` writes them), so the shrunk
scene file holds primitives and loads back as the same scene.
"""

from __future__ import annotations

import time
from typing import Callable, Optional

from pipegen.tools.stress.cases import Case, random_scene

MAX_SHRINK_RUNS = 60          # scene evaluations spent shrinking, at most


def scene_parameters():
    """The hypothesis strategy of a random scene's parameters."""
    from hypothesis import strategies as st
    coord = st.floats(-4.0, 4.0, allow_nan=False)
    pos = st.tuples(coord, coord, coord)
    unit = st.floats(0.0, 1.0, allow_nan=False)
    obj = st.fixed_dictionaries({
        "mesh": st.sampled_from(["box", "sphere", "cylinder", "plane"]),
        "translate": st.tuples(coord, st.floats(-1.0, 2.0), coord),
        "rotate": st.tuples(*[st.sampled_from([0.0, 15.0, 45.0, 90.0])] * 3),
        "scale": st.tuples(*[st.floats(0.25, 6.0)] * 3),
        "albedo": st.tuples(unit, unit, unit),
        "specular": st.floats(0.0, 1.0),
        "shininess": st.sampled_from([1.0, 8.0, 32.0, 128.0]),
    })
    light = st.fixed_dictionaries({
        "position": st.tuples(coord, st.floats(-0.5, 4.0), coord),
        "radius": st.one_of(st.floats(0.01, 10.0), st.sampled_from([1e-3, 1e3])),
        "color": st.tuples(*[st.floats(0.0, 4.0)] * 3),
    })
    camera = st.fixed_dictionaries({
        "position": st.tuples(st.floats(-8.0, 8.0), st.floats(0.2, 8.0),
                              st.floats(4.0, 12.0)),
        "target": st.tuples(coord, st.floats(-1.0, 2.0), coord),
        "fov": st.floats(20.0, 100.0),
        "near": st.sampled_from([0.05, 0.1, 0.5]),
        "far": st.sampled_from([20.0, 100.0, 1000.0]),
    })
    return st.fixed_dictionaries({"camera": camera,
                                  "objects": st.lists(obj, min_size=1, max_size=4),
                                  "lights": st.lists(light, min_size=1, max_size=6)})


def random_search(runner, n: int, size: tuple[int, int], seed: int = 0,
                  progress: Callable[[str], None] = lambda msg: None,
                  shrink_runs: int = MAX_SHRINK_RUNS):
    """Run ``n`` random scenes; returns ``(results, failing)`` where ``failing`` is
    ``(params, CaseResult)`` of the shrunk failing scene (the smallest found within
    ``shrink_runs`` more scenes), or None."""
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hseed

    results = []
    seen: dict[str, bool] = {}
    state = {"runs": 0, "failing": None, "generated": 0, "attempts": 0}

    class Broken(Exception):
        pass

    def evaluate(params) -> Optional[object]:
        scene = _scene_or_none(params, size)
        if scene is None:
            return None
        state["runs"] += 1
        res = runner.run_case(Case(f"random{state['runs']}", "a random scene", scene))
        return res

    class Done(BaseException):              # not an Exception: hypothesis lets it through
        pass

    @hseed(seed)
    @settings(max_examples=n, database=None, deadline=None, derandomize=False,
              suppress_health_check=list(HealthCheck),
              phases=[Phase.generate, Phase.shrink], report_multiple_bugs=False)
    @given(scene_parameters())
    def search(params):
        if state["failing"] is not None:
            state["attempts"] += 1
            if (state["runs"] >= state["generated"] + shrink_runs
                    or state["attempts"] > 20 * shrink_runs):
                raise Done()                # shrink budget spent: keep the smallest so far
        key = repr(params)
        if key not in seen:
            seen[key] = _evaluate(params)
        if seen[key]:                       # one raise statement: hypothesis tells failures
            raise Broken()                  # apart by where they are raised

    def _evaluate(params) -> bool:
        shrinking = state["failing"] is not None
        if shrinking and state["runs"] >= state["generated"] + shrink_runs:
            return False                    # shrink budget spent: keep what we have
        res = evaluate(params)
        if res is None:
            return False
        if not shrinking:
            state["generated"] += 1
            results.append(res)
            progress(f"random scene {state['generated']}/{n}: {res.status}")
        if res.failed and (state["failing"] is None or _smaller(params, state["failing"][0])):
            state["failing"] = (params, res)
        return res.failed

    t0 = time.perf_counter()
    try:
        search()
    except Done:
        pass
    except Exception as e:              # Broken, or hypothesis's report of it
        if state["failing"] is None:
            raise
        del e
    progress(f"random search: {state['runs']} scenes in {time.perf_counter() - t0:.1f}s")
    return results, state["failing"]


def _smaller(a: dict, b: dict) -> bool:
    return (len(a["objects"]) + len(a["lights"]), repr(a)) < \
        (len(b["objects"]) + len(b["lights"]), repr(b))


def _scene_or_none(params: dict, size):
    """The scene, or None for parameters the scene loader refuses (a camera looking at
    itself, up parallel to the view)."""
    from pipegen.core.diagnostics import PipegenError
    import numpy as np
    cam = params["camera"]
    f = np.subtract(cam["target"], cam["position"])
    if np.linalg.norm(f) < 1e-3 or np.linalg.norm(np.cross(f, (0, 1, 0))) < 1e-3 * np.linalg.norm(f):
        return None
    try:
        return random_scene(params, *size)
    except PipegenError:
        return None
