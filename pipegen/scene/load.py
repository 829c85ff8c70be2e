"""Scenes: objects, lights and a camera, read from TOML (see ``examples/scenes/``).

A scene file::

    width = 320                      # output size in pixels
    height = 180
    ambient = [0.05, 0.05, 0.06]     # optional, default [0, 0, 0]

    [camera]
    position = [0, 7, 11]
    target = [0, 0.5, 0]
    up = [0, 1, 0]                   # optional
    fov_y_deg = 45
    near = 0.1                       # optional
    far = 100                        # optional

    [camera.previous]                # optional: the camera of the previous frame (motion
    position = [0.2, 7, 11]          # vectors: prev_view, prev_proj); missing keys are the
                                     # camera's; default: the camera itself (no motion)

    [gltf]                           # optional: a glTF file's objects, camera and lights
    file = "model.glb"               # (then [camera], [[objects]], width/height are optional)

    [[objects]]
    mesh = "box"                     # plane | box | sphere | cylinder, or: obj = "model.obj"
                                     # (an OBJ without `material`: one object per MTL material)
    name = "crate"                   # optional
    id = 3                           # optional, 1..255, default: position in the file (1-based)
    translate = [0, 0.5, 0]          # optional transform: scale, then rotate, then translate
    rotate_deg = [0, 30, 0]          # degrees about x, then y, then z
    scale = [1, 1, 1]                # or one number
    segments = 24                    # sphere/cylinder tessellation; rings (sphere);
                                     # divisions (plane)
    material = { albedo = [0.8, 0.2, 0.2], specular = 0.3, shininess = 32, alpha = 1.0,
                 translucent = false }
    layer = 2                        # optional, translucent objects only: stipple layer 1..3

    [[lights]]
    type = "point"                   # point | spot | directional (default point)
    position = [0, 1, 0]             # point, spot
    radius = 3.0                     # point, spot
    color = [1.0, 0.8, 0.6]
    direction = [0, -1, 0]           # spot, directional (the direction the light travels)
    inner_deg = 20                   # spot: full intensity inside, zero outside outer_deg
    outer_deg = 30

Procedural meshes fit in the unit cube (see ``pipegen.scene.meshes``); OBJ + MTL files are read by
``pipegen.scene.obj``, glTF 2.0 files (also loadable on their own: ``load_scene("x.glb")``) by
``pipegen.scene.gltf``.  Errors are ``PipegenError`` with the file position of the offending key
where it can be found; what a loader ignored is in ``Scene.notes`` and warned once as a
``SceneLoadWarning``.

Stipple layers (inferred lighting, Kircher & Lawrance 2009, §4)
----------------------------------------------------------------
Every object has a ``layer``: 0 for opaque objects, 1..3 for translucent ones.  In a G-buffer
a translucent object of layer L may only write the pixels that :func:`stipple_owner` gives to
L, a 2x2 pattern (layer 0, the opaque surface, keeps one pixel of every 2x2 block), so up to
three translucent layers and the opaque surface behind them are all lit in the same light
pass.  The layer of a translucent object is

- explicit: ``layer = N`` (1..3) in its ``[[objects]]`` table; or else
- automatic: the translucent objects *without* an explicit layer, ordered far -> near by the
  distance from the camera position to the centre of their world-space bounding box (ties:
  file order), get layers 1, 2, 3, 1, 2, 3, ... in that order.  So up to three translucent
  objects stacked in depth get distinct layers; explicit layers are not taken into account
  by the automatic cycle (give every overlapping object an explicit layer to control them
  all).

Layers are assigned when the scene is loaded, from its camera.
"""

from __future__ import annotations

import dataclasses
import math
import re
import reprlib
import tomllib
from pathlib import Path
from typing import Any, Optional

import numpy as np

from pipegen.scene import limits, meshes
from pipegen.core.diagnostics import PipegenError, Span
from pipegen.scene.material_fields import MaterialSetting
from pipegen.scene.model import (
    LIGHT_TYPES, STIPPLE_LAYERS, Camera, Light, Material, Scene, SceneObject, assign_layers,
    make_object, report_notes, transform_matrix)


