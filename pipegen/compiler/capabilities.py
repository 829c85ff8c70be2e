"""What a technique renders, derived from its IR, not declared: ``capabilities(tech)`` gives
the light types it draws and evaluates (and what happens to the others), whether it draws
translucent objects, its light-index capacity and the light types each packing holds, the
faces its light-index passes draw, the translucent passes reading a back-face index, and its
shadow maps.  ``compiler/mismatches.py`` sets them against a scene's features.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.ir.facts import code_facts, pass_functions
from pipegen.scene.features import LIGHT_TYPES

INDEX_SCHEMES = ("bitplanes", "max_pairs")        # packings with a per-pixel light capacity
RENDERED = "rendered"


@dataclass(frozen=True)
class Capabilities:
    light_types: tuple[tuple[str, str], ...]   # type -> RENDERED or what happens instead
    has_light_table: bool
    translucent: bool                          # draws translucent objects
    index_packings: tuple[tuple[str, str, int, frozenset], ...]   # (pack, scheme, lights
    #                                             per pixel, the light types it holds)
    slot_packings: tuple[tuple[str, int, frozenset], ...]   # channel_slots: (pack, sets, types)
    # per index packing: (pack, the faces its writers draw ("back": cull front, depth gequal;
    # "front": front faces in front of the surface), the index bank (n, k) or None)
    index_rules: tuple[tuple[str, str, Optional[tuple[int, int]]], ...] = ()
    # shadow maps (``draw scene… from lights TYPES tiles N``): the light types drawn into an
    # atlas, and the fewest tiles of any such draw (N^2; 0: no atlas); shadow volumes
    # (``draw scene… shadow_volumes``) add the light types their repeat group runs for
    shadow_types: frozenset = frozenset()
    shadow_capacity: int = 0
    # passes drawing scene.translucent that read a light-index packing whose writers test
    # depth greater/gequal (light-volume back faces behind the opaque surface): (pass, pack,
    # the point/spot light types those writers draw)
    translucent_back_reads: tuple[tuple[str, str, frozenset], ...] = ()
    # ``from lights … first K``: the light indices that may cast (the smallest K of the shadow
    # draws; 0: every index), and where it is declared ("pass 'P' (file:line)")
    shadow_first: int = 0
    shadow_first_at: str = ""
    # multisampled scene passes that read a single-sampled light-index target at a texel the
    # code computes (a nearest-fragment search, Trebilco's MSAA technique 3): (pass, target)
    index_searches: tuple[tuple[str, str], ...] = ()

    def light_type(self, t: str) -> str:
        return dict(self.light_types)[t]


def _volume_fills(volume: Optional[ir.Volume], light_type: str) -> bool:
    """Whether a light volume covers every pixel a light of this type reaches: spheres hold
    points and spots (a spot's cone lies in its sphere), cones spots; quads cover a light's
    screen bounds, the whole screen for a directional light (radius 0)."""
    v = volume or ir.Volume.SPHERE
    if v is ir.Volume.QUAD:
        return True
    if v is ir.Volume.CONE:
        return light_type == "spot"
    return light_type in ("point", "spot")


def _types_match(types: tuple[str, ...], light_type: str) -> bool:
    return not types or light_type in types


def _light_fields_read(tech: ir.Technique, passes) -> set[str]:
    fields: set[str] = set()
    for p in passes:
        functions = pass_functions(tech, p.body)
        for stmts in [p.body] + [f.body for f in functions]:
            fields |= {e.field for e in irwalk.walk_exprs(stmts) if isinstance(e, ir.LightField)}
    return fields


def _loop_vars(stmts) -> set[str]:
    """The variables of the ``for`` loops in a statement list, nested ones included."""
    found: set[str] = set()
    for st in stmts:
        if isinstance(st, ir.For):
            found.add(st.var)
            found |= _loop_vars(st.body)
        elif isinstance(st, ir.If):
            found |= _loop_vars(st.then) | _loop_vars(st.other)
    return found


def _indexes_by(e: Optional[ir.Expr], names: set[str]) -> bool:
    """``e`` is one of ``names``, or a conversion of one (``lights[uint(i)]``)."""
    while isinstance(e, ir.Construct) and len(e.args) == 1:
        e = e.args[0]
    return isinstance(e, ir.Var) and e.name in names


def _table_loop_passes(tech: ir.Technique) -> list[ir.Pass]:
    """Passes that are not light draws and loop over the light table itself (``for (int i
    ...) ... lights[i]``, in the pass or a function it calls): every light reaches their
    pixels, whatever light volumes other passes draw (a G-buffer pass that forward-lits the
    directional lights, StarCraft II's).  A loop over indices a packing holds (the LIDRs'
    ``lights[unpack(...)]``) is not one."""
    out = []
    for p in tech.passes:
        if p.draw.kind is ir.DrawKind.LIGHTS:
            continue
        for stmts in [p.body] + [f.body for f in pass_functions(tech, p.body)]:
            loops = _loop_vars(stmts)
            if loops and any(isinstance(e, ir.LightField) and _indexes_by(e.index, loops)
                             for e in irwalk.walk_exprs(stmts)):
                out.append(p)
                break
    return out


def capabilities(tech: ir.Technique) -> Capabilities:
    has_table = bool(tech.lights.fields)
    volumes = [p for p in tech.passes if p.draw.kind is ir.DrawKind.LIGHTS]
    repeats = [p for p in tech.passes if p.repeat_per_light and p.draw.kind is not
               ir.DrawKind.LIGHTS]
    fields = _light_fields_read(tech, tech.passes)
    table_loops = _table_loop_passes(tech)
    out = []
    for t in LIGHT_TYPES:
        if volumes:       # light volumes decide which pixels a light reaches
            covered = any(_types_match(p.draw.light_types, t) and _types_match(p.repeat_types, t)
                          and _volume_fills(p.draw.volume, t) for p in volumes) or any(
                _types_match(p.repeat_types, t) for p in repeats) or bool(table_loops)
        else:             # light-table loops and per-light full passes reach every pixel
            covered = has_table
        if not has_table:
            how = "ignored (the technique has no light table)"
        elif not covered:
            how = ("not drawn (its light volumes do not cover a directional light)"
                   if t == "directional" else f"not drawn (no light draw takes {t} lights)")
        elif t == "spot" and not fields & {"cos_outer", "cos_inner"}:
            how = "lit as point lights (the technique reads no cone angle)"
        elif t == "directional" and not fields & {"direction", "type"}:
            how = "not lit (the technique reads no light direction; radius 0 attenuates them)"
        else:
            how = RENDERED
        out.append((t, how))
    translucent = any(p.draw.kind is ir.DrawKind.SCENE and
                      (not p.draw.material or "translucent" in p.draw.material)
                      for p in tech.passes)
    index = tuple((k.name, k.scheme, int(k.capacity), _packing_types(tech, k))
                  for k in tech.packings if k.scheme in INDEX_SCHEMES and k.capacity)
    slots = tuple((k.name, int(dict(k.options).get("slots", 4)), _packing_types(tech, k))
                  for k in tech.packings if k.scheme == "channel_slots")
    rules = tuple((k.name,) + _packing_rule(tech, k) for k in tech.packings
                  if k.scheme in INDEX_SCHEMES and k.capacity)
    shadow_draws = [p.draw for p in tech.passes if p.draw.shadow]
    shadow_types = frozenset(t for d in shadow_draws for t in d.light_types) | frozenset(
        t for p in tech.passes if p.draw.shadow_volumes for t in p.repeat_types or LIGHT_TYPES)
    shadow_capacity = min((d.shadow_tiles ** 2 for d in shadow_draws), default=0)
    first, first_at = _shadow_first(tech)
    return Capabilities(tuple(out), has_table, translucent, index, slots, rules,
                        shadow_types, shadow_capacity, _translucent_back_reads(tech, rules),
                        first, first_at, _index_searches(tech))


def _index_searches(tech: ir.Technique) -> tuple:
    """(pass, target) for each multisampled scene pass that loads a single-sampled
    light-index packing's target at a coordinate it computes (``load(T, ivec2)``, in its body
    or a function it reaches): it looks the lights up at another pixel than its own, the
    nearest-fragment search of Trebilco's MSAA technique 3, which fails where a polygon
    covers samples but no pixel centre within reach."""
    samples = {t.name: t.samples for t in tech.targets}
    index_targets = {dict(k.options).get("target") for k in tech.packings
                     if k.scheme in INDEX_SCHEMES and k.capacity}
    out = []
    for p in tech.passes:
        attached = list(p.writes) + ([p.depth_target] if p.depth_target else [])
        if p.draw.kind is not ir.DrawKind.SCENE or max(
                [samples[n] for n in attached] or [1]) == 1:
            continue
        for stmts in [p.body] + [f.body for f in pass_functions(tech, p.body)]:
            found = sorted({e.target for e in irwalk.walk_exprs(stmts)
                            if isinstance(e, ir.Load) and e.coord is not None and
                            e.sample is None and e.target in index_targets and
                            samples[e.target] == 1})
            out += [(p.name, t) for t in found if (p.name, t) not in out]
    return tuple(out)


def _shadow_first(tech: ir.Technique) -> tuple[int, str]:
    """(K, "pass 'P' (file:line)") for the shadow-map draw with the smallest ``first K``;
    (0, "") when none declares one (every light index may cast)."""
    limited = [p for p in tech.passes if p.draw.shadow and p.draw.shadow_first]
    if not limited:
        return 0, ""
    p = min(limited, key=lambda p: p.draw.shadow_first)
    where = f" ({p.span.file}:{p.span.line})" if p.span is not None else ""
    return p.draw.shadow_first, f"pass '{p.name}'{where}"


_BEHIND_TESTS = (ir.CompareFunc.GREATER, ir.CompareFunc.GEQUAL)


def _translucent_back_reads(tech: ir.Technique, rules) -> tuple:
    """(pass, pack, types) for each pass drawing ``scene.translucent`` that reads a light-index
    packing (its target in ``reads``, or its unpack functions called from the body or the
    functions it reaches) written with back faces: the writers that keep only fragments at or
    behind the opaque surface (``depth … greater|gequal``) and the point/spot types they draw.
    Such an index holds the lights reaching the opaque surface, not those reaching only a
    translucent surface in front of it."""
    faces = {r[0]: r[1] for r in rules}
    out = []
    for p in tech.passes:
        if not (p.draw.kind is ir.DrawKind.SCENE and
                (not p.draw.material or "translucent" in p.draw.material)):
            continue
        calls = _calls(tech, p)
        for k in tech.packings:
            if faces.get(k.name) != "back":
                continue
            if not (dict(k.options).get("target") in p.reads or
                    calls & {f.name for f in k.functions}):
                continue
            behind = [w for w in _writers(tech, k)
                      if w.depth_target and w.state.depth.func in _BEHIND_TESTS]
            types = frozenset(t for w in behind for t in (w.draw.light_types or LIGHT_TYPES)
                              if t != "directional" and _types_match(w.repeat_types, t))
            if types:
                out.append((p.name, k.name, types))
    return tuple(out)


_FRONT_TESTS = (ir.CompareFunc.LESS, ir.CompareFunc.LEQUAL)


def _calls(tech: ir.Technique, p: ir.Pass) -> set[str]:
    """The user and packing functions pass ``p`` calls, directly or through the functions it
    reaches."""
    return set(code_facts(p.body).calls) | {f.name for f in pass_functions(tech, p.body)}


def _writers(tech: ir.Technique, k: ir.Packing) -> list:
    names = {f.name for f in k.functions}
    return [p for p in tech.passes
            if p.draw.kind is ir.DrawKind.LIGHTS and _calls(tech, p) & names]


def _packing_rule(tech: ir.Technique, k: ir.Packing) -> tuple[str, Optional[tuple[int, int]]]:
    """How the light passes writing a light-index packing choose their lights: the faces
    (``"front"`` when every writer draws front faces with a depth-less test: ``cull back`` or
    ``cull auto``, ``depth … less|lequal``; else ``"back"``) and the index bank, when every
    writer begins with ``if (light.index % N != K) discard;`` for one (N, K)."""
    writers = _writers(tech, k)
    front = bool(writers) and all(
        p.state.cull in (ir.CullMode.BACK, ir.CullMode.AUTO) and p.depth_target and
        p.state.depth.func in _FRONT_TESTS for p in writers)
    banks = {_bank(p.body) for p in writers}
    bank = banks.pop() if len(banks) == 1 else None
    return ("front" if front else "back"), bank


def _bank(body) -> Optional[tuple[int, int]]:
    """(N, K) for a body that begins ``if (light.index % N != K) discard;`` (uint constants)."""
    if not body or not isinstance(body[0], ir.If):
        return None
    s = body[0]
    if s.other or len(s.then) != 1 or not isinstance(s.then[0], ir.Discard):
        return None
    c = s.cond
    if not (isinstance(c, ir.Binary) and c.op == "!=" and isinstance(c.right, ir.Const)):
        return None
    m = c.left
    if not (isinstance(m, ir.Binary) and m.op == "%" and isinstance(m.right, ir.Const) and
            isinstance(m.left, ir.LightField) and m.left.field == "index" and
            m.left.index is None):
        return None
    n, r = int(m.right.value), int(c.right.value)
    return (n, r) if 0 <= r < n else None


def _packing_types(tech: ir.Technique, k: ir.Packing) -> frozenset:
    """The light types whose indices a light-index packing holds: those instanced by the
    passes that write through it (call its functions, or draw ``in PACK[k]``)."""
    names = {f.name for f in k.functions}
    types: set[str] = set()
    for p in tech.passes:
        if not (_calls(tech, p) & names or (p.draw.light_set and p.draw.light_set[0] == k.name)):
            continue
        if p.draw.kind is not ir.DrawKind.LIGHTS and not p.repeat_per_light:
            continue        # a reader (the shading pass), not a writer
        chosen = set(p.draw.light_types or LIGHT_TYPES) & set(p.repeat_types or LIGHT_TYPES)
        types |= chosen
    return frozenset(types or LIGHT_TYPES)
