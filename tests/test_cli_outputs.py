"""``-o DIR`` of ``run``, ``compile`` and ``check``: files pipegen did not write survive, a
foreign non-empty folder is refused without ``--force`` (and written with it), an output path
that cannot be a folder is a clear error (exit 1) before any work, and pass or target names of
any legal length give files."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pipegen.compiler.driver
from pipegen.cli.main import main
from pipegen.core.outdir import MANIFEST

ROOT = Path(__file__).resolve().parents[1]
FORWARD = str(ROOT / "pipelines/forward.pipe")
SMALL = ["--size", "64x36"]


def user_files(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "notes.txt").write_text("keep")
    (folder / "earlier").mkdir(exist_ok=True)
    (folder / "earlier" / "result.png").write_bytes(b"not pipegen's")


def assert_user_files(folder: Path) -> None:
    assert (folder / "notes.txt").read_text() == "keep"
    assert (folder / "earlier" / "result.png").read_bytes() == b"not pipegen's"


@pytest.mark.gl
def test_run_refuses_a_foreign_folder_without_force_and_keeps_user_files_with_it(tmp_path,
                                                                                  capsys):
    out = tmp_path / "x"
    user_files(out)
    assert main(["run", FORWARD, "-o", str(out), *SMALL]) == 1
    err = capsys.readouterr().err
    assert "did not write" in err and "--force" in err and "rendering" not in err
    assert sorted(p.name for p in out.iterdir()) == ["earlier", "notes.txt"]

    assert main(["run", FORWARD, "-o", str(out), *SMALL, "--force"]) == 0
    assert_user_files(out)
    assert (out / "color.png").exists() and (out / "color.npy").exists()
    # every picture it wrote is listed, the contact sheet too
    listed = capsys.readouterr().out
    assert str(out / "color.png") in listed and str(out / "contact_sheet.png") in listed
    assert (out / "contact_sheet.png").exists()
    assert (out / MANIFEST).exists()
    # the folder is pipegen's now: a re-run needs no --force and still keeps the user's files
    first = (out / "color.npy").stat().st_mtime_ns
    assert main(["run", FORWARD, "-o", str(out), *SMALL]) == 0
    assert_user_files(out)
    assert (out / "color.npy").stat().st_mtime_ns >= first


@pytest.mark.gl
def test_run_into_a_parent_of_earlier_results_keeps_them(tmp_path):
    """docs/cli.md's ``-o out/`` after ``-o out/forward``: the earlier result survives."""
    out = tmp_path / "out"
    assert main(["run", FORWARD, "-o", str(out / "forward"), *SMALL]) == 0
    before = {p.name: p.read_bytes() for p in (out / "forward").iterdir()}
    assert main(["run", FORWARD, "-o", str(out), *SMALL]) == 0
    assert {p.name: p.read_bytes() for p in (out / "forward").iterdir()} == before
    assert (out / "color.png").exists()


@pytest.mark.gl
def test_run_removes_only_its_own_stale_outputs(tmp_path):
    out = tmp_path / "out"
    deferred = str(ROOT / "pipelines/deferred.pipe")
    assert main(["run", deferred, "-o", str(out), *SMALL]) == 0
    deferred_only = {p.name for p in out.iterdir()} - {"color.png", "color.npy", "ds.png",
                                                      "ds.npy", "ds.stencil.png",
                                                      "ds.stencil.npy", "contact_sheet.png",
                                                      MANIFEST}
    assert deferred_only, "deferred writes G-buffer targets forward does not"
    (out / "notes.txt").write_text("keep")
    assert main(["run", FORWARD, "-o", str(out), *SMALL]) == 0
    names = {p.name for p in out.iterdir()}
    assert not (deferred_only - {"notes.txt"}) & names, "stale outputs of the earlier run go"
    assert (out / "notes.txt").read_text() == "keep"


def test_compile_keeps_check_output_and_user_files(tmp_path, capsys):
    build = tmp_path / "build"
    check_dir = build / "check" / "forward"
    # what `pipegen check` leaves: a folder with its own manifest
    from pipegen.core.outdir import OutputDir
    with OutputDir(check_dir, "check").staging() as tmp:
        (tmp / "error_color.png").write_bytes(b"png")
    assert main(["compile", FORWARD, "-o", str(build)]) == 0      # no --force needed
    assert (check_dir / "error_color.png").read_bytes() == b"png"
    assert (build / "report.txt").exists() and (build / "gl").is_dir()

    (build / "notes.txt").write_text("keep")
    assert main(["compile", FORWARD, "-o", str(build), "--backend", "gl"]) == 0
    assert not (build / "cl").exists(), "the earlier compile's CL files are pipegen's: removed"
    assert (build / "notes.txt").read_text() == "keep"
    assert (check_dir / "error_color.png").read_bytes() == b"png"

    other = tmp_path / "other"
    user_files(other)
    capsys.readouterr()
    assert main(["compile", FORWARD, "-o", str(other)]) == 1
    assert "did not write" in capsys.readouterr().err
    assert main(["compile", FORWARD, "-o", str(other), "--force"]) == 0
    assert_user_files(other)
    assert (other / "report.txt").exists()


