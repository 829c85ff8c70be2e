"""The memory sections of ``pipegen info`` and the compile report: target lifetimes and the
three figures (sum of all targets, peak live at once, bytes allocated by each runtime's
sharing; ``ir/lifetimes.py``), the G-buffer's bytes per pixel and the estimated bytes each
pass reads and writes (``ir/traffic.py``, whose docstring states the rule)."""

from __future__ import annotations

from pipegen.core.units import format_bytes
from pipegen.ir.lifetimes import START, Lifetime, MemoryPlan, Sharing, technique_memory
from pipegen.ir.traffic import frame_traffic, gbuffer, gbuffer_bytes_per_output_pixel

SHARING_WORDS = {Sharing.BYTES: ("CL", "true aliasing", "in {}'s buffer", "buffer"),
                 Sharing.DESCRIPTOR: ("GL", "slot reuse", "takes {}'s texture", "texture")}


def live_text(life: Lifetime, passes: int) -> str:
    """A lifetime as pass numbers (1-based, as the pass list prints them)."""
    first = "start" if life.first == START else str(life.first + 1)
    last = "end" if life.last >= passes else str(life.last + 1)
    return first if first == last else f"{first}-{last}"


def _percent(saved: int, total: int) -> str:
    return f"{100 * saved / total:.1f} %" if total else "0 %"


def memory_lines(tech, w: int, h: int) -> list[str]:
    plans = {s: technique_memory(tech, w, h, s) for s in (Sharing.BYTES, Sharing.DESCRIPTOR)}
    m: MemoryPlan = plans[Sharing.BYTES]
    at = ("the frame's end" if m.peak_pass >= len(tech.passes) else
          f"pass {m.peak_pass + 1} {tech.passes[m.peak_pass].name}" if m.peak_pass >= 0
          else "the frame's start")
    out = [f"memory at {w}x{h} (target lifetimes over the passes; docs/memory.md)",
           f"  sum of all targets  {format_bytes(m.total_bytes, 'MiB', exact=True)}",
           f"  peak live at once   {format_bytes(m.peak_bytes, 'MiB', exact=True)}, first reached "
           f"at {at}"]
    for sharing, plan in plans.items():
        backend, how, taken, kind = SHARING_WORDS[sharing]
        saved = m.total_bytes - plan.allocated_bytes
        pairs = [f"{s[1]} {taken.format(s[0])}" if len(s) == 2 else
                 f"{', '.join(s)} share one {kind}" for s in plan.shared()]
        out.append(f"  allocated, {backend}       "
                   f"{format_bytes(plan.allocated_bytes, 'MiB', exact=True)}  saves "
                   f"{_percent(saved, m.total_bytes)}  {how}: "
                   + ("; ".join(pairs) or "nothing to share"))
    return out


def traffic_lines(tech, w: int, h: int) -> list[str]:
    per_pass, total = frame_traffic(tech.passes, tech.targets, w, h)
    rows = [("pass", "reads", "writes", "")]
    for i, t in enumerate(per_pass, 1):
        rows.append((f"{i}. {t.name}", format_bytes(t.read_bytes, "MiB"),
                     format_bytes(t.write_bytes, "MiB"), "per light" if t.repeated else ""))
    clears = sum(t.total for t in per_pass)
    rows.append(("clears at frame start", "-", format_bytes(total - clears, "MiB"), ""))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    out = [f"bandwidth estimate at {w}x{h}, bytes per pass execution",
           "  (every pixel of each target a pass reads, writes, blends or depth-tests, once; "
           "docs/memory.md)"]
    out += ["  " + "  ".join(c.ljust(wd) for c, wd in zip(r, widths)).rstrip() for r in rows]
    repeated = any(t.repeated for t in per_pass)
    out.append(f"  total, each pass once: {format_bytes(total, 'MiB')}"
               + (" (a pass marked per light runs once per light: add its figure per "
                  "further light)" if repeated else ""))
    gb = gbuffer(tech.passes, tech.targets, tech.output)
    if gb:
        per_pixel = sum(t.format.bytes_per_pixel * t.samples for t in gb)
        terms = " + ".join(f"{t.name} {t.format.name} {t.format.bytes_per_pixel * t.samples}"
                           for t in gb)
        scaled = gbuffer_bytes_per_output_pixel(tech.passes, tech.targets, tech.output, w, h)
        out.append(f"  G-buffer: {terms} = {per_pixel} B/px"
                   + (f" ({scaled:.2f} B per output pixel)" if abs(scaled - per_pixel) > 1e-9
                      else ""))
    else:
        out.append("  G-buffer: none (no target a scene pass writes is read by a later pass)")
    return out