class _Locator:
    """Finds where a key path (``("objects", 3, "material", "albedo")``) sits in TOML text.

    tomllib keeps no positions, so this scans the text: table headers, then ``key =`` lines
    inside the table's region, then ``key =`` inside an inline table on that line.  Best effort:
    it returns the closest ancestor it can place, or None.
    """

    _header = re.compile(r"^\s*(\[\[?)\s*([A-Za-z0-9_.\-]+)\s*\]\]?")

    def __init__(self, file: str, text: str):
        self.file, self.text = file, text
        self.lines = text.splitlines()
        self.headers = []   # (line index, name, is_array)
        for i, line in enumerate(self.lines):
            m = self._header.match(line)
            if m:
                self.headers.append((i, m.group(2), m.group(1) == "[["))

    def span(self, line: int, col: int = 0, length: int = 0) -> Span:
        return Span(self.file, line + 1, col + 1, line + 1, col + 1 + length, self.text)

    def _region(self, table: Optional[str], index: Optional[int]) -> Optional[tuple[int, int]]:
        """Line range [start, end) of a table's body (its sub-tables included)."""
        if table is None:
            end = self.headers[0][0] if self.headers else len(self.lines)
            return (0, end)
        hits = [h for h in self.headers if h[1] == table]
        if index is not None:
            hits = [h for h in hits if h[2]]
            if index >= len(hits):
                return None
            start = hits[index][0]
        elif hits:
            start = hits[0][0]
        else:
            return None
        end = len(self.lines)
        for i, name, _ in self.headers:
            if i > start and not name.startswith(table + "."):
                end = i
                break
        return (start, end)

    def find(self, path: tuple) -> Optional[Span]:
        table, index, keys = None, None, list(path)
        if keys and keys[0] in ("camera", "objects", "lights"):
            table = keys.pop(0)
            if keys and isinstance(keys[0], int):
                index = keys.pop(0)
        region = self._region(table, index)
        if region is None:
            return None
        start, end = region
        if not table and not keys:          # the scene as a whole: its first line
            return self.span(0, 0, len(self.lines[0].rstrip()) if self.lines else 0)
        best = self.span(start, 0, len(self.lines[start].rstrip())) if table else None
        lo, col = start, 0
        for depth, key in enumerate(keys):
            if not isinstance(key, str):
                break
            pat = re.compile(r"(?:^|[\s{,])(" + re.escape(key) + r")\s*[=.]")    # `k =`, `k.sub =`
            found = None
            for i in range(lo, end):
                m = pat.search(self.lines[i], col if i == lo and depth else 0)
                if m:
                    found = (i, m.start(1), len(key))
                    break
            if found is None:  # maybe a sub-table header: [objects.material]
                sub = [h for h in self.headers if start <= h[0] < end and h[1].endswith("." + key)]
                if table is None and depth == 0:   # a top-level table: [name] or [[name]]
                    sub = [h for h in self.headers if h[1] == key]
                if not sub:
                    break
                found = (sub[0][0], 0, len(self.lines[sub[0][0]].rstrip()))
                lo, col = sub[0][0] + 1, 0
            else:
                lo, col = found[0], found[1] + len(key)
            best = self.span(*found)
        return best


def _describe(path: tuple) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out or "the scene"


