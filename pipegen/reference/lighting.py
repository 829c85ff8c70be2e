"""The lighting equation of the shipped techniques, evaluated in float64: the ground truth.

For a surface point P with interpolated normal n seen from the camera at C::

    att(d, r) = clamp(1 - d²/r², 0, 1)²                 zero at and beyond r
    L = light.position - P;  d = |L|;  l = L / max(d, 1e-6)
    n = normalize(n), v = normalize(C - P), h = normalize(l + v)   (guarded: x / sqrt(max(x·x, 1e-12)))
    ndl = max(n·l, 0);  ndh = max(n·h, 0)
    spec = ndl > 0 ? pow(max(ndh, 1e-6), shininess) : 0
    contribution = color * att * (albedo * ndl + specular * spec)
    spot:        × smoothstep(cos_outer, cos_inner, dot(-l, direction))
    directional: l = -direction, att = 1
    colour = ambient * albedo + Σ contributions;  sky pixels = the clear colour (0, 0, 0)

Light parameters are read as the light table stores them (rounded to float32), so the
reference and the backends light the same scene.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional

import numpy as np

from pipegen.core import formats
from pipegen.scene.meshes import light_volume
from pipegen.scene.model import Light, Scene
from pipegen.reference.raster import GBuffer, rasterize
from pipegen.reference.rounding import as_float32

if TYPE_CHECKING:
    from pipegen.reference.shadows import Shadows

EPS_DIST = 1e-6
EPS_NORM2 = 1e-12
EPS_POW = 1e-6


def safe_normalize(v: np.ndarray) -> np.ndarray:
    """v / |v| with the shaders' guard: a zero vector stays zero instead of becoming NaN."""
    return v * (1.0 / np.sqrt(np.maximum(np.einsum("...i,...i->...", v, v), EPS_NORM2)))[..., None]


