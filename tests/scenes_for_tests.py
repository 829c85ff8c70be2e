"""Scene TOML the tests build: flat planes facing a camera on the +z axis.

``planes_scene(*objects)`` is the scene text: the camera at (0, 0, 5) looking at the origin
(fov 45, near 0.5, far 50), a uniform ambient and the given ``plane(...)`` entries, each the
``plane`` mesh turned to face +z.  Without lights a surface's colour is ``ambient * albedo``,
so what a pipeline composites over such planes is known exactly.  Lights are TOML text
appended by the test (``planes_scene(...) + lights``).
"""

from __future__ import annotations

from typing import Optional, Sequence

CAMERA = """[camera]
position = [0, 0, 5]
target = [0, 0, 0]
fov_y_deg = 45
near = 0.5
far = 50
"""


def plane(name: str, albedo: Sequence[float], translate: Optional[Sequence[float]] = None,
          scale: float = 1, alpha: Optional[float] = None, layer: Optional[int] = None) -> str:
    """One ``[[objects]]`` entry: the plane mesh rotated to face +z, moved by ``translate``
    (none: at the origin) and scaled; translucent with ``alpha`` (else opaque); an explicit
    blending ``layer`` if given."""
    material = f"albedo = {list(albedo)}" + ("" if alpha is None
                                             else f", alpha = {alpha}, translucent = true")
    lines = ["[[objects]]", f'name = "{name}"', 'mesh = "plane"', "rotate_deg = [90, 0, 0]"]
    if translate is not None:
        lines.append(f"translate = {list(translate)}")
    lines += [f"scale = {scale}", f"material = {{ {material} }}"]
    if layer is not None:
        lines.append(f"layer = {layer}")
    return "\n".join(lines) + "\n"


# The opaque white wall at z = -2 behind the planes.
WALL = plane("wall", [1, 1, 1], translate=[0, 0, -2], scale=8)


def planes_scene(*objects: str, width: int = 64, height: int = 48,
                 ambient: float = 0.5) -> str:
    """The scene text: size, uniform ``ambient``, the camera on +z and ``objects``."""
    return "\n".join([f"width = {width}\nheight = {height}\n"
                      f"ambient = [{ambient}, {ambient}, {ambient}]\n", CAMERA, *objects])
