"""Regenerate docs/images/shadows.png (the README's shadow-map figure).

    python docs/make_shadow_figure.py

examples/scenes/shadows.toml at 320x180 (two spot lights and a sun casting shadows): forward.pipe
with pcf_taps 1 and 16, deferred_calver.pipe with pcf_taps 16, the float64 scene reference
(exact ray-cast shadows, ``accuracy.scene_reference``), and the 1024x1024 d32f atlas of 2 x 2
tiles (each tile stretched from its nearest texel, black, to its farthest, grey; the clear
depth 1 white); the error against the reference in the captions.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_figures import paste_titled  # noqa: E402  (the figures' shared grid)


def _stretch(atlas: np.ndarray, tiles: int = 2) -> np.ndarray:
    """Each tile's depths stretched from its nearest (black) to its farthest drawn texel
    (light grey); the clear depth 1 stays white."""
    out = np.ones_like(atlas, dtype=np.float64)
    n = atlas.shape[0] // tiles
    for ty in range(tiles):
        for tx in range(tiles):
            t = atlas[ty * n:(ty + 1) * n, tx * n:(tx + 1) * n].astype(np.float64)
            drawn = t < 1.0
            if drawn.any():
                lo, hi = t[drawn].min(), t[drawn].max()
                out[ty * n:(ty + 1) * n, tx * n:(tx + 1) * n] = np.where(
                    drawn, 0.85 * (t - lo) / max(hi - lo, 1e-12), 1.0)
    return out


def main() -> int:
    from pipegen.proof.accuracy import scene_reference
    from pipegen.compiler.driver import compile_file
    from pipegen.reference.metrics import rgb_error, to_top_down
    from pipegen.scene import load_scene

    scene = load_scene(ROOT / "examples/scenes/shadows.toml").with_size(320, 180)
    ref = scene_reference(scene).rgb
    cells, atlas = [], None
    for tech, taps in (("forward", 1), ("forward", 16), ("deferred_calver", 16)):
        print(f"rendering {tech}, pcf_taps={taps}", file=sys.stderr)
        compiled = compile_file(ROOT / f"pipelines/{tech}.pipe", params={"pcf_taps": taps})
        out = compiled.pipeline("gl").render(scene)
        e = rgb_error(out["color"], ref)
        cells.append((to_top_down(out["color"])[..., :3],
                      f"{tech}, pcf_taps={taps}: RMSE {e['rmse']:.2f}"))
        atlas = out["shadow_atlas"]
    cells.append(((np.clip(ref, 0, 1) * 255 + 0.5).astype(np.uint8),
                  "float64 reference (ray-cast shadows)"))
    h, w = ref.shape[:2]
    a = np.asarray(Image.fromarray((_stretch(to_top_down(atlas)) * 255).astype(np.uint8)).resize(
        (2 * h + 20, 2 * h + 20), Image.BILINEAR))
    sheet = Image.new("RGB", (2 * (w + 4) + a.shape[1] + 4, 2 * (h + 20)), (255, 255, 255))
    paste_titled(sheet, [cells[:2], cells[2:]], w, h)
    x = 2 * (w + 4)
    sheet.paste(Image.fromarray(a).convert("RGB"), (x, 16))
    ImageDraw.Draw(sheet).text((x + 2, 2), "shadow_atlas (d32f, 2 x 2 tiles)", fill=(0, 0, 0))
    out = ROOT / "docs/images/shadows.png"
    sheet.save(out, optimize=True)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
