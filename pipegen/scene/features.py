"""What a scene calls for: ``scene_features(scene)`` gives the light types and counts,
translucent objects and stipple layers, specular materials, the ambient term, lights whose
volume holds the camera, the ids and normal groups in use, and the shadow-casting lights; its
``facts()`` are what a technique specialised to the scene assumes (``compiler/specialise.py``).
The costly questions, answered by rasterising the scene in float64, are in
``compiler/mismatches.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipegen.ir import nodes as ir
from pipegen.scene import shadows as S

LIGHT_TYPES = ("point", "spot", "directional")


@dataclass(frozen=True)
class SceneFeatures:
    light_counts: tuple[tuple[str, int], ...]    # per light type present, in LIGHT_TYPES order
    translucent_objects: int
    opaque_objects: int
    max_layer: int                               # highest stipple layer used (0: none)
    specular: bool                               # any material with specular > 0
    ambient: bool                                # a non-zero ambient term
    camera_inside: tuple[int, ...]               # lights whose sphere holds the camera
    object_ids: int
    normal_groups: int
    shadow_lights: int = 0                       # lights casting shadows (``shadows = true``)

    @property
    def lights(self) -> int:
        return sum(n for _, n in self.light_counts)

    @property
    def light_types(self) -> tuple[str, ...]:
        return tuple(t for t, _ in self.light_counts)

    def count(self, light_type: str) -> int:
        return dict(self.light_counts).get(light_type, 0)

    def facts(self) -> ir.SceneFacts:
        """The compile-time facts a specialised technique assumes.  The light count is
        rounded up to a power of two so that similar scenes share a variant."""
        return ir.SceneFacts(self.light_types, _pow2(self.lights), self.translucent_objects > 0,
                             self.opaque_objects > 0, self.shadow_lights > 0)

    def describe(self) -> list[str]:
        lights = ", ".join(f"{n} {t}" for t, n in self.light_counts) or "none"
        return [f"lights: {lights}",
                f"objects: {self.opaque_objects} opaque, {self.translucent_objects} translucent"
                + (f" (stipple layers up to {self.max_layer})" if self.max_layer else ""),
                f"specular materials: {'yes' if self.specular else 'no'}; ambient: "
                f"{'yes' if self.ambient else 'no'}",
                f"camera inside the volume of light(s): "
                f"{', '.join(map(str, self.camera_inside)) or 'none'}",
                f"object ids in use: {self.object_ids}; normal groups: {self.normal_groups}"]


def _pow2(n: int) -> int:
    return 1 if n <= 1 else 1 << (int(n) - 1).bit_length()


def scene_features(scene) -> SceneFeatures:
    counts = {t: 0 for t in LIGHT_TYPES}
    for light in scene.lights:
        counts[light.type] = counts.get(light.type, 0) + 1
    eye = np.asarray(scene.camera.position, np.float64)
    inside = tuple(i for i, l in enumerate(scene.lights) if l.radius > 0 and
                   np.linalg.norm(eye - np.asarray(l.position, np.float64)) <= l.radius)
    objects = list(scene.objects)
    groups = {int(g) for o in objects for g in np.unique(o.groups)}
    return SceneFeatures(
        light_counts=tuple((t, n) for t, n in counts.items() if n),
        translucent_objects=sum(o.material.translucent for o in objects),
        opaque_objects=sum(not o.material.translucent for o in objects),
        max_layer=max((o.layer for o in objects), default=0),
        specular=any(o.material.specular > 0 for o in objects),
        ambient=bool(np.any(np.asarray(scene.ambient) > 0)),
        camera_inside=inside,
        object_ids=len({o.id for o in objects}),
        normal_groups=len(groups),
        shadow_lights=len(S.shadow_lights(scene.lights)))
