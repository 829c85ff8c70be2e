"""A repeat group's pass executions as one raster launch (``backends/opencl/group.py``).

``GroupLauncher(pipe)`` builds, when the pipeline is made, the fused program of each repeat
group ``group.fusable`` accepts.  ``prepared(runs, prepare_pass)`` yields a frame's host work
one execution at a time (``CLPipeline._draw`` queues each one's device work before it asks
for the next; ``prepare`` makes them all first): each run of a fusable group's executions
becomes one callable that queues the group's first clear and a single ``pg_group`` launch;
every other execution is ``prepare_pass(k, light)`` as before.

A fused group needs no bins per light: each member pass draws the triangles of all its lights
(one set-up, as for every light of a group, ``DrawGeometry``) binned once (on the device, as
any pass), and since they are submitted light by light in the order the steps visit the
lights, a step's triangles in a bin are the next run of the bin's list whose light
(``tri_flat.w``) is the step's.  The kernel keeps one cursor per member and tile row.  Its
steps are the executions in order, ``(member, light, 0, 1 + stencil clear or 0)``, over the
tiles any light's triangles' boxes touch.

It falls back to the executions one by one (same images, more launches, each light's bins
cut from one sort: ``DrawGeometry._group_bins``) where a frame does not fit: a member whose
steps do not visit its light list in order, passes of different sizes, targets sharing
storage (``alias``), a wrapped ``_run_pass`` (the float64 read perturbation), a clearing
member that does not run first (its clear is done over the whole target before the launch,
and per row inside it).

``$PIPEGEN_CL_FUSE_GROUPS=0`` (read when a pipeline is made) turns fusion off: the tests
compare the two, bit for bit."""

from __future__ import annotations

import os
from typing import Callable, Iterator, Optional

import numpy as np

from pipegen.backends.opencl.group import fusable, group_members, group_program, shared_param
from pipegen.runtime import draws
from pipegen.runtime.cl import context as cl_context

__all__ = ["GroupLauncher", "enabled"]


