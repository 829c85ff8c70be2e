"""glTF 2.0 files (``.gltf`` with its buffers, or ``.glb``) as scene content.

pygltflib reads the document (JSON, the GLB container, data URIs); this module decodes the
accessors it needs with numpy (positions, normals, indices: any component type, byte stride,
normalised integers, sparse), walks the default scene's node tree and builds:

- **objects**: one per mesh primitive (``TRIANGLES``, ``TRIANGLE_STRIP``, ``TRIANGLE_FAN``;
  points and lines are skipped and reported), its positions and normals placed by the node's
  world transform (``matrix``, or translation · rotation · scale), ids 1, 2, ... in traversal
  order.  Without ``NORMAL`` a primitive gets flat normals (as the glTF specification asks).
  Degenerate triangles are dropped and counted; a position that is not finite is an error
  that names the mesh, primitive, accessor and vertex.
- **materials** from ``pbrMetallicRoughness`` (:func:`pbr_material` documents the mapping),
  ``alphaMode BLEND`` -> translucent with ``alpha`` = base colour alpha.
- **camera**: the first node with a perspective camera (``yfov``, ``znear``, ``zfar``; the node
  looks down its -z with +y up).
- **lights** from ``KHR_lights_punctual`` (:func:`punctual_light` documents the mapping).

Textures, vertex colours, texture coordinates, skins, animations, morph targets and material
extensions are ignored, and each kind is reported once in ``notes``.  Files that require
Draco or meshopt compression are refused (their geometry cannot be read without them).
"""

from __future__ import annotations

import math
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from pipegen.scene import gltf_input, limits, meshes
from pipegen.scene.gltf_input import GltfError
from pipegen.scene.material_fields import MaterialSetting
from pipegen.scene.model import (
    Camera, Light, Material, Scene, SceneObject, assign_layers, make_object, report_notes)


#: Minimum GGX roughness before squaring (keeps the Blinn-Phong exponent finite).
MIN_ROUGHNESS = 0.03
#: Largest Blinn-Phong exponent the roughness mapping gives.
MAX_SHININESS = 1024.0
#: Dielectric reflectance at normal incidence (the glTF metallic-roughness model's 4 %).
DIELECTRIC_F0 = 0.04
#: Without ``range``: the distance at which an inverse-square light of intensity I (the
#: largest colour component times the intensity) falls to 1/256, ``sqrt(256 I)`` = 16 sqrt(I).
RANGE_LEVEL = 1.0 / 256.0
#: Angles the scene accepts for spot cones (``outer_deg`` <= 89.9).
MAX_CONE_DEG = 89.9

SUPPORTED_REQUIRED = {"KHR_lights_punctual", "KHR_mesh_quantization", "KHR_materials_emissive_strength",
                      "KHR_materials_ior", "KHR_materials_specular", "KHR_materials_unlit",
                      "KHR_texture_transform", "KHR_materials_transmission", "KHR_materials_volume",
                      "KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_texture_basisu",
                      "EXT_texture_webp"}

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
              5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 4: "TRIANGLES",
          5: "TRIANGLE_STRIP", 6: "TRIANGLE_FAN"}


@dataclass(frozen=True)
class GltfImport:
    """What a glTF file contributes to a scene."""

    objects: tuple[SceneObject, ...]
    camera: Optional[Camera]
    lights: tuple[Light, ...]
    notes: tuple[str, ...]
    dropped: int = 0                  # degenerate triangles removed


# -- mapping rules -----------------------------------------------------------------------------


