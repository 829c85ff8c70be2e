"""Regenerate docs/images/lidr_shadow_volumes.png (the README's figure of
pipelines/lidr_shadow_volumes.pipe).

    python docs/make_lidr_shadow_volumes_figure.py

examples/scenes/shadows.toml at 320x180 with every light casting (two spots, the sun and the
point light), on GL: lidr_bitplanes.pipe (the same light indices, no shadows),
lidr_shadow_volumes, the float64 scene reference (exact ray-cast shadows); below, the stencil
that the first spot's and the sun's shadow volumes leave (depth-fail counts: black 0, lit;
brighter, inside more volumes) and the error against the reference (x8).  The error in the
captions.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_figures import paste_titled  # noqa: E402  (the figures' shared grid)


def _grey(values: np.ndarray) -> np.ndarray:
    """[0, 1] values (H, W) as an RGB picture."""
    g = (np.clip(values, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)
    return np.repeat(g[..., None], 3, axis=2)


def main() -> int:
    from pipegen.compiler.driver import compile_file
    from pipegen.proof.accuracy import scene_reference
    from pipegen.reference.metrics import error_image, rgb_error, to_top_down
    from pipegen.scene import load_scene

    scene = load_scene(ROOT / "examples/scenes/shadows.toml").with_size(320, 180)
    scene = dataclasses.replace(scene, lights=tuple(dataclasses.replace(l, shadows=True)
                                                    for l in scene.lights))
    ref = scene_reference(scene).rgb
    cells, below = [], []
    for tech in ("lidr_bitplanes", "lidr_shadow_volumes"):
        print(f"rendering {tech}", file=sys.stderr)
        compiled = compile_file(ROOT / f"pipelines/{tech}.pipe")
        out, captures = compiled.pipeline("gl").render(scene, capture_passes=True)
        e = rgb_error(out["color"], ref)
        cells.append((to_top_down(out["color"])[..., :3],
                      f"{tech}: RMSE {e['rmse']:.2f}, max {e['max']:.0f}"))
        if tech != "lidr_shadow_volumes":
            continue
        for light, name in ((0, "spot 0"), (2, "the sun")):
            stencil = next(c["targets"]["ds.stencil"] for c in captures
                           if c["pass"] == "shadow_volumes" and c["light"] == light)
            below.append((_grey(to_top_down(stencil).astype(np.float32) / 3.0),
                          f"stencil after {name}'s volumes"))
        err = error_image(out["color"], ref).max(axis=2)
        below.append((_grey(err * 8.0 / 255.0), "error x8 (shadow edges)"))
    cells.append(((np.clip(ref, 0, 1) * 255 + 0.5).astype(np.uint8),
                  "float64 reference (ray cast)"))
    h, w = ref.shape[:2]
    sheet = Image.new("RGB", (3 * (w + 4), 2 * (h + 20)), (255, 255, 255))
    paste_titled(sheet, [cells, below], w, h)
    path = ROOT / "docs/images/lidr_shadow_volumes.png"
    sheet.save(path, optimize=True)
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