class _Reader:
    """Typed access to one TOML table with errors that name the key and point at it."""

    def __init__(self, table: Any, path: tuple, loc: _Locator):
        self.loc, self.path = loc, path
        if not isinstance(table, dict):
            self.fail((), f"'{_describe(path)}' must be a table")
        self.table = table

    def fail(self, key: tuple | str, message: str, hint: str = "") -> None:
        key = (key,) if isinstance(key, str) else key
        raise PipegenError(self.loc.find(self.path + key), message, hint)

    def check_keys(self, allowed: set[str]) -> None:
        for k in self.table:
            if k not in allowed:
                self.fail(k, f"unknown key '{k}' in {_describe(self.path)}",
                          hint="allowed: " + ", ".join(sorted(allowed)))

    def has(self, key: str) -> bool:
        return key in self.table

    def _get(self, key: str, default: Any) -> Any:
        if key in self.table:
            return self.table[key]
        if default is _REQUIRED:
            self.fail((), f"missing key '{key}' in {_describe(self.path)}")
        return default

    def number(self, key: str, default: Any = None, *, positive: bool = False,
               minimum: Optional[float] = None, maximum: Optional[float] = None) -> float:
        v = self._get(key, _REQUIRED if default is None else default)
        if isinstance(v, bool) or not _finite(v):
            self.fail(key, f"'{_describe(self.path + (key,))}' must be a finite number, got {_show(v)}")
        if positive and v <= 0:
            self.fail(key, f"'{_describe(self.path + (key,))}' must be > 0, got {v}")
        if minimum is not None and v < minimum or maximum is not None and v > maximum:
            self.fail(key, f"'{_describe(self.path + (key,))}' must be in [{minimum}, {maximum}], got {v}")
        return float(v)

    def integer(self, key: str, default: Any = None, *, minimum: int = 0, maximum: int = 1 << 30) -> int:
        v = self._get(key, _REQUIRED if default is None else default)
        if isinstance(v, bool) or not isinstance(v, int) or not minimum <= v <= maximum:
            self.fail(key, f"'{_describe(self.path + (key,))}' must be an integer in "
                      f"[{minimum}, {maximum}], got {_show(v)}")
        return int(v)

    def vec3(self, key: str, default: Any = None, *, nonzero: bool = False) -> tuple[float, float, float]:
        v = self._get(key, _REQUIRED if default is None else default)
        if (not isinstance(v, list) or len(v) != 3
                or any(isinstance(x, bool) or not _finite(x)
                       for x in v)):
            self.fail(key, f"'{_describe(self.path + (key,))}' must be a list of three numbers, got {_show(v)}")
        if nonzero and not any(v):
            self.fail(key, f"'{_describe(self.path + (key,))}' must not be the zero vector")
        return (float(v[0]), float(v[1]), float(v[2]))

    def string(self, key: str, default: Any = None, choices: Optional[tuple[str, ...]] = None) -> str:
        v = self._get(key, _REQUIRED if default is None else default)
        if not isinstance(v, str):
            self.fail(key, f"'{_describe(self.path + (key,))}' must be a string, got {_show(v)}")
        if choices and v not in choices:
            self.fail(key, f"'{_describe(self.path + (key,))}' must be one of {', '.join(choices)}, got '{v}'")
        return v

    def boolean(self, key: str, default: bool) -> bool:
        v = self._get(key, default)
        if not isinstance(v, bool):
            self.fail(key, f"'{_describe(self.path + (key,))}' must be true or false, got {_show(v)}")
        return v

    def sub(self, key: str, default: Any = None) -> "_Reader":
        return _Reader(self._get(key, _REQUIRED if default is None else default), self.path + (key,), self.loc)


_REQUIRED = object()


def _finite(v) -> bool:
    """A finite number (an int too large for a float, 10**400, is not: math.isfinite would
    raise OverflowError on it)."""
    if isinstance(v, float):
        return math.isfinite(v)
    return isinstance(v, int) and abs(v) <= 1.7e308


def _show(value) -> str:
    """``repr(value)`` for a message, bounded: at most a few levels, items and characters of
    what the file wrote (a table nested 5,000 levels by dotted keys, an integer of 4,000
    digits) - repr itself would recurse, or refuse the integer."""
    shown = reprlib.Repr()
    shown.maxlevel, shown.maxlist, shown.maxdict, shown.maxstring, shown.maxother = 3, 6, 4, 60, 60
    shown.maxlong = 40
    try:
        return shown.repr(value)
    except ValueError:                      # an int past Python's 4300-digit conversion limit
        return "a number of more than 4300 digits"