def pbr_material(base_color=(1.0, 1.0, 1.0, 1.0), metallic: float = 1.0, roughness: float = 1.0,
                 alpha_mode: str = "OPAQUE") -> Material:
    """glTF metallic-roughness -> the scene's Blinn-Phong material (defaults: the spec's).

    - ``albedo`` = base colour x (1 - metallic): metals have no diffuse term;
    - ``shininess`` = 2 / a² - 2 with a = max(roughness, 0.03)² (the Blinn-Phong exponent whose
      lobe matches a GGX/Beckmann lobe of roughness a, Walter et al. 2007), in [1, 1024];
    - ``specular`` = F0 x (shininess + 8) / 8, F0 = 0.04 (1 - metallic) + metallic x mean(base
      colour): the reflectance at normal incidence times the normalisation that keeps a
      Blinn-Phong lobe's energy as it narrows (the 1/pi both terms share is left out, as the
      scene's diffuse term leaves it out);
    - ``alphaMode``: ``BLEND`` -> translucent, ``alpha`` = base colour alpha; ``OPAQUE`` and
      ``MASK`` -> opaque, ``alpha`` 1 (the cutoff needs per-pixel alpha: reported).
    """
    r, g, b, a = (float(x) for x in base_color)
    m = min(1.0, max(0.0, float(metallic)))
    rough = max(MIN_ROUGHNESS, min(1.0, float(roughness)))
    alpha_ggx = rough * rough
    shininess = min(MAX_SHININESS, max(1.0, 2.0 / (alpha_ggx * alpha_ggx) - 2.0))
    f0 = DIELECTRIC_F0 * (1.0 - m) + m * (r + g + b) / 3.0
    blend = alpha_mode == "BLEND"
    return Material(albedo=(r * (1.0 - m), g * (1.0 - m), b * (1.0 - m)),
                    specular=f0 * (shininess + 8.0) / 8.0, shininess=shininess,
                    alpha=min(1.0, max(0.0, a)) if blend else 1.0, translucent=blend)


def punctual_light(light: dict, world: np.ndarray, intensity_scale: float = 1.0) -> Light:
    """A ``KHR_lights_punctual`` light placed by its node's world matrix.

    - ``color`` = color x intensity x ``intensity_scale`` (no photometric conversion: candela
      and lux are taken as the scene's linear units);
    - ``position``: the node's origin; ``direction``: the node's -z (point lights ignore it);
    - ``radius`` = ``range``; without one, 16 sqrt(I) with I the largest component of the
      colour: where an inverse-square falloff I / d² drops to 1/256 (one 8-bit code);
    - spot ``inner_deg``/``outer_deg`` = ``innerConeAngle`` (default 0) / ``outerConeAngle``
      (default pi/4) in degrees, outer at most 89.9 and inner below outer.
    """
    kind = light.get("type")
    if kind not in ("point", "spot", "directional"):
        raise GltfError(f"light type {kind!r} is not point, spot or directional")
    color = np.asarray(light.get("color", [1.0, 1.0, 1.0]), dtype=np.float64)
    color = color * float(light.get("intensity", 1.0)) * intensity_scale
    col = (float(color[0]), float(color[1]), float(color[2]))
    d = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
    norm = np.linalg.norm(d)
    direction = tuple(float(x) for x in d / norm) if norm > 0 else (0.0, 0.0, -1.0)
    if kind == "directional":
        return Light("directional", col, direction=direction)
    pos = tuple(float(x) for x in world[:3, 3])
    rng = light.get("range")
    if rng is not None and float(rng) > 0:
        radius = float(rng)
    else:
        radius = math.sqrt(max(max(col), 0.0) / RANGE_LEVEL)
        if radius <= 0:
            radius = 1e-3
    if kind == "point":
        return Light("point", col, position=pos, radius=radius)
    spot = light.get("spot", {}) or {}
    outer = min(math.degrees(float(spot.get("outerConeAngle", math.pi / 4))), MAX_CONE_DEG)
    inner = min(math.degrees(float(spot.get("innerConeAngle", 0.0))), outer * 0.999)
    return Light("spot", col, position=pos, radius=radius, direction=direction,
                 inner_deg=max(0.0, inner), outer_deg=outer)


def framing_camera(objects, fov_y_deg: float = 45.0) -> Camera:
    """A camera for a file without one: looking at the centre of the objects' bounding box
    from its +z side, raised 20°, far enough that the box's bounding sphere fits the
    vertical field of view."""
    pts = np.concatenate([o.positions for o in objects])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, radius = 0.5 * (lo + hi), max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    dist = radius / math.sin(math.radians(fov_y_deg) / 2.0)
    e = math.radians(20.0)
    pos = centre + dist * np.array([0.0, math.sin(e), math.cos(e)])
    return Camera(position=tuple(float(x) for x in pos), target=tuple(float(x) for x in centre),
                  fov_y_deg=fov_y_deg, near=max(1e-3 * dist, 0.5 * (dist - radius)),
                  far=dist + 2.0 * radius)


# -- reading -----------------------------------------------------------------------------------


