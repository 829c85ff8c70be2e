"""The human-readable compile report: passes in order, targets and their memory (lifetimes,
the three figures, the bandwidth estimate: ``views/memory.py``), state per pass, packing
capacities and errors."""

from __future__ import annotations

from pipegen.core.units import format_bytes
from pipegen.ir import nodes as ir
from pipegen.ir.lifetimes import lifetimes
from pipegen.ir.memory import target_bytes, technique_bytes
from pipegen.views.memory import live_text, memory_lines, traffic_lines


def render_report(compiled, output_size: tuple[int, int] = (1280, 720)) -> str:
    tech: ir.Technique = compiled.technique
    w, h = output_size
    lines = [f"technique {tech.name}: {tech.title}",
             f"source    {tech.source}",
             f"phases    {' → '.join(compiled.phases_run)}"]
    if tech.params:
        lines.append("params    " + ", ".join(f"{p.name} = {_value(p.default)}"
                                               for p in tech.params))
    lines.append(f"lights    table of {tech.lights.capacity}: "
                 + ", ".join(f"{f.name} {f.type}" for f in tech.lights.fields))
    lines += ["", *target_table(tech, w, h), "", *memory_lines(tech, w, h), "",
              *traffic_lines(tech, w, h), "", *pass_section(tech)]
    if tech.packings:
        lines += ["", "packing schemes"]
        for p in tech.packings:
            opts = ", ".join(f"{k}: {_value(v)}" for k, v in p.options)
            lines.append(f"  {p.name} = {p.scheme}({opts})")
            if p.capacity is not None:
                lines.append(f"    capacity      {p.capacity} lights per pixel")
            if p.error is not None:
                lines.append(f"    error bound   {error_bound_text(p)}")
            lines += [f"    {n}" for n in p.notes]
    spec = getattr(compiled, "specialisation", None)
    if spec is not None:
        before, after = spec.memory(w, h)
        lines += ["", "scene specialisation", *[f"  {x}" for x in spec.features.describe()],
                  *[f"  {x}" for x in spec.summary()],
                  f"  target memory saved at {w}x{h}: {format_bytes(before - after, 'MiB')}"]
    return "\n".join(lines) + "\n"


def error_bound_text(p: ir.Packing) -> str:
    """The packing's static error as measured (pipegen/packing/error_tables.py, docs/encodings.md)."""
    if p.scheme in ("kircher", "spheremap", "octahedral"):
        return f"{p.error:.4g} degrees (max angular error, measured)"
    if p.scheme == "split16":
        return f"{p.error:.4g} (max |unpack(pack(x)) - x|, measured)"
    return "0 (exact)" if p.error == 0 else f"{p.error:.4g}"


def target_table(tech: ir.Technique, w: int, h: int) -> list[str]:
    rows = [("target", "format", "size", "samples", "B/px", "memory", "live", "written by",
             "read by")]
    life = lifetimes(tech.passes, tech.targets, tech.output)
    for t in tech.targets:
        tw, th = t.size.resolve(w, h)
        writers = [p.name for p in tech.passes
                   if t.name in p.writes or p.depth_target == t.name]
        readers = [p.name for p in tech.passes if t.name in p.reads]
        size = f"{tw}x{th}" + ("" if not t.size.relative or t.size.scale == 1.0
                               else f" (output*{t.size.scale:g})")
        rows.append((t.name + (" *" if t.name == tech.output else ""), t.format.name, size,
                     str(t.samples), str(t.format.bytes_per_pixel),
                     format_bytes(target_bytes(t, w, h), "MiB"),
                     live_text(life[t.name], len(tech.passes)),
                     ",".join(writers) or "-", ",".join(readers) or "-"))
    out = [f"targets at {w}x{h} (* = output; live: passes from first use to last)"] + _table(rows)
    out.append(f"  total target memory: {format_bytes(technique_bytes(tech, w, h), 'MiB')}")
    return out


def pass_section(tech: ir.Technique) -> list[str]:
    out = ["passes (in order)"]
    for i, p in enumerate(tech.passes, 1):
        repeat = ("  [repeat per light" + "".join(" " + t for t in p.repeat_types) + "]"
                  if p.repeat_per_light else "")
        out.append(f"  {i}. {p.name}: draw {p.draw.describe()}{repeat}")
        if p.writes:
            out.append(f"       writes {', '.join(p.writes)}")
        if p.reads:
            out.append(f"       reads  {', '.join(p.reads)}")
        out += [f"       {s}" for s in state_lines(p)]
    return out


def state_lines(p: ir.Pass) -> list[str]:
    s = p.state
    out = []
    for name, clear in p.clears:
        out.append(f"clear  {name} {_clear(clear)}")
    if p.depth_target:
        d = s.depth
        test = "off" if not d.enabled else \
            f"{d.func.value} {'write' if d.write else 'nowrite'}{' clamp' if d.clamp else ''}"
        if d.inside is not None:
            test += f" inside {d.inside.value}"
        out.append(f"depth  {p.depth_target} {test}")
    if s.stencil.enabled:
        for face_name, face in (("front", s.stencil.front), ("back", s.stencil.back)):
            out.append(f"stencil {face_name}: {face.func.value} ref {face.ref} "
                       f"read 0x{face.read_mask:02x} write 0x{face.write_mask:02x} "
                       f"fail {face.fail.value} zfail {face.zfail.value} "
                       f"pass {face.zpass.value}")
    for name, b in s.blend:
        parts = []
        if b.enabled:
            parts.append(f"rgb {_eq(b.rgb)} alpha {_eq(b.alpha)}")
        if b.write_mask != (True, True, True, True):
            parts.append("mask " + ("".join(c for c, on in zip("rgba", b.write_mask) if on)
                                    or "none"))
        if parts:
            out.append(f"blend  {name}: " + ", ".join(parts))
    if any(b.enabled for _, b in s.blend) and any(s.blend_constant):
        out.append("blend  constant (" + ", ".join(f"{c:g}" for c in s.blend_constant) + ")")
    out.append(f"cull   {s.cull.value}")
    if s.polygon_offset:
        out.append(f"offset {s.polygon_offset.factor:g} {s.polygon_offset.units:g}")
    return out


def _eq(e: ir.BlendEquation) -> str:
    if e.op in (ir.BlendOp.MIN, ir.BlendOp.MAX):
        return e.op.value
    return f"{e.op.value}({e.src.value}, {e.dst.value})"


def _clear(c: ir.Clear) -> str:
    parts = []
    if c.color is not None:
        parts.append("(" + ", ".join(f"{v:g}" for v in c.color) + ")")
    if c.depth is not None:
        parts.append(f"depth {c.depth:g}")
    if c.stencil is not None:
        parts.append(f"stencil {c.stencil}")
    return " ".join(parts)


def _value(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _table(rows: list[tuple[str, ...]]) -> list[str]:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return ["  " + "  ".join(c.ljust(wd) for c, wd in zip(r, widths)).rstrip() for r in rows]
