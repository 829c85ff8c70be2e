"""A repeat group's pass executions as one raster launch (``backends/opencl/group.py``).

``GroupLauncher(pipe)`` builds, when the pipeline is made, the fused program of each repeat
group ``group.fusable`` accepts; ``fuse(runs)`` takes a frame's prepared pass executions
(``PassRun``, in schedule order) and gives them back with each fusable group's run replaced
by one callable that queues the group's clears and a single ``pg_group`` launch.  Its steps
are the executions in order, ``(member, light, row of the light's tile starts in its pass's
group bins, 1 + stencil clear or 0)``, over the union of the tiles any step draws.

It falls back to the executions one by one (same images, more launches) where a frame does
not fit what the kernel reads: a step's bins not the group's (``group_bins.LightBins``: a
light alone of its type, ``cull auto``, set-up sharing off), two geometries for one member,
passes of different sizes, targets sharing storage (``alias``), a wrapped ``_run_pass``
(the float64 read perturbation), or a clearing member that does not run first (its clear is
done over the whole target before the launch, and per row inside it).

``$PIPEGEN_CL_FUSE_GROUPS=0`` (read when a pipeline is made) turns fusion off: the tests
compare the two, bit for bit."""

from __future__ import annotations

import os
from typing import Optional

import numpy as np

from pipegen.backends.opencl.group import SHARED, fusable, group_members, group_program
from pipegen.runtime.cl import context as cl_context
from pipegen.runtime.cl.group_bins import LightBins

__all__ = ["GroupLauncher", "enabled"]


def enabled() -> bool:
    return os.environ.get("PIPEGEN_CL_FUSE_GROUPS", "1") != "0"


def _shared(name: str) -> bool:
    return name in SHARED or name.startswith(("w_", "bc_", "r_"))


class GroupLauncher:
    def __init__(self, pipe):
        self.pipe = pipe
        self.groups: dict = {}           # repeat group -> (GroupProgram, pg_group kernel)
        if not enabled():
            return
        import pyopencl as cl
        plan = pipe.plan
        for g, members in group_members(plan).items():
            if fusable(plan, members, pipe.dynamic_state):
                gp = group_program(plan, members, pipe.tile)
                prog = cl_context.link_program(gp.sources)
                self.groups[g] = (gp, cl.Kernel(prog, "pg_group"))

    def fuse(self, runs: list) -> list:
        """``runs`` with each fusable group's consecutive executions as one callable."""
        if not self.groups:
            return runs
        out, i = [], 0
        while i < len(runs):
            g = runs[i].p.repeat_group
            if g not in self.groups:
                out.append(runs[i])
                i += 1
                continue
            j = i
            while j < len(runs) and runs[j].p.repeat_group == g:
                j += 1
            fused = self._fused(g, runs[i:j])
            if fused is None:
                out.extend(runs[i:j])
            else:
                out.append(fused)
            i = j
        return out

    def _fused(self, g: int, steps: list):
        """One callable for ``steps`` (a group's executions), or None where the frame does not
        fit the fused kernel (module docstring)."""
        pipe = self.pipe
        if pipe.store.alias or "_run_pass" in vars(pipe):
            return None
        gp, kernel = self.groups[g]
        member = {k: i for i, k in enumerate(gp.members)}
        sizes = {(s.width, s.height) for s in steps}
        if len(sizes) != 1 or any(s.batch is not None for s in steps):
            return None
        if any(c is not None for c in gp.clears) \
                and gp.clears[member[steps[0].k]] is None:
            return None
        drawn: dict[int, tuple] = {}     # member -> (first step drawing, its geometry, group)
        for s in steps:
            if s.drawn is None or not s.drawn[1].ntiles:
                continue
            geo, tb = s.drawn
            if not isinstance(tb, LightBins):
                return None
            i = member[s.k]
            got = drawn.setdefault(i, (s, geo, tb.group))
            if got[1] is not geo or got[2] is not tb.group:
                return None
        return lambda: self._launch(gp, kernel, steps, drawn, member)

    def _launch(self, gp, kernel, steps: list, drawn: dict, member: dict) -> None:
        import pyopencl as cl
        pipe = self.pipe
        dev, store = pipe.device, pipe.store
        for s in steps:
            store.begin_pass(s.k)        # nothing without alias (``_fused`` checks)
        for name, c in steps[0].p.clears:     # the first clear, over the whole target
            store.clear_for_pass(name, c)
        width, height = steps[0].width, steps[0].height
        # each member's raster arguments, by parameter name
        values: list[Optional[dict]] = [None] * len(gp.members)
        shared: dict = {}
        for i, (s, geo, group) in drawn.items():
            args = pipe._raster_args(s.k, s.p, s.light, width, height, s.drawn,
                                     s.frame_buf, s.frame64_buf)
            names = [n for _, n in gp.signatures[i]]
            v = dict(zip(names, args))
            v["tile_start"], v["tile_tris"] = group.start_buf, group.tris_buf
            values[i] = v
            shared.update({n: x for n, x in v.items() if _shared(n)})
        rows = []
        lights: dict = {}                # bins group -> the rows of it some step draws
        for s in steps:
            i = member[s.k]
            clear = gp.clears[i]
            z = -1
            if s.drawn is not None and s.drawn[1].ntiles:
                tb = s.drawn[1]
                z = tb.j * tb.group.start_row
                lights.setdefault(tb.group, []).append(tb.j)
                s.timing["triangles"] = tb.triangles
                s.timing["tile_entries"] = tb.entries
            rows.append((i, s.light or 0, z, 0 if clear is None else clear + 1))
            s.timing["fused"] = True
        if not lights:
            return
        # the tiles some step draws (every group's bins cover the same tiles: one size)
        tiles = np.flatnonzero(np.logical_or.reduce(
            [group.occupied[js].any(axis=0) for group, js in lights.items()]))
        args = [dev.buffer(tiles.astype(np.int32)), dev.buffer(np.array(rows, np.int32)),
                np.int32(len(steps))]
        for i, name in gp.params:
            if _shared(name) and name in shared:
                args.append(shared[name])
            elif values[i] is not None:
                args.append(values[i][name])
            else:                         # a member no step draws: never called
                args.append(self._placeholder(gp.signatures[i], name))
        cl_context.set_args(kernel, *args)
        T = pipe.tile
        ev = cl.enqueue_nd_range_kernel(pipe.queue, kernel, (len(tiles) * T,), (T,))
        pipe._events.append((steps[0].timing, ev))

    def _placeholder(self, signature, name: str):
        """An argument of the declared type for a parameter no step reads."""
        decl = dict((n, d) for d, n in signature)[name]
        if "*" in decl:
            return self.pipe.device.dummy
        if "int2" in decl:
            return self.pipe._int2(0, 0)
        return np.uint32(0) if "uint" in decl else np.int32(0)
