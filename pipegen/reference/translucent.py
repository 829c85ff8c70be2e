"""The float64 reference for lit translucent layers: what an inferred-lighting material pass
(Kircher & Lawrance 2009, §4) computes, at full resolution and without the stipple/DSF
approximations.

Per output pixel::

    c = opaque surface lit with the shared lighting equation (reference.lighting.shade),
        the clear colour on sky
    for each translucent surface covering the pixel with depth < the opaque depth,
        back to front (largest window depth first):
            c = lerp(c, lit_translucent, alpha)         # = c + (lit - c) * alpha

where ``lit_translucent`` is the same lighting equation evaluated with the translucent
surface's own position, normal and material (ambient included) and ``alpha`` its material
alpha.  Each translucent object is rasterised on its own (back faces culled, its own depth test),
so it contributes at most its nearest front face to a pixel: the per-pixel list of layers is
one entry per translucent object.

By default (``clamp_layers=True``) the destination and every lit layer are clamped to [0, 1]
before each blend, as fixed-function blending into an rgba8 target does (the destination holds
a unorm value and the source colour is clamped for unorm targets); the 8-bit rounding of the
intermediate results is not modelled (it moves the result by at most half a code per layer).

Arrays are top row first, like ``reference.lighting.reference_image``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

import numpy as np

from pipegen.scene.model import STIPPLE_LAYERS, Scene, SceneObject, stipple_map
from pipegen.reference.lighting import shade
from pipegen.reference.raster import GBuffer, edge_mask, rasterize, rasterize_each

if TYPE_CHECKING:
    from pipegen.reference.shadows import Shadows


@dataclass
class TranslucentSurface:
    """One translucent object rasterised on its own (H, W arrays, row 0 on top)."""

    object: SceneObject
    layer: int                 # its stipple layer, 1..3
    gbuffer: GBuffer           # its nearest front faces (coverage, position, normal, depth, ...)
    visible: np.ndarray        # bool: covered and in front of the opaque surface (depth less)
    lit: np.ndarray            # float64 (H, W, 3): its lit colour (before clamping), 0 where uncovered


def translucent_surfaces(scene: Scene, opaque_depth: np.ndarray,
                         cull: str = "back") -> list[TranslucentSurface]:
    """Every translucent object rasterised and lit on its own, in scene order."""
    out = []
    for obj, gb in rasterize_each(scene, ("translucent",), cull):
        visible = gb.coverage & (gb.depth < opaque_depth)
        out.append(TranslucentSurface(obj, obj.layer, gb, visible, shade(gb, scene)))
    return out


def reference_composite(scene: Scene, clamp_layers: bool = True,
                        cull: str = "back", shadows: Optional[Shadows] = None
                        ) -> tuple[np.ndarray, dict]:
    """(rgb float64 (H, W, 3) top row first, info) of the opaque scene with its translucent
    layers blended over it back to front (see the module docstring).

    ``info``:

    - ``"opaque"``: float64 (H, W, 3), the opaque-only image (``reference_image``);
    - ``"gbuffer"``: the opaque ``GBuffer``;
    - ``"surfaces"``: ``[TranslucentSurface]`` in scene order;
    - ``"count"``: int64 (H, W), how many translucent surfaces are blended at each pixel;
    - ``"covered"``: bool (H, W), ``count > 0`` (where the composite differs from the opaque
      image, up to alpha = 0 layers);
    - ``"layer_masks"``: bool (4, H, W): ``[L]`` = a visible translucent surface of stipple layer
      L covers the pixel (``[0]`` = the opaque coverage: an opaque surface, not sky, lies behind);
    - ``"conflict"``: bool (H, W), two visible translucent surfaces of the *same* layer overlap
      (a stippled G-buffer can hold only one of them: the scene's layers are badly assigned);
    - ``"silhouette"``: bool (H, W), the opaque G-buffer's silhouette plus, per translucent
      surface, the 3x3 neighbourhoods where its visible part begins or ends (its outline and
      where it goes behind opaque geometry) or crosses a crease;
    - ``"order"``: int64 (K, H, W), translucent surface indices per pixel, back to front; only
      the first ``count`` entries of a pixel are meaningful.

    ``shadows`` (``lighting.shade``'s argument) shadows the opaque surface only.
    """
    gb = rasterize(scene, ("opaque",))
    opaque = shade(gb, scene, shadows)         # shadows on the opaque surface (lighting.shade)
    surfaces = translucent_surfaces(scene, gb.depth, cull)
    H, W = gb.height, gb.width
    K = len(surfaces)
    rgb = opaque.copy()
    layer_masks = np.zeros((STIPPLE_LAYERS + 1, H, W), dtype=bool)
    silhouette = gb.silhouette.copy()
    if K == 0:
        count = np.zeros((H, W), dtype=np.int64)
        layer_masks[0] = gb.coverage
        return rgb, dict(opaque=opaque, gbuffer=gb, surfaces=surfaces, count=count,
                         covered=count > 0, layer_masks=layer_masks, conflict=np.zeros((H, W), bool),
                         silhouette=silhouette, order=np.zeros((0, H, W), np.int64))

    visible = np.stack([s.visible for s in surfaces])                       # (K, H, W)
    count = visible.sum(axis=0).astype(np.int64)
    key = np.where(visible, np.stack([s.gbuffer.depth for s in surfaces]), -np.inf)
    order = np.argsort(-key, axis=0, kind="stable")                        # far first, hidden last
    lit = np.stack([s.lit for s in surfaces])                               # (K, H, W, 3)
    alpha = np.stack([s.gbuffer.alpha for s in surfaces])                   # (K, H, W)
    rows, cols = np.indices((H, W))
    for k in range(int(count.max())):
        idx = order[k]
        on = k < count
        src = lit[idx, rows, cols]
        a = alpha[idx, rows, cols][..., None]
        dst = rgb
        if clamp_layers:
            src, dst = np.clip(src, 0.0, 1.0), np.clip(dst, 0.0, 1.0)
        rgb = np.where(on[..., None], dst + (src - dst) * a, rgb)

    layer_count = np.zeros((STIPPLE_LAYERS + 1, H, W), dtype=np.int64)
    for s in surfaces:
        layer_count[s.layer] += s.visible
        surface_id = np.where(s.visible, s.gbuffer.normal_group, -1)
        silhouette |= edge_mask(surface_id)
    layer_masks = layer_count > 0
    layer_masks[0] = gb.coverage
    conflict = (layer_count[1:] > 1).any(axis=0)
    return rgb, dict(opaque=opaque, gbuffer=gb, surfaces=surfaces, count=count, covered=count > 0,
                     layer_masks=layer_masks, conflict=conflict, silhouette=silhouette, order=order)


def stippled_gbuffer(scene: Scene, cull: str = "back") -> tuple[GBuffer, np.ndarray]:
    """(GBuffer, layer int64 (H, W)), top row first: what an inferred-lighting geometry pass
    with stippled translucency stores at the scene's size (pass ``scene.with_size(...)`` for a
    low-resolution G-buffer).  The opaque objects are drawn first; then at each pixel owned by
    stipple layer L >= 1 (:func:`pipegen.scene.model.stipple_owner`, GL window rows) the nearest
    translucent surface of layer L in front of the opaque depth replaces the opaque data (depth
    test ``less``).  ``layer`` is L where a translucent surface was stored, else 0.  The
    ``triangle`` field is -1 at translucent pixels (their triangles index per-object lists);
    ``edge`` is the edge mask of the stored surfaces (object and normal group)."""
    gb = rasterize(scene, ("opaque",))
    owner = stipple_map(gb.width, gb.height, top_down=True)
    out = {f.name: np.copy(getattr(gb, f.name)) for f in dataclasses.fields(GBuffer)
           if f.name not in ("width", "height")}
    layer = np.zeros((gb.height, gb.width), dtype=np.int64)
    for surf in translucent_surfaces(scene, gb.depth, cull):
        t = surf.gbuffer
        take = surf.visible & (owner == surf.layer) & (t.depth < out["depth"])
        for name, value in out.items():
            if name not in ("triangle", "edge"):
                value[take] = getattr(t, name)[take]
        out["triangle"][take] = -1
        layer[take] = surf.layer
    surface = np.where(out["object_id"] < 0, -1, out["object_id"] * 256 + out["normal_group"])
    out["edge"] = edge_mask(np.where(layer > 0, -2 - surface, out["triangle"]))
    return GBuffer(width=gb.width, height=gb.height, **out), layer
