"""Files the package ships (the grammar, the templates) and the user's cache folder, where
the built parser (``syntax_tree``), the syntax trees of parsed files (``syntax``) and compiled
templates (``backends.templating``) are kept.  Imports neither lark nor numpy."""

from __future__ import annotations

import os
import sys
from typing import Callable, Optional


def package_text(package: str, name: str) -> Optional[str]:
    """The text (UTF-8) of file ``name`` shipped in ``package``, None when there is none.
    Read from the package's folder; only a package that is not a folder (a zip) goes
    through ``importlib.resources``, whose imports cost a compile several milliseconds."""
    import importlib.util
    # found, not imported: a data package needs no code run, only its folder
    spec = importlib.util.find_spec(package)
    folders = list(spec.submodule_search_locations or ()) if spec else []
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


def grammar_text() -> str:
    text = package_text("pipegen.grammar", "pipe.lark")
    if text is None:
        raise FileNotFoundError("pipe.lark is missing from pipegen.grammar")
    return text


def cache_dir() -> Optional[str]:
    """The user's pipegen cache folder (the built parser, syntax trees, compiled templates):
    ``$PIPEGEN_CACHE_DIR`` (empty: no cache), else ``$XDG_CACHE_HOME/pipegen``, else
    ``~/.cache/pipegen`` (``%LOCALAPPDATA%\\pipegen\\cache`` on Windows).  None when there is
    no usable home."""
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


def owned_privately(st: os.stat_result) -> bool:
    """Owned by this user and writable by nobody else (POSIX); unpickling a file someone else
    could have written would run their code."""
    if not hasattr(os, "getuid"):
        return True
    import stat
    return st.st_uid == os.getuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def load_cached(path: str, load: Callable):
    """``load(file)`` of a cache file, or None when it is missing, unsafe to unpickle or
    unreadable."""
    try:
        if not (owned_privately(os.stat(os.path.dirname(path))) and owned_privately(os.stat(path))):
            return None
        with open(path, "rb") as f:
            return load(f)
    except Exception:      # missing, truncated, from another lark: build it again
        return None


def save_cached(obj, path: str, save: Callable) -> None:
    """``save(obj, file)`` into the cache file ``path``, atomically (a temporary file renamed
    over the target), so that concurrent processes never read a partial file."""
    import tempfile
    folder = os.path.dirname(path)
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        if not owned_privately(os.stat(folder)):
            return
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=folder)
        try:
            with os.fdopen(fd, "wb") as f:
                save(obj, f)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
    except Exception:      # read-only or full disk, races with another process: not cached
        pass
