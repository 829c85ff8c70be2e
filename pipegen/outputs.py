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


def packed_channels(tech: ir.Technique) -> dict[str, tuple[bool, ...]]:
    """Per colour target, which channels hold packed integers (light indices, ID bit fields):
    the channels whose written value comes from an index-packing function.  Those must match
    exactly across backends; the other channels of the same target (a linear depth beside an
    ID, say) keep their format's tolerance."""
    prefixes = tuple(p.name + "_" for p in tech.packings if p.scheme in _INDEX_SCHEMES)
    packed: dict[str, list[bool]] = {}
    for p in tech.passes:
        for s in irwalk.walk_stmts(p.body):
            if not isinstance(s, ir.Output):
                continue
            flags = packed.setdefault(s.target, [False] * 4)
            for c, part in enumerate(_components(s.value)):
                if part is not None and _calls_packing(part, prefixes):
                    flags[c] = True
    return {t: tuple(f[:tech.target(t).format.channels]) for t, f in packed.items()}


def _components(value: ir.Expr) -> list:
    """The expression behind each of the 4 components of a written vec4 (None: unknown, or
    the whole value when it is not a constructor)."""
    if isinstance(value, ir.Construct):
        parts: list = []
        for a in value.args:
            parts += [a] * max(1, a.type.size)
        return (parts + [None] * 4)[:4]
    return [value] * 4


def _calls_packing(e: ir.Expr, prefixes: tuple[str, ...]) -> bool:
    return any(isinstance(x, ir.Call) and not x.builtin and x.name.startswith(prefixes)
               for x in irwalk.walk_exprs([ir.ExprStmt(e)]))


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
