"""``pipegen info FILE``: what a technique exposes, read from its IR (``Compiled.technique``):
parameters (type, default, allowed values), targets (format, size and bytes at an output size),
passes in order, and packing schemes."""

from __future__ import annotations

from typing import Optional

from pipegen.core.units import format_bytes
from pipegen.frontend.lower.names import param_type_name
from pipegen.ir import nodes as ir
from pipegen.ir.lifetimes import lifetimes
from pipegen.ir.memory import target_bytes, technique_bytes
from pipegen.views.memory import live_text, memory_lines, traffic_lines
from pipegen.views.report import error_bound_text


def describe(compiled, output_size: tuple[int, int],
             defaults: Optional[dict[str, object]] = None) -> str:
    """The ``info`` text.  ``defaults``: the parameters' declared defaults when ``compiled``
    was compiled with overrides (its IR then holds the overridden values)."""
    tech: ir.Technique = compiled.technique
    w, h = output_size
    lines = [f"technique {tech.name}: {tech.title}" if tech.title else f"technique {tech.name}",
             f"source    {tech.source or '<string>'}", ""]

    lines.append("parameters (override with -p NAME=VALUE)")
    if tech.params:
        overridden = defaults is not None
        head = ("name", "type", "default") + (("value",) if overridden else ()) + ("allowed",)
        rows = [head]
        for p in tech.params:
            default = defaults.get(p.name, p.default) if overridden else p.default
            kind = param_type_name(p)       # the language's word: a word parameter is `format`
            allowed = ", ".join(value_text(v) for v in p.allowed) if p.allowed else \
                ("true, false" if p.type == ir.BOOL else f"any {kind}")
            rows.append((p.name, kind, value_text(default))
                        + ((value_text(p.default),) if overridden else ()) + (allowed,))
        lines += table(rows)
    else:
        lines.append("  (none)")

    lines += ["", f"targets at output size {w}x{h} (* = the output image; live: the passes "
                  f"from its first use to its last)"]
    rows = [("name", "format", "size", "samples", "B/px", "bytes", "live")]
    life = lifetimes(tech.passes, tech.targets, tech.output)
    for t in tech.targets:
        tw, th = t.size.resolve(w, h)
        size = f"{tw}x{th}"
        if not t.size.relative:
            size += " (fixed)"
        elif t.size.scale != 1.0:
            size += f" (output*{t.size.scale:g})"
        rows.append((t.name + (" *" if t.name == tech.output else ""), t.format.name, size,
                     str(t.samples), str(t.format.bytes_per_pixel),
                     format_bytes(target_bytes(t, w, h), "MiB", exact=True),
                     live_text(life[t.name], len(tech.passes))))
    lines += table(rows)
    lines.append(f"  total: {format_bytes(technique_bytes(tech, w, h), 'MiB', exact=True)}")

    lines += ["", "passes (in order)"]
    for i, p in enumerate(tech.passes, 1):
        parts = [f"draw {p.draw.describe()}"]
        if p.writes:
            parts.append("writes " + ", ".join(p.writes))
        if p.depth_target:
            parts.append("depth " + p.depth_target)
        if p.reads:
            parts.append("reads " + ", ".join(p.reads))
        if p.repeat_group is not None:
            parts.append("repeat per light" + "".join(" " + t for t in p.repeat_types))
        lines.append(f"  {i}. {p.name}: " + "; ".join(parts))

    lines += ["", *memory_lines(tech, w, h), "", *traffic_lines(tech, w, h)]

    lines += ["", "packing schemes"]
    if tech.packings:
        for p in tech.packings:
            opts = ", ".join(f"{k}: {option_text(v)}" for k, v in p.options)
            facts = []
            if p.capacity is not None:
                facts.append(f"capacity {p.capacity} lights per pixel")
            if p.error is not None:
                facts.append(f"error bound {error_bound_text(p)}")
            fns = [f.name for f in p.functions]
            if fns:
                facts.append("functions " + ", ".join(fns))
            lines.append(f"  {p.name} = {p.scheme}({opts})"
                         + (": " + "; ".join(facts) if facts else ""))
    else:
        lines.append("  (none)")
    return "\n".join(lines) + "\n"


def value_text(v) -> str:
    """A parameter value as the .pipe language spells it."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def option_text(v) -> str:
    if isinstance(v, tuple) and all(isinstance(x, tuple) and len(x) == 2 for x in v):
        return "{" + ", ".join(f"{k}: {option_text(x)}" for k, x in v) + "}"
    return value_text(v)


def table(rows: list[tuple[str, ...]]) -> list[str]:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return ["  " + "  ".join(c.ljust(wd) for c, wd in zip(r, widths)).rstrip() for r in rows]
