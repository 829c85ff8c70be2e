"""Turn target codes into pictures people can look at.

What a target holds decides how it is shown, and the technique says what it holds
(:func:`target_views` reads the fragment bodies and the packing declarations):

- colour targets as they are; other float/unorm data auto-ranged (signed data from [-1, 1]);
- depth, whatever the format (``d24s8``, ``d32f``, or an ``r32f`` written with
  ``frag_coord.z``; also a channel written with ``-view_pos.z``): **near bright**, stretched
  from the nearest to the farthest pixel that is not at the clear value (linearly in window
  depth, i.e. in 1 / distance); cleared pixels are black;
- stencil and integer targets: one colour per value (:func:`category_color`, 0 black) and a
  legend of the values present;
- packed targets decoded through their declared packing: a ``bitfield`` channel as one panel
  per field, a normal encoding (``kircher``, ``spheremap``, ``octahedral``) decoded to a
  normal, ``split16`` to its value, light-index packings as the light set of each pixel and
  the number of lights per pixel.

A picture is a list of :class:`Panel`; :func:`compose` lays them out with their titles and
legends, :func:`write_pictures` writes ``TARGET.png`` for every target of a render and
``contact_sheet.png`` with all of them.  Arrays are bottom row first (GL window order),
pictures top row first.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from pipegen.ir import nodes as ir, walk as irwalk
from pipegen.core.formats import Format, Kind

_INDEX_SCHEMES = ("bitplanes", "max_pairs", "channel_slots")
_NORMAL_SCHEMES = ("kircher", "spheremap", "octahedral")
LEGEND_ENTRIES = 12          # values listed in a legend (most frequent first), the rest counted
BACKGROUND = (32, 32, 32)
TEXT = (230, 230, 230)
DIM_TEXT = (160, 160, 160)
DEPTH_FAR = 0.15             # grey level of the farthest non-cleared depth (near is 1.0)


# =============================================================================================
# Colours
# =============================================================================================


def category_color(values) -> np.ndarray:
    """One colour per integer value, the same in every picture: 0 (empty) black, other values
    spread round the hue circle by the golden ratio (so neighbouring values differ
    strongly), alternating two brightness levels.  (..., 3) uint8."""
    v = np.asarray(values).astype(np.uint64)
    h = v * np.uint64(0x9E3779B97F4A7C15)              # wraps: multiplicative hash
    hue = (h >> np.uint64(40)).astype(np.float64) / float(1 << 24)
    bright = np.where(((h >> np.uint64(37)) & np.uint64(1)) == 1, 0.72, 0.98)
    sat = np.where(((h >> np.uint64(38)) & np.uint64(1)) == 1, 0.55, 0.8)
    rgb = _hsv_to_rgb(hue, sat, bright)
    rgb = (rgb * 255 + 0.5).astype(np.uint8)
    rgb[v == 0] = 0
    return rgb


def false_color(values: np.ndarray) -> np.ndarray:
    """Distinct values -> distinct saturated colours; zero (empty) stays black."""
    return category_color(values)


def _hsv_to_rgb(h, s, v) -> np.ndarray:
    h6 = (np.asarray(h) % 1.0) * 6.0
    i = np.floor(h6).astype(np.int64) % 6
    f = h6 - np.floor(h6)
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    choices = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)]
    out = np.zeros(np.shape(h6) + (3,))
    for k, (r, g, b) in enumerate(choices):
        sel = i == k
        for c, x in enumerate((r, g, b)):
            out[..., c] = np.where(sel, x, out[..., c])
    return out


# =============================================================================================
# Panels
# =============================================================================================


@dataclass
class Panel:
    """One picture of (part of) a target: ``rgb`` (H, W, 3) uint8, row 0 = bottom like the
    target; ``legend`` pairs a label with the colour it is drawn in; ``note`` is a line of
    text (a depth range, say); ``categorical`` panels are scaled without smoothing."""

    rgb: np.ndarray
    title: str = ""
    legend: list = field(default_factory=list)     # [(label, (r, g, b))]
    note: str = ""
    categorical: bool = False


def depth_panel(window_depth: np.ndarray, cleared: Optional[np.ndarray], near: float,
                far: float, title: str = "depth") -> Panel:
    """Window-space depth in [0, 1] -> distance from the camera, near bright."""
    return distance_panel(eye_distance(window_depth, near, far), cleared, title=title)


def distance_panel(distance: np.ndarray, cleared: Optional[np.ndarray],
                   title: str = "depth") -> Panel:
    """Any quantity proportional to the distance from the camera (> 0): near white, the
    farthest non-cleared pixel dark grey (``DEPTH_FAR``), cleared pixels black.  The grey
    level is linear in 1 / distance between the nearest and farthest non-cleared pixel, which
    is linear in window depth: the stretch a depth buffer itself has, so near objects are
    told apart from the floor behind them."""
    d = np.asarray(distance, dtype=np.float64)
    keep = np.isfinite(d) & (d > 0) & (np.ones(d.shape, bool) if cleared is None else ~cleared)
    g = np.zeros(d.shape)
    note = "nothing drawn"
    if keep.any():
        lo, hi = float(d[keep].min()), float(d[keep].max())
        inv = 1.0 / np.where(keep, d, 1.0)
        t = (1.0 / lo - inv) / (1.0 / lo - 1.0 / hi) if hi > lo else np.zeros_like(d)
        g = np.where(keep, 1.0 - (1.0 - DEPTH_FAR) * np.clip(t, 0, 1), 0.0)
        note = f"near {_num(lo)} = white, far {_num(hi)} = grey"
    return Panel(_gray(g), title, note=note)


def eye_distance(window_depth: np.ndarray, near: float, far: float) -> np.ndarray:
    """Window depth in [0, 1] -> distance along the view axis (a perspective projection)."""
    z = np.asarray(window_depth, dtype=np.float64) * 2.0 - 1.0
    return (2.0 * near * far) / np.maximum(far + near - z * (far - near), 1e-12)


def linear_depth(d: np.ndarray, near: float, far: float, invert: bool = False) -> np.ndarray:
    """Window depth in [0,1] -> distance mapped to [0,1] between near and far (sky = 1)."""
    t = np.clip((eye_distance(d, near, far) - near) / (far - near), 0, 1)
    return 1.0 - t if invert else t


def category_panel(values: np.ndarray, title: str = "", labels: Optional[dict] = None,
                   colors: Optional[np.ndarray] = None) -> Panel:
    """Integer values (H, W) -> one colour each (:func:`category_color`) and a legend of the
    values present, most frequent first (at most ``LEGEND_ENTRIES``; the rest are counted).
    ``labels`` maps a value to its legend text (default: the number)."""
    v = np.asarray(values).astype(np.uint64)
    uniq, inverse, counts = np.unique(v.reshape(-1), return_inverse=True, return_counts=True)
    if colors is None:      # colour the distinct values only: images have few of them
        rgb = category_color(uniq)[inverse.reshape(-1)].reshape(v.shape + (3,))
    else:
        rgb = colors
    order = np.argsort(-counts, kind="stable")
    shown = sorted(int(x) for x in uniq[order[:LEGEND_ENTRIES]])
    legend = [((labels or {}).get(x, str(x)), tuple(int(c) for c in category_color(x)))
              for x in shown]
    if len(uniq) > len(shown):
        legend.append((f"+{len(uniq) - len(shown)} more", None))
    return Panel(rgb, title, legend=legend, categorical=True)


def _gray(x: np.ndarray) -> np.ndarray:
    g = (np.clip(np.nan_to_num(x), 0, 1) * 255 + 0.5).astype(np.uint8)
    return np.dstack([g, g, g])


def _autorange(x: np.ndarray) -> np.ndarray:
    finite = np.isfinite(x)
    if not finite.any():
        return np.zeros_like(x)
    lo, hi = float(x[finite].min()), float(x[finite].max())
    return (np.where(finite, x, lo) - lo) / (hi - lo if hi > lo else 1.0)


def _num(x: float) -> str:
    return f"{x:.3g}"


def _data_panel(values: np.ndarray, kind: str = "data", title: str = "") -> Panel:
    """Float data (H, W) or (H, W, C): colour as is, normals from [-1, 1], else auto-ranged."""
    if values.ndim == 2:
        lo, hi = np.nanmin(values), np.nanmax(values)
        note = f"{_num(lo)} = black, {_num(hi)} = white" if hi > lo else f"all {_num(lo)}"
        return Panel(_gray(_autorange(values)), title, note=note)
    rgb = values[..., :3] if values.shape[2] >= 3 else np.dstack(
        [values, np.zeros(values.shape[:2] + (3 - values.shape[2],))])
    note = ""
    finite = rgb[np.isfinite(rgb)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    if kind == "normal" or (kind == "data" and lo < 0 and max(-lo, hi) <= 1.001):
        rgb = rgb * 0.5 + 0.5
        note = "xyz from [-1, 1]"
    elif kind == "data" and (lo < 0 or hi > 1):
        note = "per channel " + ", ".join(
            f"{_num(np.nanmin(rgb[..., c]))}..{_num(np.nanmax(rgb[..., c]))}" for c in range(3))
        rgb = np.dstack([_autorange(rgb[..., c]) for c in range(3)])
    return Panel((np.clip(np.nan_to_num(rgb), 0, 1) * 255 + 0.5).astype(np.uint8), title,
                 note=note)


# =============================================================================================
# What a target holds: read from the technique
# =============================================================================================


@dataclass(frozen=True)
class Role:
    """What some channels of a colour target hold.  ``kind``: ``window_depth`` (frag_coord.z),
    ``linear_depth`` (scaled -view_pos.z), ``bitfield`` (``raw``: the integer itself, else
    through ``to_unorm``), ``normal`` (a normal encoding), ``split16``, ``index`` (a light-index
    packing; the whole target) or ``data`` (anything else)."""

    kind: str
    channels: tuple[int, ...]
    packing: Optional[ir.Packing] = None
    raw: bool = False


@dataclass(frozen=True)
class TargetView:
    """How to picture one target: ``kind`` is ``depth``, ``integer``, ``color``, ``data`` or
    ``packed`` (then ``roles`` say which channels hold what); ``clears`` are the values the
    target is cleared to (target declaration and pass clears)."""

    kind: str
    roles: tuple[Role, ...] = ()
    clears: tuple = ()


def target_views(tech: ir.Technique) -> dict[str, TargetView]:
    """How to picture every target of ``tech`` (by target name)."""
    packings = {p.name: p for p in tech.packings}
    roles: dict[str, list] = {}
    for p in tech.passes:
        locals_ = _single_assignment_locals(p.body)
        for s in irwalk.walk_stmts(p.body):
            if not isinstance(s, ir.Output):
                continue
            found = _roles_of(s.value, packings, locals_, tech.target(s.target).format)
            # Several writes: per channel, a constant gives way to a role, and two different
            # roles are plain data; a light-index packing anywhere makes the target an index.
            old = roles.setdefault(s.target, found)
            for c, r in enumerate(found):
                if old[c] is None or (r is not None and r.kind == "index"):
                    old[c] = r
                elif r is not None and r != old[c] and old[c].kind != "index":
                    old[c] = Role("data", (c,))
    views = {}
    for t in tech.targets:
        clears = [t.clear] + [c for p in tech.passes for name, c in p.clears if name == t.name]
        if t.format.has_depth:
            views[t.name] = TargetView("depth", clears=tuple(c.depth if c.depth is not None
                                                             else 0.0 for c in clears))
            continue
        colors = tuple(c.color if c.color is not None else (0.0,) * 4 for c in clears
                       if c.color is not None or c is t.clear)
        found = [r for r in roles.get(t.name, []) if r]
        if all(r.kind == "data" for r in found):
            found = []
        if any(r.kind == "index" for r in found):
            views[t.name] = TargetView("packed", tuple(r for r in found if r.kind == "index")[:1],
                                       colors)
        elif found:
            views[t.name] = TargetView("packed", tuple(_merge(found)), colors)
        elif t.format.is_integer:
            views[t.name] = TargetView("integer", clears=colors)
        elif t.name == tech.output or (t.format.channels >= 3 and t.format.kind is Kind.UNORM):
            views[t.name] = TargetView("color", clears=colors)
        else:
            views[t.name] = TargetView("data", clears=colors)
    return views


def _merge(roles: list[Role]) -> list[Role]:
    """Consecutive components with the same role (a vec2 normal encoding) as one role."""
    out: list[Role] = []
    for r in roles:
        if out and out[-1].kind == r.kind and out[-1].packing is r.packing and \
                r.kind in ("normal", "split16") and len(out[-1].channels) < 2:
            out[-1] = Role(r.kind, out[-1].channels + r.channels, r.packing, r.raw)
        else:
            out.append(r)
    return out


def _single_assignment_locals(body) -> dict[str, ir.Expr]:
    """Locals declared with a value and never assigned again: name -> value."""
    decl: dict[str, ir.Expr] = {}
    assigned: set[str] = set()
    for s in irwalk.walk_stmts(body):
        if isinstance(s, ir.Declare):
            if s.name in decl or s.init is None:
                assigned.add(s.name)
            else:
                decl[s.name] = s.init
        elif isinstance(s, ir.Assign):
            base = s.target
            while isinstance(base, (ir.Swizzle, ir.Index)):
                base = base.base
            if isinstance(base, ir.Var):
                assigned.add(base.name)
    return {k: v for k, v in decl.items() if k not in assigned}


def _components(value: ir.Expr, locals_: dict) -> list:
    """The expression behind each of the 4 components of a written value (None: constant)."""
    value = _resolve(value, locals_)
    if isinstance(value, ir.Construct):
        parts: list = []
        for a in value.args:
            a = _resolve(a, locals_)
            parts += [None if isinstance(a, ir.Const) else a] * max(1, a.type.size)
        return (parts + [None] * 4)[:4]
    return [value] * 4


def _resolve(e: ir.Expr, locals_: dict, depth: int = 0) -> ir.Expr:
    while isinstance(e, ir.Var) and e.kind == "local" and e.name in locals_ and depth < 8:
        e, depth = locals_[e.name], depth + 1
    return e


def _roles_of(value: ir.Expr, packings: dict, locals_: dict, fmt: Format) -> list:
    roles: list = []
    comps = _components(value, locals_)
    for c, e in enumerate(comps[:fmt.channels]):
        roles.append(None if e is None else
                     _role(e, c, packings, locals_) or Role("data", (c,)))
    return roles


def _role(e: ir.Expr, channel: int, packings: dict, locals_: dict) -> Optional[Role]:
    calls = [x for x in irwalk.walk_exprs([ir.ExprStmt(e)])
             if isinstance(x, ir.Call) and not x.builtin]
    for call in calls:
        pack, _, fn = call.name.partition("_")
        p = packings.get(pack)
        if p is None:
            continue
        if p.scheme in _INDEX_SCHEMES:
            return Role("index", (0, 1, 2, 3), p)
        if p.scheme == "bitfield" and call is e and fn == "to_unorm":
            return Role("bitfield", (channel,), p)
        if p.scheme == "bitfield" and fn == "pack" and _only_conversions(e, call):
            return Role("bitfield", (channel,), p, raw=True)
        if p.scheme in _NORMAL_SCHEMES and call is e and fn == "encode":
            return Role("normal", (channel,), p)
        if p.scheme == "split16" and call is e and fn == "pack":
            return Role("split16", (channel,), p)
    if _is_swizzle_of(e, "frag_coord", "z"):
        return Role("window_depth", (channel,))
    if _scaled(e, locals_, lambda x: _is_swizzle_of(x, "view_pos", "z")):
        return Role("linear_depth", (channel,))
    return None


def _is_swizzle_of(e, name: str, comp: str) -> bool:
    return (isinstance(e, ir.Swizzle) and e.components == comp and isinstance(e.base, ir.Var)
            and e.base.name == name and e.base.kind == "input")


def _only_conversions(e, inner) -> bool:
    """``e`` is ``inner`` wrapped in scalar conversions only (``uint(x)``, ``uvec4(x, …)``)."""
    while e is not inner:
        if isinstance(e, ir.Construct) and e.args and e.type.size == 1:
            e = e.args[0]
        else:
            return False
    return True


def _constant(e) -> bool:
    return isinstance(e, ir.Const) or (isinstance(e, ir.Var) and e.kind == "param")


def _scaled(e, locals_, leaf) -> bool:
    """``e`` is ``leaf`` negated, or multiplied or divided by constants and parameters."""
    e = _resolve(e, locals_)
    if leaf(e):
        return True
    if isinstance(e, ir.Unary) and e.op == "-":
        return _scaled(e.operand, locals_, leaf)
    if isinstance(e, ir.Binary) and e.op in ("*", "/"):
        if _constant(e.right):
            return _scaled(e.left, locals_, leaf)
        if e.op == "*" and _constant(e.left):
            return _scaled(e.right, locals_, leaf)
    return False


# =============================================================================================
# Pictures of targets
# =============================================================================================


def target_panels(name: str, codes: np.ndarray, tech: ir.Technique, near: float, far: float,
                  views: Optional[dict] = None) -> list[Panel]:
    """The panels that picture ``codes`` of target (or aspect) ``name`` (``ds``,
    ``ds.stencil``) of ``tech``; ``near``/``far``: the camera planes."""
    views = target_views(tech) if views is None else views
    base, _, aspect = name.partition(".")
    fmt = tech.target(base).format
    view = views.get(base, TargetView("data"))
    if aspect == "stencil":
        return [category_panel(codes, "stencil")]
    if view.kind == "depth":
        d = fmt.dequantize(codes) if fmt.kind is Kind.DEPTH_STENCIL else codes.astype(np.float64)
        cleared = _cleared_depth(codes, fmt, view.clears)
        return [depth_panel(d, cleared, near, far)]
    if view.kind == "integer":
        return [_integer_panel(codes, fmt)]
    if view.kind == "packed":
        return _packed_panels(codes, fmt, view, near, far)
    return [_data_panel(fmt.dequantize(codes), "color" if view.kind == "color" else "data")]


def _channel(codes: np.ndarray, c: int) -> np.ndarray:
    return codes if codes.ndim == 2 else codes[..., c]


def _cleared_depth(codes, fmt: Format, clears) -> np.ndarray:
    mask = np.zeros(codes.shape[:2], bool)
    for d in clears or (1.0,):
        mask |= codes == fmt.clear_codes(depth=d)
    return mask


def _cleared(codes, fmt: Format, clears, channels) -> np.ndarray:
    """Pixels whose ``channels`` all hold one of the clear values."""
    mask = np.zeros(codes.shape[:2], bool)
    for color in clears or ((0.0,) * 4,):
        q = fmt.clear_codes(color)
        m = np.ones(codes.shape[:2], bool)
        for c in channels:
            m &= _channel(codes, c) == q[c]
        mask |= m
    return mask


def _integer_panel(codes: np.ndarray, fmt: Format) -> Panel:
    if codes.ndim == 2:
        return category_panel(codes)
    bits = max(fmt.bits)
    packed = np.zeros(codes.shape[:2], np.uint64)
    for c in range(codes.shape[2]):
        packed = (packed << np.uint64(bits)) | codes[..., c].astype(np.uint64)
    labels = {}
    mask = (1 << bits) - 1
    for v in np.unique(packed):
        v = int(v)
        labels[v] = "(" + ", ".join(str((v >> (bits * (codes.shape[2] - 1 - c))) & mask)
                                    for c in range(codes.shape[2])) + ")"
    return category_panel(packed, labels=labels)


def _options(p: ir.Packing) -> dict:
    return {k: v for k, v in p.options}


def _packed_panels(codes, fmt: Format, view: TargetView, near, far) -> list[Panel]:
    from pipegen.packing import schemes as packing_mod

    values = fmt.dequantize(codes)
    panels: list[Panel] = []
    used: set[int] = set()
    for r in view.roles:
        used |= set(r.channels)
        cleared = _cleared(codes, fmt, view.clears, r.channels)
        if r.kind == "window_depth":
            panels.append(depth_panel(_channel(values, r.channels[0]), cleared, near, far))
        elif r.kind == "linear_depth":
            panels.append(distance_panel(_channel(values, r.channels[0]), cleared))
        elif r.kind == "bitfield":
            impl = packing_mod.numpy_impl("bitfield", _options(r.packing), fmt)
            ch = r.channels[0]
            v = (_channel(codes, ch).astype(np.uint64) if r.raw or fmt.is_integer
                 else impl["from_unorm"](_channel(values, ch)))
            for fname, _ in _options(r.packing)["fields"]:
                panels.append(category_panel(impl[f"{fname}_of"](v),
                                             f"{r.packing.name}.{fname}"))
        elif r.kind == "normal" and len(r.channels) == 2:
            impl = packing_mod.numpy_impl(r.packing.scheme, _options(r.packing), fmt)
            n = impl["decode"](np.stack([_channel(values, c) for c in r.channels], -1))
            p = _data_panel(np.asarray(n, np.float64), "normal", f"{r.packing.name}.decode")
            p.rgb[cleared] = 0
            panels.append(p)
        elif r.kind == "split16" and len(r.channels) == 2:
            impl = packing_mod.numpy_impl("split16", _options(r.packing), fmt)
            x = impl["unpack"](np.stack([_channel(values, c) for c in r.channels], -1))
            panels.append(_data_panel(np.asarray(x, np.float64), title=f"{r.packing.name}"))
        elif r.kind == "index":
            panels += _index_panels(codes, values, fmt, r.packing)
            used |= set(range(fmt.channels))
        else:
            used -= set(r.channels)
    # Channels written with constants have no role and are left out.
    rest = [c for r in view.roles if r.kind == "data" for c in r.channels if c not in used]
    if rest:
        data = values if values.ndim == 2 else values[..., rest]
        if data.ndim == 3 and data.shape[2] == 1:
            data = data[..., 0]
        panels.append(_data_panel(data, title="".join("rgba"[c] for c in rest)))
    return panels


def _index_panels(codes, values, fmt: Format, p: ir.Packing) -> list[Panel]:
    """A light-index target: the light set of each pixel and the number of lights."""
    from pipegen.packing import schemes as packing_mod

    impl = packing_mod.numpy_impl(p.scheme, _options(p), fmt)
    # Decode each distinct texel once: a frame has few distinct light sets, many pixels.
    c = codes if codes.ndim == 3 else codes[..., None]
    packed = np.zeros(c.shape[:2], np.uint64)
    for ch in range(c.shape[2]):
        packed = (packed << np.uint64(max(fmt.bits))) | c[..., ch].astype(np.uint64)
    texels, first, inverse = np.unique(packed.reshape(-1), return_index=True,
                                       return_inverse=True)
    v = values.reshape(-1, values.shape[-1]) if values.ndim == 3 else values.reshape(-1, 1)
    v4 = v[first]
    if v4.shape[1] < 4:
        v4 = np.concatenate([v4, np.zeros((len(v4), 4 - v4.shape[1]))], -1)
    cap = p.capacity or 4
    lights = np.stack([impl["unpack"](v4, k) for k in range(cap)], -1).astype(np.int64)
    keys, counts, labels = [], [], {}
    for row in lights:
        ids = sorted({int(i) for i in row if i > 0})   # a set: order and duplicates aside
        h = 0                                  # a colour per set, the same in every picture
        for i in ids:
            h = (h * 0x100000001B3 + i) & 0xFFFFFFFFFFFFFFFF
        keys.append(h)
        counts.append(len(ids))
        labels[h] = "+".join(f"L{i - 1}" for i in ids) if ids else "none"
    shape = codes.shape[:2]
    key = np.asarray(keys, np.uint64)[inverse.reshape(-1)].reshape(shape)
    count = np.asarray(counts, np.int64)[inverse.reshape(-1)].reshape(shape)
    sets = category_panel(key, "light set", labels=labels)
    counts = category_panel(count, "lights per pixel")
    return [sets, counts]


def to_rgb8(codes: np.ndarray, fmt: Format, hint: str = "auto",
            near: float = 0.1, far: float = 100.0) -> np.ndarray:
    """``codes`` of a target of ``fmt`` -> (H, W, 3) uint8, without the technique.

    ``hint``: "color", "index", "normal", "depth", "stencil", "data" or "auto".  A depth hint
    reads window depth (any depth format, or a float target holding ``frag_coord.z``; 1.0 is
    taken as the clear value).  :func:`target_panels` knows more (packings, clear values).
    """
    if hint == "auto":
        hint = _guess(fmt)
    if hint == "stencil":
        return category_color(codes)
    if hint == "index":
        if codes.ndim == 2:
            return category_color(codes)
        packed = np.zeros(codes.shape[:2], np.uint64)
        for c in range(codes.shape[2]):
            packed = (packed << np.uint64(max(fmt.bits))) | codes[..., c].astype(np.uint64)
        return category_color(packed)
    if hint == "depth":
        d = fmt.dequantize(codes) if fmt.kind is Kind.DEPTH_STENCIL else codes.astype(np.float64)
        if d.ndim == 3:
            d = d[..., 0]
        return depth_panel(d, d >= 1.0, near, far).rgb
    return _data_panel(fmt.dequantize(codes), hint).rgb


def _guess(fmt: Format) -> str:
    if fmt.kind in (Kind.DEPTH, Kind.DEPTH_STENCIL):
        return "depth"
    if fmt.kind is Kind.UINT:
        return "index"
    return "color" if fmt.channels >= 3 and fmt.kind is Kind.UNORM else "data"


# =============================================================================================
# Layout: pictures with titles and legends, the contact sheet
# =============================================================================================


def _font(size: int = 11):
    from PIL import ImageFont
    try:
        return ImageFont.load_default(size=size)
    except TypeError:        # Pillow < 10.1: the fixed bitmap font
        return ImageFont.load_default()


def _text_width(draw, text: str, font) -> int:
    return int(draw.textlength(text, font=font)) if text else 0


def _fit(img, box: Optional[tuple[int, int]], categorical: bool, min_h: int = 12):
    """``img`` scaled to fit ``box`` (w, h), keeping its aspect, but at least ``min_h`` tall."""
    from PIL import Image
    if box is None:
        return img
    w, h = img.size
    s = min(box[0] / w, box[1] / h)
    nw, nh = max(1, round(w * s)), max(min(min_h, box[1]), round(h * s))
    if (nw, nh) == (w, h):
        return img
    smooth = not categorical and s < 1
    return img.resize((nw, nh), Image.Resampling.BOX if smooth else Image.Resampling.NEAREST)


def compose(panels: list[Panel], box: Optional[tuple[int, int]] = None):
    """The panels side by side, each with its title, note and legend under it (PIL image, top
    row first).  ``box``: scale each panel to fit (w, h); None keeps the target's pixels."""
    from PIL import Image, ImageDraw
    font = _font()
    line = 14
    scratch = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    cols = []
    for p in panels:
        img = _fit(Image.fromarray(np.ascontiguousarray(p.rgb[::-1])), box, p.categorical)
        width = max(img.size[0], 96)
        rows = []          # legend rows: lists of (label, colour)
        cur, cur_w = [], 0
        for label, color in p.legend:
            w = 14 + _text_width(scratch, label, font) + 8
            if cur and cur_w + w > width:
                rows.append(cur)
                cur, cur_w = [], 0
            cur.append((label, color))
            cur_w += w
        if cur:
            rows.append(cur)
        text = [t for t in (p.title, p.note) if t]
        width = max([width] + [_text_width(scratch, t, font) for t in text])
        height = img.size[1] + 2 + line * (len(text) + len(rows))
        cols.append((img, text, rows, width, height))
    gap = 8
    W = sum(c[3] for c in cols) + gap * (len(cols) - 1)
    H = max(c[4] for c in cols)
    out = Image.new("RGB", (W, H), BACKGROUND)
    draw = ImageDraw.Draw(out)
    x = 0
    for img, text, rows, width, _ in cols:
        out.paste(img, (x, 0))
        y = img.size[1] + 2
        for i, t in enumerate(text):
            draw.text((x + 2, y), t, fill=TEXT if i == 0 else DIM_TEXT, font=font)
            y += line
        for row in rows:
            xx = x + 2
            for label, color in row:
                if color is not None:
                    draw.rectangle([xx, y + 2, xx + 9, y + 11], fill=tuple(color),
                                   outline=DIM_TEXT)
                    xx += 14
                draw.text((xx, y), label, fill=TEXT, font=font)
                xx += _text_width(draw, label, font) + 8
            y += line
        x += width + gap
    return out


