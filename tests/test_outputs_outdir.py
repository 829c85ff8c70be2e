"""``pipegen.core.outdir.OutputDir``: pipegen never deletes or overwrites a file it did not write; a
failure leaves the previous outputs intact; a foreign non-empty folder is refused unless forced;
a path that cannot be a folder is reported before any work."""

import json
import os

import pytest

from pipegen.core.diagnostics import PipegenError
from pipegen.core.outdir import MANIFEST, OutputDir, foreign_entries, read_manifest, safe_name


def write(out: OutputDir, files: dict[str, str]) -> None:
    with out.staging() as tmp:
        for rel, text in files.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_text(text)


def listing(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                  if p.is_file())


def test_new_folder_is_created_with_a_manifest(tmp_path):
    out = tmp_path / "a" / "b"
    write(OutputDir(out, "test"), {"x.txt": "1", "sub/y.txt": "2"})
    assert listing(out) == [MANIFEST, "sub/y.txt", "x.txt"]
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["command"] == "test"
    assert sorted(manifest["files"]) == ["sub/y.txt", "x.txt"]
    assert not [p for p in tmp_path.rglob("*") if "pipegen-stage" in p.name], "no staging left"


def test_rewrite_replaces_own_files_removes_stale_ones_and_keeps_the_users(tmp_path):
    out = tmp_path / "out"
    write(OutputDir(out, "test"), {"a.txt": "old", "gone.txt": "old", "sub/b.txt": "old"})
    (out / "notes.txt").write_text("keep")
    (out / "sub" / "mine.txt").write_text("keep too")
    write(OutputDir(out, "test"), {"a.txt": "new"})        # owned folder: no --force needed
    assert (out / "a.txt").read_text() == "new"
    assert not (out / "gone.txt").exists() and not (out / "sub" / "b.txt").exists()
    assert (out / "notes.txt").read_text() == "keep"
    assert (out / "sub" / "mine.txt").read_text() == "keep too"
    assert sorted(read_manifest(out)) == ["a.txt"]



def test_rewrite_leaves_unchanged_outputs_as_they_are(tmp_path):
    """A file whose new content is what pipegen wrote there before is not replaced: the same
    inode and mtime (a build tool watching the folder sees only what changed); a changed one
    is replaced, and the manifest lists both."""
    out = tmp_path / "out"
    write(OutputDir(out, "test"), {"same.txt": "1", "edited.txt": "old"})
    before = {n: os.stat(out / n) for n in ("same.txt", "edited.txt")}
    os.utime(out / "same.txt", ns=(1, 1))            # an mtime no rewrite could give it
    write(OutputDir(out, "test"), {"same.txt": "1", "edited.txt": "new"})
    after = os.stat(out / "same.txt")
    assert (after.st_ino, after.st_mtime_ns) == (before["same.txt"].st_ino, 1)
    assert (out / "edited.txt").read_text() == "new"
    assert os.stat(out / "edited.txt").st_ino != before["edited.txt"].st_ino
    assert sorted(read_manifest(out)) == ["edited.txt", "same.txt"]
    assert not [p for p in tmp_path.rglob("*") if "pipegen-stage" in p.name], "no staging left"

def test_stale_folder_of_own_files_is_removed_when_empty(tmp_path):
    out = tmp_path / "out"
    write(OutputDir(out, "test"), {"cl/k.cl": "k", "r.txt": "r"})
    write(OutputDir(out, "test"), {"r.txt": "r2"})
    assert not (out / "cl").exists()


