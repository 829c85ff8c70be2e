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
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from pipegen.scene import meshes
from pipegen.scene.model import (
    Camera, Light, Material, Scene, SceneObject, assign_layers, make_object, report_notes)


class GltfError(ValueError):
    """A glTF file pipegen cannot use (malformed, or needing an unsupported extension)."""


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
    def __init__(self, path: Path):
        import pygltflib
        self.path = path
        try:
            self.g = pygltflib.GLTF2().load(str(path))
        except (ValueError, KeyError, TypeError) as e:
            raise GltfError(f"cannot read the glTF document: {e}") from None
        if self.g is None:
            raise GltfError("cannot read the glTF document")
        self._buffers: dict[int, bytes] = {}

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            buf = self.g.buffers[i]
            uri = buf.uri
            if uri is None:
                data = self.g.binary_blob()
                if data is None:
                    raise GltfError(f"buffer {i} has no uri and the file has no binary chunk")
            elif uri.startswith("data:"):          # any media type (pygltflib knows one)
                import base64
                from urllib.parse import unquote_to_bytes
                header, _, payload = uri.partition(",")
                data = (base64.b64decode(payload) if header.endswith(";base64")
                        else unquote_to_bytes(payload))
            else:
                from urllib.parse import unquote
                data = (self.path.parent / unquote(uri)).read_bytes()
            if len(data) < buf.byteLength:
                raise GltfError(f"buffer {i} holds {len(data)} bytes, fewer than its byteLength "
                                f"{buf.byteLength}")
            self._buffers[i] = bytes(data)
        return self._buffers[i]

    def accessor(self, i: int) -> np.ndarray:
        """float64 (count, width) for float or normalised data, int64 otherwise."""
        if not 0 <= i < len(self.g.accessors):
            raise GltfError(f"accessor {i} does not exist")
        a = self.g.accessors[i]
        if a.componentType not in _COMPONENT or a.type not in _WIDTH:
            raise GltfError(f"accessor {i}: unsupported componentType {a.componentType} / type {a.type}")
        dt = np.dtype(_COMPONENT[a.componentType]).newbyteorder("<")
        width = _WIDTH[a.type]
        if a.bufferView is None:
            out = np.zeros((a.count, width), dtype=dt)
        else:
            out = self._view(a.bufferView, a.byteOffset or 0, a.count, dt, width, f"accessor {i}")
        if a.sparse is not None and a.sparse.count:
            s = a.sparse
            idt = np.dtype(_COMPONENT[s.indices.componentType]).newbyteorder("<")
            idx = self._view(s.indices.bufferView, s.indices.byteOffset or 0, s.count, idt, 1,
                             f"accessor {i} sparse indices")[:, 0].astype(np.int64)
            vals = self._view(s.values.bufferView, s.values.byteOffset or 0, s.count, dt, width,
                              f"accessor {i} sparse values")
            if idx.size and (idx.min() < 0 or idx.max() >= a.count):
                raise GltfError(f"accessor {i}: sparse index out of range")
            out = out.copy()
            out[idx] = vals
        if dt.kind == "f":
            return out.astype(np.float64)
        if a.normalized:
            info = np.iinfo(dt)
            return np.maximum(out.astype(np.float64) / info.max, -1.0)
        return out.astype(np.int64)

    def _view(self, view: int, offset: int, count: int, dt: np.dtype, width: int,
              what: str) -> np.ndarray:
        if not 0 <= view < len(self.g.bufferViews):
            raise GltfError(f"{what}: bufferView {view} does not exist")
        bv = self.g.bufferViews[view]
        data = self.buffer(bv.buffer)
        start = (bv.byteOffset or 0) + offset
        elem = dt.itemsize * width
        stride = bv.byteStride or elem
        need = stride * (count - 1) + elem if count else 0
        if start + need > len(data) or offset + need > bv.byteLength:
            raise GltfError(f"{what} reads past the end of bufferView {view}")
        if count == 0:
            return np.zeros((0, width), dtype=dt)
        raw = np.frombuffer(data, np.uint8, count=need, offset=start)
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
    g = doc.g
    notes: list[str] = []
    required = set(g.extensionsRequired or [])
    unsupported = sorted(required - SUPPORTED_REQUIRED)
    if unsupported:
        raise GltfError(f"the file requires {', '.join(unsupported)}, which pipegen does not read")
    ignored_ext = sorted(set(g.extensionsUsed or []) - {"KHR_lights_punctual", "KHR_mesh_quantization"})
    if ignored_ext:
        notes.append(f"{path.name}: extensions ignored: {', '.join(ignored_ext)}")
    lights_def = ((g.extensions or {}).get("KHR_lights_punctual") or {}).get("lights", [])

    if g.scenes:
        scene_index = g.scene if g.scene is not None else 0
        roots = list(g.scenes[scene_index].nodes or [])
    else:
        children = {c for n in g.nodes for c in (n.children or [])}
        roots = [i for i in range(len(g.nodes)) if i not in children]

    materials_cache: dict[Optional[int], Material] = {}
    dropped_textures: set[str] = set()
    material_notes: set[str] = set()

    def material(i: Optional[int]) -> Material:
        if i not in materials_cache:
            if i is None:
                materials_cache[i] = pbr_material()
                material_notes.add("primitives without a material get the glTF default "
                                   "(white, metallic 1, roughness 1)")
            else:
                m = g.materials[i]
                pbr = m.pbrMetallicRoughness
                base = (pbr.baseColorFactor if pbr and pbr.baseColorFactor is not None
                        else [1.0, 1.0, 1.0, 1.0])
                metallic = pbr.metallicFactor if pbr and pbr.metallicFactor is not None else 1.0
                rough = pbr.roughnessFactor if pbr and pbr.roughnessFactor is not None else 1.0
                mode = m.alphaMode or "OPAQUE"
                materials_cache[i] = pbr_material(base, metallic, rough, mode)
                label = m.name or f"material {i}"
                for key, tex in (("baseColorTexture", pbr and pbr.baseColorTexture),
                                 ("metallicRoughnessTexture", pbr and pbr.metallicRoughnessTexture),
                                 ("normalTexture", m.normalTexture),
                                 ("occlusionTexture", m.occlusionTexture),
                                 ("emissiveTexture", m.emissiveTexture)):
                    if tex is not None:
                        dropped_textures.add(f"{label}.{key}")
                if m.emissiveFactor and any(float(x) > 0 for x in m.emissiveFactor):
                    material_notes.add("emissiveFactor ignored (no emission in the scene model)")
                if mode == "MASK":
                    material_notes.add("alphaMode MASK drawn opaque (alphaCutoff needs textures)")
                if m.extensions:
                    material_notes.add("material extensions ignored: "
                                       + ", ".join(sorted(m.extensions)))
        return materials_cache[i]

    objects: list[SceneObject] = []
    lights: list[Light] = []
    camera_node: Optional[tuple[int, np.ndarray]] = None
    ignored_attrs: set[str] = set()
    skipped_modes: set[str] = set()
    dropped = 0
    stack = [(r, np.eye(4)) for r in reversed(roots)]
    visited = set()
    while stack:
        ni, parent = stack.pop()
        if ni in visited:
            raise GltfError(f"node {ni} is reached twice (the node hierarchy must be a tree)")
        visited.add(ni)
        if not 0 <= ni < len(g.nodes):
            raise GltfError(f"node {ni} does not exist")
        node = g.nodes[ni]
        world = parent @ _local_matrix(node)
        if node.camera is not None and camera_node is None:
            camera_node = (node.camera, world)
        ext = (node.extensions or {}).get("KHR_lights_punctual")
        if ext is not None:
            li = ext.get("light")
            if li is None or not 0 <= li < len(lights_def):
                raise GltfError(f"node {ni} refers to light {li}, which does not exist")
            try:
                lights.append(punctual_light(lights_def[li], world, intensity_scale))
            except GltfError as e:
                raise GltfError(f"light {li}: {e}") from None
        if node.skin is not None:
            ignored_attrs.add("skins")
        if node.mesh is not None:
            mesh = g.meshes[node.mesh]
            base_name = node.name or mesh.name or f"node{ni}"
            prims = mesh.primitives or []
            for pi, prim in enumerate(prims):
                mode = 4 if prim.mode is None else prim.mode
                if mode not in (4, 5, 6):
                    skipped_modes.add(_MODES.get(mode, str(mode)))
                    continue
                attrs = prim.attributes
                if attrs.POSITION is None:
                    raise GltfError(f"mesh {node.mesh} primitive {pi} has no POSITION")
                for a in ("TEXCOORD_0", "TEXCOORD_1", "COLOR_0", "TANGENT", "JOINTS_0", "WEIGHTS_0"):
                    if getattr(attrs, a, None) is not None:
                        ignored_attrs.add(a)
                if prim.targets:
                    ignored_attrs.add("morph targets")
                pos = doc.accessor(attrs.POSITION)[:, :3].astype(np.float64)
                bad = np.flatnonzero(~np.isfinite(pos).all(axis=1))
                if len(bad):
                    raise GltfError(f"mesh {node.mesh} ('{mesh.name or ''}') primitive {pi}: "
                                    f"POSITION (accessor {attrs.POSITION}) vertex {int(bad[0])} is "
                                    f"not finite: {pos[bad[0]].tolist()}")
                idx = (doc.accessor(prim.indices)[:, 0] if prim.indices is not None
                       else np.arange(len(pos)))
                if idx.size and (idx.min() < 0 or idx.max() >= len(pos)):
                    raise GltfError(f"mesh {node.mesh} primitive {pi}: index {int(idx.max())} out of "
                                    f"range ({len(pos)} vertices)")
                tris = _triangles(mode, idx)
                if not len(tris):
                    continue
                p = pos[tris.reshape(-1)]
                if attrs.NORMAL is not None:
                    nrm = doc.accessor(attrs.NORMAL)[:, :3].astype(np.float64)
                    n = meshes.normalize_rows(nrm[tris.reshape(-1)])
                    n = np.where(np.isfinite(n).all(axis=1, keepdims=True), n, 0.0)
                    flat = np.repeat(meshes.face_normals(p), 3, axis=0)
                    n = np.where((np.linalg.norm(n, axis=1) > 0)[:, None], n, flat)
                else:
                    n = np.repeat(meshes.face_normals(p), 3, axis=0)
                local = meshes.finish_mesh(p, n)
                dropped += len(tris) - local.triangle_count
                if not local.triangle_count:
                    continue
                name = base_name if len(prims) == 1 else f"{base_name}/{pi}"
                obj_id = first_id + len(objects)
                if obj_id > 255:
                    raise GltfError("more than 255 mesh primitives: object ids are 8-bit (1..255)")
                objects.append(make_object(name, obj_id, f"{path.name}#mesh{node.mesh}/{pi}", local,
                                           material(prim.material), world))
        for c in reversed(node.children or []):
            stack.append((c, world))
    if not objects:
        raise GltfError("the scene has no triangles")

    camera = None
    if camera_node is not None:
        ci, world = camera_node
        cam = g.cameras[ci]
        if cam.type == "perspective" and cam.perspective is not None:
            p = cam.perspective
            eye = world[:3, 3]
            fwd = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
            up = world[:3, :3] @ np.array([0.0, 1.0, 0.0])
            fwd, up = fwd / np.linalg.norm(fwd), up / np.linalg.norm(up)
            near = float(p.znear) if p.znear else 0.1
            if p.zfar:
                far = float(p.zfar)
            else:
                pts = np.concatenate([o.positions for o in objects])
                corners = np.array([[x, y, z] for x in (pts[:, 0].min(), pts[:, 0].max())
                                    for y in (pts[:, 1].min(), pts[:, 1].max())
                                    for z in (pts[:, 2].min(), pts[:, 2].max())])
                far = max(2.0 * float(np.linalg.norm(corners - eye, axis=1).max()), 10.0 * near)
                notes.append(f"{path.name}: camera without zfar (infinite): far = {far:.4g}, twice "
                             "the distance to the farthest corner of the scene's bounding box")
            camera = Camera(position=tuple(float(x) for x in eye),
                            target=tuple(float(x) for x in eye + fwd),
                            up=tuple(float(x) for x in up),
                            fov_y_deg=math.degrees(float(p.yfov)), near=near, far=far)
        else:
            notes.append(f"{path.name}: {cam.type} camera ignored (only perspective cameras)")

    if dropped_textures:
        shown = sorted(dropped_textures)
        notes.append(f"{path.name}: textures dropped (not supported): {', '.join(shown[:8])}"
                     + (f" and {len(shown) - 8} more" if len(shown) > 8 else ""))
    for n in sorted(material_notes):
        notes.append(f"{path.name}: {n}")
    if ignored_attrs:
        notes.append(f"{path.name}: ignored {', '.join(sorted(ignored_attrs))}")
    if skipped_modes:
        notes.append(f"{path.name}: primitives skipped (not triangles): {', '.join(sorted(skipped_modes))}")
    if dropped:
        notes.append(f"{path.name}: dropped {dropped} degenerate (zero-area) triangles")
    return GltfImport(tuple(objects), camera, tuple(lights), tuple(notes), dropped)


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


