"""Memory traffic a frame costs, estimated from the passes alone: the figure a user can compare
G-buffer layouts by where a software rasteriser's frame times cannot rank them (the noise
between runs is larger than the differences).

**The estimation rule.**  Each pass execution touches every pixel of every target it uses once
(covered fraction 1: what a full-screen draw does; a scene draw with overdraw touches more, a
light volume fewer, and neither is known without a scene), at ``memory.target_bytes`` per
target (samples included):

- a target it reads (``reads``): read once;
- a colour target it writes: written once, and read once more where blending is on (the
  destination); a write mask with every channel off writes nothing;
- its depth/stencil target: read where the depth or stencil test is on, written where it
  writes depth or a stencil op can change the stencil;
- a target the pass clears: written once.

A frame adds the clears at its start (every target written once) and runs each pass once,
except a repeat group's passes and a shadow-map pass, which run once per light (or per
shadow-casting light): ``frame_traffic`` takes how many times each pass runs.

The **G-buffer** is the set of targets a pass drawing the scene writes and a later pass reads
(its depth or colour attachments, not the output), leaving out a target any pass blends into
(an accumulation buffer holds lighting, not the surface): its bytes per pixel are the sum of their
formats' (at their own size; ``gbuffer_bytes_per_output_pixel`` scales by the target sizes).
"""

from __future__ import annotations

from typing import Mapping, Optional, Sequence

from pipegen.core.records import record
from pipegen.ir import nodes as ir
from pipegen.ir.memory import target_bytes


@record(frozen=True)
class PassTraffic:
    name: str
    read_bytes: int
    write_bytes: int
    repeated: bool       # runs once per light (a repeat group or a shadow-map pass)

    @property
    def total(self) -> int:
        return self.read_bytes + self.write_bytes


def _stencil_writes(s: ir.StencilState) -> bool:
    return any(f.write_mask and any(op is not ir.StencilOp.KEEP
                                    for op in (f.fail, f.zfail, f.zpass))
               for f in (s.front, s.back))


def pass_traffic(p, targets: Mapping, width: int, height: int) -> PassTraffic:
    """Bytes one execution of pass ``p`` reads and writes (the module docstring's rule);
    ``targets``: {name: target} (``ir.Target`` or ``TargetPlan``)."""
    size = {n: target_bytes(t, width, height) for n, t in targets.items()}
    read = sum(size[n] for n in p.reads)
    write = sum(size[n] for n, _ in p.clears)
    for n in p.writes:
        blend = p.state.blend_for(n)
        if any(blend.write_mask):
            write += size[n]
            if blend.enabled:
                read += size[n]
    if p.depth_target:
        s = p.state
        fmt = targets[p.depth_target].format
        stencil_on = fmt.has_stencil and s.stencil.enabled
        if s.depth.enabled or stencil_on:
            read += size[p.depth_target]
        if s.depth.write or (stencil_on and _stencil_writes(s.stencil)):
            write += size[p.depth_target]
    repeated = p.repeat_group is not None or p.draw.shadow
    return PassTraffic(p.name, read, write, repeated)


def frame_traffic(passes: Sequence, targets: Sequence, width: int, height: int,
                  runs: Optional[Sequence[int]] = None) -> tuple[list[PassTraffic], int]:
    """(per pass traffic of one execution, the frame's total bytes): the clears at the start
    of the frame plus each pass times ``runs[k]`` (default: once each)."""
    by_name = {t.name: t for t in targets}
    per_pass = [pass_traffic(p, by_name, width, height) for p in passes]
    runs = runs if runs is not None else [1] * len(passes)
    clears = sum(target_bytes(t, width, height) for t in targets)
    return per_pass, clears + sum(t.total * n for t, n in zip(per_pass, runs))


def gbuffer(passes: Sequence, targets: Sequence, output: str) -> list:
    """The G-buffer's targets in declaration order (the module docstring)."""
    written_by_scene: dict[str, int] = {}
    for k, p in enumerate(passes):
        if p.draw.kind is ir.DrawKind.SCENE and not p.draw.shadow:
            for n in list(p.writes) + ([p.depth_target] if p.depth_target else []):
                written_by_scene.setdefault(n, k)
    blended = {n for p in passes for n in p.writes if p.state.blend_for(n).enabled}
    read_later = {n for n, k in written_by_scene.items()
                  if n not in blended and any(n in q.reads for q in passes[k + 1:])}
    return [t for t in targets if t.name in read_later and t.name != output]


def gbuffer_bytes_per_output_pixel(passes: Sequence, targets: Sequence, output: str,
                                   width: int, height: int) -> float:
    """The G-buffer's bytes over the output's pixels (a target at half scale counts a
    quarter)."""
    return sum(target_bytes(t, width, height)
               for t in gbuffer(passes, targets, output)) / (width * height)