def enabled() -> bool:
    return os.environ.get("PIPEGEN_CL_FUSE_GROUPS", "1") != "0"


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

    def prepare(self, runs: list, prepare_pass: Callable) -> list:
        """``prepared``'s callables, all made first."""
        return list(self.prepared(runs, prepare_pass))

    def prepared(self, runs: list, prepare_pass: Callable) -> Iterator:
        """The host work of a frame's executions ``runs`` (``(k, light)``, in schedule order),
        each made when it is asked for: each fusable group's run as one callable (or its
        executions one by one where the frame does not fit), the rest
        ``prepare_pass(k, light)``."""
        i = 0
        passes = self.pipe.plan.passes
        while i < len(runs):
            g = passes[runs[i][0]].repeat_group
            if g not in self.groups:
                yield prepare_pass(*runs[i])
                i += 1
                continue
            j = i
            while j < len(runs) and passes[runs[j][0]].repeat_group == g:
                j += 1
            fused = self._prepare(g, runs[i:j])
            if fused is not None:
                yield fused
            else:
                for k, light in runs[i:j]:
                    yield prepare_pass(k, light)
            i = j

    def _prepare(self, g: int, steps: list):
        """The fused launch of a group's executions ``steps``, its geometry and bins made, or
        None where the frame does not fit (module docstring)."""
        pipe = self.pipe
        if pipe.store.alias or "_run_pass" in vars(pipe) or pipe.profile is not None:
            return None
        gp, kernel = self.groups[g]
        passes = pipe.plan.passes
        member = {k: i for i, k in enumerate(gp.members)}
        if any(not isinstance(light, (int, np.integer)) for _, light in steps):
            return None
        ks = list(dict.fromkeys(k for k, _ in steps))     # the members drawn, in step order
        sizes = {pipe._pass_size(passes[k]) for k in ks}
        if len(sizes) != 1:
            return None
        if any(c is not None for c in gp.clears) and gp.clears[member[steps[0][0]]] is None:
            return None
        width, height = sizes.pop()
        geometry, selection = pipe.geometry, pipe._selection
        drawn: dict[int, tuple] = {}        # member -> (geometry, bins, its pass, its lights)
        timings = []
        for k, light in steps:
            timings.append({"pass": passes[k].name, "light": light, "fused": True})
        for k in ks:
            p = passes[k]
            # the lights its executions draw (``LightSelection.instance``: all of them, or
            # those of the draw's filter), once per member rather than per execution
            keep = selection.members(p.draw) if draws.light_filter(p.draw) else None
            lights = [int(l) for kk, l in steps if kk == k and (keep is None or l in keep)]
            if not lights:
                continue
            if list(geometry._light_batch(k, p, lights)) != lights:
                return None        # the member's triangles are not its steps' lights in order
            timing = next(t for t, (kk, _) in zip(timings, steps) if kk == k)
            got = geometry.pass_triangles(k, p, width, height, timing, lights)
            if got is not None and not all(l in got[0].ranges for l in lights):
                return None        # no light ranges to find the tiles by (``cull auto``)
            if got is not None:
                drawn[member[k]] = (got[0], got[1], p, lights)
                timing["triangles"] = got[1].triangles
        pipe._timings.extend(timings)
        return lambda: self._launch(gp, kernel, steps, drawn, member, timings[0], width, height)

    def _tiles(self, drawn: dict, width: int, height: int) -> np.ndarray:
        """The tiles any drawn light's triangles' boxes touch (a superset of those with
        triangles: a tile without any draws nothing)."""
        T = self.pipe.tile
        tiles_x, tiles_y = -(-width // T), -(-height // T)
        hit = np.zeros((tiles_y, tiles_x), bool)
        seen = set()
        for geo, _, _, lights in drawn.values():
            if (id(geo), tuple(lights)) in seen:   # deferred's shading: its marking's lights
                continue
            seen.add((id(geo), tuple(lights)))
            spans = np.array([geo.ranges[l] for l in lights if l in geo.ranges], np.int64)
            spans = spans[spans[:, 1] > spans[:, 0]] if len(spans) else spans
            if not len(spans):
                continue
            bb = geo.tris.bbox
            # each light's box; reduceat runs on to the next light's start (to the end for the
            # last), which can only add triangles between the lights: a superset still
            lo = np.minimum.reduceat(bb[:, :2], spans[:, 0])
            hi = np.maximum.reduceat(bb[:, 2:], spans[:, 0])
            x0, y0 = np.clip(lo // T, 0, None).T
            x1, y1 = np.minimum(hi // T, (tiles_x - 1, tiles_y - 1)).T
            ok = (x0 <= x1) & (y0 <= y1)
            x0, y0, x1, y1 = x0[ok], y0[ok], x1[ok] + 1, y1[ok] + 1
            # each light's rectangle of tiles, as +1/-1 at its corners summed over both axes
            # (one count for all the lights, not a slice assignment each)
            w = tiles_x + 1
            at = np.concatenate([y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1])
            sign = np.repeat(np.array([1.0, -1.0, -1.0, 1.0]), len(x0))
            corners = np.bincount(at, sign, (tiles_y + 1) * w).reshape(tiles_y + 1, w)
            hit |= corners.cumsum(0).cumsum(1)[:tiles_y, :tiles_x] > 0.5
        return np.flatnonzero(hit.ravel()).astype(np.int32)

    def _launch(self, gp, kernel, steps: list, drawn: dict, member: dict, timing: dict,
                width: int, height: int) -> None:
        import pyopencl as cl
        pipe = self.pipe
        dev, store = pipe.device, pipe.store
        # nothing without alias (``_prepare`` checks); each member once, in pass order: a
        # pass's clears are those of targets whose lifetime starts by it, the same set
        for k in sorted({k for k, _ in steps}):
            store.begin_pass(k)
        for name, c in pipe.plan.passes[steps[0][0]].clears:   # the first clear, everywhere
            store.clear_for_pass(name, c)
        if not drawn:
            return
        tiles = self._tiles(drawn, width, height)
        if not len(tiles):
            return
        # each member's raster arguments, by parameter name
        values: list[Optional[dict]] = [None] * len(gp.members)
        shared: dict = {}
        for i, (geo, tb, p, lights) in drawn.items():
            args = pipe._raster_args(gp.members[i], p, lights[0], width, height, (geo, tb),
                                     pipe._frame_buf, pipe._frame64_buf)
            values[i] = v = dict(zip([n for _, n in gp.signatures[i]], args))
            shared.update({n: x for n, x in v.items() if shared_param(n)})
        # (member, light, 0, 1 + stencil clear value or 0) per step, from lookups by pass
        ks, lights = np.array(steps, np.int64).reshape(-1, 2).T
        by_pass = np.zeros((max(member) + 1, 2), np.int32)
        for k, i in member.items():
            by_pass[k] = (i, 0 if gp.clears[i] is None else gp.clears[i] + 1)
        rows = np.zeros((len(steps), 4), np.int32)
        rows[:, 0], rows[:, 1], rows[:, 3] = by_pass[ks, 0], lights, by_pass[ks, 1]
        args = [dev.buffer(tiles), dev.buffer(rows), np.int32(len(steps))]
        empty = None
        for i, name in gp.params:
            if shared_param(name) and name in shared:
                args.append(shared[name])
            elif values[i] is not None:
                args.append(values[i][name])
            elif name == "tile_start":       # a member no light draws: every tile empty
                if empty is None:
                    T = pipe.tile
                    empty = dev.buffer(np.zeros(-(-width // T) * -(-height // T) + 1, np.int32))
                args.append(empty)
            elif name == "band":             # ... its lists a tile's (the empty ones above)
                args.append(np.int32(pipe.tile))
            else:
                args.append(self._placeholder(gp.signatures[i], name))
        cl_context.set_args(kernel, *args)
        T = pipe.tile
        ev = cl.enqueue_nd_range_kernel(pipe.queue, kernel, (len(tiles) * T,), (T,))
        pipe._events.append((timing, ev))

    def _placeholder(self, signature, name: str):
        """An argument of the declared type for a parameter no step reads."""
        decl = dict((n, d) for d, n in signature)[name]
        if "*" in decl:
            return self.pipe.device.dummy
        if "int2" in decl:
            return self.pipe._int2(0, 0)
        return np.uint32(0) if "uint" in decl else np.int32(0)