def load_scene(path: str | Path) -> Scene:
    """A scene file (TOML), or a glTF 2.0 file (``.gltf``, ``.glb``) rendered as it is: its
    meshes, materials, first camera and ``KHR_lights_punctual`` lights at ``DEFAULT_SIZE``
    (``pipegen.scene.gltf``).  What a loader ignored is in ``Scene.notes`` (and warned once)."""
    path = Path(path)
    if path.suffix.lower() in (".gltf", ".glb"):
        from pipegen.scene import gltf
        return gltf.load_gltf_scene(path)
    from pipegen.core.sources import read_source
    try:
        text = read_source(str(path))     # regular UTF-8 files only; a bad byte is located
    except OSError as e:
        raise PipegenError(None, f"cannot read scene file '{path}': {e.strerror or e}",
                           hint="pass a scene .toml (or a .gltf / .glb file)") from None
    return parse_scene(text, str(path), base_dir=path.parent, name=path.stem)


def load_scene_noting(path: str | Path, say=None) -> Scene:
    """``load_scene`` for a command line: what the loader ignored is said once, as a
    ``note:`` line on stderr (``say``: how), not also as a Python warning with its source
    line."""
    import sys
    import warnings
    from pipegen.scene.model import SceneLoadWarning
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneLoadWarning)
        scene = load_scene(path)
    for note in scene.notes:
        (say or (lambda text: print(text, file=sys.stderr)))(f"note: {note}")
    return scene


def _toml_error(e: Exception, text: str, file: str) -> PipegenError:
    """tomllib's message ends in ``(at line L, column C)`` or ``(at end of document)``: the
    position becomes the error's span (tomllib counts lines at '\\n' only, as spans do)."""
    msg = str(e)
    m = re.search(r"\s*\(at line (\d+), column (\d+)\)$", msg)
    if m:
        line, column = int(m.group(1)), int(m.group(2))
        span = Span(file, line, column, line, column + 1, text)
    else:
        m = re.search(r"\s*\(at end of document\)$", msg)
        span = Span.at_offset(file, text, len(text.rstrip()))
    message = msg[:m.start()] if m else msg
    return PipegenError(span, f"invalid TOML: {message}",
                        "see https://toml.io for the syntax")


def parse_scene(text: str, file: str = "<scene>", base_dir: Path | str = ".", name: str = "scene") -> Scene:
    loc = _Locator(file, text)
    depth, at = limits.nesting_depth(text, toml=True)
    if depth > limits.MAX_NESTING:          # tomllib recurses: RecursionError past ~330
        raise PipegenError(Span.at_offset(file, text, at),
                           f"arrays and inline tables nest more than {limits.MAX_NESTING} levels")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise _toml_error(e, text, file) from None
    except ValueError as e:                 # int() past its 4300-digit limit, unlocated
        long = re.search(r"\w{4000,}", text)
        raise PipegenError(Span.at_offset(file, text, long.start() if long else 0),
                           f"invalid TOML: a number too long to read ({limits.quoted(str(e))})"
                           ) from None

    top = _Reader(data, (), loc)
    top.check_keys({"width", "height", "ambient", "camera", "objects", "lights", "name", "gltf"})
    notes: list[str] = []
    imported = None
    if top.has("gltf"):
        imported = _gltf_reference(top.sub("gltf"), Path(base_dir))
        notes += imported.notes
    from pipegen.core.defaults import DEFAULT_SIZE
    sized = imported is None
    width = top.integer("width", None if sized else DEFAULT_SIZE[0], minimum=1, maximum=16384)
    height = top.integer("height", None if sized else DEFAULT_SIZE[1], minimum=1, maximum=16384)
    ambient = np.array(top.vec3("ambient", [0.0, 0.0, 0.0]))
    cam_table = data.get("camera")
    if imported is not None and (not top.has("camera") or (
            isinstance(cam_table, dict) and set(cam_table) <= {"previous"})):
        camera = imported.camera
    else:
        camera = _camera(top.sub("camera"))
    previous = None
    if isinstance(cam_table, dict) and "previous" in cam_table:
        previous = _camera(top.sub("camera").sub("previous"), base=camera)

    objects_raw = data.get("objects", [])
    if not isinstance(objects_raw, list) or (not objects_raw and imported is None):
        top.fail("objects", "a scene needs at least one [[objects]] entry")
    parsed: list[tuple[SceneObject, Optional[int], int]] = []   # object, layer, TOML index
    if imported is not None:
        parsed += [(o, None, -1) for o in imported.objects]
    for i, o in enumerate(objects_raw):
        objs, layer = _object(_Reader(o, ("objects", i), loc), i, Path(base_dir), len(parsed) + 1,
                              notes)
        parsed += [(obj, layer, i) for obj in objs]
    if len(parsed) > 255:
        top.fail("objects", f"the scene has {len(parsed)} objects; object ids are 8-bit (1..255)",
                 hint="an OBJ file gives one object per material, a glTF file one per mesh "
                      "primitive")
    objects = assign_layers([o for o, _, _ in parsed], camera.position, [l for _, l, _ in parsed])
    seen: dict[int, int] = {}
    for (_, _, i), o in zip(parsed, objects):
        if o.id in seen:
            j = seen[o.id]
            where = lambda k: f"objects[{k}]" if k >= 0 else "the glTF file"  # noqa: E731
            raise PipegenError(loc.find(("objects", i, "id")) or loc.find(("objects", i)),
                               f"object id {o.id} is used by {where(j)} and {where(i)}",
                               hint="ids must be unique (1..255); an OBJ file with N materials "
                                    "takes N ids from its `id` on")
        seen[o.id] = i

    lights_raw = data.get("lights", [])
    if not isinstance(lights_raw, list):
        top.fail("lights", "'lights' must be an array of tables ([[lights]])")
    lights = [_light(_Reader(l, ("lights", i), loc)) for i, l in enumerate(lights_raw)]
    if imported is not None:
        lights = list(imported.lights) + lights
    report_notes(notes)
    return Scene(width, height, ambient, tuple(objects), tuple(lights), camera,
                 name=top.string("name", name), notes=tuple(notes), previous_camera=previous)