class _Doc:
    """The document and its buffers, read on first use, and the accessors decoded with every
    range checked against what holds it (:mod:`pipegen.scene.gltf_input` read the file)."""

    def __init__(self, path: Path):
        self.path = path
        self.g, self._binary = gltf_input.load_document(path)
        self._buffers: dict[int, bytes] = {}

    def buffer(self, i: int, ref: str) -> bytes:
        if i not in self._buffers:
            buf = _item(self.g.buffers, i, "buffer", ref)
            self._buffers[i] = gltf_input.buffer_bytes(buf.uri, buf.byteLength, self.path.parent,
                                                       self._binary if i == 0 else None,
                                                       f"buffers[{i}]")
        return self._buffers[i]

    def accessor(self, i: int, ref: str, semantic: str = "") -> np.ndarray:
        """float64 (count, width) for float or normalised data, int64 otherwise.  ``ref`` is
        the JSON path that names accessor ``i``; ``semantic`` ``POSITION``/``NORMAL`` (VEC3)
        or ``indices`` (unsigned SCALAR), as the specification requires of them."""
        a = _item(self.g.accessors, i, "accessor", ref)
        where = f"accessors[{i}]"
        if a.count > limits.max_elements():
            raise GltfError(f"count {a.count} is more than the limit of {limits.max_elements()} "
                            "(PIPEGEN_SCENE_MAX_ELEMENTS raises it)", where + ".count")
        if semantic in ("POSITION", "NORMAL") and a.type != "VEC3":
            raise GltfError(f"{semantic} must be VEC3, not {a.type}", where + ".type")
        if semantic == "indices" and (a.type != "SCALAR" or a.componentType not in (5121, 5123, 5125)):
            raise GltfError("indices must be unsigned SCALAR (componentType 5121, 5123 or 5125)",
                            where)
        dt = np.dtype(_COMPONENT[a.componentType]).newbyteorder("<")
        width = _WIDTH[a.type]
        if a.bufferView is None:                 # zeros (count bounded above), sparse values
            out = np.zeros((a.count, width), dtype=dt)
        else:
            out = self._view(a.bufferView, a.byteOffset or 0, a.count, dt, width, where)
        if a.sparse is not None:
            out = self._sparse(a, out, dt, width, where + ".sparse")
        if dt.kind == "f":
            return out.astype(np.float64)
        if a.normalized:
            info = np.iinfo(dt)
            return np.maximum(out.astype(np.float64) / info.max, -1.0)
        return out.astype(np.int64)

    def _sparse(self, a, out: np.ndarray, dt: np.dtype, width: int, where: str) -> np.ndarray:
        s = a.sparse
        if s.count > a.count:
            raise GltfError(f"count {s.count} is more than the accessor's {a.count}",
                            where + ".count")
        idt = np.dtype(_COMPONENT[s.indices.componentType]).newbyteorder("<")
        idx = self._view(s.indices.bufferView, s.indices.byteOffset or 0, s.count, idt, 1,
                         where + ".indices")[:, 0].astype(np.int64)
        vals = self._view(s.values.bufferView, s.values.byteOffset or 0, s.count, dt, width,
                          where + ".values")
        if idx.max() >= a.count:
            k = int(np.argmax(idx >= a.count))
            raise GltfError(f"index {int(idx[k])} (entry {k}) is out of range: the accessor "
                            f"has {a.count} elements", where + ".indices")
        out = out.copy()
        out[idx] = vals
        return out

    def _view(self, view: int, offset: int, count: int, dt: np.dtype, width: int,
              where: str) -> np.ndarray:
        bv = _item(self.g.bufferViews, view, "bufferView", where + ".bufferView")
        view_where = f"bufferViews[{view}]"
        data = self.buffer(bv.buffer, view_where + ".buffer")
        begin = bv.byteOffset or 0
        if begin + bv.byteLength > len(data):
            raise GltfError(f"bytes {begin}..{begin + bv.byteLength} run past the end of buffer "
                            f"{bv.buffer} ({len(data)} bytes)", view_where)
        elem = dt.itemsize * width
        stride = bv.byteStride or elem
        if stride < elem:
            raise GltfError(f"byteStride {stride} is less than the {elem} bytes of an element "
                            "read through it", view_where + ".byteStride")
        need = stride * (count - 1) + elem
        if offset + need > bv.byteLength:
            raise GltfError(f"reads past the end of bufferView {view}: {count} elements "
                            f"of {elem} bytes at byteOffset {offset}, stride {stride} need "
                            f"{offset + need} bytes, it has {bv.byteLength}", where)
        raw = np.frombuffer(data, np.uint8, count=need, offset=begin + offset)
        rows = np.lib.stride_tricks.as_strided(raw, (count, elem), (stride, 1))
        return np.ascontiguousarray(rows).view(dt).reshape(count, width)


