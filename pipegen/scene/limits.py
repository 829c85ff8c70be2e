"""Bounds on what a scene file may ask of the loaders: scene files come from elsewhere, and a
malformed or hostile one must end in a located ``PipegenError``, never in a traceback, a hang
or an allocation without bound.  ``docs/scenes.md`` ("Limits") lists each limit, why it is
what it is and the error it gives.

The shipped scenes, and the real Dabrovic Sponza split 4x (224k triangles, a 9.7 MB OBJ
file), are far inside every limit.  Two are the size of the user's content rather than of
its structure, so they can be raised from the environment::

    PIPEGEN_SCENE_MAX_BYTES=1073741824     # MAX_FILE_BYTES
    PIPEGEN_SCENE_MAX_ELEMENTS=16777216    # MAX_ELEMENTS

The others bound structure no real file needs (nesting, corners of one face) and are fixed.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path
from typing import Optional

from pipegen.core.diagnostics import PipegenError
from pipegen.core.sources import MAX_SOURCE_BYTES

#: Largest OBJ, MTL, .gltf, .glb or glTF buffer file, and largest ``byteLength`` of a glTF
#: buffer (a ``data:`` URI sits inside the .gltf file, so the same bound holds for it): 26x
#: the 4x Sponza OBJ.  Reading a file costs a few times its size in memory.
DEFAULT_MAX_FILE_BYTES = 256 << 20
#: Largest count of one glTF accessor, and of the ``v``/``vn`` records, face corners and
#: triangles of one OBJ file: 6x the 672k corners of the 4x Sponza.  The loaders' arrays are
#: float64 rows, so a mesh this size takes a few hundred MiB while it is read.
DEFAULT_MAX_ELEMENTS = 1 << 22
#: Corners of one OBJ face (a polygon is cut into a fan of corners - 2 triangles): exporters
#: write triangles and quads, CAD files a few dozen corners now and then.
MAX_FACE_CORNERS = 1024

# items in one top-level glTF array (nodes, meshes, accessors, ...): pipegen renders at most 255
# objects, and pygltflib takes about a millisecond per node (10^6 nodes: 20 minutes)
MAX_ITEMS = 4096
#: Brackets and braces open at once in a TOML scene or a glTF document, and levels of tables a
#: TOML scene's dotted keys make.  tomllib and json recurse once or more per level and raise
#: RecursionError past about 330 (TOML arrays) or 1000 (JSON) levels: this stops well short
#: of that, wherever in a program's stack the loader runs.  A scene needs 3 levels, a glTF
#: file about 6 (more in ``extras``).
MAX_NESTING = 64
#: (corner, face) pairs an OBJ file's normal smoothing may compare around vertices on a crease
#: (valence² each; the 4x Sponza has 3.5M pairs around all its vertices) and of triangles
#: sharing an edge (a few seconds at the limit), and pairs held at once (about 100 bytes
#: each): a vertex shared by more than 2048 faces cannot be on a crease.
MAX_SMOOTHING_PAIRS = 1 << 24
SMOOTHING_BATCH_PAIRS = 1 << 22
#: A TOML scene file: it lists objects and lights (at most 255 objects), its meshes live in
#: OBJ or glTF files.  The same bound as a ``.pipe`` source.
MAX_TOML_BYTES = MAX_SOURCE_BYTES
#: Characters of a value the file wrote that an error message quotes.
MAX_QUOTED = 80


def _from_env(name: str, default: int) -> int:
    raw = os.environ.get(name)
    if raw is None or raw == "":
        return default
    try:
        value = int(raw)
    except ValueError:
        value = 0
    if value <= 0:
        raise PipegenError(None, f"{name}={raw!r} is not a positive integer")
    return value


def max_file_bytes() -> int:
    """:data:`DEFAULT_MAX_FILE_BYTES`, or ``$PIPEGEN_SCENE_MAX_BYTES``."""
    return _from_env("PIPEGEN_SCENE_MAX_BYTES", DEFAULT_MAX_FILE_BYTES)


def max_elements() -> int:
    """:data:`DEFAULT_MAX_ELEMENTS`, or ``$PIPEGEN_SCENE_MAX_ELEMENTS``."""
    return _from_env("PIPEGEN_SCENE_MAX_ELEMENTS", DEFAULT_MAX_ELEMENTS)


class UnreadableFile(OSError):
    """A path a loader will not read: not a regular file, or too large."""


def read_file(path: str | Path, limit: int, nbytes: Optional[int] = None) -> bytes:
    """The bytes of ``path``, a regular file (a device, FIFO or folder is refused before it
    is opened: ``/dev/zero`` would read forever): all of them, at most ``limit``, or with
    ``nbytes`` only the first ``nbytes``.  ``OSError`` (``UnreadableFile`` among them, its
    ``strerror`` says why) when it cannot be read."""
    st = os.stat(path)
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(21, "Is a directory", str(path))
    if not stat.S_ISREG(st.st_mode):
        raise UnreadableFile(0, "not a regular file", str(path))
    if nbytes is None and st.st_size > limit:
        raise UnreadableFile(0, too_large(st.st_size, limit), str(path))
    with open(path, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):        # replaced since the stat
            raise UnreadableFile(0, "not a regular file", str(path))
        data = f.read(limit + 1 if nbytes is None else nbytes)
    if len(data) > limit:                                          # grew since the stat
        raise UnreadableFile(0, too_large(len(data), limit), str(path))
    return data


def too_large(size: int, limit: int) -> str:
    return (f"{size_text(size)}, more than the limit of {size_text(limit)} "
            "(PIPEGEN_SCENE_MAX_BYTES raises it)")


def size_text(n: int) -> str:
    """``n`` bytes for a message: ``256 MiB``, ``4.0 KiB``, ``12 bytes``."""
    if n >= 1 << 20:
        return f"{n / (1 << 20):g} MiB"
    if n >= 1 << 10:
        return f"{n / (1 << 10):.1f} KiB"
    return f"{n} bytes"


def quoted(text: str | bytes) -> str:
    """At most about :data:`MAX_QUOTED` characters of ``text`` for a message: its start and
    its end around the count of characters left out (a 10^9-digit index, a long line)."""
    if isinstance(text, bytes):
        text = text.decode(errors="replace")
    if len(text) <= MAX_QUOTED:
        return text
    return f"{text[:MAX_QUOTED - 30]} ...{len(text) - MAX_QUOTED + 10} more... {text[-24:]}"


_JSON_SPECIAL = re.compile(r'["\[\]{}]')
_TOML_TOKENS = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"[^"\\\n]*(?:\\.[^"\\\n]*)*"'
                          r"|'[^'\n]*'|#[^\n]*|[\[\]{}]")


def nesting_depth(text: str, toml: bool = False, limit: int = MAX_NESTING) -> tuple[int, int]:
    """How deep ``[`` and ``{`` nest in JSON (or with ``toml``, TOML) text outside its strings
    and comments - how deep a recursive parser would descend - up to ``limit + 1`` (the scan
    stops there), and the offset of the bracket that reached that depth.  No recursion, and a
    JSON string is skipped with ``str.find`` (a 100 MB ``data:`` URI in milliseconds).
    Brackets after a string left open are not counted in JSON and are in TOML (the file is
    malformed either way)."""
    depth = deepest = at = 0
    i, pattern = 0, _TOML_TOKENS if toml else _JSON_SPECIAL
    while deepest <= limit:
        m = pattern.search(text, i)
        if m is None:
            break
        start, i = m.start(), m.end()
        c = text[start]                     # not m.group(): a string may be megabytes long
        if c in "[{":
            depth += 1
            if depth > deepest:
                deepest, at = depth, start
        elif c in "]}":
            depth = max(0, depth - 1)
        elif c == '"' and not toml:
            i = _json_string_end(text, i)
            if i < 0:
                break
    return deepest, at


def _json_string_end(text: str, i: int) -> int:
    """The offset after the quote closing the JSON string whose text starts at ``i``, or -1."""
    while True:
        k = text.find('"', i)
        if k < 0:
            return -1
        slashes = k - len(text[i:k].rstrip("\\")) if text[k - 1] == "\\" else 0
        if slashes % 2 == 0:
            return k + 1
        i = k + 1
