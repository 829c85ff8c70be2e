"""The command line as docs/cli.md describes it: usage errors exit 2 with a message, ``--version``,
per-command help with its own examples and every option's default, ``pipegen info``, a scene
file given as the technique, one default output size, and the Python API (``import pipegen``)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pipegen
from pipegen.cli.arguments import MAX_SIZE
from pipegen.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
FORWARD = str(ROOT / "pipelines/forward.pipe")


def cli(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "pipegen.cli", *args], capture_output=True,
                          text=True, timeout=timeout, cwd=ROOT)


def usage_error(capsys, argv) -> str:
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    return capsys.readouterr().err


@pytest.mark.parametrize("size, words", [
    ("0x0", ["0x0", f"1..{MAX_SIZE}"]),
    ("abc", ["abc", "WIDTHxHEIGHT"]),
    ("-5x10", ["-5x10", f"1..{MAX_SIZE}"]),
    ("640x99999", ["640x99999", f"1..{MAX_SIZE}"]),
])
@pytest.mark.parametrize("command", ["run", "compile", "check", "info"])
def test_bad_size_is_a_usage_error_with_the_limits(capsys, tmp_path, command, size, words):
    err = usage_error(capsys, [command, FORWARD, "--size", size, "-o", str(tmp_path / "o")]
                      if command != "info" else [command, FORWARD, "--size", size])
    assert "--size" in err and all(w in err for w in words), err
    assert not (tmp_path / "o").exists()


def test_parameter_without_equals_is_a_usage_error(capsys, tmp_path):
    err = usage_error(capsys, ["run", FORWARD, "-p", "max_lights", "-o", str(tmp_path)])
    assert "NAME=VALUE" in err and "max_lights" in err


def test_usage_errors_exit_2_through_the_real_command(tmp_path):
    for args in (["run", FORWARD, "--size", "-5x10", "-o", str(tmp_path / "o")],
                 ["compile", FORWARD, "-o", str(tmp_path / "o"), "-p", "name"],
                 ["run", FORWARD],                      # -o missing
                 []):
        proc = cli(*args)
        assert proc.returncode == 2, (args, proc.stderr)
        assert "Traceback" not in proc.stderr
    assert "argument --size: bad size '-5x10'" in cli("run", FORWARD, "--size", "-5x10",
                                                      "-o", "o").stderr


def test_bad_parameter_value_is_an_input_error_exit_1(capsys, tmp_path):
    assert main(["info", str(ROOT / "pipelines/inferred.pipe"), "-p",
                 "lbuffer_scale=0.3"]) == 1
    assert "lbuffer_scale" in capsys.readouterr().err


def test_version():
    proc = cli("--version")
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"pipegen {pipegen.__version__}"
    assert pipegen.__version__[0].isdigit()
    proc = subprocess.run([sys.executable, "-m", "pipegen", "--version"], capture_output=True,
                          text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 0 and proc.stdout.strip() == f"pipegen {pipegen.__version__}"


@pytest.mark.parametrize("command, defaults", [
    ("compile", ["(default: all)", "(default: 1280x720"]),
    ("run", ["(default: gl)", "1280x720 for the built-in scene",
             "(default: the built-in default scene)"]),
    ("check", ["(default: build/check/<technique>)", "(default: the built-in default scene)"]),
    ("info", ["(default: 1280x720"]),
])
def test_each_command_help_shows_its_examples_and_defaults(capsys, command, defaults):
    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    examples = text[text.index("examples:"):]
    commands = {line.split()[1] for line in examples.splitlines()
                if line.strip().startswith("pipegen ")}
    assert commands == {command}, examples
    flat = " ".join(text.split())
    for d in defaults:
        assert d in flat, (d, text)
    if command != "info":
        assert "--force" in text and "default: refuse" in flat


def test_info_lists_parameters_targets_passes_and_packings(capsys):
    assert main(["info", str(ROOT / "pipelines/inferred.pipe")]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    row = next(l.split() for l in lines if l.strip().startswith("lbuffer_scale"))
    assert row[:3] == ["lbuffer_scale", "float", "0.625"]
    assert "0.5, 0.625, 0.75, 1" in out                       # allowed values
    assert next(l.split() for l in lines if l.strip().startswith("dsf "))[:3] == \
        ["dsf", "bool", "true"]
    # word parameters under the language's type word (docs/language.md), not the IR's void
    assert next(l.split() for l in lines if l.strip().startswith("normal_format"))[:3] == \
        ["normal_format", "format", "rg16f"]
    assert " void " not in out
    assert "targets at output size 1280x720" in out
    color = next(l.split() for l in lines if l.strip().startswith("color *"))
    assert color[2:4] == ["rgba8", "1280x720"] and "3686400" in color      # 1280*720*4
    lbuf = next(l.split() for l in lines if l.strip().startswith("lbuf "))
    assert lbuf[1:3] == ["rgba16f", "800x450"] and "2880000" in lbuf       # 0.625 scale, 8 B
    for p in ("1. geometry", "2. lighting", "3. spot_lighting", "4. directional_lighting",
              "5. material", "6. translucent"):
        assert p in out
    assert "nrm = kircher(target: gnormal)" in out
    # the error bound with its unit, as the compile report gives it
    assert "error bound 0.2231 degrees (max angular error, measured)" in out
    assert "id = bitfield(fields: {object: 8, group: 8}, target: gdsf)" in out


def test_info_with_overrides_and_size(capsys):
    assert main(["info", str(ROOT / "pipelines/inferred.pipe"), "-p", "lbuffer_scale=0.5",
                 "--size", "640x360"]) == 0
    out = capsys.readouterr().out
    row = next(l.split() for l in out.splitlines() if l.strip().startswith("lbuffer_scale"))
    assert row[:4] == ["lbuffer_scale", "float", "0.625", "0.5"]     # default, value
    lbuf = next(l.split() for l in out.splitlines() if l.strip().startswith("lbuf "))
    assert lbuf[2] == "320x180"


def test_info_on_a_technique_with_capacity(capsys):
    assert main(["info", str(ROOT / "pipelines/lidr_bitplanes.pipe")]) == 0
    out = capsys.readouterr().out
    assert "slots = bitplanes(index_bits: 8, target: lightidx)" in out
    assert "capacity 4 lights per pixel" in out
    index_bits = next(l.split() for l in out.splitlines() if l.strip().startswith("index_bits"))
    assert index_bits == ["index_bits", "int", "8", "8,", "16,", "32"]   # the allowed values


@pytest.mark.parametrize("command", ["run", "compile", "check", "info"])
def test_scene_file_given_as_technique_says_so(capsys, tmp_path, command):
    scene = str(ROOT / "examples/scenes/small.toml")
    argv = [command, scene] + (["-o", str(tmp_path / "o")] if command != "info" else [])
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "this looks like a scene file" in err and "--scene" in err
    assert not (tmp_path / "o").exists()


def test_scene_file_with_another_suffix_is_recognised(capsys, tmp_path):
    renamed = tmp_path / "scene.pipe"
    renamed.write_text((ROOT / "examples/scenes/small.toml").read_text())
    assert main(["info", str(renamed)]) == 1
    assert "this looks like a scene file" in capsys.readouterr().err


def test_technique_given_as_scene_says_so(capsys, tmp_path):
    assert main(["run", FORWARD, "--scene", FORWARD, "-o", str(tmp_path / "o")]) == 1
    assert "looks like a technique" in capsys.readouterr().err


@pytest.mark.gl
def test_one_default_output_size(tmp_path, capsys):
    """Without --size: the built-in scene is rendered at DEFAULT_SIZE, and compile's printed
    report, report.txt and info state memory at the same size; a scene file keeps its own."""
    assert pipegen.DEFAULT_SIZE == (1280, 720)
    w, h = pipegen.DEFAULT_SIZE
    assert main(["run", FORWARD, "-o", str(tmp_path / "run")]) == 0
    assert np.load(tmp_path / "run" / "color.npy").shape[:2] == (h, w)
    assert main(["run", FORWARD, "--scene", str(ROOT / "examples/scenes/small.toml"),
                 "-o", str(tmp_path / "small")]) == 0
    assert np.load(tmp_path / "small" / "color.npy").shape[:2] == (64, 96)
    capsys.readouterr()
    assert main(["compile", FORWARD, "-o", str(tmp_path / "build")]) == 0
    printed = capsys.readouterr().out
    assert f"targets at {w}x{h}" in printed
    assert f"targets at {w}x{h}" in (tmp_path / "build" / "report.txt").read_text()
    assert main(["compile", FORWARD, "-o", str(tmp_path / "build"), "--size", "64x36"]) == 0
    assert "targets at 64x36" in capsys.readouterr().out
    assert "targets at 64x36" in (tmp_path / "build" / "report.txt").read_text()


def test_api_import_is_lazy_and_light():
    code = ("import sys\n"
            "from pipegen import compile_file, load_scene, default_scene, save_pngs\n"
            "import pipegen\n"
            "c = compile_file('pipelines/forward.pipe')\n"
            "s = load_scene('examples/scenes/small.toml')\n"
            "assert c.name == 'forward' and s.width == 96\n"
            "heavy = [m for m in sys.modules if m.split('.')[0] in ('moderngl', 'pyopencl')]\n"
            "assert not heavy, heavy\n"
            "print('ok', pipegen.__version__)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("ok ")


@pytest.mark.gl
def test_save_pngs_from_python(tmp_path):
    compiled = pipegen.compile_file(ROOT / "pipelines/forward.pipe")
    scene = pipegen.default_scene().with_size(64, 36)
    targets = compiled.pipeline("gl").render(scene)
    paths = pipegen.save_pngs(compiled, scene, targets, tmp_path / "pics")
    assert set(paths) == set(targets) == {"color", "ds", "ds.stencil", "shadow_atlas"}
    from PIL import Image
    assert all(p.exists() for p in paths.values())
    assert Image.open(paths["color"]).size == (64, 36)
    assert not list((tmp_path / "pics").glob("*.npy"))
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(pipegen.PipegenError, match="did not write"):
        pipegen.save_pngs(compiled, scene, targets, tmp_path / "mine")
    paths = pipegen.save_pngs(compiled, scene, targets, tmp_path / "mine", npy=True, force=True)
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"
    assert (tmp_path / "mine" / "color.npy").exists()
