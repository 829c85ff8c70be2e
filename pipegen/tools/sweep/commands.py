"""The command line that reproduces one row of a sweep: ``pipegen sweep`` of that variant alone,
on that backend, with the same scene, size, frames and reference (``results.json``'s ``command``
per row, shown in ``index.html``)."""

from __future__ import annotations

import os
import shlex
from typing import Optional


def _path(p: str) -> str:
    """A path as the user would type it here: relative to the working folder when inside it."""
    rel = os.path.relpath(os.path.abspath(p))
    return rel if not rel.startswith("..") else os.path.abspath(p)


def row_command(file: str, params: tuple, backend: str, spec: dict, size: tuple[int, int],
                frames: int, reference: Optional[str] = None,
                reference_samples: int = 1, general: bool = False) -> str:
    """``pipegen sweep FILE --scene S --size WxH -p k=v ... --backend B --frames N -o DIR``
    (and ``--general`` when the row is of the general build); a scene given as a loaded
    ``Scene`` has no path: ``--scene`` then names a placeholder."""
    from pipegen.tools.sweep.variants import value_text
    args = ["pipegen", "sweep", _path(file)]
    if spec.get("path"):
        args += ["--scene", _path(spec["path"])]
    elif spec.get("pickle"):
        args += ["--scene", "SCENE.toml"]       # the Scene was given in Python: save it as one
    args += ["--size", f"{size[0]}x{size[1]}"]
    for k, v in params:
        args += ["-p", f"{k}={value_text(v)}"]
    args += ["--backend", backend, "--frames", str(frames)]
    if reference:
        args += ["--reference", reference]
    if reference_samples and reference_samples > 1:
        args += ["--reference-samples", str(reference_samples)]
    if general:
        args += ["--general"]
    args += ["-o", "out/sweep-row"]
    return " ".join(shlex.quote(a) for a in args)
