"""Regenerate docs/images/lidr_msaa.png (docs/accuracy.md, "LIDR MSAA techniques 1, 2 and 3
side by side"): Trebilco's three MSAA techniques on the same crops, beside the float64 scene
reference supersampled 4x4 (16 samples per pixel, box filter).

    python docs/make_lidr_msaa_figure.py

On CL (GL renders the same images: `pipegen check` gives 0 codes): tests/data/thin_poles.toml at
160x90 (poles 0.65-0.94 px wide before the lit wall) and examples/scenes/edges.toml at 192x108
(the grille of bars).  Columns: technique 1 (lidr_msaa_texture), 2 (lidr_transparent),
3 (lidr_nearest_edge), 3 again with the pixels whose search failed (its `edge_miss` target) in
magenta, the reference.  Each crop 80x60, magnified 3x (nearest); captions give the crop's
RMSE against the reference in rgba8 codes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_figures import paste_titled  # noqa: E402  (the figures' shared grid)

SCENES = {   # scene: (size, crop x0, y0, x1, y1)
    "tests/data/thin_poles.toml": ((160, 90), (28, 4, 108, 64)),
    "examples/scenes/edges.toml": ((192, 108), (36, 12, 116, 72)),
}
TECHNIQUES = (("lidr_msaa_texture", "1 MSAA texture"), ("lidr_transparent", "2 front faces"),
              ("lidr_nearest_edge", "3 nearest edge"))
ZOOM = 3
MISSED = (255, 0, 255)


def _zoom(image: np.ndarray) -> np.ndarray:
    return np.kron(image.astype(np.uint8), np.ones((ZOOM, ZOOM, 1), np.uint8))


def main() -> int:
    from pipegen.compiler.driver import compile_file
    from pipegen.proof.accuracy import output_codes
    from pipegen.proof.references import choose_reference
    from pipegen.reference.metrics import reference_codes
    from pipegen.scene import load_scene

    rows = []
    for path, (size, (x0, y0, x1, y1)) in SCENES.items():
        scene = load_scene(ROOT / path).with_size(*size)
        name = Path(path).stem
        print(f"{name}: the float64 reference (4x4 supersampled)", file=sys.stderr)
        ref = choose_reference("scene", compile_file(ROOT / "pipelines/lidr_bitplanes.pipe"), 4)
        want = reference_codes(ref.output_rgb(scene))[y0:y1, x0:x1]
        row = []
        for technique, label in TECHNIQUES:
            print(f"{name}: {technique}", file=sys.stderr)
            compiled = compile_file(ROOT / f"pipelines/{technique}.pipe", scene=scene)
            targets = compiled.pipeline("cl").render(scene)
            got = output_codes(compiled, targets)[::-1, :, :3][y0:y1, x0:x1]   # top row first
            rmse = float(np.sqrt(np.mean((got.astype(np.float64) - want) ** 2)))
            row.append((_zoom(got), f"{label}: RMSE {rmse:.1f}"))
            if "edge_miss" in targets:
                missed = targets["edge_miss"][::-1][y0:y1, x0:x1] > 0
                marked = got.copy()
                marked[missed] = MISSED
                row.append((_zoom(marked), f"3: search failed ({int(missed.sum())} px)"))
        row.append((_zoom(want), f"reference, {name} {size[0]}x{size[1]}"))
        rows.append(row)
    w, h = 80 * ZOOM, 60 * ZOOM
    sheet = Image.new("RGB", (5 * (w + 4), len(rows) * (h + 20)), (255, 255, 255))
    paste_titled(sheet, rows, w, h)
    out = ROOT / "docs/images/lidr_msaa.png"
    sheet.save(out, optimize=True)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