def _local_matrix(node) -> np.ndarray:
    if node.matrix is not None and len(node.matrix) == 16:
        return np.array(node.matrix, dtype=np.float64).reshape(4, 4).T    # column-major
    m = np.eye(4)
    if node.scale is not None:
        m = np.diag([*map(float, node.scale), 1.0]) @ m
    if node.rotation is not None:
        x, y, z, w = (float(c) for c in node.rotation)
        n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
        x, y, z, w = x / n, y / n, z / n, w / n
        r = np.eye(4)
        r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        m = r @ m
    if node.translation is not None:
        t = np.eye(4)
        t[:3, 3] = [float(c) for c in node.translation]
        m = t @ m
    return m


def _invertible(world: np.ndarray) -> bool:
    """Whether a node's world matrix can place a mesh: finite, with a finite inverse of its
    3x3 part (normals use the inverse transpose; a scale of 0 has none)."""
    if not np.isfinite(world).all():
        return False
    lin = world[:3, :3]
    det = np.linalg.det(lin)
    if not np.isfinite(det) or det == 0:
        return False
    with np.errstate(all="ignore"):
        return bool(np.isfinite(np.linalg.inv(lin)).all())


def _triangles(mode: int, idx: np.ndarray) -> np.ndarray:
    if mode == 4:
        return idx[: len(idx) // 3 * 3].reshape(-1, 3)
    k = np.arange(max(len(idx) - 2, 0))
    if mode == 5:                                   # strip: every other triangle flipped
        even = (k % 2) == 0
        a = np.where(even, idx[k], idx[k + 1])
        b = np.where(even, idx[k + 1], idx[k])
        return np.stack([a, b, idx[k + 2]], axis=1)
    return np.stack([np.full(len(k), idx[0]), idx[k + 1], idx[k + 2]], axis=1)   # fan


def load_gltf(path: str | Path, first_id: int = 1, intensity_scale: float = 1.0) -> GltfImport:
    """Objects, camera (None if the file has none), lights and notes of a glTF file."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(2, "No such file or directory", str(path))
    doc = _Doc(path)
    notes = _extension_notes(doc.g, path.name)
    walk = _NodeWalk(doc, path.name, first_id, intensity_scale, _punctual_lights(doc.g))
    walk.run(_root_nodes(doc.g))
    if not walk.objects:
        hidden = (f" (nodes {sorted(walk.unplaced)[:8]} have a singular transform)"
                  if walk.unplaced else "")
        raise GltfError("the scene has no triangles" + hidden, "meshes")
    camera = None
    if walk.camera_node is not None:
        camera, camera_note = _file_camera(doc.g, *walk.camera_node, walk.objects, path.name)
        if camera_note:
            notes.append(camera_note)
    notes += walk.notes()
    return GltfImport(tuple(walk.objects), camera, tuple(walk.lights), tuple(notes), walk.dropped)


def _extension_notes(g, file_name: str) -> list[str]:
    """Refuse a file that requires an extension pipegen cannot do without; note the used ones
    it ignores."""
    unsupported = sorted(set(g.extensionsRequired or []) - SUPPORTED_REQUIRED)
    if unsupported:
        raise GltfError(f"the file requires {', '.join(unsupported)}, which pipegen does not read",
                        "extensionsRequired")
    ignored = sorted(set(g.extensionsUsed or []) - {"KHR_lights_punctual", "KHR_mesh_quantization"})
    return [f"{file_name}: extensions ignored: {', '.join(ignored)}"] if ignored else []


def _punctual_lights(g) -> list:
    """The document's ``KHR_lights_punctual`` light definitions (nodes refer to them by index)."""
    return ((g.extensions or {}).get("KHR_lights_punctual") or {}).get("lights", [])


def _item(items, index, what: str, where: str, owner: str = ""):
    """``items[index]`` for an index read from the file at JSON path ``where``: one out of
    range (or negative, which Python would count from the end) is the file's error, not an
    IndexError.  ``owner`` says who refers to it (default: ``where`` less its last key)."""
    if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items or ()):
        owner = owner or where.rpartition(".")[0] or where
        raise GltfError(f"{owner} refers to {what} {index}, which does not exist "
                        f"(the file has {len(items or ())})", where)
    return items[index]


