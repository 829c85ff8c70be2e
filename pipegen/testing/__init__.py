"""Test your technique (docs/testing.md): render it, and assert that GL and CL agree, that it
stays within the bound of its own float64 evaluation, and that it matches stored goldens, each
target held to the bound of the tolerance model (docs/tolerances.md)::

    from pipegen.testing import assert_backends_agree, assert_close_to_f64, \\
        assert_matches_golden, render

    def test_my_technique():
        assert_backends_agree("my_technique.pipe", "scene.toml")
        assert_close_to_f64("my_technique.pipe", "scene.toml")
        assert_matches_golden(render("my_technique.pipe", "scene.toml"), "goldens/")

Names are imported on first use: ``import pipegen.testing`` (and the pytest plugin that
pipegen installs) costs nothing until a function is called.
"""

from __future__ import annotations

from pipegen.core.lazy import lazy_names


def _api():
    from pipegen.testing import api
    return api


__getattr__, __dir__ = lazy_names(globals(), dict.fromkeys((
    "render", "assert_backends_agree", "assert_close_to_f64", "assert_matches_golden",
    "assert_close_to_reference",
    "ComparisonFailure", "ClampWarning", "Targets", "TargetImage", "load_technique",
    "load_test_scene",
    "TEST_SIZE"), _api))
