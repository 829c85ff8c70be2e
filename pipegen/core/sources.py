"""Reading ``.pipe`` files and finding included ones.

A source file is a regular file (not a directory, device, FIFO…) of at most
``MAX_SOURCE_BYTES``, in UTF-8; anything else is a ``PipegenError`` (located at the offending
byte for bad UTF-8), never an unbounded read.

``include "PATH"`` is looked up, in order:

1. relative to the folder of the including file (an absolute PATH is taken as it is);
2. in the library shipped with pipegen (``pipelines/common`` in the repository, the package
   ``pipegen.library`` once installed), whose files are included as ``common/NAME.pipe``;
3. in each folder of ``$PIPEGEN_PATH`` (separated by ``os.pathsep``).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Optional

from pipegen.core.diagnostics import PipegenError, Span

MAX_SOURCE_BYTES = 1 << 20          # 1 MiB: the shipped techniques are under 10 KiB
LIBRARY_PREFIX = "common/"          # how techniques name the library's files


class NotASourceFile(OSError):
    """The path exists but is not something a technique may include or be read from."""


def read_source(path: str) -> str:
    """The text of the source file ``path``.  Raises ``FileNotFoundError`` when there is no
    such file, another ``OSError`` when it cannot be read, is not a regular file or is too
    large, and ``PipegenError`` at the first bad byte when it is not UTF-8."""
    if "\0" in path:
        raise NotASourceFile(0, "the path contains a NUL character")
    try:
        st = os.stat(path)
    except NotADirectoryError:
        raise FileNotFoundError(2, "No such file or directory") from None
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(21, "Is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise NotASourceFile(0, "not a regular file")
    if st.st_size > MAX_SOURCE_BYTES:
        raise NotASourceFile(0, f"larger than {MAX_SOURCE_BYTES >> 20} MiB")
    with open(path, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):   # replaced since the stat
            raise NotASourceFile(0, "not a regular file")
        data = f.read(MAX_SOURCE_BYTES + 1)
    if len(data) > MAX_SOURCE_BYTES:
        raise NotASourceFile(0, f"larger than {MAX_SOURCE_BYTES >> 20} MiB")
    return decode(data, path)


def decode(data: bytes, filename: str) -> str:
    """UTF-8 bytes as text (a BOM is dropped); a ``PipegenError`` at the first bad byte."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        text = data.decode("utf-8", errors="replace")
        good = data[:e.start].decode("utf-8")       # what precedes the bad byte is valid
        span = Span.at_offset(filename, text, len(good))
        raise PipegenError(span, f"the file is not valid UTF-8 (byte 0x{data[e.start]:02x})",
                           "save it as UTF-8") from None


def library_dir() -> Optional[Path]:
    """The folder of the shipped library: the installed package ``pipegen.library``, or
    ``pipelines/common`` of a source checkout."""
    import importlib.util
    try:
        spec = importlib.util.find_spec("pipegen.library")
    except (ImportError, ValueError):
        spec = None
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        if os.path.isdir(location):
            return Path(location)
    repo = Path(__file__).resolve().parents[2] / "pipelines" / "common"
    return repo if repo.is_dir() else None


def search_path() -> list[str]:
    """The folders of ``$PIPEGEN_PATH``, in order (empty entries skipped)."""
    return [p for p in os.environ.get("PIPEGEN_PATH", "").split(os.pathsep) if p]


def include_candidates(include: str, including_file: str) -> list[tuple[str, str]]:
    """Where ``include "INCLUDE"`` in ``including_file`` may be, in search order:
    ``[(path, what the place is), …]``."""
    out = [(os.path.normpath(os.path.join(os.path.dirname(including_file), include)),
            "next to the including file")]
    if os.path.isabs(include):
        return out
    relative = include.replace("\\", "/")
    lib = library_dir()
    if lib is not None and relative.startswith(LIBRARY_PREFIX):
        out.append((os.path.normpath(os.path.join(lib, relative[len(LIBRARY_PREFIX):])),
                    "the pipegen library"))
    for folder in search_path():
        out.append((os.path.normpath(os.path.join(folder, include)), "PIPEGEN_PATH"))
    return out