def _root_nodes(g) -> list[tuple[int, str]]:
    """The default scene's root nodes, each with the JSON path naming it; without scenes,
    every node that is nobody's child."""
    if g.scenes:
        scene_index = g.scene if g.scene is not None else 0
        scene = _item(g.scenes, scene_index, "scene", "scene", "the file's `scene`")
        return [(n, f"scenes[{scene_index}].nodes[{k}]") for k, n in enumerate(scene.nodes or [])]
    children = {c for n in g.nodes for c in (n.children or [])}
    return [(i, f"nodes[{i}]") for i in range(len(g.nodes)) if i not in children]


class _Materials:
    """The scene material of each glTF material index, made on first use (a material no drawn
    primitive uses adds no notes), and what the mapping left out."""

    def __init__(self, g):
        self._g = g
        self._cache: dict[Optional[int], Material] = {}
        self.dropped_textures: set[str] = set()
        self.notes: set[str] = set()

    def __call__(self, i: Optional[int]) -> Material:
        if i not in self._cache:
            self._cache[i] = self._default() if i is None else self._convert(i)
        return self._cache[i]

    def _default(self) -> Material:
        self.notes.add("primitives without a material get the glTF default "
                       "(white, metallic 1, roughness 1)")
        return pbr_material()

    def _convert(self, i: int) -> Material:
        m = self._g.materials[i]       # in range: _add_primitive checked it
        pbr = m.pbrMetallicRoughness
        base = (pbr.baseColorFactor if pbr and pbr.baseColorFactor is not None
                else [1.0, 1.0, 1.0, 1.0])
        metallic = pbr.metallicFactor if pbr and pbr.metallicFactor is not None else 1.0
        rough = pbr.roughnessFactor if pbr and pbr.roughnessFactor is not None else 1.0
        mode = m.alphaMode or "OPAQUE"
        material = pbr_material(base, metallic, rough, mode)
        label = m.name or f"material {i}"
        for key, tex in (("baseColorTexture", pbr and pbr.baseColorTexture),
                         ("metallicRoughnessTexture", pbr and pbr.metallicRoughnessTexture),
                         ("normalTexture", m.normalTexture),
                         ("occlusionTexture", m.occlusionTexture),
                         ("emissiveTexture", m.emissiveTexture)):
            if tex is not None:
                self.dropped_textures.add(f"{label}.{key}")
        settings = _material_settings(m, label)
        if settings:
            material = dataclasses.replace(material, settings=settings)
        if mode == "MASK":
            self.notes.add("alphaMode MASK drawn opaque (alphaCutoff needs textures)")
        if m.extensions:
            self.notes.add("material extensions ignored: " + ", ".join(sorted(m.extensions)))
        return material


def _material_settings(m, label: str) -> tuple[MaterialSetting, ...]:
    """A glTF material's fields for a technique's material block: ``emissiveFactor`` as
    ``emissive``, and the numbers and lists of numbers in ``extras`` under their keys.  Used
    where the technique declares them, ignored elsewhere (``MaterialSetting.required``)."""
    source = f"glTF material '{label}'"
    out = []
    # pygltflib fills an absent emissiveFactor with its default, black: only a glowing
    # material sets the field (black leaves the technique's default)
    if m.emissiveFactor is not None and any(float(x) != 0 for x in m.emissiveFactor):
        out.append(MaterialSetting("emissive", tuple(float(x) for x in m.emissiveFactor), None,
                                   source, required=False))
    extras = m.extras if isinstance(m.extras, dict) else {}
    for key, value in extras.items():
        value = tuple(value) if isinstance(value, list) else value
        nested = isinstance(value, tuple) and any(isinstance(v, (list, dict)) for v in value)
        if isinstance(value, dict) or nested:    # no field's value: not kept (and unhashable)
            continue
        out.append(MaterialSetting(str(key), value, None, f"{source} extras", required=False))
    return tuple(out)


