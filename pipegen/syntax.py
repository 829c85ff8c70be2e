"""Parsing: ``.pipe`` text -> ``ast.Module`` (grammar in ``grammar/pipe.lark``).

The grammar is LALR(1) with lark's contextual lexer; the parser is built once per process.  Parse
errors become ``PipegenError``s that name what was found and, in the user's words, what could
have come there instead, e.g. ``unexpected number '1.0'; expected ',' or ')'``.

This module is ``parse`` and the caches (the built parser, the syntax tree of every text
parsed); the lark half, the parse tree turned into ``ast`` nodes and the syntax errors, is
``syntax_tree.py``, imported only when a text is not in the cache.
"""

from __future__ import annotations

import functools
import os
import sys
from typing import TYPE_CHECKING, Callable, Optional

from . import ast

if TYPE_CHECKING:
    from lark import Lark

#: How deeply constructs may nest (parse-tree levels: statements, calls, operators; each operator
#: of a chain like a + b + c is a level; parentheses alone are not).  The shipped techniques use at most 13; every later phase walks the tree
#: recursively, so the limit keeps them far from Python's recursion limit.
MAX_NESTING = 100


def parse(text: str, filename: str = "<string>") -> ast.Module:
    """Parse one ``.pipe`` file (or a packing scheme's generated functions).

    A text parsed before, under the same file name, grammar and front-end code, is loaded
    from the user's cache folder instead (``_ast_cache_file``): a few milliseconds, where
    loading the parser and parsing take tens (every technique includes the library's
    ``common/lighting.pipe``).  Errors are never cached: a text that fails is parsed again."""
    path = _ast_cache_file(text, filename)
    if path is not None:
        module = _load_cached(path, _load_ast)
        if module is not None:
            return module
    module = _parse(text, filename)
    if path is not None:
        _save_ast(module, path)
    return module


def _parse(text: str, filename: str) -> ast.Module:
    """Parse with lark (``syntax_tree.parse_tree``): imported only here, so that a compile whose
    syntax trees are all cached never imports lark."""
    from .syntax_tree import parse_tree
    return parse_tree(text, filename)


class _WholeWords:
    """Lexes a name in every parser state, even where no name can follow.

    The contextual lexer offers each state only the terminals it can shift.  Where keywords
    are expected but no name (`depth ds less`), ``lesser`` would lex as the keyword ``less``
    followed by ``er``; with NAME always offered, a word lexes whole and keywords are
    recognised only as whole words (lark turns an exact keyword match of NAME into the
    keyword).  The stream itself passes through unchanged.
    """

    always_accept = ("NAME",)

    def process(self, stream):
        return stream


# ---------------------------------------------------------------------------------------------
# The parser, built once per grammar and cached on disk
# ---------------------------------------------------------------------------------------------

_OPTIONS = dict(parser="lalr", propagate_positions=True, maybe_placeholders=True)
_CACHE_FORMAT = "1"          # bump when what is written to the cache changes


@functools.cache
def _parser() -> Lark:
    """The LALR parser.  Building its tables takes 0.15-0.6 s, so the built parser is kept in
    the user's cache folder (``cache_dir()``) and loaded from there (about 20 ms) by every
    later process with the same grammar, lark and Python.  A missing, unreadable,
    unsafe or stale cache file only means the parser is built again; a read-only install or
    cache folder only means it is not saved."""
    from lark import Lark
    grammar = _grammar_text()
    folder = cache_dir()
    path = _cache_file(folder, grammar) if folder is not None else None
    if path is not None:
        parser = _load_cached(path)
        if parser is not None:
            return parser
    parser = Lark(grammar, postlex=_WholeWords(), **_OPTIONS)
    if path is not None:
        _save_cached(parser, path)
    return parser


def _grammar_text() -> str:
    text = package_text("pipegen.grammar", "pipe.lark")
    if text is None:
        raise FileNotFoundError("pipe.lark is missing from pipegen.grammar")
    return text


def package_text(package: str, name: str) -> Optional[str]:
    """The text (UTF-8) of file ``name`` shipped in ``package``, None when there is none.
    Read from the package's folder; only a package that is not a folder (a zip) goes
    through ``importlib.resources``, whose imports cost a compile several milliseconds."""
    import importlib
    module = importlib.import_module(package)
    folders = list(getattr(module, "__path__", ()))
    if folders and all(os.path.isdir(f) for f in folders):
        for folder in folders:
            try:
                with open(os.path.join(folder, name), encoding="utf-8") as f:
                    return f.read()
            except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
                continue
        return None
    import importlib.resources
    res = importlib.resources.files(package).joinpath(name)
    return res.read_text(encoding="utf-8") if res.is_file() else None


def cache_dir() -> Optional[str]:
    """Where the built parser is kept: ``$PIPEGEN_CACHE_DIR`` (empty: no cache), else
    ``$XDG_CACHE_HOME/pipegen``, else ``~/.cache/pipegen`` (``%LOCALAPPDATA%\\pipegen\\cache``
    on Windows).  None when there is no usable home."""
    explicit = os.environ.get("PIPEGEN_CACHE_DIR")
    if explicit is not None:
        return explicit or None
    if sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        return os.path.join(os.environ["LOCALAPPDATA"], "pipegen", "cache")
    base = os.environ.get("XDG_CACHE_HOME") or ""
    if not os.path.isabs(base):
        home = os.path.expanduser("~")
        if not home or home == "~":
            return None
        base = os.path.join(home, ".cache")
    return os.path.join(base, "pipegen")


