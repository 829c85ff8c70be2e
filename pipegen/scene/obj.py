"""Wavefront OBJ and MTL files: geometry, per-``usemtl`` parts and their materials.

The reader is vectorised: numpy classifies the lines by their first bytes; the records of
each kind are cut from the file a run of consecutive lines at a time (not one bytes object
per line), their numbers and indices parsed in one call each (plain decimals by
:mod:`pipegen.scene.decimals`, bit-identical to ``strtod``), polygons triangulated as fans
and normals smoothed (:func:`pipegen.scene.meshes.smooth_normals`); the parts' normal
groups weld each OBJ vertex once.  Python only touches the lines of other statements.  The
real Dabrovic Sponza split 4x (224k triangles) loads in 0.4-0.5 s of CPU time, about half
of what it took before issue 26 and a seventeenth of the line-by-line loader of issue 13
(``benchmarks/load_scene.py``; its docstring has the figures and the commands).

Why not a mesh library: trimesh (the candidate; its OBJ reader, 5.2.0, was tried on the files
the tests use) merges vertices by (v, vt, vn), so smoothing over the file's vertices would
change at texture seams; with ``maintain_order=True`` it drops per-corner ``vn`` normals of quad
faces without a message; it hands polygons of five or more corners back untriangulated at its
``load_obj`` level, logs unreadable records at debug level instead of raising with a line,
opens every ``map_Kd`` image with PIL while reading the MTL and keeps MTL colours as 8-bit
values.  Keeping the project's checks (errors with lines, counts of what was ignored) and the
same normals would have meant reading the file a second time.  The glTF side does use a
library (pygltflib, ``pipegen/scene/gltf.py``).

Nothing is dropped silently: every statement the renderer does not use (``vt``, ``o``, ``g``,
``s``, ``l``, texture maps, ``Ka``, ``illum`` ...) is counted and reported once per file in
:attr:`ObjModel.notes`, and degenerate triangles are dropped and counted.  Errors
(:class:`pipegen.scene.meshes.ObjError`) name the 1-based line: a bad number, an index out of
range, a face with fewer than three corners, or a vertex that is not finite (NaN, inf).

MTL mapping (per ``newmtl``, used by the faces after ``usemtl NAME``):

=========  ======================================================================  ===========
MTL        scene material                                                          if absent
=========  ======================================================================  ===========
``Kd``     ``albedo`` (r g b, below 0 clamped to 0; one number is grey)             0.8 grey
``Ks``     ``specular`` = mean of its three components                              0
``Ns``     ``shininess`` = ``Ns``, at least 1 (a Blinn-Phong exponent, like ours)   32
``d``      ``alpha`` = ``d`` (dissolve), clamped to [0, 1]                          1
``Tr``     ``alpha`` = 1 - ``Tr`` when there is no ``d`` (``d`` wins if both)       --
=========  ======================================================================  ===========

``translucent`` is ``alpha < 1``.  Faces before any ``usemtl``, or naming a material no MTL
file defines, get the defaults above (reported).
"""

from __future__ import annotations

import functools
import math
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from pipegen.scene import decimals, limits, meshes
from pipegen.scene.meshes import Mesh, ObjError

#: Statements of an OBJ file the reader uses; every other one is counted and reported.
USED = {b"v", b"vn", b"f", b"usemtl", b"mtllib"}
#: MTL statements mapped to the scene's material; others are reported as ignored.
MTL_USED = {"newmtl", "kd", "ks", "ns", "d", "tr"}

_MEANING = {"vt": "texture coordinates", "o": "object names", "g": "groups", "s": "smoothing groups",
            "l": "lines", "p": "points", "vp": "parameter-space vertices", "usemap": "texture maps"}

_STATEMENT = re.compile(rb"^[ \t]*([^\s#]+)[ \t]*([^\r\n#]*)", re.M)


@dataclass(frozen=True)
class MtlMaterial:
    """An MTL material mapped to the scene's parameters (see the module docstring)."""

    name: str
    albedo: tuple[float, float, float] = (0.8, 0.8, 0.8)
    specular: float = 0.0
    shininess: float = 32.0
    alpha: float = 1.0

    @property
    def translucent(self) -> bool:
        return self.alpha < 1.0


DEFAULT_MATERIAL = MtlMaterial("(default)")