def _gltf_reference(r: _Reader, base_dir: Path):
    """``[gltf]``: a glTF file's objects, and its lights and camera unless turned off."""
    from pipegen.scene import gltf
    r.check_keys({"file", "lights", "camera", "light_intensity"})
    rel = r.string("file")
    path = (base_dir / rel) if not Path(rel).is_absolute() else Path(rel)
    scale = r.number("light_intensity", 1.0, minimum=0.0)
    try:
        imported = gltf.load_gltf(path, intensity_scale=scale)
    except OSError as e:
        r.fail("file", f"cannot read glTF file '{path}': {e.strerror}")
    except gltf.GltfError as e:
        r.fail("file", f"bad glTF file: {path}: {e}")
    if not r.boolean("lights", True):
        imported = dataclasses.replace(imported, lights=())
    if not r.boolean("camera", True):
        imported = dataclasses.replace(imported, camera=None)
    if imported.camera is None:
        imported = dataclasses.replace(imported, camera=gltf.framing_camera(imported.objects))
    return imported


def _camera(r: _Reader, base: Optional[Camera] = None) -> Camera:
    """``[camera]``, or with ``base`` ``[camera.previous]``: its missing keys are ``base``'s."""
    if not isinstance(r.table, dict):
        r.fail((), f"'{_describe(r.path)}' must be a table")
    r.check_keys({"position", "target", "up", "fov_y_deg", "near", "far"}
                 | ({"previous"} if base is None else set()))
    d = (lambda k, v: v) if base is None else (lambda k, v: list(getattr(base, k))
                                               if isinstance(getattr(base, k), tuple)
                                               else getattr(base, k))
    cam = Camera(
        position=r.vec3("position", d("position", None)),
        target=r.vec3("target", d("target", None)),
        up=r.vec3("up", d("up", [0.0, 1.0, 0.0]), nonzero=True),
        fov_y_deg=r.number("fov_y_deg", d("fov_y_deg", None)),
        near=r.number("near", d("near", 0.1), positive=True),
        far=r.number("far", d("far", 100.0), positive=True),
    )
    if not 0.0 < cam.fov_y_deg < 180.0:
        r.fail("fov_y_deg", f"camera.fov_y_deg must be in (0, 180), got {cam.fov_y_deg}")
    if cam.far <= cam.near:
        r.fail("far", f"camera.far ({cam.far}) must be greater than camera.near ({cam.near})")
    f = np.subtract(cam.target, cam.position)
    if np.linalg.norm(f) == 0:
        r.fail("target", "camera.target must differ from camera.position")
    if np.linalg.norm(np.cross(f, cam.up)) < 1e-9 * np.linalg.norm(f) * np.linalg.norm(cam.up):
        r.fail("up", "camera.up must not be parallel to the viewing direction")
    return cam