@pytest.fixture
def gl_as_cl(monkeypatch):
    """``check`` with the GL pipeline standing in for CL: this tests only the output folder."""
    real = pipegen.compiler.driver.Compiled.pipeline
    monkeypatch.setattr(pipegen.compiler.driver.Compiled, "pipeline",
                        lambda self, backend="gl", size=None: real(self, "gl", size))


@pytest.mark.gl
def test_check_keeps_user_files_and_needs_force_for_a_foreign_folder(tmp_path, capsys,
                                                                     gl_as_cl):
    out = tmp_path / "check"
    user_files(out)
    scene = str(ROOT / "examples/scenes/small.toml")
    assert main(["check", FORWARD, "--scene", scene, "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "did not write" in err and "rendering" not in err
    assert main(["check", FORWARD, "--scene", scene, "-o", str(out), "--force"]) == 0
    assert_user_files(out)
    assert (out / "error_color.png").exists()
    assert main(["check", FORWARD, "--scene", scene, "-o", str(out)]) == 0
    assert_user_files(out)


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if anything is compiled or rendered."""
    def refuse(*a, **k):
        raise AssertionError("work was done before the output folder was checked")
    monkeypatch.setattr(pipegen.compiler.driver, "compile_file", refuse)
    monkeypatch.setattr(pipegen.compiler.driver.Compiled, "pipeline", refuse)


@pytest.mark.parametrize("command", ["run", "compile", "check"])
def test_output_path_that_is_a_file_is_an_error_before_any_work(tmp_path, capsys, no_work,
                                                                command):
    f = tmp_path / "f"
    f.write_text("a file")
    assert main([command, FORWARD, "-o", str(f)]) == 1
    err = capsys.readouterr().err
    assert "is a file, not a folder" in err and "Traceback" not in err
    assert f.read_text() == "a file"
    assert main([command, FORWARD, "-o", str(f / "sub")]) == 1
    assert "not a folder" in capsys.readouterr().err
    assert main([command, FORWARD, "-o", "/proc/nope/x"]) == 1
    assert "cannot create output folder" in capsys.readouterr().err


def test_bad_output_path_through_the_real_command_fails_before_rendering(tmp_path):
    f = tmp_path / "f"
    f.write_text("a file")
    for out in (str(f), "/proc/nope/x"):
        proc = subprocess.run([sys.executable, "-m", "pipegen.cli", "run", FORWARD, "-o", out],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 1, proc.stderr
        assert "Traceback" not in proc.stderr and proc.stderr.startswith("error: ")
        assert "rendering" not in proc.stderr, "no render may happen"


LONG = """\
technique long "a technique with names as long as the language allows"
lights[8] {{ position: vec3, radius: float, color: vec3 }}
target {t} : rgba8 clear (0, 0, 0, 1)
target ds : d24s8 clear depth 1.0 stencil 0
output {t}
pass {p} {{
  draw scene.opaque
  writes {t}
  depth ds less write
  fragment {{
    {t} = vec4(albedo, 1.0);
  }}
}}
"""


@pytest.mark.gl
def test_pass_and_target_names_of_300_characters_give_files(tmp_path, capsys):
    src = tmp_path / "long.pipe"
    src.write_text(LONG.format(t="t" * 300, p="p" * 300))
    assert main(["compile", str(src), "-o", str(tmp_path / "build")]) == 0
    for backend, suffixes in (("gl", {".vert", ".frag"}), ("cl", {".cl"})):
        files = [f for f in (tmp_path / "build" / backend).iterdir()
                 if not f.name.startswith("prelude")]         # the CL prelude the pass includes
        assert {f.suffix for f in files} == suffixes
        assert all(f.name.startswith("01_ppp") and len(f.name) <= 130 for f in files)
    assert main(["run", str(src), "-o", str(tmp_path / "out"), *SMALL]) == 0
    pngs = [p for p in (tmp_path / "out").iterdir() if p.name.startswith("ttt")]
    assert {p.suffix for p in pngs} == {".png", ".npy"}
    arr = np.load(next(p for p in pngs if p.suffix == ".npy"))
    assert arr.shape == (36, 64, 4)
    printed = capsys.readouterr().out
    assert any(line.strip() == str(p) for p in pngs for line in printed.splitlines())


def test_failed_compile_leaves_the_previous_outputs_byte_for_byte(tmp_path, capsys):
    build = tmp_path / "build"
    assert main(["compile", FORWARD, "-o", str(build)]) == 0
    before = {p: p.read_bytes() for p in build.rglob("*") if p.is_file()}
    bad = tmp_path / "bad.pipe"
    bad.write_text(Path(FORWARD).read_text().replace("normalize(normal)", "normalize(nrml)"))
    (tmp_path / "common").symlink_to(ROOT / "pipelines" / "common")
    assert main(["compile", str(bad), "-o", str(build)]) == 1
    assert "nrml" in capsys.readouterr().err
    assert {p: p.read_bytes() for p in build.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.pipe", "build", "common"]
