"""Write a render's targets as PNG pictures and raw ``.npy`` arrays (``pipegen run``,
``pipegen.save_pngs``) into an output folder pipegen owns (``outdir.py``)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Union

import numpy as np

from pipegen.core import formats
from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.core.outdir import OutputDir, as_output_dir, safe_name
from pipegen.views.visualize import save_png, to_rgb8, write_pictures

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


def write_render(compiled, scene, targets: dict[str, np.ndarray],
                 out: Union[str, os.PathLike, OutputDir], npy: bool = True) -> Path:
    """Write every target as ``TARGET.png`` (visualised per kind of content, top row first) and,
    with ``npy``, its raw codes as ``TARGET.npy`` (row 0 at the bottom) into ``out``, through
    ``outdir.OutputDir``: a folder holding files pipegen did not write is refused (pass an
    ``OutputDir(..., force=True)`` to write into it anyway), the previous outputs are replaced
    only when everything was written.  Returns the folder."""
    out = as_output_dir(out, "run")
    tech = compiled.technique
    hints = target_hints(tech)
    with out.staging() as tmp:
        for name, codes in targets.items():
            base, _, aspect = name.partition(".")
            fmt = tech.target(base).format
            hint = "stencil" if aspect == "stencil" else hints.get(name, "auto")
            if aspect == "stencil":
                fmt = formats.get("r8")
            if npy:
                np.save(tmp / file_name(name, ".npy"), codes)
            save_png(tmp / file_name(name, ".png"), to_rgb8(codes, fmt, hint, scene.camera.near,
                                                            scene.camera.far))
        write_pictures(tmp, compiled, scene, targets, file_name)
    return out.path


def save_pngs(compiled, scene, targets: dict[str, np.ndarray],
              folder: Union[str, os.PathLike], *, npy: bool = False,
              force: bool = False) -> dict[str, Path]:
    """Save the targets a pipeline rendered as PNG pictures, one per target, in ``folder``, as
    ``pipegen run`` does (``npy=True`` also writes the raw ``.npy`` arrays).  ``folder`` is
    created if missing; a folder holding files pipegen did not write is refused with a
    ``PipegenError`` unless ``force`` (and even then those files are kept).  Returns
    ``{target: path of its PNG}``."""
    out = write_render(compiled, scene, targets, OutputDir(folder, "save_pngs", force), npy)
    return {name: out / file_name(name, ".png") for name in targets}


def file_name(target: str, suffix: str) -> str:
    """The file a target is written to: ``TARGET.png``, ``ds.stencil.npy``; very long target
    names are shortened (``outdir.safe_name``)."""
    return safe_name(target, suffix)