_MATERIAL_KEYS = ("albedo", "specular", "shininess", "alpha", "translucent")


def _material(m: _Reader) -> Material:
    """pipegen's own material keys; any other key is a field for a technique's material block,
    kept with its position and checked when a technique renders the scene
    (scene/material_fields.py)."""
    settings = tuple(_setting(m, k) for k in m.table if k not in _MATERIAL_KEYS)
    return Material(
        albedo=m.vec3("albedo"),
        specular=m.number("specular", 0.25, minimum=0.0),
        shininess=m.number("shininess", 32.0, positive=True),
        alpha=m.number("alpha", 1.0, minimum=0.0, maximum=1.0),
        translucent=m.boolean("translucent", False),
        settings=settings,
    )


def _setting(m: _Reader, key: str) -> MaterialSetting:
    value = m.table[key]
    ok = lambda v: isinstance(v, (int, float)) and not isinstance(v, bool)  # noqa: E731
    if not (ok(value) or isinstance(value, list) and value and all(ok(v) for v in value)):
        m.fail(key, f"material field '{key}' in {_describe(m.path)} must be a number or a list "
               f"of numbers, not {_show(value)}",
               hint="pipegen's own material keys: " + ", ".join(_MATERIAL_KEYS) + "; any other "
                    "key is a field of the technique's `material { … }` block")
    value = tuple(value) if isinstance(value, list) else value
    return MaterialSetting(key, value, m.loc.find(m.path + (key,)), _describe(m.path))


def mtl_material(m) -> Material:
    """An :class:`pipegen.scene.obj.MtlMaterial` as the scene's material."""
    return Material(albedo=tuple(float(x) for x in m.albedo), specular=float(m.specular),
                    shininess=float(m.shininess), alpha=float(m.alpha), translucent=m.translucent)