class _NodeWalk:
    """Walks the node tree depth first, children in order, and collects what the nodes carry:
    an object per drawn primitive, the lights, the first camera node and what was ignored."""

    def __init__(self, doc: _Doc, file_name: str, first_id: int, intensity_scale: float,
                 lights_def: list):
        self.doc, self.g, self.file_name = doc, doc.g, file_name
        self.first_id, self.intensity_scale, self.lights_def = first_id, intensity_scale, lights_def
        self.materials = _Materials(doc.g)
        self.objects: list[SceneObject] = []
        self.lights: list[Light] = []
        self.camera_node: Optional[tuple[int, np.ndarray]] = None    # (camera index, world)
        self.ignored_attrs: set[str] = set()
        self.skipped_modes: set[str] = set()
        self.unplaced: set[int] = set()      # nodes whose transform cannot place a mesh
        self.dropped = 0

    def run(self, roots: list[tuple[int, str]]) -> None:
        """Depth first with a stack, not recursion: a chain of a million nodes is walked, and
        a node reached twice (a cycle, or two parents) is an error where it is reached."""
        stack = [(r, ref, np.eye(4)) for r, ref in reversed(roots)]
        visited = set()
        while stack:
            ni, ref, parent = stack.pop()
            node = _item(self.g.nodes, ni, "node", ref)
            if ni in visited:
                raise GltfError(f"node {ni} is reached twice (the node hierarchy must be a tree)",
                                ref)
            visited.add(ni)
            world = parent @ _local_matrix(node)
            self._visit(ni, node, world)
            for k in reversed(range(len(node.children or []))):
                stack.append((node.children[k], f"nodes[{ni}].children[{k}]", world))

    def _visit(self, ni: int, node, world: np.ndarray) -> None:
        if node.camera is not None and self.camera_node is None:
            self.camera_node = (node.camera, world, ni)
        ext = (node.extensions or {}).get("KHR_lights_punctual")
        if ext is not None:
            self._add_light(ni, ext.get("light"), world)
        if node.skin is not None:
            self.ignored_attrs.add("skins")
        if node.mesh is not None:
            mesh = _item(self.g.meshes, node.mesh, "mesh", f"nodes[{ni}].mesh", f"node {ni}")
            base_name = node.name or mesh.name or f"node{ni}"
            prims = mesh.primitives or []
            for pi, prim in enumerate(prims):
                name = base_name if len(prims) == 1 else f"{base_name}/{pi}"
                self._add_primitive(node.mesh, mesh, pi, prim, name, world, ni)

    def _add_light(self, ni: int, li: Optional[int], world: np.ndarray) -> None:
        where = f"nodes[{ni}].extensions.KHR_lights_punctual.light"
        _item(self.lights_def, li, "light", where, f"node {ni}")
        if not np.isfinite(world).all():
            raise GltfError("the node's transform is not finite (it carries a light)",
                            f"nodes[{ni}]")
        try:
            self.lights.append(punctual_light(self.lights_def[li], world, self.intensity_scale))
        except GltfError as e:
            raise GltfError(e.message, f"extensions.KHR_lights_punctual.lights[{li}]") from None

    def _add_primitive(self, mesh_index: int, mesh, pi: int, prim, name: str,
                       world: np.ndarray, ni: int) -> None:
        mode = 4 if prim.mode is None else prim.mode
        if mode not in (4, 5, 6):
            self.skipped_modes.add(_MODES.get(mode, str(mode)))
            return
        where = f"meshes[{mesh_index}].primitives[{pi}]"
        if prim.attributes.POSITION is None:
            raise GltfError(f"mesh {mesh_index} primitive {pi} has no POSITION", where + ".attributes")
        for a in ("TEXCOORD_0", "TEXCOORD_1", "COLOR_0", "TANGENT", "JOINTS_0", "WEIGHTS_0"):
            if getattr(prim.attributes, a, None) is not None:
                self.ignored_attrs.add(a)
        if prim.targets:
            self.ignored_attrs.add("morph targets")
        triangles, local = _primitive_mesh(self.doc, mesh_index, mesh, pi, prim, mode)
        if local is None:
            return
        self.dropped += triangles - local.triangle_count
        if not local.triangle_count:
            return
        obj_id = self.first_id + len(self.objects)
        if obj_id > 255:
            raise GltfError("more than 255 mesh primitives: object ids are 8-bit (1..255)", where)
        if prim.material is not None:
            _item(self.g.materials, prim.material, "material", where + ".material",
                  f"mesh {mesh_index} primitive {pi}")
        if not _invertible(world):
            self.unplaced.add(ni)
            return
        obj = make_object(name, obj_id, f"{self.file_name}#mesh{mesh_index}/{pi}", local,
                          self.materials(prim.material), world)
        if not np.isfinite(obj.positions).all():
            self.unplaced.add(ni)
            return
        self.objects.append(obj)

    def notes(self) -> list[str]:
        """What the walk ignored or dropped, one note per kind, in a fixed order."""
        name, notes = self.file_name, []
        if self.materials.dropped_textures:
            shown = sorted(self.materials.dropped_textures)
            notes.append(f"{name}: textures dropped (not supported): {', '.join(shown[:8])}"
                         + (f" and {len(shown) - 8} more" if len(shown) > 8 else ""))
        for n in sorted(self.materials.notes):
            notes.append(f"{name}: {n}")
        if self.ignored_attrs:
            notes.append(f"{name}: ignored {', '.join(sorted(self.ignored_attrs))}")
        if self.skipped_modes:
            notes.append(f"{name}: primitives skipped (not triangles): "
                         f"{', '.join(sorted(self.skipped_modes))}")
        if self.dropped:
            notes.append(f"{name}: dropped {self.dropped} degenerate (zero-area) triangles")
        if self.unplaced:
            shown = ", ".join(str(n) for n in sorted(self.unplaced)[:8])
            notes.append(f"{name}: meshes of nodes with a singular or overflowing transform "
                         f"skipped (a scale of 0 hides a node): node {shown}"
                         + (f" and {len(self.unplaced) - 8} more" if len(self.unplaced) > 8 else ""))
        return notes


