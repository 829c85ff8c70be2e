"""Regenerate docs/images/inferred_msaa_dsf.png (docs/accuracy.md, "Inferred lighting with
8x MSAA"), after Kircher & Lawrance's Figure 3: the same 8x MSAA frame upsampled from the
0.625 L-buffer without and with discontinuity-sensitive filtering.

    python docs/make_inferred_msaa_figure.py

examples/scenes/edges.toml at 320x180, inferred.pipe with samples=8, lbuffer_scale=0.625, on CL
(llvmpipe's GL stops at 4 samples), dsf false and true, and the float64 reference the sweep
uses (the technique at lbuffer_scale 1.0, single-sampled, 4x4 supersampled: 16 shaded
samples per pixel, box filter).  Two crops, each magnified 4x (nearest): the dark box against
the brightly lit wall, and the lit sphere's edge; the captions give each crop's RMSE against
the reference in rgba8 codes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_figures import paste_titled  # noqa: E402  (the figures' shared grid)

SIZE = (320, 180)
CROPS = {"dark box": (56, 20, 136, 100), "sphere": (190, 80, 270, 160)}   # x0, y0, x1, y1
ZOOM = 4


def main() -> int:
    from pipegen.compiler.driver import compile_file
    from pipegen.proof.accuracy import output_codes
    from pipegen.proof.references import choose_reference
    from pipegen.reference.metrics import reference_codes
    from pipegen.scene import load_scene

    scene = load_scene(ROOT / "examples/scenes/edges.toml").with_size(*SIZE)
    pipe = ROOT / "pipelines/inferred.pipe"
    ref = choose_reference("self", compile_file(pipe), 4)
    print("evaluating the float64 reference (4x4 supersampled)", file=sys.stderr)
    want = reference_codes(ref.output_rgb(scene))
    images = {}
    for dsf in (False, True):
        print(f"rendering inferred, samples=8, dsf={dsf}", file=sys.stderr)
        compiled = compile_file(pipe, params={"samples": 8, "lbuffer_scale": 0.625, "dsf": dsf})
        targets = compiled.pipeline("cl").render(scene)
        images[dsf] = output_codes(compiled, targets)[::-1, :, :3]      # top row first
    rows = []
    for name, (x0, y0, x1, y1) in CROPS.items():
        row = []
        for dsf, label in ((False, "no DSF"), (True, "DSF")):
            crop = images[dsf][y0:y1, x0:x1]
            err = crop.astype(np.float64) - want[y0:y1, x0:x1]
            rmse = float(np.sqrt(np.mean(err ** 2)))
            big = np.kron(crop.astype(np.uint8), np.ones((ZOOM, ZOOM, 1), np.uint8))
            row.append((big, f"8x MSAA, {label}, {name}: RMSE {rmse:.1f}"))
        ref_crop = want[y0:y1, x0:x1].astype(np.uint8)
        row.append((np.kron(ref_crop, np.ones((ZOOM, ZOOM, 1), np.uint8)),
                    "reference (1.0, 4x4 supersampled)"))
        rows.append(row)
    w, h = (CROPS["dark box"][2] - CROPS["dark box"][0]) * ZOOM, \
        (CROPS["dark box"][3] - CROPS["dark box"][1]) * ZOOM
    sheet = Image.new("RGB", (3 * w + 8, len(rows) * (h + 20)), (255, 255, 255))
    paste_titled(sheet, rows, w, h)
    out = ROOT / "docs/images/inferred_msaa_dsf.png"
    sheet.save(out, optimize=True)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