@dataclass(frozen=True)
class ObjPart:
    """The faces of one ``usemtl`` material, in file order: a mesh of their own (normals from
    the whole file's smoothing, normal groups of this part)."""

    material: MtlMaterial
    mesh: Mesh
    dropped: int            # degenerate triangles removed from this part


@dataclass
class ObjModel:
    path: Path
    parts: list[ObjPart]
    positions: np.ndarray                   # (3T, 3) every triangle read, in file order
    normals: np.ndarray                     # (3T, 3)
    notes: list[str] = field(default_factory=list)
    triangles_read: int = 0
    dropped: int = 0
    vertex: Optional[np.ndarray] = None     # (3T,) each corner's OBJ vertex (0-based)

    @functools.cached_property
    def mesh(self) -> Mesh:
        """All faces as one mesh (normal groups over the whole file), made on first use."""
        return meshes.finish_mesh(self.positions, self.normals, self.vertex)


# -- OBJ ---------------------------------------------------------------------------------------


def _line_of(data: bytes, key: bytes, k: int) -> int:
    """1-based line of the ``k``-th (0-based) statement ``key`` (error paths only)."""
    seen = 0
    for m in _STATEMENT.finditer(data):
        if m.group(1) == key:
            if seen == k:
                return data.count(b"\n", 0, m.start()) + 1
            seen += 1
    return 0


@dataclass(frozen=True)
class _Records:
    """The records of one statement kind (``v``, ``vn`` or ``f``) in a scanned file: byte
    offsets of their lines and of the newlines ending them (in ``data``, the normalised text)."""

    data: bytes
    keyword: bytes
    starts: np.ndarray
    ends: np.ndarray

    def __len__(self) -> int:
        return len(self.starts)

    def text(self, sep: bytes) -> bytes:
        """Every record's text after the keyword, each followed by ``sep``.  Consecutive lines
        are cut from the file as one slice whose inner keywords become ``sep``, so the work is
        a few bytes operations per run of records, not per record (a bare keyword line keeps
        its keyword: the parse then fails and the slow path reports it)."""
        if not len(self):
            return b""
        k = len(self.keyword)
        breaks = np.flatnonzero(self.starts[1:] != self.ends[:-1] + 1)
        begin = self.starts[np.r_[0, breaks + 1]] + k
        end = self.ends[np.r_[breaks, len(self) - 1]]
        inner = b"\n" + self.keyword + b" "
        runs = [self.data[a:b].replace(inner, sep) for a, b in zip(begin.tolist(), end.tolist())]
        return sep.join(runs) + sep

    def bodies(self) -> list[bytes]:
        """Each record's text after the keyword, one bytes object per record (slow paths)."""
        k = len(self.keyword)
        return [self.data[s + k: e] for s, e in zip(self.starts.tolist(), self.ends.tolist())]


def _numbers(records: _Records, width: int, data: bytes) -> np.ndarray:
    """(len(records), width) float64 from records of at least ``width`` numbers each."""
    key = records.keyword
    if not len(records):
        return np.zeros((0, width))
    text = records.text(b" ")
    flat = decimals.parse_floats(text)          # plain decimals: numpy, bit-identical
    if flat is None:
        try:
            flat = np.fromstring(text, dtype=np.float64, sep=" ")   # C strtod
        except ValueError:
            flat = None
    if flat is not None and flat.size == width * len(records):
        return flat.reshape(-1, width)
    out = np.empty((len(records), width))
    for k, rec in enumerate(records.bodies()):   # slow path: extra components (w) or an error
        parts = rec.split()
        try:
            if len(parts) < width:
                raise ValueError(f"needs {width} numbers")
            out[k] = [float(x) for x in parts[:width]]
        except ValueError as e:
            what = {b"v": "a 'v' record needs three coordinates",
                    b"vn": "a 'vn' record needs three components"}[key]
            detail = "" if "needs" in str(e) else f" ({e})"
            raise ObjError(f"{what}: '{key.decode()} {limits.quoted(rec.strip())}'"
                           f"{limits.quoted(detail)}", _line_of(data, key, k)) from None
    return out


