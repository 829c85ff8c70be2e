"""Parsing: ``.pipe`` text -> ``ast.Module`` (grammar in ``grammar/pipe.lark``).

The grammar is LALR(1) with lark's contextual lexer; the parser is built once per process.  Parse
errors become ``PipegenError``s that name what was found and, in the user's words, what could
have come there instead, e.g. ``unexpected number '1.0'; expected ',' or ')'``.

This module is ``parse`` and the cache of the syntax tree of every text parsed; the lark half
(the parser, built once and kept in the user's cache folder; the parse tree turned into ``ast``
nodes; the syntax errors) is ``syntax_tree.py``, imported only when a text is not in the
cache.  The cache folder and the shipped grammar are ``package_files``'.
"""

from __future__ import annotations

import functools
import os
import sys
from typing import Optional

from pipegen.frontend import ast
from pipegen.core.package_files import cache_dir, grammar_text, load_cached, save_cached


def parse(text: str, filename: str = "<string>") -> ast.Module:
    """Parse one ``.pipe`` file (or a packing scheme's generated functions).

    A text parsed before, under the same file name, grammar and front-end code, is loaded
    from the user's cache folder instead (``_ast_cache_file``): a few milliseconds, where
    loading the parser and parsing take tens (every technique includes the library's
    ``common/lighting.pipe``).  Errors are never cached: a text that fails is parsed again."""
    path = _ast_cache_file(text, filename)
    if path is not None:
        module = load_cached(path, _load_ast)
        if module is not None:
            return module
    module = _parse(text, filename)
    if path is not None:
        _save_ast(module, path)
    return module


def _parse(text: str, filename: str) -> ast.Module:
    """Parse with lark (``syntax_tree.parse_tree``): imported only here, so that a compile whose
    syntax trees are all cached never imports lark."""
    from pipegen.frontend.syntax_tree import parse_tree
    return parse_tree(text, filename)


# ---------------------------------------------------------------------------------------------
# Parsed files, cached on disk
# ---------------------------------------------------------------------------------------------

_CACHE_FORMAT = "1"          # bump when what is written to the cache changes

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
    ``syntax_tree.py`` (the parser and the transformer), ``expect_syntax.py`` (an expectation's
    words), ``ast.py``, ``diagnostics.py`` and ``records.py`` (the node and span classes) as
    they are on disk, lark's ``__init__.py`` (its version) and Python's version.
    Any edit to them starts a fresh set of cache files.  None when a source cannot be read
    (then nothing is cached).  Neither lark nor the transformer is imported for it."""
    import hashlib
    import importlib.util
    h = hashlib.sha256()
    h.update("\0".join([_CACHE_FORMAT, "%d.%d" % sys.version_info[:2],
                        grammar_text()]).encode("utf-8"))
    try:
        sources = [importlib.util.find_spec(name).origin
                   for name in ("lark", "pipegen.frontend.syntax_tree", "pipegen.frontend.parse", "pipegen.frontend.ast",
                                "pipegen.frontend.expect_syntax",
                                "pipegen.core.diagnostics", "pipegen.core.records")]
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
    save_cached(module, path, lambda m, f: pickle.dump(m, f, protocol=pickle.HIGHEST_PROTOCOL))
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
