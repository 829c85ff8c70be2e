"""Calver's post-processing phase in float64: tone mapping, distance fog and depth of field, the
operations of ``pipelines/deferred_calver.pipe``'s resolve pass, applied to the float64 lighting
reference (``reference.lighting``).

The pass reads one thing per texel, the lit buffer ``accum`` (rgba16f): RGB the accumulated
light, alpha the surface's view-space z (minus its view depth) where fog or depth of field is on,
the clear value 1 on sky pixels.  So, per pixel, with ``depth`` the view depth (``inf`` on sky)::

    fog 1 (linear):       f = clamp((depth - fog_start) / (fog_end - fog_start), 0, 1)
    fog 2 (exponential):  f = 1 - exp(-fog_density * depth)
    fogged(c, depth)      = mix(c, fog_colour, f)                    (c itself when fog is 0)
    blur(depth)           = clamp(|depth - focus_distance| / focus_range, 0, 1)
    depth of field:       coc = blur(depth) * dof_max_coc (pixels); the centre texel with weight
                          1 plus, for each of dof_taps taps o_i of ``DOF_TAPS`` (unit disc),
                          the texel at floor(window_xy + o_i * coc) clamped to the image, with
                          weight 1 if its depth is greater than the centre's, else blur(its
                          depth); the weighted mean of fogged(texel colour, texel depth)
                          (Riguer's gather as Calver gives it, the taps scaled by the centre's
                          circle of confusion as in Riguer's original)
    tone map (tonemap):   x = c * exposure;  x / (1 + x)  per channel (Reinhard)

Order: fog per texel, the gather over the fogged texels, then the tone map; the result is
quantised to rgba8 like any reference (``lighting.to_rgba8``).

What is modelled of the storage: the view depth is rounded to float16, as the rgba16f alpha the
pass reads holds it (so that the reference picks the same tap texels as the pass: a tap's texel
is a discontinuous function of the depth); the tap offsets are the float32 literals of the
shader.  The colours are the float64 lighting (the accumulator's rgba16f rounding of them is in
the tests' bounds).  Window coordinates: x right, y *up* from the bottom row (GL); the arrays
here are top row first like every reference, and flipped for the gather.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipegen.reference.lighting import reference_image
from pipegen.reference.raster import GBuffer

# The gather pattern of deferred_calver.pipe (dof_tap): axes, diagonals, then a ring of radius
# 1/2 turned by 22.5 degrees; a tap count n takes the first n.  Window coordinates (y up).
_S = 0.70710678
_C, _N = 0.46193977, 0.19134172
DOF_TAPS = np.asarray([
    (1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0),
    (_S, _S), (-_S, _S), (-_S, -_S), (_S, -_S),
    (_C, _N), (_N, _C), (-_N, _C), (-_C, _N), (-_C, -_N), (-_N, -_C), (_N, -_C), (_C, -_N),
], dtype=np.float32).astype(np.float64)


def _f32(x: float) -> float:
    return float(np.float32(x))


@dataclass(frozen=True)
class PostParams:
    """The post-processing parameters of deferred_calver.pipe, with its defaults (all off)."""

    tonemap: bool = False
    exposure: float = 1.0
    fog: int = 0
    fog_r: float = 0.5
    fog_g: float = 0.55
    fog_b: float = 0.6
    fog_start: float = 5.0
    fog_end: float = 40.0
    fog_density: float = 0.05
    dof_taps: int = 0
    focus_distance: float = 10.0
    focus_range: float = 10.0
    dof_max_coc: float = 4.0

    @classmethod
    def of(cls, params: dict) -> "PostParams":
        """The post parameters among a technique's parameter overrides (others ignored)."""
        names = cls.__dataclass_fields__
        return cls(**{k: v for k, v in params.items() if k in names})


def view_depth(gbuffer: GBuffer, scene, storage: str = "rgba16f") -> np.ndarray:
    """float64 (H, W): the view depth -z_view of each pixel's surface, ``inf`` on sky; rounded to
    float16 with ``storage="rgba16f"`` (what the pass reads), exact with ``storage=None``."""
    V = scene.camera.view_matrix()
    P = gbuffer.position
    z = P @ V[2, :3] + V[2, 3]
    if storage == "rgba16f":
        z = z.astype(np.float16).astype(np.float64)
    elif storage is not None:
        raise ValueError(f"unknown depth storage {storage!r}")
    return np.where(gbuffer.coverage, -z, np.inf)


