"""The scene model: objects, lights, a camera and the output size (``Scene``), with the helpers
every loader shares (transforms, ``make_object``, stipple layers, load notes).  The loaders sit
above it: ``scene`` (TOML scene files; it re-exports this module's names, the public
``scene/load.py``), ``gltf`` (glTF 2.0) and ``obj`` (OBJ + MTL)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from pipegen.scene import meshes
from pipegen.core.diagnostics import PipegenError
from pipegen.scene.material_fields import MaterialSetting, material_table


LIGHT_TYPES = {"point": 0, "spot": 1, "directional": 2}

# Light-table fields: name -> (GLSL types accepted in a schema, number of components).
LIGHT_FIELDS = {
    "position": (("vec3",), 3),
    "radius": (("float",), 1),
    "color": (("vec3",), 3),
    "direction": (("vec3",), 3),
    "type": (("uint", "int", "float"), 1),
    "cos_inner": (("float",), 1),
    "cos_outer": (("float",), 1),
    # shadow maps (pipegen/scene/shadows.py): the light's atlas tile (-1: no shadow) and the rows of
    # its shadow projection @ view
    "shadow_tile": (("float", "int"), 1),
    "shadow_m0": (("vec4",), 4),
    "shadow_m1": (("vec4",), 4),
    "shadow_m2": (("vec4",), 4),
    "shadow_m3": (("vec4",), 4),
}


STIPPLE_LAYERS = 3   # translucent layers 1..3; layer 0 is the opaque surface


def stipple_owner(x, y):
    """The layer that owns G-buffer pixel (x, y) in the 2x2 stipple pattern:
    ``(x & 1) + 2 * (y & 1)``, so each 2x2 block has one pixel of each layer 0..3.

    ``x``, ``y`` are the integer pixel coordinates (the floor of the window coordinates, i.e.
    ``gl_FragCoord.xy`` rounded down) of the G-buffer the pattern is applied to (the
    low-resolution one in inferred lighting), with ``y`` counted from the *bottom* row as GL
    window coordinates are.  For an array stored top row first, ``y = height - 1 - row``
    (:func:`stipple_map` does that).  Accepts Python ints or integer numpy arrays.
    """
    return (x & 1) + 2 * (y & 1)


def stipple_map(width: int, height: int, top_down: bool = True) -> np.ndarray:
    """int64 (height, width): :func:`stipple_owner` of every pixel, rows top first (like the
    reference images) or, with ``top_down=False``, bottom first (GL / runtime row order)."""
    x = np.arange(width, dtype=np.int64)[None, :]
    y = np.arange(height, dtype=np.int64)[:, None]
    if top_down:
        y = height - 1 - y
    return stipple_owner(x, y)


# -- data --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Material:
    albedo: tuple[float, float, float]
    specular: float = 0.25
    shininess: float = 32.0
    alpha: float = 1.0
    translucent: bool = False
    # fields of a technique's `material { … }` block, checked when one renders the scene
    settings: tuple[MaterialSetting, ...] = ()

    @property
    def kind(self) -> str:
        """The material flag that ``draw scene.opaque`` / ``scene.translucent`` select by."""
        return "translucent" if self.translucent else "opaque"


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One object: its mesh already transformed to world space (float64)."""

    name: str
    id: int
    mesh: str                      # primitive name or the OBJ path
    material: Material
    matrix: np.ndarray             # 4x4 object -> world
    positions: np.ndarray          # (3T, 3) world space, ccw front faces seen from outside
    normals: np.ndarray            # (3T, 3) world space, unit length
    groups: np.ndarray             # (T,) normal group per triangle, 0..255
    layer: int = 0                 # stipple layer: 0 opaque, 1..3 translucent (see above)

    @property
    def triangle_count(self) -> int:
        return len(self.groups)

    @property
    def bounds_centre(self) -> np.ndarray:
        """Centre of the world-space bounding box (float64 (3,))."""
        return 0.5 * (self.positions.min(axis=0) + self.positions.max(axis=0))