def _primitive_mesh(doc: _Doc, mesh_index: int, mesh, pi: int, prim,
                    mode: int) -> tuple[int, Optional[meshes.Mesh]]:
    """A triangle primitive as a local mesh, with the number of triangles it had before the
    degenerate ones were dropped; ``(0, None)`` when its indices make no triangle."""
    attrs = prim.attributes
    where = f"meshes[{mesh_index}].primitives[{pi}]"
    pos = doc.accessor(attrs.POSITION, where + ".attributes.POSITION", "POSITION")
    bad = np.flatnonzero(~np.isfinite(pos).all(axis=1))
    if len(bad):
        raise GltfError(f"mesh {mesh_index} ('{mesh.name or ''}') primitive {pi}: "
                        f"POSITION (accessor {attrs.POSITION}) vertex {int(bad[0])} is "
                        f"not finite: {pos[bad[0]].tolist()}", f"accessors[{attrs.POSITION}]")
    idx = (doc.accessor(prim.indices, where + ".indices", "indices")[:, 0]
           if prim.indices is not None else np.arange(len(pos)))
    if idx.size and idx.max() >= len(pos):
        k = int(np.argmax(idx >= len(pos)))
        raise GltfError(f"mesh {mesh_index} primitive {pi}: index {int(idx[k])} (entry {k}) out "
                        f"of range ({len(pos)} vertices)", f"accessors[{prim.indices}]")
    tris = _triangles(mode, idx)
    if not len(tris):
        return 0, None
    p = pos[tris.reshape(-1)]
    try:
        return len(tris), _finish(doc, attrs, where, pos, tris, p)
    except meshes.ObjError as e:               # the work of finding normal groups is bounded
        raise GltfError(str(e), where) from None


def _finish(doc: _Doc, attrs, where: str, pos: np.ndarray, tris: np.ndarray,
            p: np.ndarray) -> meshes.Mesh:
    """The primitive's mesh from its corner positions ``p``: its NORMAL, or flat normals."""
    if attrs.NORMAL is None:                   # flat normals, as the glTF specification asks
        return meshes.finish_mesh(p, np.repeat(meshes.face_normals(p), 3, axis=0))
    nrm = doc.accessor(attrs.NORMAL, where + ".attributes.NORMAL", "NORMAL")
    if len(nrm) != len(pos):
        raise GltfError(f"NORMAL has {len(nrm)} elements, POSITION {len(pos)}",
                        where + ".attributes.NORMAL")
    n = meshes.normalize_rows(nrm[tris.reshape(-1)])
    n = np.where(np.isfinite(n).all(axis=1, keepdims=True), n, 0.0)
    flat = np.repeat(meshes.face_normals(p), 3, axis=0)
    n = np.where((np.linalg.norm(n, axis=1) > 0)[:, None], n, flat)   # unusable: the face's
    return meshes.finish_mesh(p, n)


