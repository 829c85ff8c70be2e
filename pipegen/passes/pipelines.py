"""The compiler's pass pipelines, as data run by ``manager.run_pipeline``.

``GENERAL``: every compile, after the front end (lower, validate).  ``SCENE``: a technique
compiled for a scene (``compiler/specialise.py``), after ``GENERAL`` and ``assume_scene``
(which sets ``tech.scene``).  The names are what ``Compiled.phases_run`` records and
``pipegen compile --dump-after`` takes.
"""

from __future__ import annotations

import functools

from pipegen.passes import (opt_fold_constants, opt_hoist_invariants, opt_unused_functions,
                            specialise_params)
from pipegen.passes.manager import Fixpoint, Pass, Pipeline, pass_names

GENERAL: Pipeline = (
    Pass("specialise", specialise_params.run),
    Pass("fold", opt_fold_constants.run),
    Pass("prune", opt_unused_functions.run),
    Pass("hoist", opt_hoist_invariants.run),
)


@functools.cache
def _scene() -> Pipeline:
    # The scene facts first make tests of light types and shadow tiles constant; folding then
    # removes the branches, dead code and the reads they held (until none of them changes the
    # IR: a read dropped can make a function unused, whose constants may fold), and culling
    # removes the passes and targets nothing needs.
    from pipegen.passes import (
        cull_empty_draws, cull_unread, opt_dead_code, opt_unread_reads, spec_light_types,
        spec_shadows)
    return (
        Pass("spec_light_types", spec_light_types.run),
        Pass("spec_shadows", spec_shadows.run),
        Fixpoint("simplify", (
            Pass("fold", opt_fold_constants.run),
            Pass("dead_code", opt_dead_code.run),
            Pass("unread_reads", opt_unread_reads.run),
            Pass("prune", opt_unused_functions.run),
        )),
        Pass("cull_empty_draws", cull_empty_draws.run),
        Pass("cull_unread", cull_unread.run),
    )


def __getattr__(name: str):
    # ``SCENE`` is data like ``GENERAL``, built when first read: a compile without a scene
    # (most of them) then imports none of the scene passes
    if name == "SCENE":
        return _scene()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def all_pass_names() -> list[str]:
    """Every pass name a compile may run, general ones first."""
    return list(dict.fromkeys(pass_names(GENERAL) + pass_names(_scene())))