@dataclass(frozen=True)
class Light:
    type: str                                  # point | spot | directional
    color: tuple[float, float, float]
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    direction: tuple[float, float, float] = (0.0, 0.0, -1.0)   # unit, the way light travels
    inner_deg: float = 0.0
    outer_deg: float = 0.0
    shadows: bool = False                      # casts shadows (a point light: six tiles; shadows.py)

    @property
    def type_code(self) -> int:
        return LIGHT_TYPES[self.type]

    @property
    def cos_inner(self) -> float:
        """Spot: cos(inner).  Other types get -1 (with cos_outer = -2), so that a generic
        ``smoothstep(cos_outer, cos_inner, dot(-l, dir))`` is 1 for every direction."""
        return math.cos(math.radians(self.inner_deg)) if self.type == "spot" else -1.0

    @property
    def cos_outer(self) -> float:
        return math.cos(math.radians(self.outer_deg)) if self.type == "spot" else -2.0


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of two 3-vectors, the same products and differences (bit-identical),
    without its general-case overhead (~40 us a call; renderers ask for the view matrix every
    frame)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


@dataclass(frozen=True)
class Camera:
    position: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y_deg: float = 45.0
    near: float = 0.1
    far: float = 100.0
    # a fixed aspect ratio (None: the output's): a reference evaluated at the size of a
    # scaled target keeps the projection of the output it stands in for
    aspect: Optional[float] = None

    def view_matrix(self) -> np.ndarray:
        """World -> view (look-at; the camera looks down its -z), float64, column vectors."""
        eye = np.asarray(self.position, dtype=np.float64)
        f = np.asarray(self.target, dtype=np.float64) - eye
        f /= np.linalg.norm(f)
        s = _cross(f, np.asarray(self.up, dtype=np.float64))
        s /= np.linalg.norm(s)
        u = _cross(s, f)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = s, u, -f
        m[:3, 3] = -m[:3, :3] @ eye
        return m

    def projection(self, aspect: float) -> np.ndarray:
        """View -> GL clip space (z in [-w, w]), like ``gluPerspective``; float64.  ``aspect``:
        the output's width / height, unless the camera fixes its own."""
        aspect = self.aspect or aspect
        t = 1.0 / math.tan(math.radians(self.fov_y_deg) / 2.0)
        n, f = self.near, self.far
        p = np.zeros((4, 4))
        p[0, 0] = t / aspect
        p[1, 1] = t
        p[2, 2] = (f + n) / (n - f)
        p[2, 3] = 2.0 * f * n / (n - f)
        p[3, 2] = -1.0
        return p


@dataclass(frozen=True)
class Geometry:
    """A non-indexed triangle list in world space, float32, ready for a vertex buffer."""

    positions: np.ndarray   # (V, 3)
    normals: np.ndarray     # (V, 3)
    albedo: np.ndarray      # (V, 3)
    material: np.ndarray    # (V, 3): specular, shininess, alpha
    ids: np.ndarray         # (V, 2): object id, normal group
    layer: Optional[np.ndarray] = None   # (V,): stipple layer (0 opaque, 1..3); not interleaved

    def __post_init__(self):
        if self.layer is None:   # geometry built without layers (tests, fakes): all opaque
            object.__setattr__(self, "layer", np.zeros(len(self.positions), np.float32))

    @property
    def vertex_count(self) -> int:
        return len(self.positions)

    def interleaved(self) -> np.ndarray:
        """(V, 14) float32 in attribute order position, normal, albedo, material, ids
        (``layer`` is a separate array, not part of this layout)."""
        return np.concatenate([self.positions, self.normals, self.albedo, self.material, self.ids],
                              axis=1).astype(np.float32)


