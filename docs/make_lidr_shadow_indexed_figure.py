"""Regenerate docs/images/lidr_shadow_indexed.png (the shadow maps indexed by light index).

    python docs/make_lidr_shadow_indexed_figure.py

pipelines/lidr_shadow_indexed.pipe (Trebilco's "Shadow Maps", final pass: the forward pass
looks each unpacked light's shadow map up by its light index; light indices 0..shadow_lights-1
cast) at 320x180, pcf_taps 4 jittered, shadow_bias 0.25, on GL, beside the float64 scene
reference (exact ray-cast shadows, ``accuracy.scene_reference``), the error in the captions:

- top: examples/scenes/overlapping_spot_shadows.toml (four shadowed spots overlapping) and its
  3 x 3 atlas (four tiles drawn; each stretched from its nearest texel, black, to its farthest,
  grey; the clear depth 1 white);
- bottom: examples/scenes/shadows.toml with every light casting (two spots, a sun, a point
  light: 3 + 6 = 9 tiles), once with the shipped range (shadow_lights = 4) and once with
  shadow_lights = 2, where the sun (index 2) and the point light (index 3) lie past the range:
  the warning names them and they are lit unshadowed.
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
from make_shadow_figure import _stretch  # noqa: E402  (the atlas's grey ramp per tile)

PARAMS = {"pcf_taps": 4, "pcf_pattern": "jittered", "shadow_bias": 0.25}
W, H = 320, 180


def _render(scene, **params):
    from pipegen.compiler.driver import compile_file
    compiled = compile_file(ROOT / "pipelines/lidr_shadow_indexed.pipe",
                            params={**PARAMS, **params})
    for m in compiled.mismatches(scene):
        print(f"warning: {m.message}", file=sys.stderr)
    return compiled.pipeline("gl").render(scene)


def _cell(out, ref, title, late):
    from pipegen.reference.metrics import rgb_error, to_top_down
    e = rgb_error(out["color"], ref)
    past = f" (lights {late} unshadowed)" if late else ""
    return (to_top_down(out["color"])[..., :3], f"{title}: RMSE {e['rmse']:.2f}{past}")


def main() -> int:
    from pipegen.proof.accuracy import scene_reference
    from pipegen.reference.metrics import to_top_down
    from pipegen.scene import load_scene
    from pipegen.scene import shadows as S

    overlap = load_scene(ROOT / "examples/scenes/overlapping_spot_shadows.toml").with_size(W, H)
    s = load_scene(ROOT / "examples/scenes/shadows.toml").with_size(W, H)
    every = dataclasses.replace(s, lights=tuple(dataclasses.replace(l, shadows=True)
                                                for l in s.lights))
    rows = []
    for scene, variants in ((overlap, [({}, "lidr_shadow_indexed")]),
                            (every, [({}, "shadow_lights=4"),
                                     ({"shadow_lights": 2}, "shadow_lights=2")])):
        print(f"rendering {scene.name}", file=sys.stderr)
        ref = scene_reference(scene).rgb
        row, atlas = [], None
        for params, title in variants:
            out = _render(scene, **params)
            late = S.casters_from(scene.lights, params.get("shadow_lights", 4))
            row.append(_cell(out, ref, title, ", ".join(map(str, late))))
            atlas = atlas if atlas is not None else out["shadow_atlas"]
        row.append(((np.clip(ref, 0, 1) * 255 + 0.5).astype(np.uint8),
                    "float64 reference (ray-cast shadows)"))
        if len(row) == 2:           # the top row: the atlas in the third cell
            a = np.asarray(Image.fromarray((_stretch(to_top_down(atlas), 3) * 255)
                                           .astype(np.uint8)).resize((H, H), Image.BILINEAR))
            cell = np.full((H, W, 3), 255, np.uint8)
            cell[:, :H] = a[..., None]
            row.append((cell, "shadow_atlas (d32f, 3 x 3 tiles)"))
        rows.append(row)
    sheet = Image.new("RGB", (3 * (W + 4), 2 * (H + 20)), (255, 255, 255))
    paste_titled(sheet, rows, W, H)
    out = ROOT / "docs/images/lidr_shadow_indexed.png"
    sheet.save(out, optimize=True)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
