"""Adversarial scenes for ``pipegen stress`` (issue 11, item 1; DESIGN.md §8).

Every case is built from a *base scene* (the built-in default scene when none is given) by
``dataclasses.replace``: the base's objects, camera and size are kept unless the case is about
them, and the case adds or moves lights, objects or the camera to reach the numerically hard
configuration it names.  Where a case needs a surface point, it takes the visible surface at
the centre of the image (``probe``: the float64 rasterisation of ``pipegen.reference``), so a
case aims at what the camera sees whatever the base scene is.

``CASES`` maps a name to its builder ``(base, probe) -> Scene``; ``GROUPS`` names sets of cases
(``--cases quick``); ``build(base, names)`` gives ``[Case]``.  ``random_scene`` draws a scene
from plain parameters (what ``hypothesis`` strategies generate, ``strategies.py``), so a shrunk
failing scene can be written back as a TOML file of primitives (``random_scene_toml``);
``scene_toml`` writes any scene (objects as OBJ files beside it).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from pipegen.scene import meshes
from pipegen.scene.model import (
    Camera, Light, Material, Scene, SceneObject, make_object, transform_matrix)

F32 = np.float32


@dataclass(frozen=True)
class Case:
    name: str
    description: str
    scene: Scene


@dataclass(frozen=True)
class Probe:
    """The surface seen at the image centre (float64): point, unit normal, and the camera."""
    point: np.ndarray
    normal: np.ndarray
    eye: np.ndarray
    covered: bool


def probe(scene: Scene) -> Probe:
    """The visible surface at the centre pixel (or the nearest covered pixel to it)."""
    from pipegen.reference.raster import rasterize
    g = rasterize(scene)
    eye = np.asarray(scene.camera.position, np.float64)
    if not g.coverage.any():
        fwd = np.subtract(scene.camera.target, eye)
        return Probe(eye + fwd, -fwd / np.linalg.norm(fwd), eye, False)
    h, w = g.coverage.shape
    ys, xs = np.nonzero(g.coverage)
    k = int(np.argmin((ys - h // 2) ** 2 + (xs - w // 2) ** 2))
    p = g.position[ys[k], xs[k]]
    n = g.normal[ys[k], xs[k]]
    n = n / max(np.linalg.norm(n), 1e-300)
    if np.dot(n, eye - p) < 0:
        n = -n
    return Probe(p.copy(), n.copy(), eye, True)


def _light(pos, radius, color=(1.0, 0.9, 0.8), **kw) -> Light:
    return Light("point", tuple(float(c) for c in color), tuple(float(c) for c in pos),
                 float(radius), **kw)


def _with_lights(base: Scene, lights, name: str) -> Scene:
    return dataclasses.replace(base, lights=tuple(lights), name=f"{base.name}/{name}")


def _tangent(n: np.ndarray) -> np.ndarray:
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    t = np.cross(n, a)
    return t / np.linalg.norm(t)


# -- lights at and around the radius -----------------------------------------------------------

def _at_radius(base: Scene, pr: Probe, ulps: int) -> Scene:
    """A light 1.5 units above the probe point along its normal, radius the float32 distance
    to it, moved ``ulps`` float32 ulps: the fragment at the centre pixel sits exactly at the
    radius (0), just inside (-1) or just outside (+1)."""
    c = pr.point + 1.5 * pr.normal
    d = float(F32(np.linalg.norm(c.astype(F32).astype(np.float64) - pr.point)))
    r = F32(d)
    for _ in range(abs(ulps)):
        r = np.nextafter(r, F32(np.inf) if ulps > 0 else F32(0))
    return _with_lights(base, [_light(c, float(r), (1.5, 1.2, 1.0))], f"radius{ulps:+d}ulp")


def _light_on_surface(base: Scene, pr: Probe) -> Scene:
    """A light centre exactly on the visible surface (d = 0 at that fragment: l = 0/max(0,
    eps)), and one a hair above it."""
    return _with_lights(base, [_light(pr.point, 2.0, (1.2, 1.0, 0.8)),
                               _light(pr.point + 1e-5 * pr.normal + 0.7 * _tangent(pr.normal),
                                      1.5, (0.5, 0.8, 1.2))], "light_on_surface")


def _camera_in_light(base: Scene, pr: Probe) -> Scene:
    """The camera inside a light volume (its sphere holds the eye and the probe point)."""
    r = 1.2 * float(np.linalg.norm(pr.point - pr.eye))
    return _with_lights(base, list(base.lights[:3]) + [_light(pr.eye, r, (0.9, 0.9, 0.9))],
                        "camera_in_light")


def _near_clip(base: Scene, pr: Probe) -> Scene:
    """Light spheres cut by the near plane, the camera outside them: centres ahead of the eye
    at radius + near/2, so each sphere pokes through the near plane."""
    cam = base.camera
    fwd = np.subtract(cam.target, cam.position)
    fwd = fwd / np.linalg.norm(fwd)
    lights = []
    for k, r in enumerate((0.6, 2.0, 6.0)):
        side = _tangent(fwd) * (0.3 * (k - 1))
        c = np.asarray(cam.position) + fwd * (r + 0.5 * cam.near) + side
        lights.append(_light(c, r, (0.6, 0.7, 0.9)))
    return _with_lights(base, lights, "near_clip")


def _grazing(base: Scene, pr: Probe) -> Scene:
    """Grazing view and light: the camera 2 degrees above the probe's tangent plane, a light
    in the tangent plane (n.l = 0 at the probe) and one 0.5 degrees above it."""
    t = _tangent(pr.normal)
    dist = max(4.0, float(np.linalg.norm(pr.eye - pr.point)))
    a = math.radians(2.0)
    eye = pr.point + dist * (math.cos(a) * -t + math.sin(a) * pr.normal)
    cam = dataclasses.replace(base.camera, position=tuple(eye), target=tuple(pr.point + 2.0 * t),
                              up=tuple(pr.normal))
    b = math.radians(0.5)
    b2 = np.cross(pr.normal, t)
    lights = [_light(pr.point + 3.0 * b2, 6.0, (1.0, 1.0, 1.0)),
              _light(pr.point + 3.0 * (math.cos(b) * -b2 + math.sin(b) * pr.normal), 6.0,
                     (1.0, 0.6, 0.4))]
    return dataclasses.replace(_with_lights(base, lights, "grazing"), camera=cam)


def _translated(base: Scene, offset: float) -> Scene:
    """The whole scene (objects, lights, camera) moved ``offset`` units along (1, 0.5, -1)/1.5:
    float32 positions then carry ulps of ``offset`` (6e-5 at 10^3, 1e-3 at 10^4)."""
    t = np.array([1.0, 0.5, -1.0]) / 1.5 * offset
    objects = tuple(_moved(o, t) for o in base.objects)
    lights = tuple(dataclasses.replace(l, position=tuple(np.add(l.position, t)))
                   if l.type != "directional" else l for l in base.lights)
    cam = base.camera
    cam = dataclasses.replace(cam, position=tuple(np.add(cam.position, t)),
                              target=tuple(np.add(cam.target, t)))
    return dataclasses.replace(base, objects=objects, lights=lights, camera=cam,
                               name=f"{base.name}/translated{offset:g}")


def _moved(o: SceneObject, t: np.ndarray) -> SceneObject:
    m = o.matrix.copy()
    m[:3, 3] += t
    return dataclasses.replace(o, matrix=m, positions=o.positions + t)


def _plane_object(name, oid, centre, size, normal_axis_rot=(0, 0, 0), albedo=(0.7, 0.7, 0.7),
                  specular=0.2) -> SceneObject:
    m = transform_matrix(centre, normal_axis_rot, (size, 1.0, size))
    return make_object(name, oid, "plane", meshes.plane(), Material(tuple(albedo), specular, 16.0),
                       m)


def _depth_far(base: Scene, pr: Probe) -> Scene:
    """Depth far from the camera: two facing planes 40 units away, separated by 8 d24 codes of
    window depth there (resolved by d24 and d32f alike; 1 code would z-fight in d24), seen
    head on with near = 0.1."""
    cam = Camera((0.0, 1.0, 0.0), (0.0, 1.0, -40.0), (0.0, 1.0, 0.0), 45.0, 0.1, 100.0)
    n, f, z = cam.near, cam.far, 40.0
    # window depth of view distance z: (f / (f - n)) * (1 - n / z); d/dz = f n / ((f - n) z^2)
    dz_per_code = (1.0 / 16777215.0) / (f * n / ((f - n) * z * z))
    gap = 8.0 * dz_per_code
    back = _plane_object("back", 1, (0.0, 1.0, -z - gap), 30.0, (90, 0, 0), (0.2, 0.4, 0.9))
    front = _plane_object("front", 2, (4.0, 1.0, -z), 12.0, (90, 0, 0), (0.9, 0.3, 0.2))
    lights = [_light((0.0, 3.0, -z + 6.0), 12.0, (1.2, 1.1, 1.0)),
              _light((6.0, 0.0, -z + 3.0), 8.0, (0.4, 0.8, 1.2))]
    return dataclasses.replace(base, objects=(back, front), lights=tuple(lights), camera=cam,
                               name=f"{base.name}/depth_far")


def _sky(base: Scene, pr: Probe) -> Scene:
    """Half the image is sky (pixels left at the cleared depth), with lights whose volumes
    reach into it and a directional-free light set."""
    cam = base.camera
    pos = np.asarray(cam.position, np.float64)
    tgt = np.asarray(cam.target, np.float64)
    up = np.asarray(cam.up, np.float64)
    d = np.linalg.norm(tgt - pos)
    new_target = tgt + up * d * math.tan(math.radians(cam.fov_y_deg) / 2.0)
    lights = [_light(pr.point + 1.0 * pr.normal, 4.0, (1.0, 0.9, 0.8)),
              _light(new_target, 3.0, (0.6, 0.6, 1.2))]
    return dataclasses.replace(_with_lights(base, lights, "sky"),
                               camera=dataclasses.replace(cam, target=tuple(new_target)))


def _radius(base: Scene, pr: Probe, r: float, name: str) -> Scene:
    c = pr.point + max(min(0.5 * r, 1.0), 1e-4) * pr.normal
    return _with_lights(base, [_light(c, r, (1.0, 0.9, 0.8))], name)


def _many_lights(base: Scene, pr: Probe, n: int) -> Scene:
    """``n`` lights over the probe point (a ring of radius 0.05 at height 1, radius 3), total
    colour 2.5, so every one of them reaches the centre pixel."""
    lights = []
    t = _tangent(pr.normal)
    b = np.cross(pr.normal, t)
    for k in range(n):
        a = 2 * math.pi * k / n
        c = pr.point + pr.normal + 0.05 * (math.cos(a) * t + math.sin(a) * b)
        hue = (0.6 + 0.4 * math.cos(a), 0.6 + 0.4 * math.cos(a + 2.1), 0.6 + 0.4 * math.cos(a + 4.2))
        lights.append(_light(c, 3.0, tuple(2.5 / n * h for h in hue)))
    return _with_lights(base, lights, f"lights{n}")


def _half_overflow(base: Scene, pr: Probe) -> Scene:
    """Light colours past half's largest finite value: 4 lights of 40000 each (a sum of
    160000 > 65504 in float16 accumulation), next to an ordinary light."""
    lights = [_light(pr.point + pr.normal + 0.1 * k * _tangent(pr.normal), 2.5,
                     (40000.0, 20000.0, 1.0)) for k in range(4)]
    lights.append(_light(pr.point + 2.0 * _tangent(pr.normal) + pr.normal, 2.0, (1.0, 1.0, 1.0)))
    return _with_lights(base, lights, "half_overflow")


def _denormal(base: Scene, pr: Probe) -> Scene:
    """Denormal attenuation: colours of 1e-38 (float32 denormals after attenuation: flushed by
    both backends, kept by the float64 evaluation), beside a light of ordinary colour."""
    lights = [_light(pr.point + pr.normal, 3.0, (1e-38, 3e-39, 1e-38)),
              _light(pr.point + 2.0 * _tangent(pr.normal) + pr.normal, 2.0, (0.8, 0.8, 0.8))]
    return _with_lights(base, lights, "denormal")


def _overlap(base: Scene, pr: Probe) -> Scene:
    """More overlapping lights than any shipped packing holds: 9 lights of radius 3 within 0.5
    of each other over the probe point (the bit-plane and CPU-sort packings hold 4, the max
    pairs 2)."""
    lights = []
    t = _tangent(pr.normal)
    b = np.cross(pr.normal, t)
    for i in range(3):
        for j in range(3):
            c = pr.point + pr.normal + 0.25 * ((i - 1) * t + (j - 1) * b)
            lights.append(_light(c, 3.0, (0.3 + 0.1 * i, 0.3 + 0.1 * j, 0.4)))
    return _with_lights(base, lights, "overlap")


# -- degenerate geometry -----------------------------------------------------------------------

def _custom_object(name: str, oid: int, positions, normals, albedo=(0.8, 0.8, 0.8),
                   specular=0.3) -> SceneObject:
    positions = np.asarray(positions, np.float64).reshape(-1, 3)
    normals = np.asarray(normals, np.float64).reshape(-1, 3)
    normals = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    groups = np.arange(len(positions) // 3, dtype=np.int64) % 255 + 1
    return SceneObject(name, oid, "custom", Material(tuple(albedo), specular, 32.0), np.eye(4),
                       positions, normals, groups)


def _facing_quad(cam: Camera, dist: float, half: float, normal_fn) -> tuple[np.ndarray, np.ndarray]:
    """A square ``2 half`` wide facing the camera at ``dist``, split into a grid of 8x8 quads;
    vertex normals from ``normal_fn(u, v, view axes)`` (u, v in [-1, 1])."""
    eye = np.asarray(cam.position, np.float64)
    f = np.subtract(cam.target, eye)
    f = f / np.linalg.norm(f)
    s = np.cross(f, cam.up)
    s = s / np.linalg.norm(s)
    u_ax = np.cross(s, f)
    n = 8
    pos, nrm = [], []
    for i in range(n):
        for j in range(n):
            corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j), (i + 1, j + 1), (i, j + 1)]
            for a, b in corners:
                u, v = 2.0 * a / n - 1.0, 2.0 * b / n - 1.0
                pos.append(eye + dist * f + half * (u * s + v * u_ax))
                nrm.append(normal_fn(u, v, s, u_ax, f))
    return np.array(pos), np.array(nrm)


def _normals_case(base: Scene, pr: Probe, kind: str) -> Scene:
    """A camera-facing quad whose vertex normals are the hard inputs of normal encodings:
    ``back``: exactly the view direction (view-space (0, 0, -1): the pole of spheremap /
    Kircher's encoding); ``near_back``: within 1e-3 rad of it; ``seam``: view-space normals
    sweeping the octahedral fold (view z in [-0.1, 0.1]) and the axes (x = 0 or y = 0)."""
    cam = base.camera

    def fn(u, v, s, up, f):
        if kind == "back":
            return f
        if kind == "near_back":
            return f + 1e-3 * (u * s + v * up)
        a = math.atan2(v, u)
        return math.cos(a) * s + math.sin(a) * up + 0.1 * u * v * f
    d = 3.0
    half = d * math.tan(math.radians(cam.fov_y_deg) / 2.0) * 0.8
    pos, nrm = _facing_quad(cam, d, half, fn)
    obj = _custom_object(f"normals_{kind}", 200, pos, nrm, (0.8, 0.75, 0.7))
    eye = np.asarray(cam.position)
    f = np.subtract(cam.target, eye)
    f = f / np.linalg.norm(f)
    lights = [_light(eye + (d - 1.0) * f, 3.0, (1.0, 1.0, 1.0)),
              _light(eye + (d + 1.0) * f, 3.0, (0.8, 0.6, 1.0))]
    return dataclasses.replace(base, objects=(obj,), lights=tuple(lights),
                               name=f"{base.name}/normals_{kind}")


def _zero_area(base: Scene, pr: Probe) -> Scene:
    """Zero-area triangles (three collinear vertices, and three equal ones) inside the base
    scene's geometry, in front of the probe point."""
    eye = pr.eye
    mid = 0.5 * (eye + pr.point)
    t = _tangent(pr.normal)
    line = [mid, mid + t, mid + 2 * t, mid, mid, mid]
    nrm = [pr.normal] * 6
    obj = _custom_object("zero_area", 201, line, nrm)
    return dataclasses.replace(_with_lights(base, base.lights, "zero_area"),
                               objects=tuple(base.objects) + (obj,))


def _odd_lowres(base: Scene, pr: Probe, w: int, h: int) -> Scene:
    """An odd-sized small buffer (low-resolution targets of half or 5/8 size round down),
    the base scene's depth discontinuities at a few pixels each."""
    return dataclasses.replace(base.with_size(w, h), name=f"{base.name}/odd{w}x{h}")


Builder = Callable[[Scene, Probe], Scene]

CASES: dict[str, tuple[str, Builder]] = {
    "base": ("the base scene as it is", lambda b, p: b),
    "radius_exact": ("a surface point exactly at a light's radius", lambda b, p: _at_radius(b, p, 0)),
    "radius_minus_ulp": ("... 1 float32 ulp inside", lambda b, p: _at_radius(b, p, -1)),
    "radius_plus_ulp": ("... 1 float32 ulp outside", lambda b, p: _at_radius(b, p, 1)),
    "light_on_surface": ("a light centre on the surface", _light_on_surface),
    "camera_in_light": ("the camera inside a light volume", _camera_in_light),
    "near_clip": ("light volumes cut by the near plane", _near_clip),
    "grazing": ("grazing view (2 deg) and light (0, 0.5 deg) angles", _grazing),
    "far_1e3": ("the scene translated 10^3 units", lambda b, p: _translated(b, 1e3)),
    "far_1e4": ("the scene translated 10^4 units", lambda b, p: _translated(b, 1e4)),
    "depth_far": ("surfaces 8 d24 codes apart 40 units away (d24 vs d32f)", _depth_far),
    "sky": ("half the image sky at the cleared depth", _sky),
    "tiny_radius": ("a light of radius 1e-3", lambda b, p: _radius(b, p, 1e-3, "tiny_radius")),
    "huge_radius": ("a light of radius 1e4", lambda b, p: _radius(b, p, 1e4, "huge_radius")),
    "lights_1": ("1 light on one pixel", lambda b, p: _many_lights(b, p, 1)),
    "lights_16": ("16 lights on one pixel", lambda b, p: _many_lights(b, p, 16)),
    "lights_64": ("64 lights on one pixel", lambda b, p: _many_lights(b, p, 64)),
    "lights_256": ("256 lights on one pixel", lambda b, p: _many_lights(b, p, 256)),
    "half_overflow": ("light colours summing past 65504", _half_overflow),
    "denormal": ("denormal light contributions", _denormal),
    "overlap": ("9 overlapping lights (more than the packings hold)", _overlap),
    "zero_area": ("zero-area triangles", _zero_area),
    "normals_back": ("normals at view (0, 0, -1)", lambda b, p: _normals_case(b, p, "back")),
    "normals_near_back": ("normals within 1e-3 of view (0, 0, -1)",
                          lambda b, p: _normals_case(b, p, "near_back")),
    "normals_seam": ("normals across octahedral seams", lambda b, p: _normals_case(b, p, "seam")),
    "odd_lowres": ("odd-sized buffer (odd halves) at depth discontinuities",
                   lambda b, p: _odd_lowres(b, p, b.width - 1 if b.width % 2 == 0 else b.width,
                                            b.height - 1 if b.height % 2 == 0 else b.height)),
    "odd_tiny": ("a 13x7 buffer", lambda b, p: _odd_lowres(b, p, 13, 7)),
}

GROUPS = {
    "all": tuple(CASES),
    "quick": ("base", "radius_exact", "radius_plus_ulp", "light_on_surface", "camera_in_light",
              "near_clip", "far_1e4", "sky", "lights_16", "half_overflow", "overlap",
              "normals_back", "odd_tiny"),
    # what CI runs on every shipped technique (tests/test_stress.py)
    "ci": ("base", "radius_exact", "light_on_surface", "camera_in_light", "far_1e4",
           "lights_16", "overlap", "normals_back", "odd_tiny"),
}


def case_names(spec: Optional[str]) -> list[str]:
    """``--cases a,b,quick`` -> case names in ``CASES`` order (unknown names: ValueError)."""
    if not spec:
        return list(CASES)
    chosen: set[str] = set()
    for part in (s.strip() for s in spec.split(",")):
        if not part:
            continue
        if part in GROUPS:
            chosen |= set(GROUPS[part])
        elif part in CASES:
            chosen.add(part)
        else:
            raise ValueError(f"unknown stress case {part!r}: choose from "
                             f"{', '.join(list(GROUPS) + list(CASES))}")
    return [c for c in CASES if c in chosen]


def build(base: Scene, names: Optional[list[str]] = None) -> list[Case]:
    pr = probe(base)
    out = []
    for name in names or list(CASES):
        desc, fn = CASES[name]
        scene = fn(base, pr)
        out.append(Case(name, desc, dataclasses.replace(scene, name=f"{base.name}/{name}")))
    return out


# -- random scenes (hypothesis draws the parameters; these build and write the scene) ----------

def random_scene(params: dict, width: int, height: int) -> Scene:
    """A scene from plain parameters: ``camera`` (position, target, fov, near), ``objects``
    (mesh, translate, scale, rotate, albedo, specular), ``lights`` (position, radius,
    colour).  The same dictionary written by ``random_scene_toml`` loads as the same scene."""
    from pipegen.scene.load import parse_scene
    return parse_scene(random_scene_toml(params, width, height), "<random scene>",
                       name="random")


def _num(x) -> str:
    return repr(float(x))


def _vec(v) -> str:
    return "[" + ", ".join(_num(x) for x in v) + "]"


def random_scene_toml(params: dict, width: int, height: int) -> str:
    cam = params["camera"]
    lines = ["name = \"random\"", f"width = {int(width)}", f"height = {int(height)}",
             f"ambient = {_vec(params.get('ambient', (0.05, 0.05, 0.05)))}", "",
             "[camera]", f"position = {_vec(cam['position'])}", f"target = {_vec(cam['target'])}",
             f"fov_y_deg = {_num(cam['fov'])}", f"near = {_num(cam['near'])}",
             f"far = {_num(cam['far'])}", ""]
    for o in params["objects"]:
        lines += ["[[objects]]", f"mesh = \"{o['mesh']}\"", f"translate = {_vec(o['translate'])}",
                  f"rotate_deg = {_vec(o['rotate'])}", f"scale = {_vec(o['scale'])}",
                  f"material = {{ albedo = {_vec(o['albedo'])}, specular = {_num(o['specular'])}, "
                  f"shininess = {_num(o.get('shininess', 32.0))} }}", ""]
    for l in params["lights"]:
        lines += ["[[lights]]", f"position = {_vec(l['position'])}", f"radius = {_num(l['radius'])}",
                  f"color = {_vec(l['color'])}", ""]
    return "\n".join(lines)


def scene_toml(scene: Scene, folder: Path, stem: str) -> Path:
    """Write ``scene`` as ``folder/stem.toml`` (objects as OBJ files ``stem_objN.obj`` in world
    space, identity transform, their vertex normals as written; the OBJ reader drops
    zero-area triangles, so a scene that had some loads without them).  Returns the path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cam = scene.camera
    lines = [f"name = \"{stem}\"", f"width = {scene.width}", f"height = {scene.height}",
             f"ambient = {_vec(scene.ambient)}", "", "[camera]",
             f"position = {_vec(cam.position)}", f"target = {_vec(cam.target)}",
             f"up = {_vec(cam.up)}", f"fov_y_deg = {_num(cam.fov_y_deg)}",
             f"near = {_num(cam.near)}", f"far = {_num(cam.far)}", ""]
    for k, o in enumerate(scene.objects):
        obj_name = f"{stem}_obj{k}.obj"
        _write_obj(folder / obj_name, o)
        m = o.material
        lines += ["[[objects]]", f"name = \"{o.name}\"", f"id = {o.id}", f"obj = \"{obj_name}\"",
                  f"material = {{ albedo = {_vec(m.albedo)}, specular = {_num(m.specular)}, "
                  f"shininess = {_num(m.shininess)}, alpha = {_num(m.alpha)}, "
                  f"translucent = {'true' if m.translucent else 'false'} }}"]
        if o.layer and m.translucent:
            lines.append(f"layer = {o.layer}")
        lines.append("")
    for l in scene.lights:
        lines += ["[[lights]]", f"type = \"{l.type}\"", f"color = {_vec(l.color)}"]
        if l.type != "directional":
            lines += [f"position = {_vec(l.position)}", f"radius = {_num(l.radius)}"]
        if l.type != "point":
            lines.append(f"direction = {_vec(l.direction)}")
        if l.type == "spot":
            lines += [f"inner_deg = {_num(l.inner_deg)}", f"outer_deg = {_num(l.outer_deg)}"]
        lines.append("")
    path = folder / f"{stem}.toml"
    path.write_text("\n".join(lines))
    return path


def _write_obj(path: Path, o: SceneObject) -> None:
    out = [f"# {o.name}: world space, written by pipegen stress"]
    out += ["v " + " ".join(repr(float(c)) for c in p) for p in np.asarray(o.positions)]
    out += ["vn " + " ".join(repr(float(c)) for c in n) for n in np.asarray(o.normals)]
    for t in range(len(o.positions) // 3):
        a, b, c = 3 * t + 1, 3 * t + 2, 3 * t + 3
        out.append(f"f {a}//{a} {b}//{b} {c}//{c}")
    path.write_text("\n".join(out) + "\n")