@dataclass(frozen=True, eq=False)
class Scene:
    width: int
    height: int
    ambient: np.ndarray                    # (3,) float64
    objects: tuple[SceneObject, ...]
    lights: tuple[Light, ...]
    camera: Camera
    name: str = "scene"
    clear_color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    notes: tuple[str, ...] = ()            # what the loaders ignored or changed, said once
    previous_camera: Optional[Camera] = None   # the previous frame's; None: ``camera``

    @property
    def prev_camera(self) -> Camera:
        """The previous frame's camera (``prev_view``, ``prev_proj``): ``camera`` unless the
        scene gives one (``[camera.previous]``)."""
        return self.previous_camera if self.previous_camera is not None else self.camera

    def with_previous_camera(self, camera: Optional[Camera]) -> "Scene":
        return dataclasses.replace(self, previous_camera=camera)

    def with_size(self, width: int, height: int) -> "Scene":
        if width < 1 or height < 1:
            raise PipegenError(None, f"output size must be positive, got {width}x{height}")
        return dataclasses.replace(self, width=int(width), height=int(height))

    @property
    def aspect(self) -> float:
        return self.width / self.height

    @property
    def light_types(self) -> set[str]:
        return {l.type for l in self.lights}

    @property
    def has_translucent(self) -> bool:
        return any(o.material.translucent for o in self.objects)

    def select(self, material: tuple[str, ...] = ()) -> list[SceneObject]:
        """Objects passing a material filter: () is all, else the flags to keep."""
        for m in material:
            if m not in ("opaque", "translucent"):
                raise PipegenError(None, f"unknown material filter '{m}' (opaque, translucent)")
        return [o for o in self.objects if not material or o.material.kind in material]

    def geometry(self, material: tuple[str, ...] = ()) -> Geometry:
        objs = self.select(tuple(material))
        if not objs:
            z = np.zeros((0, 3), np.float32)
            return Geometry(z, z, z, z, np.zeros((0, 2), np.float32), np.zeros(0, np.float32))
        pos = np.concatenate([o.positions for o in objs])
        nrm = np.concatenate([o.normals for o in objs])
        counts = [len(o.positions) for o in objs]
        albedo = np.repeat([o.material.albedo for o in objs], counts, axis=0)
        mat = np.repeat([(o.material.specular, o.material.shininess, o.material.alpha) for o in objs],
                        counts, axis=0)
        ids = np.concatenate([np.stack([np.full(len(o.groups) * 3, o.id), np.repeat(o.groups, 3)], axis=1)
                              for o in objs])
        layer = np.repeat([o.layer for o in objs], counts)
        f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
        return Geometry(f32(pos), f32(nrm), f32(albedo), f32(mat), f32(ids), f32(layer))

    def material_table(self, schema) -> np.ndarray:
        """float64 (ids, fields, 4): each object id's material fields for a technique's
        schema ((name, type, default) triples); ``scene/material_fields.py``."""
        return material_table(self.objects, schema)

    def light_table(self, fields: list[tuple[str, str]], capacity: int) -> np.ndarray:
        """float32 (capacity, F, 4): field k of light i in ``[i, k]``, components first, the
        rest zero; rows past the scene's lights are zero.

        Fields that do not apply to a light type still hold safe values: point lights have
        direction (0, 0, -1) and cos_inner/cos_outer = -1/-2 (a spot factor of 1 everywhere);
        directional lights have position 0 and their (ignored) radius, default 0.
        """
        if len(self.lights) > capacity:
            raise PipegenError(None, f"the scene has {len(self.lights)} lights but the light table "
                               f"holds {capacity}", hint="raise the capacity in `lights[N]`")
        for name, type_str in fields:
            if name not in LIGHT_FIELDS:
                raise PipegenError(None, f"unknown light field '{name}'",
                                   hint="fields: " + ", ".join(LIGHT_FIELDS))
            if type_str not in LIGHT_FIELDS[name][0]:
                raise PipegenError(None, f"light field '{name}' has type "
                                   f"{LIGHT_FIELDS[name][0][0]}, not {type_str}")
        table = np.zeros((capacity, len(fields), 4), dtype=np.float32)
        from pipegen.scene.shadows import SHADOW_FIELDS, light_fields, shadow_table
        shadows = None                          # shadow fields: from the scene, not the light
        for k, (name, _) in enumerate(fields):
            if name in SHADOW_FIELDS:
                shadows = shadow_table(self) if shadows is None else shadows
                table[:len(self.lights), k] = light_fields(self, name, shadows)
                continue
            for i, light in enumerate(self.lights):
                v = np.atleast_1d(np.asarray(light_field(light, name), dtype=np.float64))
                table[i, k, : len(v)] = v
        return table


