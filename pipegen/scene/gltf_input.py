"""Reading a glTF file as untrusted input: the file itself, the GLB container, the JSON
document and the buffers its URIs name, each within :mod:`pipegen.scene.limits`.

Every error is a :class:`GltfError` whose ``where`` locates it: a byte offset of a ``.glb``
(``byte 12``), a line and column of the JSON text, or a JSON path (``buffers[0].uri``).

- files (the ``.gltf``/``.glb`` and its buffers) must be regular files (not a device, FIFO or
  folder: ``/dev/zero`` would read forever) of at most ``limits.max_file_bytes()``, and a
  buffer file is read only up to its ``byteLength``;
- a buffer URI is a ``data:`` URI or a relative path that stays inside the folder holding the
  glTF file once resolved (``..`` and symbolic links included): a scene from elsewhere cannot
  read ``/etc/passwd`` and render it as geometry;
- the GLB header and chunk lengths must agree with the file's size;
- the JSON may nest at most ``limits.MAX_NESTING`` levels (json recurses), holds no NaN,
  Infinity or number too large for a float, and has the shape of :mod:`gltf_schema`.
"""

from __future__ import annotations

import base64
import binascii
import json
import struct
from pathlib import Path
from typing import Optional
from urllib.parse import unquote, unquote_to_bytes, urlsplit

from pipegen.scene import gltf_schema, limits

GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942
MAX_NUMBER_DIGITS = 40          # longer JSON integers are refused before Python parses them


class GltfError(ValueError):
    """A glTF file pipegen cannot use (malformed, or needing an unsupported extension);
    ``where`` locates the problem in the file (empty when the file as a whole is at fault)."""

    def __init__(self, message: str, where: str = ""):
        super().__init__(f"{where}: {message}" if where else message)
        self.message, self.where = message, where


class _Unreadable(str):
    """A JSON number Python would make inf or refuse (``1e999``, 5000 digits): kept as its
    text, so the schema reports it where it stands ("... is not of type 'number'")."""


def split_glb(data: bytes) -> tuple[bytes, int, Optional[bytes]]:
    """A GLB file's JSON chunk, the offset where it starts and its BIN chunk (None without
    one); chunks of other types are skipped, as the specification asks."""
    if len(data) < 20:
        raise GltfError(f"a .glb file needs a 12-byte header and a chunk, this one has "
                        f"{len(data)} bytes", "byte 0")
    magic, version, length = data[:4], *struct.unpack_from("<II", data, 4)
    if magic != GLB_MAGIC:
        raise GltfError(f"not a binary glTF file (it starts with {magic!r}, not b'glTF')",
                        "byte 0")
    if version != 2:
        raise GltfError(f"GLB version {version}; pipegen reads version 2", "byte 4")
    if length != len(data):
        raise GltfError(f"the header gives a length of {length} bytes, the file has "
                        f"{len(data)}", "byte 8")
    chunks, offset = [], 12
    while offset < length:
        if offset + 8 > length:
            raise GltfError(f"a chunk header needs 8 bytes, {length - offset} are left",
                            f"byte {offset}")
        size, kind = struct.unpack_from("<II", data, offset)
        if offset + 8 + size > length:
            raise GltfError(f"the chunk's length of {size} bytes runs past the end of the file "
                            f"({length - offset - 8} bytes left)", f"byte {offset}")
        chunks.append((kind, offset + 8, data[offset + 8: offset + 8 + size]))
        offset += 8 + size
    if chunks[0][0] != CHUNK_JSON:
        raise GltfError(f"the first chunk has type 0x{chunks[0][0]:08x}, not JSON", "byte 16")
    binary = chunks[1][2] if len(chunks) > 1 and chunks[1][0] == CHUNK_BIN else None
    return chunks[0][2], chunks[0][1], binary


def _text_position(text: str, offset: int, file_offset: Optional[int], raw: bytes) -> str:
    """Where character ``offset`` of the JSON text is: a line and column in a .gltf, a byte
    of the file in a .glb (whose JSON sits at ``file_offset``)."""
    if file_offset is not None:
        return f"byte {file_offset + len(text[:offset].encode())}"
    line = text.count("\n", 0, offset) + 1
    return f"line {line}, column {offset - (text.rfind(chr(10), 0, offset) + 1) + 1}"


