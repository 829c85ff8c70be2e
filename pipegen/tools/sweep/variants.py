"""What a sweep renders: the axes (``-p NAME=V1,V2`` or a technique's declared ones) and
their cartesian product per technique file, each combination a :class:`Variant`."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Optional

from pipegen.core.diagnostics import PipegenError


@dataclass(frozen=True)
class Variant:
    """One technique file with one value per swept parameter."""

    index: int
    file: str
    technique: str
    params: tuple = ()            # ((name, value), ...): the swept axes, in axis order

    @property
    def params_text(self) -> str:
        return " ".join(f"{k}={value_text(v)}" for k, v in self.params)

    @property
    def label(self) -> str:
        return f"{self.technique} {self.params_text}".strip()

    @property
    def slug(self) -> str:
        parts = [f"{k}-{value_text(v)}" for k, v in self.params]
        return "_".join([f"{self.index:02d}", self.technique, *parts])


def value_text(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return f"{v:g}" if isinstance(v, float) else str(v)


def parse_axes(items: list) -> dict[str, list]:
    """``["lbuffer_scale=0.5,1.0", ("dsf", True), ...]`` -> ``{name: [values]}``, in order."""
    from pipegen.compiler.inputs import literal
    axes: dict[str, list] = {}
    for item in items:
        if isinstance(item, tuple):
            name, values = item[0], item[1]
            values = values if isinstance(values, (list, tuple)) else [values]
            if len(values) == 1 and isinstance(values[0], str):
                values = [literal(v.strip()) for v in values[0].split(",")]
        else:
            name, sep, text = str(item).partition("=")
            if not sep or not name.strip() or not text.strip():
                raise PipegenError(None, f"bad parameter axis {item!r}: write NAME=V1,V2,...",
                                   hint="e.g. -p lbuffer_scale=0.5,0.625,1.0")
            values = [literal(v.strip()) for v in text.split(",") if v.strip()]
        name = name.strip()
        axes.setdefault(name, [])
        axes[name] += [v for v in values if v not in axes[name]]
    return axes


def declared_axes(technique) -> dict[str, list]:
    """The axes a technique sweeps without ``-p``: parameters with declared allowed values, in
    declaration order, and ``bool`` parameters (``false, true``)."""
    out = {}
    for p in technique.params:
        if p.allowed:
            out[p.name] = list(p.allowed)
        elif getattr(p.type.scalar, "value", None) == "bool" and p.type.size == 1:
            out[p.name] = [False, True]
    return out


def plan_variants(files: list, axes: Optional[dict] = None) -> tuple[list[Variant], dict]:
    """Every (file, combination of its axes) as a ``Variant``, each compiled once here (a bad
    value fails now, before any job); returns (variants, {variant index: Compiled})."""
    from pipegen.compiler.driver import compile_file
    variants, compiled = [], {}
    used: set[str] = set()
    for file in files:
        base = compile_file(file)
        names = {p.name for p in base.technique.params}
        if axes:
            file_axes = {k: v for k, v in axes.items() if k in names}
        else:
            file_axes = declared_axes(base.technique)
        used |= set(file_axes)
        keys = list(file_axes)
        for combo in itertools.product(*(file_axes[k] for k in keys)):
            params = tuple(zip(keys, combo))
            c = compile_file(file, dict(params)) if params else base
            v = Variant(len(variants), str(file), c.technique.name, params)
            variants.append(v)
            compiled[v.index] = c
    if axes:
        unknown = [k for k in axes if k not in used]
        if unknown:
            raise PipegenError(None, f"no technique given has a parameter "
                                     f"{', '.join(map(repr, unknown))}",
                               hint="pipegen info FILE lists a technique's parameters")
    return variants, compiled