def light_field(light: Light, name: str):
    """The value a light-table field holds for ``light`` (float64)."""
    if name == "type":
        return float(light.type_code)
    if name == "cos_inner":
        return light.cos_inner
    if name == "cos_outer":
        return light.cos_outer
    return getattr(light, name)


# -- loading -----------------------------------------------------------------------------------


class SceneLoadWarning(UserWarning):
    """What a loader ignored or changed (textures, unsupported statements, degenerate
    triangles, defaults it had to pick); also kept in ``Scene.notes``."""


def report_notes(notes: list[str]) -> None:
    """Warn each note once, attributed to the first caller outside pipegen's loaders."""
    import sys
    import warnings
    here = Path(__file__).parent
    loaders = {here / name for name in ("model.py", "load.py", "gltf.py", "obj.py", "meshes.py")}
    level, frame = 1, sys._getframe(0)
    while frame is not None and Path(frame.f_code.co_filename) in loaders:
        frame, level = frame.f_back, level + 1
    for note in notes:
        warnings.warn(note, SceneLoadWarning, stacklevel=level)


def rotation_matrix(rotate_deg) -> np.ndarray:
    """Rotation about x, then y, then z (degrees): R = Rz @ Ry @ Rx."""
    ax, ay, az = (math.radians(a) for a in rotate_deg)
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def transform_matrix(translate=(0, 0, 0), rotate_deg=(0, 0, 0), scale=(1, 1, 1)) -> np.ndarray:
    """Object -> world: scale, then rotate, then translate."""
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(rotate_deg) @ np.diag(np.asarray(scale, dtype=np.float64))
    m[:3, 3] = translate
    return m


def make_object(name: str, obj_id: int, mesh_name: str, mesh: meshes.Mesh, material: Material,
                matrix: np.ndarray) -> SceneObject:
    """Place a local mesh in the world.  Normals use the inverse transpose; a mirroring
    transform (negative determinant) reverses the winding so front faces stay ccw."""
    lin = matrix[:3, :3]
    pos = mesh.positions @ lin.T + matrix[:3, 3]
    nrm = mesh.normals @ np.linalg.inv(lin)   # == (inv(lin).T @ n.T).T
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    if np.linalg.det(lin) < 0:
        order = np.arange(len(pos)).reshape(-1, 3)[:, [0, 2, 1]].reshape(-1)
        pos, nrm = pos[order], nrm[order]
    return SceneObject(name, obj_id, mesh_name, material, matrix, pos, nrm, mesh.groups.copy())


def assign_layers(objects: list[SceneObject], camera_position,
                  explicit: Optional[list[Optional[int]]] = None) -> list[SceneObject]:
    """Objects with their stipple ``layer`` set (see the module docstring): opaque 0;
    translucent: ``explicit[i]`` where given (1..3), else the automatic far -> near cycle
    1, 2, 3, 1, ... over the translucent objects without an explicit layer, by the distance
    from ``camera_position`` to the centre of each one's bounding box (stable: ties keep
    list order)."""
    explicit = list(explicit) if explicit is not None else [None] * len(objects)
    eye = np.asarray(camera_position, dtype=np.float64)
    auto = [i for i, o in enumerate(objects) if o.material.translucent and explicit[i] is None]
    dist = [float(np.linalg.norm(objects[i].bounds_centre - eye)) for i in auto]
    order = sorted(range(len(auto)), key=lambda k: -dist[k])       # stable: far first
    layers = [0] * len(objects)
    for rank, k in enumerate(order):
        layers[auto[k]] = rank % STIPPLE_LAYERS + 1
    out = []
    for i, o in enumerate(objects):
        if o.material.translucent and explicit[i] is not None:
            if not 1 <= explicit[i] <= STIPPLE_LAYERS:
                raise PipegenError(None, f"object '{o.name}': layer {explicit[i]} is not in "
                                   f"1..{STIPPLE_LAYERS}")
            layers[i] = int(explicit[i])
        out.append(o if o.layer == layers[i] else dataclasses.replace(o, layer=layers[i]))
    return out
