"""Regenerate docs/images/calver_materials.png (Calver's material table in deferred_calver).

    python docs/make_calver_materials_figure.py

examples/scenes/calver_materials.toml at 288x192, GL: deferred_calver.pipe with the scene's
material fields (metallic half-Lambert box, wrapped sphere at half ambient, flat cylinder glowing
by its specular colour, an emissive lamp), the same scene with every field removed (today's
model: the defaults), the float64 reference of the table (``reference/calver_materials.py``) and
its error x 64 off silhouettes (1 code: a quarter of full scale), RMSE and max in the caption.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_figures import paste_titled  # noqa: E402  (the figures' shared grid)

FIELDS = re.compile(r", (kspec_blend|diffuse_fn|kamb|kemm) = [0-9.]+|, emissive = \[[^]]*\]")


def main() -> int:
    from pipegen.compiler.driver import compile_file
    from pipegen.reference.calver_materials import calver_shade
    from pipegen.reference.metrics import error_image, heat_map, rgb_error, to_top_down
    from pipegen.reference.raster import rasterize
    from pipegen.scene import parse_scene

    path = ROOT / "examples/scenes/calver_materials.toml"
    text = path.read_text()
    plain = FIELDS.sub("", text)
    assert not any(FIELDS.search(line) or "emissive" in line
                   for line in plain.splitlines() if line.startswith("material"))
    pipe = compile_file(ROOT / "pipelines/deferred_calver.pipe").pipeline("gl")
    cells = []
    for title, t in (("material table", text), ("no fields (the defaults)", plain)):
        scene = parse_scene(t, str(path), base_dir=path.parent).with_size(288, 192)
        print(f"rendering deferred_calver, {title}", file=sys.stderr)
        out = pipe.render(scene)["color"]
        if t is text:
            gb = rasterize(scene, ("opaque",))
            ref = calver_shade(gb, scene)
            e = rgb_error(out, ref, ~gb.silhouette)
            err = error_image(out, ref).max(axis=2) * ~gb.silhouette
        cells.append((to_top_down(out)[..., :3], f"deferred_calver, {title}"))
    cells.insert(1, ((np.clip(ref, 0, 1) * 255 + 0.5).astype(np.uint8),
                     "float64 reference (calver_materials.py)"))
    cells.append((heat_map(err * 64 / 255), f"error x64: RMSE {e['rmse']:.2f}, max {e['max']:.0f}"))
    h, w = ref.shape[:2]
    sheet = Image.new("RGB", (2 * (w + 4), 2 * (h + 20)), (255, 255, 255))
    paste_titled(sheet, [cells[:2], cells[2:]], w, h)
    out_path = ROOT / "docs/images/calver_materials.png"
    sheet.save(out_path, optimize=True)
    print(out_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
