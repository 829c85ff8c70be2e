"""Code that pipegen generates and compiles at run time, kept compiled across processes.

``records`` writes each record class's ``__init__`` as source text and compiles it the first
time the class is instantiated: about 70 classes in one ``pipegen compile``, 2-3 % of a
fresh process (``benchmarks/compile_time.py --against``, best of 5: deferred_calver 0.254 ->
0.249 s, lidr_shadow_prepass 0.249 -> 0.242 s; 1.5 % of its instructions by callgrind: the
first calls of Python's compiler also wait for its code and data to reach the caches).  The
compiled code depends only on the text and the interpreter, so it is kept in the user's cache folder
(``package_files.cache_dir``), in one file of ``{source text: code object}`` (``marshal``)
per bytecode version, read once on first use; a process that compiled something new writes
the file again when it exits (atomically; concurrent writers: the last one's set wins,
which only costs the other's entries a compile next time).

The file holds code, so it is read only when the folder and the file are the user's own
and writable by no one else (``package_files.load_cached``), as Python's own ``.pyc`` files
and the compiled templates; with no usable cache folder every text is compiled each time.
"""

from __future__ import annotations

import os
from types import CodeType
from typing import Optional

#: Most texts kept: pipegen's own record classes are ~170, so this only bounds a file that
#: something else filled.
MAX_ENTRIES = 2048

_codes: Optional[dict] = None      # source text -> code, once the cache file has been read
_added = False                     # a text compiled in this process, not yet in the file


def compiled(source: str) -> CodeType:
    """``compile(source, "<string>", "exec")``, from the cache when it holds the text."""
    global _codes, _added
    if _codes is None:
        _codes = _load()
    code = _codes.get(source)
    if code is None:
        code = compile(source, "<string>", "exec")
        if len(_codes) < MAX_ENTRIES:
            _codes[source] = code
            if not _added and _cache_file() is not None:
                import atexit
                atexit.register(_save)
            _added = True
    return code


def _cache_file() -> Optional[str]:
    from importlib.util import MAGIC_NUMBER
    from pipegen.core.package_files import cache_dir
    base = cache_dir()
    if base is None:
        return None
    return os.path.join(base, "code", f"code-{MAGIC_NUMBER.hex()}.marshal")


def _load() -> dict:
    import marshal
    from pipegen.core.package_files import load_cached
    path = _cache_file()
    codes = load_cached(path, marshal.load) if path else None
    if not isinstance(codes, dict) or not all(
            type(k) is str and type(v) is CodeType for k, v in codes.items()):
        return {}
    return codes


def _save() -> None:
    """Write the texts compiled so far (at exit, when this process added any)."""
    import marshal
    from pipegen.core.package_files import save_cached
    path = _cache_file()
    if path and _codes:
        save_cached(dict(_codes), path, marshal.dump)
