"""The backend-neutral part of a compiled plan (docs/internals.md, "Compiled plan"), and the IR
queries every code generator needs per pass (which functions, stage inputs and target reads a
pass's shader uses).  Backends add their code (``vertex``/``fragment`` or kernels) to each pass.

All enum values are the IR enums' ``.value`` strings; containers are lists, so that the plan is
plain data a generated module can hold as a literal.
"""

from __future__ import annotations

from typing import Iterator

from .. import ir, irwalk


def technique_plan(tech: ir.Technique, backend: str) -> dict:
    return {
        "technique": tech.name,
        "title": tech.title,
        "backend": backend,
        "source": tech.source,
        "params": {p.name: p.default for p in tech.params},
        "lights": {"capacity": tech.lights.capacity,
                   "fields": [[f.name, str(f.type)] for f in tech.lights.fields]},
        "output": tech.output,
        "targets": [target_plan(t) for t in tech.targets],
        "passes": [pass_plan(p) for p in tech.passes],
        "light_sets": {p.name: int(dict(p.options).get("slots", 4))
                       for p in tech.packings if p.scheme == "channel_slots"},
    }


def _clear(c: ir.Clear) -> dict:
    return {"clear_color": None if c.color is None else list(c.color),
            "clear_depth": c.depth, "clear_stencil": c.stencil}


def target_plan(t: ir.Target) -> dict:
    clear = _clear(t.clear)
    if t.format.is_color and clear["clear_color"] is None:
        clear["clear_color"] = [0, 0, 0, 0]      # "a target without clear is cleared to zero"
    return {"name": t.name, "format": t.format.name, "scale": t.size.scale,
            "width": t.size.width, "height": t.size.height, "samples": t.samples, **clear}


def pass_plan(p: ir.Pass) -> dict:
    d = p.draw
    return {
        "name": p.name,
        "draw": {"kind": d.kind.value, "material": list(d.material),
                 "volume": None if d.volume is None else d.volume.value,
                 "light_types": list(d.light_types),
                 "light_set": None if d.light_set is None else list(d.light_set),
                 "scissor": d.scissor},
        "repeat_group": p.repeat_group,
        "repeat_types": list(p.repeat_types),
        "clears": [{"target": name, **_clear(c)} for name, c in p.clears],
        "writes": list(p.writes),
        "reads": list(p.reads),
        "depth_target": p.depth_target,
        "state": state_plan(p.state, p.writes),
    }


def _face(f: ir.StencilFace) -> dict:
    return {"func": f.func.value, "ref": f.ref, "read_mask": f.read_mask,
            "write_mask": f.write_mask, "fail": f.fail.value, "zfail": f.zfail.value,
            "zpass": f.zpass.value}


def _eq(e: ir.BlendEquation) -> list:
    return [e.op.value, e.src.value, e.dst.value]


def state_plan(s: ir.PassState, writes: tuple[str, ...]) -> dict:
    blend = {}
    for t in writes:
        b = s.blend_for(t)
        blend[t] = {"enabled": b.enabled, "rgb": _eq(b.rgb), "alpha": _eq(b.alpha),
                    "write_mask": list(b.write_mask)}
    depth = {"func": s.depth.func.value, "write": s.depth.write, "clamp": s.depth.clamp}
    if s.depth.inside is not None:      # `cull auto` passes: the back-face lights' test
        depth["inside"] = s.depth.inside.value
    return {
        "depth": depth,
        "stencil": {"front": _face(s.stencil.front), "back": _face(s.stencil.back)},
        "blend": blend,
        "blend_constant": list(s.blend_constant),
        "cull": s.cull.value,
        "polygon_offset": None if s.polygon_offset is None else
        [s.polygon_offset.factor, s.polygon_offset.units],
    }


# ---- per-pass code queries -------------------------------------------------------------------


def pass_functions(tech: ir.Technique, body: tuple[ir.Stmt, ...]) -> list[ir.Function]:
    """The functions ``body`` reaches, callees before callers (so no prototypes are needed)."""
    by_name = {f.name: f for f in tech.all_functions()}
    order: list[ir.Function] = []
    seen: set[str] = set()

    def visit(stmts) -> None:
        for e in irwalk.walk_exprs(stmts):
            if isinstance(e, ir.Call) and not e.builtin and e.name not in seen \
                    and e.name in by_name:
                seen.add(e.name)
                visit(by_name[e.name].body)
                order.append(by_name[e.name])

    visit(body)
    return order


def code_exprs(body, functions) -> Iterator[ir.Expr]:
    """Every expression of a pass's body and of the functions it uses."""
    yield from irwalk.walk_exprs(body)
    for f in functions:
        yield from irwalk.walk_exprs(f.body)


def stage_inputs(body, functions) -> set[str]:
    """Names of the stage inputs (``Var(kind="input")``) the code reads; ``light.index`` and
    ``light.FIELD`` of the drawn light count as the input ``light``."""
    out = set()
    for e in code_exprs(body, functions):
        if isinstance(e, ir.Var) and e.kind == "input":
            out.add(e.name)
        elif isinstance(e, ir.LightField) and e.index is None:
            out.add("light")
    return out


def sampled_targets(body, functions) -> set[str]:
    return {e.target for e in code_exprs(body, functions) if isinstance(e, ir.Sample)}
