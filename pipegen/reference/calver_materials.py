"""Calver's material table and emissive term in float64: what ``pipelines/deferred_calver.pipe``
computes with its ``material { … }`` record per object id (Calver 2003, "Surface Material" and
the light model's ``Illuminate``), with exact shaping functions where the pipeline samples its
lookup textures.

For a surface point with object id o, record m = the scene's material table at o (float32
values, as the light table stores them), albedo Cs0, specular colour Cs1 = (specular,) * 3::

    colour = ambient * Cs0 * m.kamb + m.emissive + m.kemm * Cs1            (once, not per light)
    per light (l, att, the shadow factor as reference/lighting.py and reference/shadows.py):
        ndl = n.l  (not clamped: a shaping function decides what a back-facing light does)
        diffuse = DIFFUSE_FUNCTIONS[m.diffuse_fn](ndl)
        spec = ndl > 0 ? pow(max(n.h, 1e-6), shininess) : 0        (Calver's cascade multiplier)
        colour += att * (Cl * Cs0 * diffuse + spec * Cs1 * lerp(Cl, 1, m.kspec_blend))

Diffuse rows: 0 ``max((x + wrap) / (1 + wrap), 0)`` (the technique's ``wrap`` parameter; Lambert
at 0), 1 wrap 0.5, 2 half-Lambert ``((x + 1) / 2)^2``, 3 flat ``1 - (1 - max(x, 0))^2``.  With
the defaults (diffuse_fn 0, kspec_blend 0, kamb 1, kemm 0, emissive 0) this is
``reference.lighting.shade``.  The ``hemisphere`` parameter is not modelled (its default is 0).
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from pipegen.reference.lighting import EPS_POW, incidence, reached, safe_normalize
from pipegen.reference.raster import GBuffer
from pipegen.reference.rounding import as_float32
from pipegen.reference.shadows import Shadows

# deferred_calver.pipe's material block: (name, type, default), in its order
CALVER_MATERIAL = (("diffuse_fn", "uint", (0.0,)), ("kspec_blend", "float", (0.0,)),
                   ("kamb", "float", (1.0,)), ("kemm", "float", (0.0,)),
                   ("emissive", "vec3", (0.0, 0.0, 0.0)))


def diffuse_function(row: np.ndarray, x: np.ndarray, wrap: float = 0.0) -> np.ndarray:
    """The diffuse shaping function of each point's row (``diffuse_lut``'s rows) at n.l = x."""
    lambert = np.maximum(x, 0.0)
    return np.select([row == 0, row == 1, row == 2],
                     [np.maximum((x + wrap) / (1.0 + wrap), 0.0),
                      np.maximum((x + 0.5) / 1.5, 0.0), (x * 0.5 + 0.5) ** 2],
                     lambert * (2.0 - lambert))


def material_records(scene) -> dict[str, np.ndarray]:
    """{field: (256, components) float64}: every object id's fields, float32-rounded."""
    table = as_float32(scene.material_table(CALVER_MATERIAL))
    return {name: table[:, k, :len(default)] for k, (name, _, default) in
            enumerate(CALVER_MATERIAL)}


def calver_shade(gbuffer: GBuffer, scene, shadows: Optional[Shadows] = None,
                 wrap: float = 0.0) -> np.ndarray:
    """float64 (H, W, 3) colour before clamping (sky = the clear colour); ``shadows`` as
    ``reference.lighting.shade`` takes them."""
    out = np.zeros((gbuffer.height, gbuffer.width, 3))
    out[:] = scene.clear_color
    cov = gbuffer.coverage
    m = {k: v[gbuffer.object_id[cov]] for k, v in material_records(scene).items()}
    P, n = gbuffer.position[cov], safe_normalize(gbuffer.normal[cov])
    albedo, shin = gbuffer.albedo[cov], gbuffer.shininess[cov]
    cs1 = np.repeat(gbuffer.specular[cov][:, None], 3, axis=1)
    v = safe_normalize(np.asarray(scene.camera.position, dtype=np.float64) - P)
    row = m["diffuse_fn"][:, 0]
    colour = as_float32(scene.ambient) * albedo * m["kamb"] + m["emissive"] + m["kemm"] * cs1
    for i, light in enumerate(scene.lights):
        sel = reached(light, P)
        l, att = incidence(light, P[sel])
        ndl = np.einsum("ij,ij->i", n[sel], l)
        diffuse = diffuse_function(row[sel], ndl, wrap)
        ndh = np.maximum(np.einsum("ij,ij->i", n[sel], safe_normalize(l + v[sel])), 0.0)
        spec = np.where(ndl > 0, np.power(np.maximum(ndh, EPS_POW), shin[sel]), 0.0)
        cl = as_float32(light.color)
        highlight = cs1[sel] * (cl + m["kspec_blend"][sel] * (1.0 - cl))     # lerp(Cl, 1, K)
        term = att[:, None] * (cl * albedo[sel] * diffuse[:, None] + spec[:, None] * highlight)
        factor = None if shadows is None else shadows.factor(scene, i, light, P[sel], n[sel])
        if factor is not None:
            term = term * factor[:, None]
        colour[sel] += term
    out[cov] = colour
    return out