def panels_image(panels: list[Panel]):
    """The PNG picture of a target: the bare image (the target's pixels) when it is one panel
    without a legend, else :func:`compose` at the target's own pixel size."""
    from PIL import Image
    if len(panels) == 1 and not panels[0].legend:
        return Image.fromarray(np.ascontiguousarray(panels[0].rgb[::-1]))
    return compose(panels)


def contact_sheet(pictures: list[tuple[str, list[Panel]]], title: str = "",
                  box: tuple[int, int] = (256, 144), width: int = 1100):
    """All targets on one sheet: each tile is :func:`compose` of a target's panels, fitted to
    ``box``, with a label under it (``pictures``: (label, panels) in order)."""
    from PIL import Image, ImageDraw
    font = _font(12)
    line = 16
    tiles = []
    for label, panels in pictures:
        img = compose(panels, box)
        tile = Image.new("RGB", (max(img.size[0], 8 + 7 * len(label)), img.size[1] + line + 4),
                         BACKGROUND)
        tile.paste(img, (0, 0))
        ImageDraw.Draw(tile).text((0, img.size[1] + 3), label, fill=(255, 255, 160), font=font)
        tiles.append(tile)
    pad = 12
    width = max([width] + [t.size[0] + 2 * pad for t in tiles])
    rows, cur, cur_w = [], [], pad
    for t in tiles:
        if cur and cur_w + t.size[0] + pad > width:
            rows.append(cur)
            cur, cur_w = [], pad
        cur.append(t)
        cur_w += t.size[0] + pad
    if cur:
        rows.append(cur)
    head = line + pad if title else 0
    H = pad + head + sum(max(t.size[1] for t in r) + pad for r in rows)
    sheet = Image.new("RGB", (width, H), BACKGROUND)
    draw = ImageDraw.Draw(sheet)
    if title:
        draw.text((pad, pad), title, fill=TEXT, font=font)
    y = pad + head
    for r in rows:
        x = pad
        for t in r:
            sheet.paste(t, (x, y))
            x += t.size[0] + pad
        y += max(t.size[1] for t in r) + pad
    return sheet