def parse_json(raw: bytes, file_offset: Optional[int] = None) -> dict:
    """The glTF JSON document in ``raw`` (UTF-8), checked against :mod:`gltf_schema`.
    ``file_offset``: where ``raw`` starts in a .glb (positions are then bytes of the file)."""
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        at = f"byte {(file_offset or 0) + e.start}"
        raise GltfError(f"the JSON is not valid UTF-8 (byte 0x{raw[e.start]:02x})", at) from None
    depth, at = limits.nesting_depth(text)
    if depth > limits.MAX_NESTING:
        raise GltfError(f"the JSON nests more than {limits.MAX_NESTING} levels of arrays and "
                        "objects", _text_position(text, at, file_offset, raw))

    def number(s: str):
        value = float(s)
        return value if value not in (float("inf"), float("-inf")) else _Unreadable(s)

    def integer(s: str):
        return int(s) if len(s) <= MAX_NUMBER_DIGITS else _Unreadable(s)

    def constant(s: str):
        raise json.JSONDecodeError(f"{s} is not a JSON value", text, text.find(s))

    try:
        document = json.loads(text, parse_float=number, parse_int=integer,
                              parse_constant=constant)
    except json.JSONDecodeError as e:
        raise GltfError(f"invalid JSON: {e.msg}", _text_position(text, e.pos, file_offset, raw)) from None
    if not isinstance(document, dict):
        raise GltfError("the JSON document is not an object", "the document")
    for key in gltf_schema.READ:             # before the schema walks every item
        items = document.get(key)
        if isinstance(items, list) and len(items) > limits.MAX_ITEMS:
            raise GltfError(f"{len(items)} {key}: more than the {limits.MAX_ITEMS} a scene may "
                            f"hold", key)
    problem = gltf_schema.first_error(document)
    if problem is not None:
        raise GltfError(limits.quoted(problem[1]), problem[0])
    return document


def buffer_bytes(uri: Optional[str], byte_length: int, folder: Path, glb_binary: Optional[bytes],
                 where: str) -> bytes:
    """The first ``byte_length`` bytes of a buffer: the GLB's BIN chunk (no ``uri``), a
    ``data:`` URI, or a file inside ``folder``; ``where`` is the buffer's JSON path."""
    limit = limits.max_file_bytes()
    if byte_length > limit:
        raise GltfError(f"the buffer is {limits.too_large(byte_length, limit)}",
                        where + ".byteLength")
    if uri is None:
        if glb_binary is None:
            raise GltfError("the buffer has no uri and the file has no binary chunk", where)
        data = glb_binary
    elif uri.startswith("data:"):
        header, comma, payload = uri.partition(",")
        if not comma:
            raise GltfError("a data: URI needs a comma before its data", where + ".uri")
        try:
            data = (base64.b64decode(payload, validate=True) if header.endswith(";base64")
                    else unquote_to_bytes(payload))
        except (binascii.Error, ValueError) as e:
            raise GltfError(f"cannot decode the data: URI ({e})", where + ".uri") from None
    else:
        data = _buffer_file(uri, byte_length, folder, limit, where + ".uri")
    if len(data) < byte_length:
        raise GltfError(f"the buffer holds {len(data)} bytes, fewer than its byteLength "
                        f"{byte_length}", where)
    return bytes(data[:byte_length])


def _buffer_file(uri: str, byte_length: int, folder: Path, limit: int, where: str) -> bytes:
    """The first ``byte_length`` bytes of the file a relative URI names inside ``folder``."""
    parts = urlsplit(uri)
    if parts.scheme or parts.netloc or uri.startswith(("/", "\\")):
        raise GltfError(f"'{limits.quoted(uri)}' is not a relative path (buffers are files "
                        "beside the glTF file, or data: URIs)", where)
    name = unquote(parts.path)
    if "\0" in name:
        raise GltfError("the uri holds a NUL character", where)
    try:
        root = folder.resolve()
        target = (root / name).resolve()
    except (OSError, RuntimeError) as e:             # a symbolic link loop
        raise GltfError(f"cannot resolve '{limits.quoted(uri)}': {e}", where) from None
    if not target.is_relative_to(root):
        raise GltfError(f"'{limits.quoted(uri)}' leads outside the folder of the glTF file "
                        f"({root})", where)
    try:
        return limits.read_file(target, limit, byte_length)
    except OSError as e:
        raise GltfError(f"cannot read '{limits.quoted(uri)}': {e.strerror or e}", where) from None


def load_document(path: Path):
    """The pygltflib document of a .gltf or .glb file and the GLB's BIN chunk (or None)."""
    import pygltflib
    raw = limits.read_file(path, limits.max_file_bytes())
    binary, offset = None, None
    if path.suffix.lower() == ".glb" or raw.startswith(GLB_MAGIC):
        raw, offset, binary = split_glb(raw)
    document = parse_json(raw, offset)
    read = {k: v for k, v in document.items() if k in gltf_schema.READ}
    try:
        g = pygltflib.GLTF2.from_json(json.dumps(read), infer_missing=True)
    except (ValueError, KeyError, TypeError, AttributeError) as e:   # the schema should stop these
        raise GltfError(f"pygltflib cannot read the document: {limits.quoted(str(e))}",
                        "the document") from None
    return g, binary