def _object(r: _Reader, index: int, base_dir: Path, next_id: int,
            notes: list[str]) -> tuple[list[SceneObject], Optional[int]]:
    """The objects of one ``[[objects]]`` entry: one, or for an OBJ file without a
    ``material`` table one per ``usemtl`` material (ids from ``id`` on, or from ``next_id``:
    the position among the scene's objects, 1-based), and the explicit stipple layer."""
    r.check_keys({"name", "id", "mesh", "obj", "translate", "rotate_deg", "scale", "material",
                  "segments", "rings", "divisions", "layer"})
    if r.has("mesh") == r.has("obj"):
        r.fail((), f"objects[{index}] needs exactly one of 'mesh' (plane, box, sphere, cylinder) "
                   "or 'obj' (a path)")
    parts: list[tuple[str, meshes.Mesh, Optional[Material]]]   # name suffix, mesh, material
    if r.has("mesh"):
        kind = r.string("mesh", choices=tuple(meshes.PRIMITIVES))
        params = {"sphere": ("segments", "rings"), "cylinder": ("segments",), "plane": ("divisions",),
                  "box": ()}[kind]
        for p in ("segments", "rings", "divisions"):
            if r.has(p) and p not in params:
                r.fail(p, f"'{p}' does not apply to a {kind}")
        kwargs = {p: r.integer(p, minimum=3 if p != "divisions" else 1, maximum=512)
                  for p in params if r.has(p)}
        parts, mesh_name = [("", meshes.PRIMITIVES[kind](**kwargs), None)], kind
    else:
        from pipegen.scene import obj as objfile
        rel = r.string("obj")
        obj_path = (base_dir / rel) if not Path(rel).is_absolute() else Path(rel)
        try:
            model = objfile.read_obj(obj_path)
        except OSError as e:
            r.fail("obj", f"cannot read OBJ file '{obj_path}': {e.strerror}")
        except meshes.ObjError as e:
            where = f"{obj_path}:{e.line}: " if e.line else f"{obj_path}: "
            r.fail("obj", f"bad OBJ file: {where}{e}")
        mesh_name = str(obj_path)
        if r.has("material"):
            parts = [("", model.mesh, None)]
            named = [p.material.name for p in model.parts if p.material.name != "(default)"]
            if named:
                notes.append(f"{obj_path.name}: the scene's material replaces its "
                             f"{len(named)} MTL material(s) ({', '.join(named[:6])}"
                             f"{', ...' if len(named) > 6 else ''})")
            notes += [n for n in model.notes if ".mtl:" not in n]
        else:
            parts = [(f"/{p.material.name}" if len(model.parts) > 1 else "", p.mesh,
                      mtl_material(p.material)) for p in model.parts if p.mesh.triangle_count]
            notes += model.notes
            if not parts:
                r.fail("obj", f"OBJ file '{obj_path}' has no triangle left after dropping "
                              "degenerate ones")

    scale_raw = r.table.get("scale", 1.0)
    if isinstance(scale_raw, list):
        scale = r.vec3("scale")
    else:
        s = r.number("scale", 1.0)
        scale = (s, s, s)
    if any(s == 0 for s in scale):
        r.fail("scale", f"objects[{index}].scale must not have a zero component")
    matrix = transform_matrix(r.vec3("translate", [0, 0, 0]), r.vec3("rotate_deg", [0, 0, 0]), scale)

    material = _material(r.sub("material")) if r.has("material") or r.has("mesh") else None
    first_id = r.integer("id", next_id, minimum=1, maximum=255)
    if first_id + len(parts) - 1 > 255:
        r.fail("id", f"objects[{index}] needs ids {first_id}..{first_id + len(parts) - 1} (one per "
                     f"material of its OBJ file), past 255")
    name = r.string("name", f"{mesh_name if r.has('mesh') else 'obj'}{index}")
    translucent = [(material or m).translucent for _, _, m in parts]
    layer = None
    if r.has("layer"):
        if not all(translucent):
            r.fail("layer", f"objects[{index}].layer is for translucent objects only",
                   hint="set `translucent = true` in its material, or remove the layer")
        layer = r.integer("layer", minimum=1, maximum=STIPPLE_LAYERS)
    return [make_object(name + suffix, first_id + k, mesh_name, mesh, material or m, matrix)
            for k, (suffix, mesh, m) in enumerate(parts)], layer


def _light(r: _Reader) -> Light:
    kind = r.string("type", "point", choices=tuple(LIGHT_TYPES))
    keys = {"point": {"position", "radius", "color", "shadows"},
            "spot": {"position", "radius", "color", "direction", "inner_deg", "outer_deg",
                     "shadows"},
            "directional": {"direction", "color", "radius", "shadows"}}[kind]
    r.check_keys(keys | {"type"})
    color = r.vec3("color")
    shadows = r.boolean("shadows", False)
    if kind == "directional":
        return Light("directional", color, direction=_unit(r.vec3("direction", nonzero=True)),
                     radius=r.number("radius", 0.0, minimum=0.0), shadows=shadows)
    position, radius = r.vec3("position"), r.number("radius", positive=True)
    if kind == "point":
        return Light("point", color, position=position, radius=radius, shadows=shadows)
    inner = r.number("inner_deg", minimum=0.0, maximum=89.9)
    outer = r.number("outer_deg", minimum=0.0, maximum=89.9)
    if not inner < outer:
        r.fail("outer_deg", f"a spot light needs inner_deg < outer_deg, got {inner} and {outer}")
    from pipegen.scene.shadows import SPOT_MAX_OUTER_DEG
    if shadows and outer > SPOT_MAX_OUTER_DEG:
        r.fail("outer_deg", f"a spot light casting shadows needs outer_deg <= "
               f"{SPOT_MAX_OUTER_DEG:g} (its shadow map is one perspective frustum), got {outer}",
               hint="narrow the cone, or drop `shadows`")
    return Light("spot", color, position=position, radius=radius,
                 direction=_unit(r.vec3("direction", nonzero=True)), inner_deg=inner, outer_deg=outer,
                 shadows=shadows)