def attenuation(d2: np.ndarray, radius: float) -> np.ndarray:
    """clamp(1 - d²/r², 0, 1)²: 1 at the centre, exactly 0 at and beyond the radius."""
    return np.clip(1.0 - d2 / (radius * radius), 0.0, 1.0) ** 2


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def incidence(light: Light, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(l (n, 3), att (n,)): the unit direction towards ``light`` and its attenuation (a spot's
    cone falloff included) at n surface points."""
    if light.type == "directional":
        return np.broadcast_to(-as_float32(light.direction), P.shape), np.ones(len(P))
    L = as_float32(light.position) - P
    d2 = np.einsum("ij,ij->i", L, L)
    l = L / np.maximum(np.sqrt(d2), EPS_DIST)[:, None]
    att = attenuation(d2, float(as_float32(light.radius)))
    if light.type == "spot":
        cos_a = np.einsum("ij,j->i", -l, as_float32(light.direction))
        att = att * smoothstep(float(as_float32(light.cos_outer)), float(as_float32(light.cos_inner)), cos_a)
    return l, att


def reached(light: Light, P: np.ndarray):
    """The points of P (n, 3) that ``light`` may reach: all for a directional light, else the
    indices strictly inside its radius (att is exactly 0 elsewhere)."""
    if light.type == "directional":
        return slice(None)
    L = as_float32(light.position) - P
    r = float(as_float32(light.radius))
    return np.flatnonzero(np.einsum("ij,ij->i", L, L) < r * r)


def light_contribution(light: Light, P: np.ndarray, normal: np.ndarray, camera_pos: np.ndarray,
                       albedo: np.ndarray, specular: np.ndarray, shininess: np.ndarray) -> np.ndarray:
    """One light's contribution (n, 3) at n surface points (flat arrays, float64)."""
    color = as_float32(light.color)
    l, att = incidence(light, P)
    n = safe_normalize(normal)
    v = safe_normalize(camera_pos - P)
    h = safe_normalize(l + v)
    ndl = np.maximum(np.einsum("ij,ij->i", n, l), 0.0)
    ndh = np.maximum(np.einsum("ij,ij->i", n, h), 0.0)
    spec = np.where(ndl > 0, np.power(np.maximum(ndh, EPS_POW), shininess), 0.0)
    return color * att[:, None] * (albedo * ndl[:, None] + (specular * spec)[:, None])


def shade(gbuffer: GBuffer, scene: Scene, shadows: Optional[Shadows] = None) -> np.ndarray:
    """float64 (H, W, 3) colour before clamping: ambient plus every light, sky = clear colour.

    ``shadows`` (``reference.shadows``): ``MappedShadows(maps, pcf_taps, bias)``, with ``maps``
    from ``shadow_maps``: the contribution of each light with a map is scaled by its
    ``shadow_factor``; ``ExactShadows()``: each shadow-casting light's by the exact visibility
    of the light (``visibility``, ray casting: the hard shadows shadow maps approximate);
    None: no shadows."""
    out = np.zeros((gbuffer.height, gbuffer.width, 3))
    out[:] = scene.clear_color
    cov = gbuffer.coverage
    P, N = gbuffer.position[cov], gbuffer.normal[cov]
    albedo, spec, shin = gbuffer.albedo[cov], gbuffer.specular[cov], gbuffer.shininess[cov]
    cam = np.asarray(scene.camera.position, dtype=np.float64)
    colour = as_float32(scene.ambient) * albedo
    for i, light in enumerate(scene.lights):
        sel = reached(light, P)
        term = light_contribution(light, P[sel], N[sel], cam, albedo[sel], spec[sel], shin[sel])
        factor = None if shadows is None else shadows.factor(scene, i, light, P[sel],
                                                             safe_normalize(N[sel]))
        if factor is not None:
            term = term * factor[:, None]
        colour[sel] += term
    out[cov] = colour
    return out


def reference_image(scene: Scene, material: tuple[str, ...] = ("opaque",),
                    shadows: Optional[Shadows] = None) -> tuple[np.ndarray, GBuffer]:
    """(colour float64 (H, W, 3) before clamping, G-buffer) of the scene's opaque objects
    (``shadows``: as ``shade`` takes them)."""
    gb = rasterize(scene, material)
    return shade(gb, scene, shadows), gb


def to_rgba8(colour: np.ndarray) -> np.ndarray:
    """The rgba8 codes a technique writes: clamp, round half to even, alpha 1."""
    rgba = np.concatenate([colour, np.ones(colour.shape[:-1] + (1,))], axis=-1)
    return formats.get("rgba8").quantize(rgba)


def lights_per_pixel(gbuffer: GBuffer, scene: Scene, conservative: bool = False,
                     faces: str = "back", sky: bool = False) -> np.ndarray:
    """int (H, W): how many lights may touch each pixel's surface point (0 on sky).

    Default: the point and spot lights whose sphere (radius) strictly contains the point, plus
    every directional light.  ``conservative=True`` counts what a light-volume pass with
    ``cull front`` and ``depth gequal`` marks instead: lights whose *circumscribing* volume
    mesh has a back face at or behind the surface along the pixel's view ray (this also counts
    volumes hidden behind the surface), so it bounds what an index packing must hold.
    ``faces="front"`` (with ``conservative``) counts what a pass drawing the volumes' *front*
    faces with ``depth lequal`` (``cull auto``, ``inside always``) marks: lights whose
    circumscribing sphere meets the view ray between the eye and the surface (Trebilco's
    light-volume front faces, volumes wholly in front of the surface included); ``sky=True``
    counts sky pixels too, along the whole ray (a translucent object over the sky reads them).
    """
    cov = gbuffer.coverage
    front = conservative and faces == "front"
    where = np.ones_like(cov) if (front and sky) else cov
    cam = np.asarray(scene.camera.position, dtype=np.float64)
    P = gbuffer.position[where]
    ray = P - cam
    t_surface = np.linalg.norm(ray, axis=1)
    u = ray / np.maximum(t_surface, 1e-300)[:, None]
    if front and sky:        # sky pixels: the ray through the pixel centre, to infinity
        h, w = cov.shape
        ys, xs = np.mgrid[0:h, 0:w]
        ndc = np.stack([(xs + 0.5) / w * 2 - 1, 1 - (ys + 0.5) / h * 2, np.ones((h, w)),
                        np.ones((h, w))], axis=-1)[where]
        inv = np.linalg.inv(scene.camera.projection(scene.aspect) @ scene.camera.view_matrix())
        far = ndc @ inv.T
        d = far[:, :3] / far[:, 3:] - cam
        d /= np.linalg.norm(d, axis=1)[:, None]
        open_ = ~cov[where]
        u[open_] = d[open_]
        t_surface[open_] = np.inf
    count = np.zeros(len(P), dtype=np.int64)
    grow = volume_grow()
    for light in scene.lights:
        if light.type == "directional":
            count += 1
            continue
        centre, r = as_float32(light.position), float(as_float32(light.radius))
        if not conservative:
            L = centre - P
            count += np.einsum("ij,ij->i", L, L) < r * r
            continue
        count += volume_marks(light, cam, u, t_surface, front, grow)
    out = np.zeros(cov.shape, dtype=np.int64)
    out[where] = count
    return out


def volume_grow() -> float:
    """How far the sphere mesh a light pass draws reaches, in radii (it circumscribes the
    light's sphere)."""
    return float(np.linalg.norm(light_volume("sphere").astype(np.float64), axis=1).max())


def volume_marks(light: Light, cam: np.ndarray, u: np.ndarray, t_surface: np.ndarray,
                 front: bool, grow: float) -> np.ndarray:
    """Which of the rays from ``cam`` along the unit directions ``u`` (N, 3), ending at the
    surface ``t_surface`` away (inf: the sky), a light-volume pass marks for ``light``:
    ``front=False`` (back faces, ``depth gequal``): its circumscribing volume has a back face
    at or behind the surface; ``front=True`` (front faces, ``depth lequal``, ``inside
    always``): the volume meets the ray between the eye and the surface.  (N,) bool."""
    hit, t_near, t_far = ray_volume_span(light, cam, u, grow)
    if front:
        return hit & (t_far >= 0) & (t_near <= t_surface)
    return hit & (t_far >= t_surface)


def ray_volume_span(light: Light, cam: np.ndarray, u: np.ndarray, grow: float):
    """Where the rays from ``cam`` along the unit directions ``u`` (N, 3) meet the sphere of
    radius ``grow`` x the light's radius around it (float32 centre and radius, as the light
    table holds them): (hit (N,) bool, t_near, t_far)."""
    centre, r = as_float32(light.position), float(as_float32(light.radius))
    R = r * grow
    oc = centre - cam
    b = u @ oc
    disc = b * b - (oc @ oc - R * R)
    s = np.sqrt(np.maximum(disc, 0.0))
    return disc > 0, b - s, b + s