def _file_camera(g, ci: int, world: np.ndarray, ni: int, objects: list[SceneObject],
                 file_name: str) -> tuple[Optional[Camera], Optional[str]]:
    """The camera of the first camera node and a note: None and why for a camera that is not
    perspective, or whose node's transform gives it no direction; the far plane chosen for
    one without ``zfar``."""
    cam = _item(g.cameras, ci, "camera", f"nodes[{ni}].camera", "a node")
    if cam.type != "perspective" or cam.perspective is None:
        return None, f"{file_name}: {cam.type} camera ignored (only perspective cameras)"
    p = cam.perspective
    eye = world[:3, 3]
    fwd = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
    up = world[:3, :3] @ np.array([0.0, 1.0, 0.0])
    with np.errstate(all="ignore"):
        fwd, up = fwd / np.linalg.norm(fwd), up / np.linalg.norm(up)
        sideways = np.linalg.norm(np.cross(fwd, up))
    if not (np.isfinite(eye).all() and np.isfinite(fwd).all() and np.isfinite(up).all()
            and sideways > 1e-6):
        return None, (f"{file_name}: camera of node {ni} ignored (its transform gives it no "
                      "position, direction or up)")
    near = float(p.znear) if p.znear else 0.1
    note = None
    if p.zfar is not None and p.zfar <= near:
        raise GltfError(f"zfar {p.zfar} is not greater than znear {near}",
                        f"cameras[{ci}].perspective.zfar")
    if p.zfar:
        far = float(p.zfar)
    else:
        far = _far_past_objects(objects, eye, near)
        note = (f"{file_name}: camera without zfar (infinite): far = {far:.4g}, twice "
                "the distance to the farthest corner of the scene's bounding box")
    camera = Camera(position=tuple(float(x) for x in eye),
                    target=tuple(float(x) for x in eye + fwd),
                    up=tuple(float(x) for x in up),
                    fov_y_deg=math.degrees(float(p.yfov)), near=near, far=far)
    return camera, note


def _far_past_objects(objects: list[SceneObject], eye: np.ndarray, near: float) -> float:
    """A far plane for an infinite perspective: twice the distance from the eye to the farthest
    corner of the objects' bounding box, and at least 10 x near."""
    pts = np.concatenate([o.positions for o in objects])
    corners = np.array([[x, y, z] for x in (pts[:, 0].min(), pts[:, 0].max())
                        for y in (pts[:, 1].min(), pts[:, 1].max())
                        for z in (pts[:, 2].min(), pts[:, 2].max())])
    return max(2.0 * float(np.linalg.norm(corners - eye, axis=1).max()), 10.0 * near)


def load_gltf_scene(path: str | Path) -> Scene:
    """A glTF file as a whole scene at ``pipegen.DEFAULT_SIZE`` with no ambient light; a file
    without a camera gets :func:`framing_camera`."""
    from pipegen.core.defaults import DEFAULT_SIZE
    path = Path(path)
    try:
        imported = load_gltf(path)
    except OSError as e:
        from pipegen.core.diagnostics import PipegenError
        raise PipegenError(None, f"cannot read glTF file '{path}': {e.strerror}") from None
    except GltfError as e:
        from pipegen.core.diagnostics import PipegenError
        raise PipegenError(None, f"bad glTF file: {path}: {e}") from None
    camera = imported.camera or framing_camera(imported.objects)
    objects = assign_layers(list(imported.objects), camera.position)
    notes = list(imported.notes)
    if imported.camera is None:
        notes.append(f"{path.name}: no perspective camera; one frames the scene's bounding box")
    report_notes(notes)
    return Scene(DEFAULT_SIZE[0], DEFAULT_SIZE[1], np.zeros(3), tuple(objects), imported.lights,
                 camera, name=path.stem, notes=tuple(notes))


