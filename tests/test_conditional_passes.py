"""Passes, repeat blocks and targets present only where a condition over parameters holds
(`pass NAME if COND { … }`, docs/language.md): the condition is folded while lowering, so each
value of the parameters compiles to just its own passes and targets; anything in a condition
that is not a parameter, a literal, a word of a word parameter, a comparison, `!`, `&&`, `||`
is an error at the place it is written."""

from __future__ import annotations

import pytest

from pipegen.compiler.driver import compile_file
from pipegen.core.diagnostics import PipegenError

HEAD = '''technique cond "conditional passes"
param mode = sum in {sum, copy}
param taps = 4 in {1, 4}
param on = true
lights[4] { position: vec3, radius: float, color: vec3 }
target color : rgba8 clear (0, 0, 0, 1)
'''

TECHNIQUE = HEAD + '''target temp : rgba8 clear 0 if mode == copy
pass direct if mode == sum && on {
  draw fullscreen
  writes color
  fragment { color = vec4(0.25); }
}
repeat per light if mode == copy {
  pass into_temp if taps > 1 {
    draw fullscreen
    writes temp
    fragment { temp = vec4(light.color, 1.0); }
  }
  pass back {
    draw fullscreen
    reads temp
    writes color
    fragment { color = load(temp); }
  }
}
'''


def compiled(tmp_path, text: str, **params):
    path = tmp_path / "cond.pipe"
    path.write_text(text)
    return compile_file(path, params=params or None, verify_each=True).technique


def names(items) -> list[str]:
    return [x.name for x in items]


def test_default_keeps_only_its_passes_and_targets(tmp_path):
    tech = compiled(tmp_path, TECHNIQUE)
    assert names(tech.passes) == ["direct"]
    assert names(tech.targets) == ["color"]


def test_word_override_selects_the_other_passes(tmp_path):
    tech = compiled(tmp_path, TECHNIQUE, mode="copy")
    assert names(tech.passes) == ["into_temp", "back"]
    assert [p.repeat_group for p in tech.passes] == [0, 0]
    assert names(tech.targets) == ["color", "temp"]


def test_pass_condition_inside_a_block_joins_the_blocks(tmp_path):
    tech = compiled(tmp_path, TECHNIQUE, mode="copy", taps=1)
    assert names(tech.passes) == ["back"]
    assert compiled(tmp_path, TECHNIQUE, on=False).passes == ()


def test_groups_are_numbered_again_after_absent_ones(tmp_path):
    text = HEAD + '''repeat per light if mode == copy { pass a { draw fullscreen writes color
      fragment { color = vec4(1.0); } } }
    repeat per light { pass b { draw fullscreen writes color fragment { color = vec4(1.0); } } }
    '''
    tech = compiled(tmp_path, text)
    assert [(p.name, p.repeat_group) for p in tech.passes] == [("b", 0)]


def test_a_word_parameter_holds_only_its_listed_words(tmp_path):
    with pytest.raises(PipegenError, match="cpy is not an allowed value of parameter 'mode'"):
        compiled(tmp_path, TECHNIQUE, mode="cpy")


ERRORS = [
    # (condition, the text the error points at, words of the message)
    ("mode == cpy", "cpy", "'cpy' is not a value parameter 'mode' can hold"),
    ("mode == 1", "mode == 1", "holds a word; it cannot be compared with the number 1"),
    ("taps", "taps", "must be true or false, not the number 4"),
    ("taps > on", "taps > on", "`>` compares numbers"),
    ("mode < sum", "mode < sum", "`<` compares numbers"),
    ("light.radius > 0.0", "light.radius", "a field or swizzle cannot appear in a condition"),
    ("num_lights > 0u", "num_lights", "'num_lights' is a stage input: a condition reads only"),
    ("tap > 1", "tap", "unknown parameter 'tap'"),
    ("max(taps, 2) > 1", "max(taps, 2)", "a call cannot appear"),
    ("taps + 1 > 2", "taps + 1", "operator `+` cannot appear"),
    ("!taps", "taps", "`!` needs true or false"),
    ("on && taps", "taps", "`&&` and `||` join true or false"),
]


@pytest.mark.parametrize("cond, at, words", ERRORS, ids=[e[0] for e in ERRORS])
def test_condition_errors_are_positioned(tmp_path, cond, at, words):
    text = HEAD + f"pass p if {cond} {{ draw fullscreen writes color " \
                  f"fragment {{ color = vec4(1.0); }} }}\n"
    with pytest.raises(PipegenError) as info:
        compiled(tmp_path, text)
    e = info.value
    line = text.splitlines()[e.span.line - 1]
    assert e.span.line == text.count("\n"), e
    assert line[e.span.column - 1:].startswith(at), (line, e.span.column, e.message)
    assert words in e.message
    assert e.hint


def test_a_present_pass_using_an_absent_target_is_an_error(tmp_path):
    text = HEAD + '''target temp : rgba8 if mode == copy
pass p {
  draw fullscreen
  writes temp
  fragment { temp = vec4(1.0); }
}
'''
    with pytest.raises(PipegenError) as info:
        compiled(tmp_path, text)
    e = info.value
    assert "pass 'p' uses target 'temp', which is present only if mode == copy" in e.message
    assert (e.span.line, e.span.column) == (8, 1)
    assert compiled(tmp_path, text, mode="copy").passes[0].name == "p"


def test_the_output_cannot_be_absent(tmp_path):
    text = HEAD.replace("target color : rgba8 clear (0, 0, 0, 1)",
                        "target color : rgba8 if mode == copy")
    with pytest.raises(PipegenError, match="the output is target .color., which is present only") as info:
        compiled(tmp_path, text)
    assert info.value.span.line == 6


def test_absent_passes_are_still_checked(tmp_path):
    text = HEAD + "pass p if mode == copy { draw fullscreen writes colr " \
                  "fragment { color = vec4(1.0); } }\n"
    with pytest.raises(PipegenError, match="unknown target 'colr'"):
        compiled(tmp_path, text)


def test_shipped_calver_modes_differ_by_their_passes_and_temp_buffer():
    from pathlib import Path
    pipe = Path(__file__).resolve().parents[1] / "pipelines/deferred_calver.pipe"
    blend = compile_file(pipe).technique
    copy = compile_file(pipe, params={"hdr_accumulate": "copy_back"}).technique
    assert set(names(copy.targets)) - set(names(blend.targets)) == {"accum_temp"}
    assert {"directional_lights", "point_lights", "spot_lights"} <= set(names(blend.passes))
    extra = [p for p in copy.passes if p.name not in names(blend.passes)]
    assert [(p.name, p.repeat_types) for p in extra] == [
        ("directional_sum", ("directional",)), ("directional_copy_back", ("directional",)),
        ("point_sum", ("point",)), ("point_copy_back", ("point",)),
        ("spot_sum", ("spot",)), ("spot_copy_back", ("spot",))]
    assert not {"directional_lights", "point_lights", "spot_lights"} & set(names(copy.passes))
