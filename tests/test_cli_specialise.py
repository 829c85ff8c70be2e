"""Scene specialisation on the command line (issue 9, docs/specialise.md): mismatches as
warnings or, with ``--strict``, an error; ``compile --scene`` and its report; ``run``/``check
[--general]`` (the variant by default) and whether it was reused; ``pipegen specialise [--verify]``;
``pipegen graph`` (SVG/PNG with Graphviz's dot, DOT text without it)."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import pytest

from pipegen.views import graph
from pipegen.compiler import specialise
from pipegen.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "examples/scenes"


def tech(name: str) -> str:
    return str(ROOT / "pipelines" / f"{name}.pipe")


def scene(name: str) -> str:
    return str(SCENES / f"{name}.toml")


TRANSLUCENT_NOT_DRAWN = "1 translucent object is not drawn (no pass draws scene.translucent)"


@pytest.fixture
def fresh_cache():
    specialise.clear_cache()
    yield
    specialise.clear_cache()


# ---- mismatches: warnings, --strict ---------------------------------------------------------


def test_run_strict_is_an_error_before_anything_renders(capsys, tmp_path):
    """Not marked gl: rendering would fail the test (tests/conftest.py)."""
    out = tmp_path / "out"
    assert main(["run", tech("forward"), "--scene", scene("mixed_lights"), "--strict",
                 "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: forward will not render all of ")
    assert f"\n  {TRANSLUCENT_NOT_DRAWN}\n" in err
    assert "hint: without --strict" in err
    assert not out.exists()


def test_check_strict_lists_every_mismatch(capsys, tmp_path):
    assert main(["check", tech("lidr_bitplanes"), "--scene", scene("translucent_layers"),
                 "--size", "48x27", "--strict", "-o", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err
    listed = [l for l in err.splitlines() if l.startswith("  ")]
    assert len(listed) == 2, err
    assert listed[0] == "  15 translucent objects are not drawn (no pass draws scene.translucent)"
    assert listed[1].endswith("the packing `slots` (bitplanes) holds 4: lights will be dropped")
    assert not (tmp_path / "c").exists()


def test_strict_without_a_mismatch_is_quiet(capsys, tmp_path):
    assert main(["compile", tech("forward"), "--scene", scene("small"), "--strict",
                 "-o", str(tmp_path / "b")]) == 0
    assert "warning" not in capsys.readouterr().err


@pytest.mark.gl
def test_run_warns_before_rendering_and_renders(capsys, tmp_path):
    assert main(["run", tech("forward"), "--scene", scene("mixed_lights"), "--size", "32x18",
                 "-o", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err
    warning = (f"warning: part of {scene('mixed_lights')} will not be rendered: "
               f"{TRANSLUCENT_NOT_DRAWN}")
    assert warning in err.splitlines()
    assert err.index("warning:") < err.index("rendering forward")
    assert (tmp_path / "r" / "color.npy").exists()


@pytest.mark.gl
@pytest.mark.cl
def test_check_warns_and_recalls_the_mismatch_under_the_table(capsys, tmp_path):
    rc = main(["check", tech("forward"), "--scene", scene("mixed_lights"), "--size", "32x18",
               "-o", str(tmp_path / "c")])
    captured = capsys.readouterr()
    assert rc == 0, captured.out
    assert TRANSLUCENT_NOT_DRAWN in captured.err
    assert "note: 1 thing in this scene the technique does not render" in captured.out
    assert "all targets agree" in captured.out


# ---- compile --scene ----------------------------------------------------------------------


def test_compile_with_a_scene_writes_the_reasons(capsys, tmp_path):
    out = tmp_path / "inferred"
    assert main(["compile", tech("inferred"), "--scene", scene("small"), "-o", str(out)]) == 0
    report = (out / "report.txt").read_text()
    assert "scene specialisation" in report
    assert ("pass `translucent` culled: it draws scene.translucent back_to_front and the "
            "scene has no translucent objects") in report
    assert "table `lights` shrunk: 128 -> 4" in report
    assert "passes: 6 -> 3 (geometry, lighting, material)" in report
    assert report in capsys.readouterr().out
    # the emitted pipeline is the specialised one: 3 passes' shaders
    assert len(list((out / "gl").glob("*.frag"))) == 3


def test_compile_strict_needs_a_scene(capsys, tmp_path):
    with pytest.raises(SystemExit) as e:
        main(["compile", tech("forward"), "--strict", "-o", str(tmp_path / "b")])
    assert e.value.code == 2
    assert "--strict needs --scene" in capsys.readouterr().err


def test_compile_strict_refuses_before_writing(capsys, tmp_path):
    assert main(["compile", tech("deferred"), "--scene", scene("mixed_lights"), "--strict",
                 "-o", str(tmp_path / "b")]) == 1
    assert TRANSLUCENT_NOT_DRAWN in capsys.readouterr().err
    assert not (tmp_path / "b").exists()


# ---- variants ----------------------------------------------------------------------------------


@pytest.mark.gl
def test_run_renders_the_variant_by_default_and_says_what_it_cut(capsys, tmp_path, fresh_cache):
    """run specialises by default (issue 26): it says whether the variant was compiled or
    reused and lists each cut with its reason; --specialise is the default kept as a no-op;
    --general renders the general build, with no variant."""
    argv = ["run", tech("deferred_calver"), "--scene", scene("small"), "--size", "32x18", "-o"]
    assert main(argv + [str(tmp_path / "a")]) == 0
    first = capsys.readouterr().err
    assert "variant: compiled (specialised for point; at most 4 lights; nothing translucent;" \
        in first
    assert "  pass `spot_lights` culled: it draws lights as cone spot and the scene has no " \
        "spot lights" in first
    assert "  table `lights` shrunk: 128 -> 4 entries" in first
    assert main(argv[:-1] + ["--specialise", "-o", str(tmp_path / "b")]) == 0
    assert "variant: reused (" in capsys.readouterr().err
    assert main(argv[:-1] + ["--general", "-o", str(tmp_path / "c")]) == 0
    assert "variant: " not in capsys.readouterr().err
    written = {p.name for p in (tmp_path / "a").iterdir()}
    general = {p.name for p in (tmp_path / "c").iterdir()}
    assert "spot_lut.png" not in written and "spot_lut.png" in general


def test_general_and_specialise_exclude_each_other(capsys, tmp_path):
    with pytest.raises(SystemExit) as e:
        main(["run", tech("deferred"), "--general", "--specialise", "-o", str(tmp_path)])
    assert e.value.code == 2
    assert "not allowed with argument --general" in capsys.readouterr().err


@pytest.mark.gl
@pytest.mark.cl
def test_check_compares_the_variant_by_default(capsys, tmp_path, fresh_cache):
    assert main(["check", tech("deferred_calver"), "--scene", scene("small"), "--size", "32x18",
                 "-o", str(tmp_path / "c")]) == 0
    captured = capsys.readouterr()
    assert "variant: compiled (" in captured.err and "passes 11 -> 7;" in captured.err
    rows = {l.split()[0] for l in captured.out.splitlines()[2:] if l.strip()}
    assert "spot_lut" not in rows and "accum" in rows        # the variant's targets only
    assert "all targets agree" in captured.out
    assert main(["check", tech("deferred_calver"), "--scene", scene("small"), "--size", "32x18",
                 "--general", "-o", str(tmp_path / "g")]) == 0
    captured = capsys.readouterr()
    rows = {l.split()[0] for l in captured.out.splitlines()[2:] if l.strip()}
    assert "variant: " not in captured.err and "spot_lut" in rows


# ---- pipegen specialise ------------------------------------------------------------------------


def test_specialise_prints_features_cuts_and_lists(capsys):
    assert main(["specialise", tech("deferred_calver"), "--scene", scene("small")]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].startswith("deferred_calver on ")
    assert "scene features" in lines and "  lights: 4 point" in lines
    assert "  nothing: the technique renders everything this scene has" in lines
    assert "specialised for: point; at most 4 lights; nothing translucent; no shadows" in lines
    assert ("  pass `tabulate_spot` culled: it writes `spot_lut`, read only by culled pass "
            "`spot_lights`") in lines
    assert ("  target `spot_lut` culled: used only by culled passes `tabulate_spot`, "
            "`spot_lights`") in lines
    assert "  parameter max_lights = 4" in lines
    before = next(l for l in lines if l.startswith("passes   before (11): "))
    assert "spot_lights" in before
    after = next(l for l in lines if l.strip().startswith("after  (7): "))
    assert "spot_lights" not in after
    assert any(l.startswith("targets  before (12)") for l in lines)
    memory = next(l for l in lines if l.startswith("target memory at 96x64: "))
    assert "saved)" in memory and "(0 B saved)" not in memory


def test_specialise_lists_mismatches_and_strict_fails(capsys):
    assert main(["specialise", tech("forward"), "--scene", scene("mixed_lights")]) == 0
    out = capsys.readouterr().out
    assert "not rendered for this scene (--strict makes this an error)" in out
    assert f"  {TRANSLUCENT_NOT_DRAWN}" in out.splitlines()
    assert main(["specialise", tech("forward"), "--scene", scene("mixed_lights"),
                 "--strict"]) == 1
    assert TRANSLUCENT_NOT_DRAWN in capsys.readouterr().err


def test_specialise_needs_a_scene(capsys):
    with pytest.raises(SystemExit) as e:
        main(["specialise", tech("forward")])
    assert e.value.code == 2
    assert "--scene" in capsys.readouterr().err


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("technique, scene_name", [("deferred_calver", "small"),
                                                   ("inferred", "small"),
                                                   ("forward_multipass", "mixed_lights")])
def test_specialise_verify_identical(capsys, technique, scene_name):
    assert main(["specialise", tech(technique), "--scene", scene(scene_name), "--size", "48x27",
                 "--verify"]) == 0
    out = capsys.readouterr().out
    assert "verify at 48x27: every target the specialised pipeline produces, bit for bit" in out
    rows = [l for l in out.splitlines() if "targets identical (" in l]
    assert len(rows) == 2                             # one per backend
    assert out.rstrip().endswith("identical: the specialised pipeline renders what the general "
                                 "one renders")


def _drop_pass(name: str):
    def phase(tech):
        return dataclasses.replace(tech, passes=tuple(p for p in tech.passes if p.name != name))
    return phase


@pytest.mark.gl
def test_specialise_verify_names_the_first_differing_pass(capsys, monkeypatch, fresh_cache):
    """A scene phase that wrongly drops a live pass: --verify exits 1 naming where the two
    pipelines part."""
    monkeypatch.setattr(specialise, "SCENE_PHASES",
                        specialise.SCENE_PHASES + (("broken", _drop_pass("per_light")),))
    assert main(["specialise", tech("forward_multipass"), "--scene", scene("small"),
                 "--size", "32x18", "--verify", "--backend", "gl"]) == 1
    captured = capsys.readouterr()
    assert "targets differ (" in captured.out
    err = captured.err.strip().splitlines()[-1]
    assert err.startswith("error: the specialised pipeline differs from the general one; "
                          "first differing pass: ")
    where = err.split("first differing pass: ")[1]
    assert where.split(":")[0].split()[0] in ("per_light", "resolve"), where


# ---- pipegen graph ------------------------------------------------------------------------------


def test_graph_writes_dot_text_with_culled_passes_greyed(capsys, tmp_path):
    out = tmp_path / "g.dot"
    assert main(["graph", tech("inferred"), "--scene", scene("small"), "-o", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out}"
    text = out.read_text()
    assert text.startswith('digraph "inferred" {')
    line = next(l for l in text.splitlines() if l.strip().startswith('"pass:translucent" ['))
    assert f'fillcolor="{graph.FAINT}"' in line and "dashed" in line
    assert "culled: it draws scene.translucent\\nback_to_front and the" in line
    assert ('tooltip="it draws scene.translucent back_to_front and the scene has no '
            'translucent objects"') in line
    live = next(l for l in text.splitlines() if l.strip().startswith('"pass:geometry" ['))
    assert "culled" not in live
    assert '"pass:lighting" -> "target:lbuf"' in text           # a write
    assert '"target:lbuf" -> "pass:material"' in text           # a read
    assert "specialised for: point; at most 4 lights; nothing translucent" in text
    # with --scene the targets are sized as run renders that scene (small.toml: 96x64; the
    # L-buffer at 0.625 of it), not at the default 1280x720
    assert "60x40" in text and "800x450" not in text and "1280x720" not in text


def test_graph_of_the_general_technique(tmp_path):
    out = tmp_path / "deferred.gv"
    assert main(["graph", tech("deferred"), "-o", str(out)]) == 0
    text = out.read_text()
    assert "culled" not in text
    assert 'label="repeat per light (point, spot lights)"' in text
    assert '"pass:gbuffer" -> "target:ds" [color="#2e7d32", dir="both", ' \
           'label="depth test, depth write"]' in text


@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz's dot is not installed")
@pytest.mark.parametrize("suffix, magic", [(".svg", b"<svg"), (".png", b"\x89PNG")])
def test_graph_renders_with_graphviz(capsys, tmp_path, suffix, magic):
    out = tmp_path / f"g{suffix}"
    assert main(["graph", tech("inferred"), "--scene", scene("small"), "-o", str(out)]) == 0
    assert magic in out.read_bytes()[:400]
    assert capsys.readouterr().out.strip() == f"wrote {out}"


def test_graph_without_graphviz_writes_the_dot_text(capsys, monkeypatch, tmp_path):
    monkeypatch.setattr(graph, "find_dot", lambda: None)
    out = tmp_path / "g.svg"
    assert main(["graph", tech("forward"), "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert not out.exists()
    assert (tmp_path / "g.dot").read_text().startswith('digraph "forward" {')
    assert "Graphviz's dot is not installed" in captured.out
    assert "hint: install Graphviz" in captured.err


def test_graph_file_suffix_is_checked(capsys, tmp_path):
    with pytest.raises(SystemExit) as e:
        main(["graph", tech("forward"), "-o", str(tmp_path / "g.txt")])
    assert e.value.code == 2
    assert "bad graph file" in capsys.readouterr().err
    (tmp_path / "dir.svg").mkdir()
    assert main(["graph", tech("forward"), "-o", str(tmp_path / "dir.svg")]) == 1
    assert "is a folder, not a file" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["specialise", "graph"])
def test_help_shows_the_examples(capsys, command):
    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    examples = text[text.index("examples:"):]
    assert {l.split()[1] for l in examples.splitlines()
            if l.strip().startswith("pipegen ")} == {command}



def test_general_build_says_what_unused_shadow_maps_cost():
    """forward.pipe's general build clears its atlas and runs the (untaken) shadow lookup on
    a scene where no light casts shadows: run and check --general print a note saying the
    variant removes both;
    none where lights cast shadows, none for the specialised variant (compile --scene), none
    for a technique without shadow maps."""
    from pipegen import compile_file, load_scene
    from pipegen.cli.scene_args import unused_cost_note
    small, shadows = load_scene(scene("small")), load_scene(scene("shadows"))
    forward = compile_file(tech("forward"))
    note = unused_cost_note(forward, small)
    assert note.startswith("no light in this scene casts shadows") and "--general" in note
    assert unused_cost_note(forward, shadows) is None
    assert unused_cost_note(forward.specialise(small), small) is None
    assert unused_cost_note(compile_file(tech("deferred")), small) is None


@pytest.mark.gl
def test_run_prints_the_unused_shadow_note(capsys, tmp_path):
    assert main(["run", tech("forward"), "--scene", scene("small"), "--size", "16x9",
                 "--general", "-o", str(tmp_path / "r")]) == 0
    assert "note: no light in this scene casts shadows" in capsys.readouterr().err
    assert main(["run", tech("forward"), "--scene", scene("small"), "--size", "16x9",
                 "-o", str(tmp_path / "s")]) == 0
    assert "note: no light" not in capsys.readouterr().err


def test_docs_specialise_md_shows_what_the_command_prints(capsys, monkeypatch):
    """The example output in docs/specialise.md is the command's output today."""
    import re
    monkeypatch.chdir(ROOT)
    command = "pipegen specialise pipelines/deferred_calver.pipe --scene examples/scenes/small.toml"
    doc = (ROOT / "docs" / "specialise.md").read_text()
    shown = re.search(re.escape("$ " + command) + r"\n(.*?)^```", doc, re.S | re.M).group(1)
    assert main(command.split()[1:]) == 0
    assert capsys.readouterr().out == shown
