"""Regenerate the figures in docs/images/.

    python docs/make_figures.py

inferred_dsf.png: inferred lighting on examples/scenes/edges.toml at lbuffer_scale 0.625 with
and without discontinuity-sensitive filtering, the full-resolution float64 reference, and the
two error maps (rgba8 codes, black 0 -> white >= 40).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[1]


def paste_titled(sheet: Image.Image, rows: list, w: int, h: int) -> None:
    """The figures' grid: ``rows`` of cells (uint8 image array, title) or None (left blank),
    each w x h image 4 pixels from the next and under its title (16 pixels), rows 20 apart."""
    draw = ImageDraw.Draw(sheet)
    for r, row in enumerate(rows):
        for c, cell in enumerate(row):
            if cell is None:
                continue
            x, y = c * (w + 4), r * (h + 20)
            sheet.paste(Image.fromarray(np.ascontiguousarray(cell[0])), (x, y + 16))
            draw.text((x + 2, y + 2), cell[1], fill=(0, 0, 0))


def main() -> int:
    from pipegen.compiler.driver import compile_file
    from pipegen.reference.metrics import error_image, heat_map, rgb_error, to_top_down
    from pipegen.reference.translucent import reference_composite
    from pipegen.scene import load_scene

    scene = load_scene(ROOT / "examples/scenes/edges.toml").with_size(384, 216)
    ref, _ = reference_composite(scene)
    images, errors, titles = {}, {}, {}
    for dsf in (True, False):
        print(f"rendering inferred, dsf={dsf}", file=sys.stderr)
        compiled = compile_file(ROOT / "pipelines/inferred.pipe",
                                params={"lbuffer_scale": 0.625, "dsf": dsf})
        img = compiled.pipeline("gl").render(scene)["color"]
        name = "DSF" if dsf else "bilinear"
        images[name] = to_top_down(img)[..., :3]
        err = np.asarray(error_image(img, ref), dtype=np.float64)
        err = err.max(axis=-1) if err.ndim == 3 else err
        errors[name] = heat_map(err / 40.0)
        titles[name] = f"RMSE {rgb_error(img, ref)['rmse']:.1f} codes"
    layout = [
        [(images["DSF"], f"inferred 0.625, DSF: {titles['DSF']}"),
         ((np.clip(ref, 0, 1) * 255 + 0.5).astype(np.uint8), "float64 reference, full res"),
         (images["bilinear"], f"inferred 0.625, bilinear: {titles['bilinear']}")],
        [(errors["DSF"], "error, DSF (white >= 40 codes)"), None,
         (errors["bilinear"], "error, bilinear (white >= 40 codes)")],
    ]
    h, w = ref.shape[:2]
    sheet = Image.new("RGB", (3 * w + 8, 2 * (h + 18) + 2), (255, 255, 255))
    paste_titled(sheet, layout, w, h)
    out = ROOT / "docs/images/inferred_dsf.png"
    sheet.save(out, optimize=True)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
