"""The built LALR parser is kept in the user's cache folder and loaded from there, and so is
the syntax tree of every file parsed; a missing, corrupt, foreign or unwritable cache only
costs a rebuild (or a parse), never an error, and never a tree from other text or another
front end."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from lark import Lark

from pipegen.core import package_files
from pipegen.frontend import parse as syntax, syntax_tree
from pipegen.core.diagnostics import PipegenError

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
    return syntax_tree.lalr_parser.__wrapped__()      # bypass the per-process functools.cache


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
        assert package_files.cache_dir() == str(tmp_path / "pipegen")


# -- parsed files ---------------------------------------------------------------------------------


def spans(node) -> list:
    """Every node's type and span, depth first (``==`` on AST nodes ignores spans)."""
    import dataclasses
    out = []

    def visit(x):
        if isinstance(x, (list, tuple)):
            for v in x:
                visit(v)
        elif dataclasses.is_dataclass(x) and not isinstance(x, type):
            span = getattr(x, "span", None)
            out.append((type(x).__name__, span and (span.file, span.line, span.column,
                                                   span.end_line, span.end_column)))
            for f in dataclasses.fields(x):
                if f.name != "span":
                    visit(getattr(x, f.name))
    visit(node)
    return out


@pytest.fixture
def parses(monkeypatch):
    """Counts texts actually parsed (a syntax tree loaded from the cache is not)."""
    count = []
    real = syntax._parse

    def counting(text, filename):
        count.append(filename)
        return real(text, filename)

    monkeypatch.setattr(syntax, "_parse", counting)
    return count


def ast_files(folder: Path) -> list[Path]:
    return sorted((folder / "ast").glob("ast-*.pickle"))


def test_a_parsed_file_is_loaded_the_next_time_with_the_same_tree_and_spans(
        tmp_path, monkeypatch, parses):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path))
    for path in SOURCES:
        text = path.read_text()
        fresh = syntax.parse(text, str(path))
        again = syntax.parse(text, str(path))
        assert again is not fresh and again == fresh, path
        assert spans(again) == spans(fresh), path
        assert again.span.text == text
    assert len(parses) == len(SOURCES), "a cached file was parsed again"
    assert len(ast_files(tmp_path)) == len(SOURCES)
    if hasattr(os, "getuid"):
        assert stat.S_IMODE((tmp_path / "ast").stat().st_mode) & 0o077 == 0


def test_another_text_or_file_name_is_parsed(tmp_path, monkeypatch, parses):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path))
    text = (ROOT / "pipelines/forward.pipe").read_text()
    a = syntax.parse(text, "a.pipe")
    b = syntax.parse(text, "b.pipe")
    c = syntax.parse(text + "\n// edited\n", "a.pipe")
    assert len(parses) == 3
    assert (a.span.file, b.span.file) == ("a.pipe", "b.pipe")
    assert c == a


def test_a_change_to_the_front_end_starts_afresh(tmp_path, monkeypatch, parses):
    """The key covers the grammar and the front end's code: an edit there (here simulated)
    never loads a tree built by the old code."""
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path))
    text = (ROOT / "pipelines/forward.pipe").read_text()
    syntax.parse(text, "f.pipe")
    monkeypatch.setattr(syntax, "_front_end_key", lambda: b"another front end")
    syntax.parse(text, "f.pipe")
    assert len(parses) == 2


def test_syntax_errors_are_not_cached(tmp_path, monkeypatch, parses):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path))
    for _ in range(2):
        with pytest.raises(PipegenError, match="unexpected"):
            syntax.parse("technique t \"x\"\npass p { draw }\n", "bad.pipe")
    assert len(parses) == 2
    assert not ast_files(tmp_path)


def test_a_corrupt_or_foreign_tree_file_is_parsed_again(tmp_path, monkeypatch, parses):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path))
    text = (ROOT / "pipelines/forward.pipe").read_text()
    expected = syntax.parse(text, "f.pipe")
    [saved] = ast_files(tmp_path)
    saved.write_bytes(saved.read_bytes()[:500])
    assert syntax.parse(text, "f.pipe") == expected
    import pickle
    saved.write_bytes(pickle.dumps(["not", "a", "module"]))
    assert syntax.parse(text, "f.pipe") == expected
    assert len(parses) == 3
    assert syntax.parse(text, "f.pipe") == expected
    assert len(parses) == 3, "the re-parsed tree was not saved again"


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX permissions")
def test_tree_files_others_can_write_are_not_trusted(tmp_path, monkeypatch, parses):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path))
    text = (ROOT / "pipelines/forward.pipe").read_text()
    syntax.parse(text, "f.pipe")
    [saved] = ast_files(tmp_path)
    saved.chmod(0o666)
    syntax.parse(text, "f.pipe")
    assert len(parses) == 2, "a tree others could have written was unpickled"


def test_the_tree_cache_keeps_the_most_recent_files(tmp_path, monkeypatch):
    monkeypatch.setenv("PIPEGEN_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(syntax, "AST_CACHE_FILES", 3)
    for i in range(6):
        syntax.parse(f"technique t{i} \"x\"\n", f"t{i}.pipe")
        path = syntax._ast_cache_file(f"technique t{i} \"x\"\n", f"t{i}.pipe")
        os.utime(path, (1000 + i, 1000 + i))        # written in this order
    kept = ast_files(tmp_path)
    assert len(kept) == 3
    newest = {Path(syntax._ast_cache_file(f"technique t{i} \"x\"\n", f"t{i}.pipe")).name
              for i in (3, 4, 5)}
    assert {p.name for p in kept} == newest
