"""Regenerate docs/images/lidr_shadow_prepass.png (the README's figure of
pipelines/lidr_shadow_prepass.pipe).

    python docs/make_lidr_shadow_prepass_figure.py

examples/scenes/overlapping_spot_shadows.toml at 320x180 (four overlapping shadow-casting spot
lights), on GL: lidr_bitplanes.pipe (the same light indices, no shadows), lidr_shadow_prepass
with shadow_filter = hard and with pcf (pcf_taps 16), the float64 scene reference (exact
ray-cast shadows); below, what the light-index pass left in its targets: the lights each pixel
holds (hard: shadowed lights take no slot) and the shadow intensity in the slot holding
light 0 (pcf, ``intensity_planes`` decoded; black where no slot holds it).  The error against the reference in the captions.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_figures import paste_titled  # noqa: E402  (the figures' shared grid)

PARAMS = {"pcf_taps": 16, "shadow_bias": 0.25}


def _grey(values: np.ndarray) -> np.ndarray:
    """[0, 1] values (H, W) as an RGB picture."""
    g = (np.clip(values, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)
    return np.repeat(g[..., None], 3, axis=2)


def main() -> int:
    from pipegen.compiler.driver import compile_file
    from pipegen.core import formats
    from pipegen.packing import schemes
    from pipegen.proof.accuracy import scene_reference
    from pipegen.reference.metrics import rgb_error, to_top_down
    from pipegen.scene import load_scene

    scene = load_scene(ROOT / "examples/scenes/overlapping_spot_shadows.toml").with_size(320, 180)
    ref = scene_reference(scene).rgb
    rgba8 = formats.get("rgba8")
    unpack_index = schemes.numpy_impl("bitplanes", {"index_bits": 8}, rgba8)["unpack"]
    unpack_lit = schemes.numpy_impl("intensity_planes", {"lights": 4}, rgba8)["unpack"]
    cells, below = [], []
    runs = (("lidr_bitplanes", {}), ("lidr_shadow_prepass", {"shadow_filter": "hard"}),
            ("lidr_shadow_prepass", {"shadow_filter": "pcf"}))
    for tech, params in runs:
        print(f"rendering {tech} {params}", file=sys.stderr)
        compiled = compile_file(ROOT / f"pipelines/{tech}.pipe",
                                params={**params, **PARAMS} if params else {})
        out = compiled.pipeline("gl").render(scene)
        e = rgb_error(out["color"], ref)
        name = tech if not params else f"shadow_filter={params['shadow_filter']}"
        cells.append((to_top_down(out["color"])[..., :3], f"{name}: RMSE {e['rmse']:.2f}"))
        v = to_top_down(out["lightidx"]).astype(np.float32) / 255
        if params.get("shadow_filter") == "hard":
            held = sum((unpack_index(v, k) > 0).astype(int) for k in range(4))
            below.append((_grey(held / 4.0), "hard: lights held per pixel (0..4)"))
        elif params:
            lit = to_top_down(out["lightlit"]).astype(np.float32) / 255
            first = sum(np.where(unpack_index(v, k) == 1, unpack_lit(lit, k), 0.0)
                        for k in range(4))
            below.append((_grey(first), "pcf: light 0's slot, its intensity"))
    cells.append(((np.clip(ref, 0, 1) * 255 + 0.5).astype(np.uint8),
                  "float64 reference (ray cast)"))
    h, w = ref.shape[:2]
    sheet = Image.new("RGB", (4 * (w + 4), 2 * (h + 20)), (255, 255, 255))
    paste_titled(sheet, [cells, [None] + below], w, h)
    path = ROOT / "docs/images/lidr_shadow_prepass.png"
    sheet.save(path, optimize=True)
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
