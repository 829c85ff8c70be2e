"""What makes a compile cheaper (issue 26 item 7) changes nothing it produces: work is reused or
stopped early only where the result is known to be the same.  The emitted text of every
shipped technique is checked byte for byte by test_emitted_golden.py; here, each shortcut
against the long way round, on shipped techniques (no rendering)."""

from __future__ import annotations

import gc
from pathlib import Path

import pytest

from pipegen.backends import cstyle
from pipegen.backends.light_rows import plan_rows
from pipegen.backends.opencl import wide as cl_wide
from pipegen.backends.opencl.dialect import OpenCLLanguage
from pipegen.backends.opencl.wide.statements import WideStatements
from pipegen.backends.opencl.wide.values import TooManyGathers
from pipegen.cli.main import main
from pipegen.cli.parser import COMMANDS, build_parser
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.ir.light_layout import table_layout
from pipegen.passes import lower_mix_constant

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def techniques():
    """Lowered techniques of the shipped files, as the CL backend emits them."""
    return {name: lower_mix_constant.run(compile_file(ROOT / "pipelines" / f"{name}.pipe")
                                         .technique)
            for name in ("forward", "deferred_calver", "lidr_bitplanes")}


def test_wide_gather_budget_decides_as_a_whole_render(techniques, monkeypatch):
    """A wide render that stops once its lane-by-lane gathers rule the pass out
    (``TooManyGathers``) decides what the render run to its end decides, pass by pass."""
    stopped = []
    budgeted = WideStatements.count_gathers

    def counting(self, rows):
        try:
            budgeted(self, rows)
        except TooManyGathers:
            stopped.append(self.pass_.name)
            raise

    def whole(self, rows):         # the count alone: every render runs to its end
        self.lane_gathers += rows

    results = {}
    for mode, count in (("budget", counting), ("whole", whole)):
        monkeypatch.setattr(WideStatements, "count_gathers", count)
        results[mode] = {(name, p.name): cl_wide.wide_fragment(tech, p, OpenCLLanguage(tech, p))
                         for name, tech in techniques.items() for p in tech.passes}
    assert results["budget"] == results["whole"]
    # LIDR's shade pass gathers 32 rows a pixel: stopped early, scalar either way
    assert "shade" in stopped and results["whole"][("lidr_bitplanes", "shade")] is None
    # deferred_calver's light passes go wide (2 gathered rows): never stopped
    assert results["whole"][("deferred_calver", "point_lights")] is not None
    assert "point_lights" not in stopped


def test_row_plan_is_made_once_per_body(techniques):
    """Every pass and backend emitting a function asks for its body's light-row plan: made
    once, the plan plan_rows makes, and made again for other parameter names."""
    tech = techniques["forward"]
    layout = table_layout(tech.lights)
    # a function that reads light rows (forward's shading of one table light)
    f = next(f for f in tech.functions
             if plan_rows(f.body, layout, [n for n, _ in f.params])._before)
    params = [n for n, _ in f.params]
    first = cstyle.row_plan(f.body, layout, params)
    assert cstyle.row_plan(f.body, table_layout(tech.lights), tuple(params)) is first
    fresh = plan_rows(f.body, layout, params)
    assert first._before == fresh._before and first._groups == fresh._groups
    assert cstyle.row_plan(f.body, layout, params + ["extra"]) is not first


MIXES = """
technique mixes "a constant-weight mix in one function, none in the other"
target color : rgba8 clear (0, 0, 0, 1)
output color

vec3 blend(vec3 a, vec3 b) { return mix(a, b, 0.25); }
vec3 tint(vec3 a) { return a * 0.5; }

pass p {
  draw fullscreen
  writes color
  fragment { color = vec4(blend(tint(vec3(frag_coord.x)), vec3(1.0)), 1.0); }
}
"""


def test_passes_keep_bodies_they_do_not_change(techniques):
    """lower_mix_constant (and the passes sharing passes/bodies.py) rewrites the bodies that
    hold what it lowers and keeps the others as the same objects (what emission learnt of
    them is found again); nothing to lower: the technique itself."""
    tech = compile_source(MIXES, "mixes.pipe").technique
    lowered = lower_mix_constant.run(tech)
    blend, tint = lowered.functions
    assert "mix" not in str(blend.body) and blend.body != tech.functions[0].body
    assert tint is tech.functions[1] and lowered.passes[0] is tech.passes[0]
    assert lower_mix_constant.run(lowered) is lowered
    assert lower_mix_constant.run(techniques["forward"]) is techniques["forward"]


def test_compile_parser_parses_as_the_full_parser(tmp_path):
    argv = ["compile", "pipelines/forward.pipe", "-o", str(tmp_path), "--size", "64x48",
            "--backend", "gl", "-p", "max_lights=4"]
    only = build_parser("compile")
    full = build_parser(None)
    assert set(only._subparsers._group_actions[0].choices) == {"compile"}
    assert set(COMMANDS) <= set(full._subparsers._group_actions[0].choices)
    a, b = vars(only.parse_args(argv)), vars(full.parse_args(argv))
    assert a.keys() == b.keys()
    assert {k: v for k, v in a.items() if k != "parser"} == \
        {k: v for k, v in b.items() if k != "parser"}


def test_main_called_from_python_freezes_nothing(tmp_path, capsys):
    """Only the command's own process freezes its imports' objects (``gc.freeze``): a
    long-lived process calling ``main`` keeps its collector as it was."""
    before = gc.get_freeze_count()
    assert main(["compile", str(ROOT / "pipelines" / "forward_multipass.pipe"), "-o",
                 str(tmp_path / "out"), "--backend", "gl"]) == 0
    assert gc.get_freeze_count() == before
