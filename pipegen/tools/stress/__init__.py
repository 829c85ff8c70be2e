"""``pipegen stress``: adversarial scenes (DESIGN.md §8) rendered on GL, CL and the technique's
float64 evaluation; every target of both float32 backends held to a bound composed through the
pipeline (docs/stress.md).

- ``cases.py``: the scenes (``CASES``, ``GROUPS``, ``build``), a TOML writer for any scene;
- the bound comes from the tolerance model (``pipegen.proof``: ``tolerance.py``, ``f64_bound.py``,
  ``f64_compare.py``; docs/tolerances.md);
- ``run.py``: ``Stress(compiled).run_case(case) -> CaseResult``;
- ``search.py``: ``--random N``: hypothesis-drawn scenes, the first failure shrunk;
- ``report.py``: the table and worst-pixel PNGs; ``command.py``: the subcommand.

From Python::

    from pipegen.tools.stress import stress
    results = stress(compiled, base_scene, cases="quick", size=(96, 64))
"""

from __future__ import annotations

from typing import Callable, Optional

DEFAULT_SIZE = (96, 64)


def stress(compiled, base=None, cases: Optional[str] = None, size=DEFAULT_SIZE,
           progress: Callable[[str], None] = lambda msg: None, general: bool = False,
           path=None):
    """Run the named cases (``cases``: comma-separated names or groups, None: all) of
    ``compiled`` (a ``Compiled`` or a technique path) on ``base`` (a loaded ``Scene``, a scene
    path, or None: the built-in scene) at ``size`` (None: the scene's): ``[CaseResult]``.
    Each case is rendered by the variant compiled for its scene (``general``: by the general
    build); ``path``: the ``.pipe`` file of a ``Compiled``, so that variants shrink the
    light table as ``pipegen run`` does."""
    import os
    from pipegen.scene.load import default_scene, load_scene
    from pipegen.tools.stress.cases import build, case_names
    from pipegen.tools.stress.run import Stress
    if isinstance(compiled, (str, os.PathLike)):
        from pipegen.compiler.driver import compile_file
        path = compiled
        compiled = compile_file(compiled)
    if isinstance(base, (str, os.PathLike)):
        base = load_scene(base)
    base = base if base is not None else default_scene()
    base = base.with_size(*size) if size else base
    runner = Stress(compiled, general=general, path=path)
    out = []
    for case in build(base, case_names(cases)):
        progress(case.name)
        out.append(runner.run_case(case))
    return out