def target_label(name: str, tech: ir.Technique, codes: np.ndarray) -> str:
    base, _, aspect = name.partition(".")
    fmt = tech.target(base).format
    h, w = codes.shape[:2]
    return f"{name}  {fmt.name}{' ' + aspect if aspect else ''}  {w}x{h}"


def contact_sheet_name(targets) -> str:
    """The contact sheet's file name: ``contact_sheet.png``, or ``_contact_sheet.png`` when a
    target is called ``contact_sheet`` (its own picture has the plain name)."""
    return "_contact_sheet.png" if "contact_sheet" in targets else "contact_sheet.png"


def write_pictures(folder, compiled, scene, targets: dict[str, np.ndarray],
                   file_name=None) -> Path:
    """Write ``TARGET.png`` for every target of a render (decoded as the technique declares,
    see the module docstring; replacing a plainer picture already there) and
    ``contact_sheet.png`` with all of them, labelled with their names, formats and sizes, into
    ``folder``.  ``file_name(target, suffix)`` names the files (default ``target + suffix``).
    Returns the sheet's path (``_contact_sheet.png`` if a target is called ``contact_sheet``)."""
    folder = Path(folder)
    name_of = file_name or (lambda n, suffix: n + suffix)
    tech = compiled.technique
    views = target_views(tech)
    near, far = scene.camera.near, scene.camera.far
    pictures = []
    for name, codes in targets.items():
        panels = target_panels(name, codes, tech, near, far, views)
        panels_image(panels).save(folder / name_of(name, ".png"))
        pictures.append((target_label(name, tech, codes), panels))
    w, h = scene.width, scene.height
    box = (256, max(12, round(256 * h / w))) if w >= h else (max(12, round(144 * w / h)), 144)
    title = f"{tech.name} on {scene.name}, {w}x{h}"
    path = folder / contact_sheet_name(targets)
    contact_sheet(pictures, title, box).save(path)
    return path


def save_png(path, rgb8: np.ndarray) -> None:
    from PIL import Image
    # Targets are stored bottom row first (GL window coordinates); pictures are top row first.
    Image.fromarray(np.ascontiguousarray(rgb8[::-1])).save(path)
