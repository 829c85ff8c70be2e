"""A ``repeat per light`` group's passes as one raster launch (issue 26 item 3).

Deferred shading on many_lights runs two passes per light (a stencil-marking pass, then the
shading pass that tests its marks) for 81 lights: 162 raster launches a frame, each with
~100 us of host work, most of a 160x90 frame.  Everything a raster kernel does is per pixel
(a tile row's registers, loaded from and stored to the targets), so one kernel whose
work-item draws one tile row for every light and pass of the group in turn (the pass's
clears, then its triangles) leaves every pixel as the launches one after another leave it.

The group program links:

* each member pass's unit, ``pass_program(..., row_fn="pg_row_K")``: the pass's own program
  with its raster kernel's body as a function drawing one run of a tile row's triangle list
  (the same text, so the same arithmetic), no kernels, program-scope names static
  (``clLinkProgram`` joins units whose names would clash: each pass has its own ``pg_in``,
  ``pg_fragment``, ``PG_SX``);
* the fused kernel ``pg_group`` (``cl_group.cl.j2``): one work-group per tile some light's
  volume touches, a loop over the frame's steps ``(member, light, 0, stencil clear)``, each
  calling its member's row function on that light's run of the row's list.  A member's bins
  are those of all its lights' triangles, submitted light by light in the order the steps
  visit them, so a light's run is the next one whose ``tri_flat.w`` is that light: one
  cursor per member (``runtime/cl/group_launch.py`` checks the order, frame by frame).

Its parameters are the members' parameters, cut from their row functions' signatures (the
one source of their order): ``SHARED`` ones and a target's buffers (``w_``/``bc_``/``r_``
+ its name, ``w_depth``/``w_stencil``: every member attaches the same depth target) once,
the rest once per member as ``m<i>_<name>``.  ``GroupProgram.params`` says where each comes
from, for the runtime (``runtime/cl/group_launch.py``) to bind.

``fusable`` says which groups qualify: float32, baked state, every pass drawing light volumes
(not shadow maps or shadow volumes) at one sample (so none of them draws its run of lights in
one launch on its own: ``batches_lights`` takes scene draws; a group of one such pass fuses
too, as the shadow-volume LIDR's light volumes do where the scene has no shadow volumes: 81
launches a frame become one, its frame 14.4 -> 10.9 ms at 160x90), no
target one member writes read by another (a read may fetch other pixels), no clear but a
stencil clear of the depth target (done per row in the kernel, and once over the whole target
first, for the tiles no step draws)."""

from __future__ import annotations

import re
from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.backends import templating
from pipegen.backends.opencl.programs import pass_program, prelude_source
from pipegen.backends.plan import PassPlan, Plan
from pipegen.core.records import record

__all__ = ["GroupProgram", "fusable", "group_program", "group_members", "shared_param",
           "SHARED"]

# parameters with one value for every member of a group (the same size, frame and light table)
SHARED = ("width", "height", "tiles_x", "frame", "lights", "pg_st")
# the row function's own parameters: the tile and the run of its list to draw
ROW = ("tile", "pg_beg", "pg_end")


@record(frozen=True)
class GroupProgram:
    """``members``: the group's pass indices, in plan order; ``sources``: the member units,
    then the fused kernel's; ``params``: per fused kernel parameter after the fixed ones
    (``tile_list``, ``steps``, ``nsteps``), ``(member, name)``: member ``member``'s parameter
    ``name`` (for a shared one, the first member that has it); ``clears``: per member, the
    stencil value its clear writes, or None; ``signatures``: per member, ``(declaration,
    name)`` of each parameter its raster kernel has (the row function's, but ``tile``), in
    order: what ``CLPipeline._raster_args`` gives."""
    members: tuple[int, ...]
    sources: tuple[str, ...]
    params: tuple[tuple[int, str], ...]
    clears: tuple[Optional[int], ...]
    signatures: tuple[tuple[tuple[str, str], ...], ...]