def _unit(v) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return (float(a[0]), float(a[1]), float(a[2]))


# -- the built-in scene ------------------------------------------------------------------------


def default_scene() -> Scene:
    """A small lit scene that needs no file: a floor, boxes, spheres and cylinders under eight
    coloured point lights (at most four light spheres over any pixel), 320x180."""
    return parse_scene(DEFAULT_SCENE_TOML, "<default scene>", name="default")


DEFAULT_SCENE_TOML = """
name = "default"
width = 320
height = 180
ambient = [0.08, 0.08, 0.09]

[camera]
position = [0.0, 6.5, 10.5]
target = [0.0, 0.6, 0.0]
fov_y_deg = 45
near = 0.5
far = 60

# The floor reaches under the camera but not behind it, so nothing needs near-plane clipping.
[[objects]]
name = "floor"
mesh = "plane"
translate = [0, 0, -20]
scale = [100, 1, 60]
material = { albedo = [0.75, 0.75, 0.72], specular = 0.15, shininess = 24 }

[[objects]]
name = "white sphere"
mesh = "sphere"
segments = 32
rings = 16
translate = [0.0, 0.9, 0.0]
scale = 1.8
material = { albedo = [0.9, 0.9, 0.9], specular = 0.6, shininess = 64 }

[[objects]]
name = "red box"
mesh = "box"
translate = [-3.6, 0.6, 0.7]
rotate_deg = [0, 25, 0]
scale = 1.2
material = { albedo = [0.85, 0.25, 0.2], specular = 0.3, shininess = 32 }

[[objects]]
name = "tall box"
mesh = "box"
translate = [3.6, 1.0, 0.5]
rotate_deg = [0, -20, 0]
scale = [1.0, 2.0, 1.0]
material = { albedo = [0.3, 0.45, 0.85], specular = 0.4, shininess = 48 }

[[objects]]
name = "gold cylinder"
mesh = "cylinder"
segments = 32
translate = [-1.8, 0.9, -3.1]
scale = [1.0, 1.8, 1.0]
material = { albedo = [0.9, 0.7, 0.3], specular = 0.5, shininess = 32 }

[[objects]]
name = "green sphere"
mesh = "sphere"
translate = [-1.6, 0.45, 1.0]
scale = 0.9
material = { albedo = [0.3, 0.8, 0.35], specular = 0.5, shininess = 40 }

[[objects]]
name = "purple cylinder"
mesh = "cylinder"
translate = [2.0, 0.35, 1.0]
scale = [1.1, 0.7, 1.1]
material = { albedo = [0.7, 0.35, 0.8], specular = 0.3, shininess = 24 }

# Eight lights on a 4 x 2 grid 3.6 apart, all at the same height, radius 3.5 < 3.6: a point is
# within 3.5 of at most the four corners of its grid cell.
[[lights]]
position = [-5.4, 1.5, -1.8]
radius = 3.5
color = [1.4, 0.45, 0.3]

[[lights]]
position = [-1.8, 1.5, -1.8]
radius = 3.5
color = [1.4, 1.1, 0.45]

[[lights]]
position = [1.8, 1.5, -1.8]
radius = 3.5
color = [0.45, 1.4, 0.55]

[[lights]]
position = [5.4, 1.5, -1.8]
radius = 3.5
color = [0.4, 1.0, 1.4]

[[lights]]
position = [-5.4, 1.5, 1.8]
radius = 3.5
color = [1.1, 0.45, 1.4]

[[lights]]
position = [-1.8, 1.5, 1.8]
radius = 3.5
color = [0.5, 0.7, 1.4]

[[lights]]
position = [1.8, 1.5, 1.8]
radius = 3.5
color = [1.4, 0.75, 0.3]

[[lights]]
position = [5.4, 1.5, 1.8]
radius = 3.5
color = [1.4, 0.5, 0.9]
"""