def tone_map(colour: np.ndarray, exposure: float) -> np.ndarray:
    """Reinhard per channel after the exposure: x / (1 + x), x = colour * exposure."""
    x = np.asarray(colour, dtype=np.float64) * _f32(exposure)
    return x / (1.0 + x)


def fog_factor(depth: np.ndarray, p: PostParams) -> np.ndarray:
    """How much fog colour replaces the surface colour, in [0, 1] (1 on sky: infinite depth)."""
    depth = np.asarray(depth, dtype=np.float64)
    if p.fog == 1:
        start, end = _f32(p.fog_start), _f32(p.fog_end)
        with np.errstate(invalid="ignore"):
            return np.clip((depth - start) / (end - start), 0.0, 1.0)
    if p.fog == 2:
        return 1.0 - np.exp(-_f32(p.fog_density) * depth)
    return np.zeros_like(depth)


def apply_fog(colour: np.ndarray, depth: np.ndarray, p: PostParams) -> np.ndarray:
    if p.fog == 0:
        return np.asarray(colour, dtype=np.float64)
    f = fog_factor(depth, p)[..., None]
    fog_colour = np.asarray([_f32(p.fog_r), _f32(p.fog_g), _f32(p.fog_b)])
    return colour * (1.0 - f) + fog_colour * f


def blur(depth: np.ndarray, p: PostParams) -> np.ndarray:
    """Riguer's blur factor: 0 in focus, 1 from focus_range away (1 on sky)."""
    return np.clip(np.abs(depth - _f32(p.focus_distance)) / _f32(p.focus_range), 0.0, 1.0)


def depth_of_field(colour: np.ndarray, depth: np.ndarray, p: PostParams) -> np.ndarray:
    """The gather blur of (fogged) ``colour`` (H, W, 3) by ``depth`` (H, W), both top row
    first; returns the blurred colour, top row first."""
    c = np.asarray(colour, dtype=np.float64)[::-1]          # window rows: row 0 at the bottom
    d = np.asarray(depth, dtype=np.float64)[::-1]
    h, w = d.shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    b = blur(d, p)
    coc = b * _f32(p.dof_max_coc)
    total = np.ones((h, w))
    acc = c.copy()
    for ox, oy in DOF_TAPS[:p.dof_taps]:
        tx = np.clip(np.floor(xs + 0.5 + ox * coc), 0, w - 1).astype(np.int64)
        ty = np.clip(np.floor(ys + 0.5 + oy * coc), 0, h - 1).astype(np.int64)
        tap_depth = d[ty, tx]
        weight = np.where(tap_depth > d, 1.0, blur(tap_depth, p))
        acc += weight[..., None] * c[ty, tx]
        total += weight
    return (acc / total[..., None])[::-1]


def post_process(lit: np.ndarray, depth: np.ndarray, p: PostParams) -> np.ndarray:
    """Fog, depth of field, tone map (each as ``p`` says) of the lit image (H, W, 3) with view
    depth (H, W), both top row first: the colour the resolve pass writes, before rgba8."""
    c = apply_fog(lit, depth, p)
    if p.dof_taps:
        c = depth_of_field(c, depth, p)
    if p.tonemap:
        c = tone_map(c, p.exposure)
    return c


def post_reference(scene, params: dict | PostParams | None = None,
                   depth_storage: str | None = "rgba16f",
                   material: tuple[str, ...] = ("opaque",)) -> tuple[np.ndarray, GBuffer]:
    """(float64 colour (H, W, 3) before rgba8, G-buffer): the lighting reference of the scene
    with deferred_calver's post-processing applied.  The lit image's sky pixels are the
    accumulator's clear colour, black (the lighting reference gives them the scene's clear
    colour, which the technique never writes into its lit buffer)."""
    p = params if isinstance(params, PostParams) else PostParams.of(params or {})
    lit, gb = reference_image(scene, material)
    lit = np.where(gb.coverage[..., None], lit, 0.0)
    return post_process(lit, view_depth(gb, scene, depth_storage), p), gb