def group_members(plan: Plan) -> dict[int, tuple[int, ...]]:
    """Each repeat group's pass indices, in plan order."""
    out: dict[int, list[int]] = {}
    for k, p in enumerate(plan.passes):
        if p.repeat_group is not None:
            out.setdefault(p.repeat_group, []).append(k)
    return {g: tuple(ks) for g, ks in out.items()}


def _stencil_clear(p: PassPlan) -> tuple[bool, Optional[int]]:
    """(whether the pass's clears can run per row in the fused kernel, its stencil value)."""
    value = None
    for name, c in p.clears:
        if name != p.depth_target or c.color is not None or c.depth is not None \
                or c.stencil is None:
            return False, None
        value = int(c.stencil) & 0xFF
    return True, value


def fusable(plan: Plan, members: tuple[int, ...], dynamic: bool = False) -> bool:
    """Whether the group of passes ``members`` runs as one fused launch (module docstring)."""
    if dynamic or plan.precision != "f32" or not members:
        return False
    passes = [plan.passes[k] for k in members]
    written = set()
    depth = {p.depth_target for p in passes if p.depth_target}
    if len(depth) > 1:
        return False
    for p in passes:
        d = p.draw
        if d.kind is not ir.DrawKind.LIGHTS or d.shadow or d.shadow_volumes \
                or p.code is None or p.sample_reads or plan.pass_samples(p) != 1 \
                or not _stencil_clear(p)[0]:
            return False
        written.update(p.attached)
    return not any(set(p.reads) & written for p in passes)


_SIGNATURE = re.compile(r"\nvoid (pg_row_\d+)\((.*?)\)\s*\{", re.S)


def _params(unit: str) -> list[tuple[str, str]]:
    """(declaration, name) of each parameter of a unit's row function, in order, cut from
    its signature (template lines ``{% if %}`` leave none behind)."""
    m = _SIGNATURE.search(unit)
    decls = [d.strip() for d in m.group(2).split(",")]
    return [(d, re.findall(r"\w+", d)[-1]) for d in decls if d]


def shared_param(name: str) -> bool:
    """Whether a raster parameter has one value for every member of a group: ``SHARED``, and a
    target's buffers (named by the target; the depth target is the same for all members)."""
    return name in SHARED or name.startswith(("w_", "bc_", "r_"))


def group_program(plan: Plan, members: tuple[int, ...], tile: int) -> GroupProgram:
    """The program of a fusable group (``fusable``)."""
    units, calls, kernel_params, params, signatures = [], [], [], [], []
    seen: dict[str, str] = {}
    for i, k in enumerate(members):
        fn = f"pg_row_{k}"
        unit = pass_program(plan, plan.passes[k], tile=tile, row_fn=fn)
        units.append(unit)
        args = []
        signatures.append(tuple((d, n) for d, n in _params(unit) if n not in ROW))
        for decl, name in _params(unit):
            if name in ROW or name == "tile_list":
                args.append({"pg_beg": "b", "pg_end": f"cur{i}"}.get(name, name))
            elif name == "repeat_light":
                args.append("(uint)st.y")
            elif shared_param(name):
                args.append(name)
                if name not in seen:
                    seen[name] = decl
                    kernel_params.append(decl)
                    params.append((i, name))
                elif seen[name] != decl:
                    raise AssertionError(f"members declare {name} differently")
            else:
                args.append(f"m{i}_{name}")
                kernel_params.append(re.sub(rf"\b{name}$", f"m{i}_{name}", decl))
                params.append((i, name))
        protos = _SIGNATURE.search(unit).group(0)[1:].rstrip("{ \n") + ";"
        calls.append({"member": i, "fn": fn, "args": args, "proto": protos,
                      "name": plan.passes[k].name})
    clears = tuple(_stencil_clear(plan.passes[k])[1] for k in members)
    has_stencil = "w_stencil" in seen
    fused = templating.render(
        "cl_group.cl.j2", technique=plan.technique, prelude=prelude_source(tile, "f32", False),
        calls=calls, params=kernel_params, stencil=has_stencil)
    return GroupProgram(tuple(members), tuple(units) + (fused,), tuple(params), clears,
                        tuple(signatures))
