"""The classes of crashes the mutation fuzzing of issue 8 found, each now a located
``PipegenError``: reading sources and includes, positions, spans, nesting; and where includes
are looked for (next to the file, the shipped library, ``PIPEGEN_PATH``)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from pipegen.core import sources
from pipegen.frontend import parse as syntax, syntax_tree
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core.diagnostics import PipegenError, Span
from pipegen.scene import parse_scene

ROOT = Path(__file__).resolve().parents[1]
FORWARD = (ROOT / "pipelines/forward.pipe").read_text()


def line_of(text: str, marker: str) -> int:
    return text[:text.index(marker)].count("\n") + 1


C_LINE = line_of(FORWARD, "vec3 c = ambient")      # the line the tests below break


def error(source: str, filename: str = "t.pipe") -> PipegenError:
    with pytest.raises(PipegenError) as info:
        compile_source(source, filename)
    return info.value


def caret_text(err: PipegenError) -> str:
    """The characters of the quoted line above the carets."""
    lines = err.render().split("\n")
    quoted, carets = lines[1], lines[2]
    start = carets.index("^")
    return quoted[start:start + carets.count("^")]


# -- reading -------------------------------------------------------------------------------

@pytest.mark.parametrize("path, words", [
    ("\\x00", "control characters"),
    ("a\x00b", "control characters"),
    ("../../../../../../../../../dev/zero", "not a regular file"),
    (".", "Is a directory"),
])
def test_bad_include_paths_are_located_errors(tmp_path, path, words):
    main = tmp_path / "t.pipe"
    err = error(f'technique t\ninclude "{path}"\n', str(main))
    assert words in err.message
    assert (err.span.file, err.span.line, err.span.column) == (str(main), 2, 1)


def test_a_fifo_is_not_opened(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    os.mkfifo(tmp_path / "pipe.pipe")
    err = error('technique t\ninclude "pipe.pipe"\n', str(tmp_path / "t.pipe"))
    assert "not a regular file" in err.message


def test_sources_over_the_size_limit_are_refused(tmp_path):
    big = tmp_path / "big.pipe"
    big.write_text("// " + "x" * sources.MAX_SOURCE_BYTES + "\n")
    err = error('technique t\ninclude "big.pipe"\n', str(tmp_path / "t.pipe"))
    assert "larger than 1 MiB" in err.message
    with pytest.raises(PipegenError, match="larger than 1 MiB"):
        compile_file(big)


def test_invalid_utf8_is_located_at_the_byte(tmp_path):
    bad = tmp_path / "bad.pipe"
    bad.write_bytes(FORWARD.encode().replace(b"vec3 c = ambient", b"vec3 c = \xff\xfeambient"))
    with pytest.raises(PipegenError) as info:
        compile_file(bad)
    err = info.value
    assert "not valid UTF-8 (byte 0xff)" in err.message
    assert (err.span.file, err.span.line, err.span.column) == (str(bad), C_LINE, 14)
    assert "\ufffd" in err.span.source_line


def test_invalid_utf8_in_an_included_file_names_that_file(tmp_path):
    (tmp_path / "lib.pipe").write_bytes(b"// ok\nfloat f(float x) { return x; } // \xc3\n")
    err = error('technique t\ninclude "lib.pipe"\n', str(tmp_path / "t.pipe"))
    assert (err.span.file, err.span.line, err.span.column) == (str(tmp_path / "lib.pipe"), 2, 35)


# -- positions -----------------------------------------------------------------------------

@pytest.mark.parametrize("odd", ["\v", "\f", "\u2028", "\u2029", "\x85", "\x1c"])
def test_odd_line_breaks_in_comments_do_not_shift_the_caret(odd):
    source = FORWARD.replace("technique forward", f"// a{odd}b\ntechnique forward").replace(
        "vec3 c = ambient", "vec3 c = ambent")
    err = error(source)
    assert err.span.line == C_LINE + 1
    assert caret_text(err) == "ambent"


def test_crlf_sources_quote_the_line_without_the_cr():
    err = error(FORWARD.replace("vec3 c = ambient", "vec3 c = ambent").replace("\n", "\r\n"))
    assert caret_text(err) == "ambent"
    assert "\r" not in err.render()


def test_control_characters_are_not_printed_raw():
    err = error(FORWARD.replace("vec3 c = ambient", "vec3 c = \x1b[31m ambient"))
    assert "\x1b" not in err.render()


def test_span_at_offset():
    text = "ab\ncd\n"
    assert (Span.at_offset("f", text, 4).line, Span.at_offset("f", text, 4).column) == (2, 2)
    assert (Span.at_offset("f", text, 6).line, Span.at_offset("f", text, 6).column) == (3, 1)


def test_long_lines_are_quoted_around_the_column():
    err = error(FORWARD.replace("vec3 c = ambient", "vec3 c = " + "1.0 + " * 40 + "ambent"))
    rendered = err.render()
    assert max(len(line) for line in rendered.split("\n")[1:3]) < 140
    assert caret_text(err) == "ambent"


def test_nesting_up_to_the_limit_compiles_through_every_phase():
    depth = syntax_tree.MAX_NESTING - 12      # the statement itself sits a few levels down
    expr = "-" * depth + "1.0"
    compiled = compile_source(FORWARD.replace("vec3 c = ambient * albedo;",
                                              f"vec3 c = ambient * albedo * {expr};"),
                              str(ROOT / "pipelines/forward.pipe"))
    assert compiled.technique.passes


def test_deep_nesting_is_a_located_error():
    err = error(FORWARD.replace("vec3 c = ambient", "vec3 c = " + "(-" * 3000 + "1.0" +
                                ")" * 3000 + " * ambient"))
    assert "nested too deeply" in err.message
    assert err.span.line == C_LINE


def test_many_passes_compile():
    """400 passes more than forward's two compile (how their compile time grows with the
    count is measured by ``python benchmarks/compile_time.py --many-passes``, not here:
    timings are no pass/fail criterion)."""
    extra = "".join(f"\npass extra{k} {{ draw fullscreen writes color "
                    f"fragment {{ color = vec4(float({k}) * 0.001); }} }}" for k in range(400))
    compiled = compile_source(FORWARD + extra, str(ROOT / "pipelines/forward.pipe"))
    assert len(compiled.technique.passes) == 402          # forward's shadow_maps, shade, 400
    assert [p.name for p in compiled.technique.passes[-2:]] == ["extra398", "extra399"]


# -- scenes ----------------------------------------------------------------------------------

@pytest.mark.parametrize("text, line, column", [
    ("width = 3\nheight = \n", 2, 10),
    ("width = 1\n[x\n", 2, 3),
    ('name = "abc', 1, 12),
])
def test_toml_syntax_errors_are_located(text, line, column):
    with pytest.raises(PipegenError) as info:
        parse_scene(text, "s.toml")
    err = info.value
    assert (err.span.file, err.span.line, err.span.column) == ("s.toml", line, column)
    assert err.render().startswith(f"s.toml:{line}:{column}: error: invalid TOML")


# -- include search path ---------------------------------------------------------------------

TECHNIQUE = """\
technique mine
include "common/lighting.pipe"
include "helpers.pipe"
lights[8] { position: vec3, radius: float, color: vec3 }
target color : rgba8
pass p { draw scene writes color fragment { color = vec4(helper(albedo), 1.0); } }
"""


def test_includes_search_next_to_the_file_then_the_library_then_pipegen_path(tmp_path,
                                                                              monkeypatch):
    user, extra = tmp_path / "user", tmp_path / "extra"
    user.mkdir()
    extra.mkdir()
    (user / "t.pipe").write_text(TECHNIQUE)
    (extra / "helpers.pipe").write_text("vec3 helper(vec3 c) { return c * 0.5; }")
    monkeypatch.setenv("PIPEGEN_PATH", os.pathsep.join(["", str(tmp_path / "nope"), str(extra)]))
    tech = compile_file(user / "t.pipe").technique        # lighting.pipe from the library
    assert [f.name for f in tech.functions] == ["helper"]    # from PIPEGEN_PATH

    # A file next to the technique comes first, even one named like the library's.
    (user / "common").mkdir()
    (user / "common" / "lighting.pipe").write_text("float mine_only(float x) { return x; }")
    compile_file(user / "t.pipe")
    assert sources.include_candidates("common/lighting.pipe", str(user / "t.pipe"))[0][0] == \
        str(user / "common" / "lighting.pipe")


def test_an_unresolved_include_lists_the_places_searched(tmp_path, monkeypatch):
    monkeypatch.setenv("PIPEGEN_PATH", str(tmp_path / "extra"))
    (tmp_path / "t.pipe").write_text('technique t\ninclude "common/nope.pipe"\n')
    with pytest.raises(PipegenError) as info:
        compile_file(tmp_path / "t.pipe")
    message = info.value.message
    assert "cannot read included file 'common/nope.pipe': not found" in message
    assert str(tmp_path / "common" / "nope.pipe") in message
    assert str(sources.library_dir() / "nope.pipe") in message
    assert str(tmp_path / "extra" / "common" / "nope.pipe") in message
    assert "PIPEGEN_PATH" in info.value.hint


def test_the_library_is_found_from_a_checkout():
    lib = sources.library_dir()
    assert lib is not None and (lib / "lighting.pipe").is_file()


# -- strings and generated code ----------------------------------------------------------------

@pytest.mark.parametrize("written, value", [
    (r"a\nb", "a\nb"), (r"\x41\u00e9\101", "AéA"), (r"\q", r"\q"), (r"\x4", r"\x4"),
    (r"\ud800", r"\ud800"), (r"\U00110000", r"\U00110000"),
    (r"common\lighting", r"common\lighting"),
])
def test_string_escapes_never_fail(written, value, recwarn):
    module = syntax.parse(f'technique t "{written}"')
    assert module.items[0].title == value
    assert not [w for w in recwarn if issubclass(w.category, DeprecationWarning)]


def test_errors_in_generated_packing_code_point_at_the_pack_declaration():
    source = (ROOT / "pipelines/inferred.pipe").read_text().replace("(object: 8", "(lbuf: 8")
    err = error(source, str(ROOT / "pipelines/inferred.pipe"))
    assert "the code packing 'id' generates does not compile" in err.message
    assert err.span.file == str(ROOT / "pipelines/inferred.pipe")
    assert err.span.source_line.startswith("pack id = bitfield")


@pytest.mark.parametrize("statement", ["vec4(1.0);", "float(1);", "ivec2(1, 2);",
                                       "load(color);"])
def test_value_statements_without_effect_are_errors(statement):
    source = FORWARD.replace("vec3 c = ambient * albedo;",
                             f"vec3 c = ambient * albedo; {statement}")
    err = error(source, str(ROOT / "pipelines/forward.pipe"))
    assert "has no effect" in err.message or "reads target" in err.message
    assert err.span.line == C_LINE


def test_bad_utf8_after_a_byte_order_mark_is_located():
    with pytest.raises(PipegenError) as info:
        sources.decode(b"\xef\xbb\xbfab\ncd\xffe", "f.pipe")
    assert (info.value.span.line, info.value.span.column) == (2, 3)
    assert sources.decode(b"\xef\xbb\xbftechnique t", "f.pipe") == "technique t"


def test_scene_file_that_is_not_utf8_is_located(tmp_path):
    """A scene file with a bad byte: an error at its line and column, not a traceback."""
    from pipegen.scene import load_scene
    bad = tmp_path / "bad.toml"
    bad.write_bytes(b"width = 64\n# \xff\xfe bad\n")
    with pytest.raises(PipegenError) as e:
        load_scene(bad)
    assert "bad.toml:2:3: error: the file is not valid UTF-8 (byte 0xff)" in e.value.render()