def test_foreign_non_empty_folder_is_refused_and_written_with_force(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("keep")
    with pytest.raises(PipegenError, match="did not write.*notes.txt"):
        OutputDir(out, "test")
    assert listing(out) == ["notes.txt"]
    write(OutputDir(out, "test", force=True), {"a.txt": "1"})
    assert (out / "notes.txt").read_text() == "keep" and (out / "a.txt").read_text() == "1"
    # now pipegen owns the folder: later writes need no --force and still keep notes.txt
    write(OutputDir(out, "test"), {"b.txt": "2"})
    assert listing(out) == [MANIFEST, "b.txt", "notes.txt"]


def test_empty_folder_is_accepted(tmp_path):
    write(OutputDir(tmp_path, "test"), {"a.txt": "1"})
    assert (tmp_path / "a.txt").exists()


def test_user_file_with_an_output_name_is_not_overwritten_without_force(tmp_path):
    out = tmp_path / "out"
    write(OutputDir(out, "test"), {"a.txt": "1"})
    (out / "a.txt").write_text("edited by hand")          # listed, but changed since
    (out / "b.txt").write_text("the user's b")            # not listed
    with pytest.raises(PipegenError, match="overwrite"):
        write(OutputDir(out, "test"), {"a.txt": "2", "b.txt": "2"})
    assert (out / "a.txt").read_text() == "edited by hand"
    assert (out / "b.txt").read_text() == "the user's b"
    write(OutputDir(out, "test", force=True), {"a.txt": "2", "b.txt": "2"})
    assert (out / "b.txt").read_text() == "2"


def test_an_edited_output_is_refused_before_any_work_and_kept_with_force(tmp_path):
    """An output the user edited is refused when the folder is checked (before any work, not
    after rendering: issue 29); with --force, pipegen replaces only what it writes again and
    keeps the edited file it no longer writes."""
    out = tmp_path / "out"
    write(OutputDir(out, "test"), {"a.txt": "1", "b.txt": "1"})
    (out / "b.txt").write_text("edited")
    with pytest.raises(PipegenError, match=r"files pipegen wrote there were changed since "
                                           r"\(b\.txt\); a new run would overwrite them"):
        OutputDir(out, "test")
    write(OutputDir(out, "test", force=True), {"a.txt": "2"})
    assert (out / "b.txt").read_text() == "edited" and (out / "a.txt").read_text() == "2"
    assert sorted(read_manifest(out)) == ["a.txt"]


def test_failure_while_generating_leaves_previous_outputs_intact(tmp_path):
    out = tmp_path / "out"
    write(OutputDir(out, "test"), {"a.txt": "old"})
    before = {p: (out / p).read_bytes() for p in listing(out)}
    with pytest.raises(RuntimeError):
        with OutputDir(out, "test").staging() as tmp:
            (tmp / "a.txt").write_text("half")
            raise RuntimeError("render failed")
    assert {p: (out / p).read_bytes() for p in listing(out)} == before
    assert not [p for p in tmp_path.rglob("*") if "pipegen-stage" in p.name]


def test_failed_first_write_leaves_no_folder(tmp_path):
    out = tmp_path / "new"
    with pytest.raises(RuntimeError):
        with OutputDir(out, "test").staging():
            raise RuntimeError("boom")
    assert not out.exists()
    assert os.listdir(tmp_path) == []


def test_sub_folder_owned_by_another_output_survives_and_is_not_foreign(tmp_path):
    build = tmp_path / "build"
    write(OutputDir(build / "check" / "t", "check"), {"error_color.png": "e"})
    assert foreign_entries(build) == []
    write(OutputDir(build, "compile"), {"report.txt": "r"})        # no --force needed
    write(OutputDir(build, "compile"), {"report.txt": "r2"})
    assert (build / "check" / "t" / "error_color.png").read_text() == "e"


def test_path_that_is_a_file_or_under_a_file_is_refused(tmp_path):
    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(PipegenError, match="is a file, not a folder"):
        OutputDir(f, "test")
    with pytest.raises(PipegenError, match="not a folder"):
        OutputDir(f / "sub", "test")
    with pytest.raises(PipegenError, match="cannot create"):
        OutputDir("/proc/nope/x", "test")
    assert f.read_text() == "x"


def test_safe_name_shortens_long_names_distinctly():
    assert safe_name("01_main", ".frag") == "01_main.frag"
    a, b = safe_name("p" * 300, ".frag"), safe_name("p" * 299 + "q", ".frag")
    assert a != b and a.endswith(".frag") and len(a.encode()) <= 120
    assert safe_name("p" * 300, ".frag") == a
