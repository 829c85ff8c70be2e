"""GL renders on the lent GPU, saved for analysis at home: every target of every shipped
technique on the three scenes of gpu_check at 640x360 (the variant run renders), two files per
scene."""
import os, sys, time
from pathlib import Path
import numpy as np
sys.path.insert(0, "benchmarks")
from common import ROOT, TECHNIQUES, scene_at
from pipegen.compiler.driver import compile_file, for_scene
out = Path(os.environ["OUT"])
for stem in ("mixed_lights", "many_lights", "street_lamps"):
    scene = scene_at(str(ROOT / f"examples/scenes/{stem}.toml"), "640x360")
    for half, names in enumerate((TECHNIQUES[:8], TECHNIQUES[8:])):   # files under 16 MB
        arrays = {}
        for name in names:
            f = str(ROOT / "pipelines" / f"{name}.pipe")
            v = for_scene(compile_file(f), scene, False, f)
            for t, a in v.pipeline("gl").render(scene).items():
                arrays[f"{name}/{t}"] = a
        path = out / f"gl_{stem}_{half}.npz"
        np.savez_compressed(path, **arrays)
        print("saved", path.name, path.stat().st_size, flush=True)