def _corner_indices(faces: _Records, data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per corner: vertex index and normal index as written (0 = none), and corners per face.

    Fast path: every corner of the file in one format (``v``, ``v/vt``, ``v//vn`` or
    ``v/vt/vn``: every corner's slashes alike and a number in each slot but an empty ``vt``),
    parsed as one integer array; a face's corners are the tokens of its line.  Anything else
    (mixed formats, an error to locate) takes a per-corner loop."""
    text = faces.text(b"\n")
    t, starts, ends = decimals.tokens(text)
    cols = text[starts[0]: ends[0]].count(b"/") + 1 if len(starts) else 1
    slashes = text.translate(None, b"0123456789-")
    skeleton = set(slashes.split()) if b"/" in slashes else set()
    if cols <= 3 and skeleton <= {b"/" * (cols - 1)} and (cols > 1 or not skeleton):
        try:
            flat = np.fromstring(text.replace(b"//", b"/0/").replace(b"/", b" "), dtype=np.int64,
                                 sep=" ")
        except ValueError:
            flat = None
        if flat is not None and flat.size == cols * len(starts):
            line_ends = np.flatnonzero(t == 10)                   # one per face
            counts = np.diff(np.r_[0, np.searchsorted(starts, line_ends)])
            small = np.flatnonzero(counts < 3)
            if len(small):
                raise ObjError("a face needs at least three vertices",
                               _line_of(data, b"f", int(small[0])))
            idx = flat.reshape(-1, cols)
            vn = idx[:, 2] if cols == 3 else np.zeros(len(idx), np.int64)
            return idx[:, 0], vn, counts
    bodies = faces.bodies()
    counts = np.fromiter((len(f.split()) for f in bodies), dtype=np.int64, count=len(bodies))
    small = np.flatnonzero(counts < 3)
    if len(small):
        raise ObjError("a face needs at least three vertices", _line_of(data, b"f", int(small[0])))
    n = int(counts.sum())
    v = np.zeros(n, np.int64)                  # slow path: mixed corner formats or an error
    vn = np.zeros(n, np.int64)
    k = 0
    for fi, f in enumerate(bodies):
        for corner in f.split():
            c = corner.split(b"/")
            try:
                v[k] = int(c[0])
                vn[k] = int(c[2]) if len(c) >= 3 and c[2] else 0
            except ValueError as e:
                raise ObjError(f"cannot read 'f {limits.quoted(f.strip())}': "
                               f"{limits.quoted(str(e))}", _line_of(data, b"f", fi)) from None
            k += 1
    return v, vn, counts


def _check_count(n: int, what: str, data: bytes, keyword: bytes = b"") -> None:
    """Refuse more than ``limits.max_elements()`` records (at the first one past it) or
    triangles: the arrays made from them are float64 rows."""
    limit = limits.max_elements()
    if n > limit:
        raise ObjError(f"{n} {what}, more than the limit of {limit} "
                       "(PIPEGEN_SCENE_MAX_ELEMENTS raises it)",
                       _line_of(data, keyword, limit) if keyword else 0)


def _resolve(idx: np.ndarray, before: np.ndarray, total: int, what: str, counts: np.ndarray,
             data: bytes, used: Optional[np.ndarray] = None) -> np.ndarray:
    """OBJ indices (1-based, or negative: relative to the records read so far) -> 0-based;
    only the corners in ``used`` (default all) are checked, the others come back 0."""
    out = np.where(idx > 0, idx - 1, before + idx)
    bad = (idx == 0) | (out < 0) | (out >= np.where(idx > 0, total, before))
    if used is not None:
        bad &= used
        out = np.where(used, out, 0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        face = int(np.searchsorted(np.cumsum(counts), k, side="right"))
        raise ObjError(f"{what} index {int(idx[k])} out of range (have {int(before[k])})",
                       _line_of(data, b"f", face))
    return out


def _scan(data: bytes):
    """The file's statements by kind: ``v``, ``vn`` and ``f`` records (:class:`_Records`), per
    face the ``v``/``vn`` records before it (for relative, negative, indices) and its material
    (index into the material names, 0 = none), the ``mtllib`` names and a count of every other
    statement.  Lines are classified by their first bytes with numpy; Python touches only the
    lines of other statements (``vt`` lines are counted without it)."""
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if b"#" in data:
        data = re.sub(rb"#[^\n]*", b"", data)
    if b"\t" in data:
        data = data.replace(b"\t", b" ")
    arr = np.frombuffer(data + b"\n\n\n", dtype=np.uint8)
    ends = np.flatnonzero(arr[: len(data) + 1] == 10)        # the newline ending each line
    starts = np.r_[0, ends[:-1] + 1]
    if np.any(arr[starts] == 32):
        data = re.sub(rb"(?m)^ +", b"", data)
        arr = np.frombuffer(data + b"\n\n\n", dtype=np.uint8)
        ends = np.flatnonzero(arr[: len(data) + 1] == 10)
        starts = np.r_[0, ends[:-1] + 1]
    c0, c1, c2 = arr[starts], arr[starts + 1], arr[starts + 2]
    end1, end2 = (c1 == 32) | (c1 == 10), (c2 == 32) | (c2 == 10)
    is_v = (c0 == ord("v")) & end1
    is_vn = (c0 == ord("v")) & (c1 == ord("n")) & end2
    is_vt = (c0 == ord("v")) & (c1 == ord("t")) & end2
    is_f = (c0 == ord("f")) & end1
    vi, vni, fi = np.flatnonzero(is_v), np.flatnonzero(is_vn), np.flatnonzero(is_f)
    records = [_Records(data, b, starts[i], ends[i]) for b, i in ((b"v", vi), (b"vn", vni),
                                                                  (b"f", fi))]
    rest = np.flatnonzero(~(is_v | is_vn | is_vt | is_f) & (c0 != 10))
    mi, libs, ignored = [], [], Counter()
    if is_vt.any():
        ignored["vt"] = int(np.count_nonzero(is_vt))
    names: list[str] = []
    for i in rest.tolist():
        key, _, tail = data[starts[i]: ends[i]].partition(b" ")
        if key == b"usemtl":
            mi.append(i)
            names.append(tail.decode(errors="replace").strip())
        elif key == b"mtllib":
            libs += tail.decode(errors="replace").split()
        elif key.strip():
            ignored[key.decode(errors="replace")] += 1
    mat_names: list[Optional[str]] = [None]
    mat_index: dict[Optional[str], int] = {None: 0}
    of_stmt = []
    for name in names:
        if name not in mat_index:
            mat_index[name] = len(mat_names)
            mat_names.append(name)
        of_stmt.append(mat_index[name])
    run = np.searchsorted(np.asarray(mi, dtype=np.int64), fi)        # usemtl statements before
    f_mat = np.r_[0, np.asarray(of_stmt, dtype=np.int64)][run]
    f_v = np.searchsorted(vi, fi)
    f_vn = np.searchsorted(vni, fi)
    return (*records, f_v, f_vn, f_mat, mat_names, libs, ignored)


def read_obj(path: str | Path, crease_deg: float = 45.0) -> ObjModel:
    """Read an OBJ file (and the MTL files its ``mtllib`` names, next to it)."""
    path = Path(path)
    data = limits.read_file(path, limits.max_file_bytes())
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    v_rec, vn_rec, f_rec, f_v, f_vn, f_mat, mat_names, libs, ignored = _scan(data)
    if not len(f_rec):
        raise ObjError("no faces")
    for rec in (v_rec, vn_rec, f_rec):
        _check_count(len(rec), f"'{rec.keyword.decode()}' records", data, rec.keyword)

    V = _numbers(v_rec, 3, data)
    bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
    if len(bad):
        k = int(bad[0])
        raise ObjError(f"vertex {k + 1} is not finite: "
                       f"'v {limits.quoted(v_rec.bodies()[k].strip())}'"
                       + (f" ({len(bad)} such vertices)" if len(bad) > 1 else ""),
                       _line_of(data, b"v", k))
    N = _numbers(vn_rec, 3, data)

    vi, ni, counts = _corner_indices(f_rec, data)
    wide = np.flatnonzero(counts > limits.MAX_FACE_CORNERS)
    if len(wide):
        raise ObjError(f"a face of {int(counts[wide[0]])} corners: at most "
                       f"{limits.MAX_FACE_CORNERS} (it would be a fan of that many triangles)",
                       _line_of(data, b"f", int(wide[0])))
    _check_count(int(counts.sum()) - 2 * len(counts), "triangles", data)
    def per_corner(before, total):
        return np.repeat(np.asarray(before, dtype=np.int64), counts)

    vi = _resolve(vi, per_corner(f_v, len(V)), len(V), "vertex", counts, data)
    has_vn = ni != 0
    if has_vn.any():
        ni = _resolve(ni, per_corner(f_vn, len(N)), len(N), "normal", counts, data, used=has_vn)

    # fans: triangle (0, k, k+1) of each face, k = 1 .. count-2
    starts = np.cumsum(counts) - counts
    tris_per_face = counts - 2
    face_of_tri = np.repeat(np.arange(len(counts)), tris_per_face)
    k = np.arange(len(face_of_tri)) - np.repeat(np.cumsum(tris_per_face) - tris_per_face, tris_per_face) + 1
    s = starts[face_of_tri]
    corner = np.stack([s, s + k, s + k + 1], axis=1)          # (T, 3) corner indices
    F = vi[corner]
    face_has_n = np.minimum.reduceat(has_vn.astype(np.int8), starts).astype(bool)
    tri_has_n = face_has_n[face_of_tri]

    positions = meshes.take_rows(V, F.reshape(-1))
    tri = positions.reshape(-1, 3, 3)
    fn_raw = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])   # length = 2 * area
    try:
        normals = meshes.smooth_normals(F, fn_raw, crease_deg)
    except ObjError as e:                           # the work around a vertex is bounded
        raise ObjError(f"{path.name}: {e}", e.line) from None
    if tri_has_n.any():
        given = meshes.normalize_rows(N[ni[corner[tri_has_n]].reshape(-1)])
        normals.reshape(-1, 3, 3)[tri_has_n] = given.reshape(-1, 3, 3)

    notes = []
    if ignored:
        kinds = sorted(ignored.items())
        what = ", ".join(f"'{limits.quoted(k)}' x{n}" + (f" ({_MEANING[k]})" if k in _MEANING else "")
                         for k, n in kinds[:12])
        more = f" and {len(kinds) - 12} other statements" if len(kinds) > 12 else ""
        notes.append(f"{path.name}: ignored {what}{more}")
    materials, mtl_notes = _materials(path, libs, data)
    notes += mtl_notes
    mat_of_tri = np.asarray(f_mat, dtype=np.int64)[face_of_tri]
    parts, missing, dropped_total = [], [], 0
    for m in np.unique(mat_of_tri):
        sel = np.flatnonzero(mat_of_tri == m)
        name = mat_names[m]
        if name is None:
            mat = DEFAULT_MATERIAL
            if len(mat_names) > 1 or materials:
                missing.append("faces before any 'usemtl'")
        elif name in materials:
            mat = materials[name]
        else:
            mat = MtlMaterial(name)
            missing.append(f"'{name}' (no MTL defines it)")
        pos = np.take(tri, sel, axis=0).reshape(-1, 3)
        nrm = np.take(normals.reshape(-1, 3, 3), sel, axis=0).reshape(-1, 3)
        try:
            mesh = meshes.finish_mesh(pos, nrm, np.take(F, sel, axis=0))
        except ObjError as e:                       # the work around an edge is bounded
            raise ObjError(f"{path.name}: {e}") from None
        parts.append(ObjPart(mat, mesh, len(sel) - mesh.triangle_count))
        dropped_total += len(sel) - mesh.triangle_count
    if missing:
        notes.append(f"{path.name}: default material (albedo 0.8, specular 0) for "
                     + ", ".join(missing))
    if dropped_total:
        notes.append(f"{path.name}: dropped {dropped_total} degenerate (zero-area) triangles of "
                     f"{len(F)}")
    return ObjModel(path, parts, positions, normals, notes, len(F), dropped_total, F.reshape(-1))


# -- MTL ---------------------------------------------------------------------------------------


def _materials(obj_path: Path, libs: list[str],
               data: bytes = b"") -> tuple[dict[str, MtlMaterial], list[str]]:
    """The materials of the MTL files ``libs`` (``mtllib`` names, inside the OBJ file's folder:
    a file from elsewhere cannot make pipegen read others) and notes on what was skipped."""
    materials: dict[str, MtlMaterial] = {}
    notes = []
    folder = obj_path.parent.resolve()
    for lib in libs:
        try:
            p = (folder / lib).resolve()
        except (OSError, RuntimeError, ValueError) as e:    # a link loop, a NUL
            raise ObjError(f"mtllib '{limits.quoted(lib)}': {e}") from None
        if not p.is_relative_to(folder):
            at = re.search(rb"^[ \t]*mtllib[^\n]*" + re.escape(lib.encode()), data, re.M)
            raise ObjError(f"mtllib '{limits.quoted(lib)}' leads outside the folder of the OBJ "
                           f"file ({folder})", data.count(b"\n", 0, at.start()) + 1 if at else 0)
        try:
            text = limits.read_file(p, limits.max_file_bytes()).decode(errors="replace")
        except OSError as e:
            notes.append(f"{obj_path.name}: cannot read material library '{lib}' ({e.strerror}); "
                         "its materials get the defaults")
            continue
        found, lib_notes = parse_mtl(text, lib)
        materials.update(found)
        notes += lib_notes
    return materials, notes


def parse_mtl(text: str, name: str = "<mtl>") -> tuple[dict[str, MtlMaterial], list[str]]:
    """Materials of an MTL file mapped to the scene's parameters (module docstring), and the
    notes on what was ignored (textures by file name, other statements by count)."""
    raw: dict[str, dict[str, list[str]]] = {}
    current: Optional[dict] = None
    ignored: Counter = Counter()
    textures: list[str] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        key = parts[0].lower()
        if key == "newmtl":
            mname = " ".join(parts[1:])
            current = raw.setdefault(mname, {})
        elif current is None:
            ignored[parts[0]] += 1
        elif key in MTL_USED:
            current[key] = parts[1:]
            current.setdefault("_lines", {})[key] = lineno
        else:
            if key.startswith("map_") or key in ("bump", "disp", "decal", "refl"):
                textures.append(parts[-1])
            ignored[parts[0]] += 1
    out = {}
    for mname, kv in raw.items():
        out[mname] = _mtl_material(mname, kv, name)
    notes = []
    if textures:
        shown = ", ".join(sorted(set(textures))[:8])
        more = len(set(textures)) - 8
        notes.append(f"{name}: textures dropped (not supported): {shown}"
                     + (f" and {more} more" if more > 0 else ""))
    other = {k: n for k, n in ignored.items() if not (k.lower().startswith("map_")
                                                     or k.lower() in ("bump", "disp", "decal", "refl"))}
    if other:
        notes.append(f"{name}: ignored " + ", ".join(f"'{k}' x{n}" for k, n in sorted(other.items())))
    return out, notes


def _mtl_material(mname: str, kv: dict, lib: str) -> MtlMaterial:
    lines = kv.get("_lines", {})

    def nums(key: str, count: int) -> Optional[list[float]]:
        if key not in kv:
            return None
        vals = [float(x) for x in kv[key] if _isnum(x)]
        if not vals or not all(math.isfinite(v) for v in vals):
            raise ObjError(f"{lib}:{lines.get(key, 0)}: cannot read '{key} {' '.join(kv[key])}' "
                           f"of material '{mname}' (needs finite numbers)")
        if count == 3:
            return vals[:3] if len(vals) >= 3 else [vals[0]] * 3
        return vals[:1]

    kd, ks, ns, d, tr = nums("kd", 3), nums("ks", 3), nums("ns", 1), nums("d", 1), nums("tr", 1)
    alpha = d[0] if d else (1.0 - tr[0] if tr else 1.0)
    return MtlMaterial(
        mname,
        albedo=tuple(max(0.0, x) for x in kd) if kd else DEFAULT_MATERIAL.albedo,
        specular=max(0.0, sum(ks) / 3.0) if ks else 0.0,
        shininess=max(1.0, ns[0]) if ns else 32.0,
        alpha=min(1.0, max(0.0, alpha)),
    )


def _isnum(x: str) -> bool:
    try:
        float(x)
        return True
    except ValueError:
        return False


def load_obj(path: str | Path, crease_deg: float = 45.0) -> Mesh:
    """Read ``v``, ``vn`` and ``f`` records into one mesh (all materials together); polygons
    are split into fans.  Faces without normals get smoothed ones: the area-weighted average
    of the face normals around the vertex that lie within ``crease_deg`` of the face's own (so
    a cube stays faceted and a tessellated sphere becomes smooth).  ``read_obj`` keeps the
    per-material parts and reports what it skipped."""
    return read_obj(path, crease_deg).mesh
