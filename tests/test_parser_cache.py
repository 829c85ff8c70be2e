"""The built LALR parser is kept in the user's cache folder and loaded from there; a missing,
corrupt, foreign or unwritable cache only costs a rebuild, never an error."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from lark import Lark

from pipegen import syntax

ROOT = Path(__file__).resolve().parents[1]
SOURCES = sorted(ROOT.glob("pipelines/**/*.pipe"))


@pytest.fixture
def builds(monkeypatch):
    """Counts parser constructions (loading from the cache does not construct)."""
    count = []
    real = Lark.__init__

    def counting(self, *args, **kw):
        count.append(1)
        real(self, *args, **kw)

    monkeypatch.setattr(Lark, "__init__", counting)
    return count


def fresh_parser() -> Lark:
    return syntax._parser.__wrapped__()      # bypass the per-process functools.cache


def cached_files(folder: Path) -> list[Path]:
    return sorted(folder.glob("parser-*.pickle"))


def test_the_parser_is_saved_once_and_then_loaded(tmp_path, monkeypatch, builds):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path / "cache"))
    built = fresh_parser()
    assert len(builds) == 1
    [saved] = cached_files(tmp_path / "cache")
    if hasattr(os, "getuid"):
        assert stat.S_IMODE(saved.stat().st_mode) & 0o077 == 0
        assert stat.S_IMODE((tmp_path / "cache").stat().st_mode) & 0o077 == 0
    loaded = fresh_parser()
    assert len(builds) == 1, "the second parser was built, not loaded"
    for path in SOURCES:
        text = path.read_text()
        a, b = loaded.parse(text), built.parse(text)
        assert a == b, path
        assert positions(a) == positions(b), path     # spans come from these


def positions(tree) -> list:
    return [(t.data, t.meta.line, t.meta.column, t.meta.end_line, t.meta.end_column)
            for t in tree.iter_subtrees() if not t.meta.empty]


def test_a_corrupt_cache_file_is_replaced(tmp_path, monkeypatch, builds):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path))
    fresh_parser()
    [saved] = cached_files(tmp_path)
    saved.write_bytes(saved.read_bytes()[:1000])
    parser = fresh_parser()
    assert len(builds) == 2
    assert parser.parse((ROOT / "pipelines/forward.pipe").read_text())
    fresh_parser()
    assert len(builds) == 2, "the rebuilt parser was not saved again"


def test_an_unwritable_cache_folder_only_means_no_cache(tmp_path, monkeypatch, builds):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(blocker / "cache"))
    fresh_parser()
    fresh_parser()
    assert len(builds) == 2
    assert blocker.read_text() == "not a folder"


def test_an_empty_cache_setting_disables_the_cache(tmp_path, monkeypatch, builds):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", "")
    monkeypatch.chdir(tmp_path)
    fresh_parser()
    fresh_parser()
    assert len(builds) == 2
    assert not list(tmp_path.rglob("parser-*"))


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX permissions")
def test_a_cache_others_can_write_is_not_trusted(tmp_path, monkeypatch, builds):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path / "safe"))
    fresh_parser()
    [saved] = cached_files(tmp_path / "safe")
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)
    (shared / saved.name).write_bytes(saved.read_bytes())
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(shared))
    fresh_parser()
    assert len(builds) == 2, "a parser from a world-writable folder was unpickled"


def test_the_default_cache_folder_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.delenv("PIPEGEN_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    if os.name != "nt":
        assert syntax.cache_dir() == str(tmp_path / "pipegen")
