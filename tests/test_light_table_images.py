"""The light table's layout in the shaders changes no pixel (issue 26 item 6).

The targets every shipped technique renders on two scenes with every light type (mixed_lights;
shadows, whose lights cast shadows through the table's shadow fields), general and specialised
builds, on GL and CL (mixed_lights, the general builds and the variants of tests/shipped.py
only with --exhaustive), hashed byte for byte against
``light_table_images.json``: the images
rendered before the table was laid out in packed vec4 rows (one field per texel before).  A
change meant to alter pixels regenerates the file:  python tests/test_light_table_images.py
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

import shipped

ROOT = Path(__file__).resolve().parents[1]
HASHES = Path(__file__).with_name("data") / "light_table_images.json"
SCENES = ("mixed_lights", "shadows")
TECHNIQUES = sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe"))


def target_hashes(technique: str, scene: str, backend: str, general: bool) -> dict[str, str]:
    """SHA-256 of every target's values (dtype and shape included) for one render."""
    from pipegen.compiler.driver import compile_file
    from pipegen.scene import load_scene
    s = load_scene(ROOT / "examples" / "scenes" / f"{scene}.toml")
    compiled = compile_file(ROOT / "pipelines" / f"{technique}.pipe",
                            scene=None if general else s)
    targets = compiled.pipeline(backend).render(s)
    out = {}
    for name in sorted(targets):
        v = np.ascontiguousarray(targets[name])
        digest = hashlib.sha256(f"{v.dtype}{v.shape}".encode() + v.tobytes()).hexdigest()
        out[name] = digest
    return out


def _key(technique: str, scene: str, backend: str, general: bool) -> str:
    return f"{technique}/{scene}/{backend}/{'general' if general else 'specialised'}"


CASES = [(t, s, b, g) for t in TECHNIQUES for s in SCENES for b in ("gl", "cl")
         for g in (True, False)]
# CI renders `shadows` (point, spot and directional lights, every one casting: every field of
# the table read); mixed_lights, the same light types without shadows, with --exhaustive
# (CI's 10-minute budget: each shipped technique costs eight compiles and renders a scene).
# Of `shadows`, CI hashes the build `run` renders by default (compiled for the scene; with
# every light type casting, it reads every field of the table); the general build with
# --exhaustive (test_specialise.py holds it equal to the specialised one on CI's scenes).
IN_CI = {"shadows"}
PARAMS = [pytest.param(*c, id=_key(*c),
                       marks=() if c[1] in IN_CI and not c[3] and c[0] not in shipped.VARIANTS
                       else pytest.mark.exhaustive) for c in CASES]


@pytest.mark.gl
@pytest.mark.cl
@pytest.mark.parametrize("technique,scene,backend,general", PARAMS)
def test_targets_unchanged(technique, scene, backend, general):
    pytest.importorskip("pyopencl")
    expected = json.loads(HASHES.read_text())[_key(technique, scene, backend, general)]
    assert target_hashes(technique, scene, backend, general) == expected


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    hashes = {_key(*c): target_hashes(*c) for c in CASES}
    HASHES.write_text(json.dumps(hashes, indent=1, sort_keys=True) + "\n")
    print(f"{len(hashes)} renders hashed into {HASHES}")