def _cache_file(folder: str, grammar: str) -> str:
    import hashlib
    import lark
    key = "\0".join([_CACHE_FORMAT, grammar, repr(sorted(_OPTIONS.items())),
                      repr(_WholeWords.always_accept), lark.__version__,
                      "%d.%d" % sys.version_info[:2]])
    return os.path.join(folder, f"parser-{hashlib.sha256(key.encode()).hexdigest()[:32]}.pickle")


def _private(st: os.stat_result) -> bool:
    """Owned by this user and writable by nobody else (POSIX); unpickling a file someone else
    could have written would run their code."""
    if not hasattr(os, "getuid"):
        return True
    import stat
    return st.st_uid == os.getuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def _load_parser(f) -> Lark:
    from lark import Lark
    return Lark.__new__(Lark)._load(f, postlex=_WholeWords())


def _load_cached(path: str, load: Callable = _load_parser):
    """``load(file)`` of a cache file, or None when it is missing, unsafe to unpickle or
    unreadable."""
    try:
        if not (_private(os.stat(os.path.dirname(path))) and _private(os.stat(path))):
            return None
        with open(path, "rb") as f:
            return load(f)
    except Exception:      # missing, truncated, from another lark: build it again
        return None


def _save_parser(parser: Lark, f) -> None:
    parser.save(f, exclude_options={"postlex"})


def _save_cached(obj, path: str, save: Callable = _save_parser) -> None:
    """``save(obj, file)`` into the cache file ``path``, atomically (a temporary file renamed
    over the target), so that concurrent processes never read a partial file."""
    import tempfile
    folder = os.path.dirname(path)
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        if not _private(os.stat(folder)):
            return
        fd, tmp = tempfile.mkstemp(prefix=".parser-", dir=folder)
        try:
            with os.fdopen(fd, "wb") as f:
                save(obj, f)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
    except Exception:      # read-only or full disk, races with another process: not cached
        pass


# ---------------------------------------------------------------------------------------------
# Parsed files, cached on disk
# ---------------------------------------------------------------------------------------------

#: Most syntax trees kept in the cache folder; the least recently written go first.
AST_CACHE_FILES = 400


def _ast_cache_file(text: str, filename: str) -> Optional[str]:
    """Where the syntax tree of ``text`` (named ``filename``: spans carry it) is cached, keyed
    by the text and everything that shapes the tree (``_front_end_key``); None without a
    cache folder."""
    base = cache_dir()
    identity = _front_end_key()
    if base is None or identity is None:
        return None
    import hashlib
    h = hashlib.sha256(identity)
    h.update(filename.encode("utf-8", "surrogatepass") + b"\0")
    h.update(text.encode("utf-8", "surrogatepass"))
    return os.path.join(base, "ast", f"ast-{h.hexdigest()[:40]}.pickle")


@functools.cache
def _front_end_key() -> Optional[bytes]:
    """Digest of what turns text into ``ast`` nodes: the grammar, this module,
    ``syntax_tree.py`` (the transformer), ``ast.py``, ``diagnostics.py`` and ``records.py`` (the
    node and span classes) as they are on disk, lark's ``__init__.py`` (its version) and Python's version.
    Any edit to them starts a fresh set of cache files.  None when a source cannot be read
    (then nothing is cached).  Neither lark nor the transformer is imported for it."""
    import hashlib
    import importlib.util
    h = hashlib.sha256()
    h.update("\0".join([_CACHE_FORMAT, "%d.%d" % sys.version_info[:2],
                        _grammar_text()]).encode("utf-8"))
    try:
        sources = [importlib.util.find_spec(name).origin
                   for name in ("lark", "pipegen.syntax_tree", "pipegen.syntax", "pipegen.ast",
                                "pipegen.diagnostics", "pipegen.records")]
        for path in sources:
            with open(path, "rb") as f:
                h.update(f.read())
    except (OSError, TypeError, AttributeError, ImportError, ValueError):
        return None
    return h.digest()


def _load_ast(f) -> ast.Module:
    import pickle
    module = pickle.load(f)
    if not isinstance(module, ast.Module):
        raise TypeError(f"not a syntax tree: {type(module).__name__}")
    return module


def _save_ast(module: ast.Module, path: str) -> None:
    """Pickle ``module`` (before any caller can change it) and keep the folder small."""
    import pickle
    _save_cached(module, path, lambda m, f: pickle.dump(m, f, protocol=pickle.HIGHEST_PROTOCOL))
    _prune(os.path.dirname(path), AST_CACHE_FILES)


def _prune(folder: str, keep: int) -> None:
    """Delete the least recently written ``ast-*`` files beyond ``keep``."""
    try:
        entries = [e for e in os.scandir(folder) if e.name.startswith("ast-")]
        if len(entries) <= keep:
            return
        entries.sort(key=lambda e: e.stat().st_mtime)
        for e in entries[:len(entries) - keep]:
            os.unlink(e.path)
    except OSError:        # another process pruned first, or the folder went away
        pass
