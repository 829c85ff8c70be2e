"""Write a render's targets as PNG pictures and raw ``.npy`` arrays, atomically."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from . import formats, ir, irwalk
from .visualize import save_png, to_rgb8

_INDEX_SCHEMES = ("bitplanes", "max_pairs", "channel_slots", "bitfield")


def target_hints(tech: ir.Technique) -> dict[str, str]:
    """How to picture each target: what the technique writes into it decides."""
    index_fns = {f.name for p in tech.packings if p.scheme in _INDEX_SCHEMES
                 for f in p.functions}
    index_prefixes = tuple(p.name + "_" for p in tech.packings if p.scheme in _INDEX_SCHEMES)
    hints = {}
    for t in tech.targets:
        if t.format.has_depth:
            hints[t.name] = "depth"
        elif t.name == tech.output:
            hints[t.name] = "color"
    for p in tech.passes:
        for s in irwalk.walk_stmts(p.body):
            if isinstance(s, ir.Output) and s.target not in hints:
                calls = [e.name for e in irwalk.walk_exprs([s]) if isinstance(e, ir.Call)]
                if any(c in index_fns or c.startswith(index_prefixes) for c in calls):
                    hints[s.target] = "index"
    return hints


def write_render(compiled, scene, targets: dict[str, np.ndarray], out: Path) -> Path:
    tech = compiled.technique
    hints = target_hints(tech)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for name, codes in targets.items():
            base, _, aspect = name.partition(".")
            fmt = tech.target(base).format
            hint = "stencil" if aspect == "stencil" else hints.get(name, "auto")
            if aspect == "stencil":
                fmt = formats.get("r8")
            np.save(tmp / f"{name}.npy", codes)
            save_png(tmp / f"{name}.png", to_rgb8(codes, fmt, hint, scene.camera.near,
                                                   scene.camera.far))
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out
