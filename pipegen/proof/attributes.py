"""Errors of a technique's intermediate targets in the terms of what they hold (issue 25; docs/
accuracy.md, "Intermediate targets").

A sweep's image errors say how far the output is from the reference; choosing between G-buffer
layouts needs the error of each stored attribute.  :func:`attributes` reads from the technique
what each target holds, from the code that writes it:

- a normal written through a normal encoding (``pack n = octahedral(target: gnormal)``, its
  ``encode`` stored in two channels): decoded through the packing, error in degrees;
- a ``bitfield`` field (stored as a uint or through ``to_unorm``): per field, in its own units
  (ids: how far apart, and how many pixels differ);
- a ``split16`` value: unpacked, in value units;
- a depth target the size of the output (or a fraction of it): the world-space position it
  reconstructs through the scene camera, error in scene units;
- anything else (a light buffer, a linear depth, an albedo): per pixel the largest channel
  error, in the format's codes for normalised formats, in stored units for float formats.

:func:`attribute_errors` compares a float32 render's targets with the same-named targets of a
reference evaluation (the reference technique in float64, or the variant's own float64
evaluation), each side decoded through its own technique's packing.  Where the reference's
target has another size (a G-buffer at ``lbuffer_scale 0.625`` against one at 1.0), the
reference is evaluated on the scene resized so that its target has the render's size
(``Reference.target_at``): the same texel centres, so silhouettes do not count as error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

from pipegen.core import formats as F
from pipegen.ir import nodes as ir

NORMAL_SCHEMES = ("kircher", "spheremap", "octahedral")


@dataclass(frozen=True)
class Attribute:
    """What (part of) a target holds and how its error is measured."""

    target: str
    kind: str                          # "normal" | "field" | "value16" | "depth" | "values"
    channels: tuple[int, ...] = ()     # the target channels it occupies (() : all)
    packing: Optional[ir.Packing] = None
    field: str = ""                    # the bitfield field
    via_unorm: bool = False            # a bitfield stored through to_unorm (float channel)

    @property
    def label(self) -> str:
        """``gnormal.xy normal (kircher)``, ``gdsf.y object (bitfield id)``, ``gds depth``."""
        where = self.target + ("." + "".join("xyzw"[c] for c in self.channels)
                               if self.channels else "")
        if self.kind == "normal":
            return f"{where} normal ({self.packing.scheme})"
        if self.kind == "field":
            return f"{where} {self.field} (bitfield {self.packing.name})"
        if self.kind == "value16":
            return f"{where} value (split16 {self.packing.name})"
        if self.kind == "depth":
            return f"{where} depth as world position"
        return where

    @property
    def column(self) -> str:
        """Short, the same whatever the packing (tables' columns): ``gnormal.xy normal``,
        ``gdsf.y object``, ``gds depth``, ``lbuf``."""
        where = self.target + ("." + "".join("xyzw"[c] for c in self.channels)
                               if self.channels else "")
        word = {"normal": " normal", "field": " " + self.field, "value16": " value",
                "depth": " depth"}.get(self.kind, "")
        return where + word

    def units(self, fmt: F.Format) -> str:
        if self.kind == "normal":
            return "degrees"
        if self.kind == "depth":
            return "scene units"
        if self.kind == "field":
            return "field steps"
        if self.kind == "values" and fmt.is_normalized and fmt.kind is not F.Kind.DEPTH_STENCIL:
            return "codes"
        return "value units"


def _width(t: ir.Type) -> int:
    return t.mat * t.mat if t.mat else t.size


def _channel_calls(value: ir.Expr) -> list[tuple[int, ir.Call]]:
    """(first channel, call) for each argument of a written ``vec4(...)`` that is a call (or a
    call converted, e.g. ``float(id.pack(...))``)."""
    if not isinstance(value, ir.Construct):
        return []
    out, at = [], 0
    for arg in value.args:
        inner = arg
        while isinstance(inner, ir.Construct) and len(inner.args) == 1:
            inner = inner.args[0]
        if isinstance(inner, ir.Call):
            out.append((at, inner))
        at += _width(arg.type)
    return out


def _outputs(stmts) -> list[ir.Output]:
    found = []
    for s in stmts:
        if isinstance(s, ir.Output):
            found.append(s)
        elif isinstance(s, ir.If):
            found += _outputs(s.then) + _outputs(s.other)
        elif isinstance(s, ir.For):
            found += _outputs(s.body)
    return found


def _packed(tech: ir.Technique, target: str) -> list[Attribute]:
    """The packed attributes written into ``target``: where the write's ``vec4(...)`` holds a
    packing's ``encode`` / ``pack`` / ``to_unorm`` call, on the channels that argument takes."""
    packings = {p.name: p for p in tech.packings}
    found: dict[tuple, Attribute] = {}
    for p in tech.passes:
        for out in _outputs(p.body):
            if out.target != target:
                continue
            for at, call in _channel_calls(out.value):
                name, _, fn = call.name.partition("_")
                pk = packings.get(name)
                if pk is None or call.builtin:
                    continue
                if pk.scheme in NORMAL_SCHEMES and fn == "encode":
                    a = [Attribute(target, "normal", (at, at + 1), pk)]
                elif pk.scheme == "split16" and fn == "pack":
                    a = [Attribute(target, "value16", (at, at + 1), pk)]
                elif pk.scheme == "bitfield" and fn in ("to_unorm", "pack"):
                    fields = dict(pk.options).get("fields") or ()
                    a = [Attribute(target, "field", (at,), pk, str(f), fn == "to_unorm")
                         for f, _ in (fields.items() if isinstance(fields, dict) else fields)]
                else:
                    continue
                for x in a:
                    found.setdefault((x.channels, x.kind, x.field), x)
    return list(found.values())


def attributes(tech: ir.Technique) -> list[Attribute]:
    """Every intermediate target's attributes (the output is measured as an image)."""
    out = []
    for t in tech.targets:
        if t.name == tech.output:
            continue
        if t.format.kind is F.Kind.DEPTH_STENCIL or t.format.name.startswith("d"):
            # a depth target as large as the output (or a fraction of it) sees through the
            # scene camera; one of a fixed size is a shadow map: its own units
            out.append(Attribute(t.name, "depth" if t.size.relative else "values"))
            continue
        packed = _packed(tech, t.name)
        used = {c for a in packed for c in a.channels}
        out += packed
        rest = tuple(c for c in range(t.format.channels) if c not in used)
        if rest:
            out.append(Attribute(t.name, "values", rest if packed else ()))
    return out


# -- measuring -------------------------------------------------------------------------------


@dataclass
class AttributeError:
    """One attribute of a float32 render against the reference's same attribute."""

    attribute: str                    # Attribute.label
    column: str                       # Attribute.column
    target: str
    units: str
    rmse: float
    p99: float
    max: float
    pixels: int                       # pixels compared
    differing: int                    # pixels whose error is not 0
    worst: list = field(default_factory=list)   # [x, y (from the top), got, reference]
    note: str = ""

    def as_dict(self) -> dict:
        return dict(attribute=self.attribute, column=self.column, target=self.target,
                    units=self.units,
                    rmse=self.rmse, p99=self.p99, max=self.max, pixels=self.pixels,
                    differing=self.differing, worst=self.worst, note=self.note)

    def brief(self) -> str:
        """``gnormal.xy normal (kircher): p99 0.31, max 1.2 degrees``."""
        return (f"{self.attribute}: rmse {_num(self.rmse)}, p99 {_num(self.p99)}, "
                f"max {_num(self.max)} {self.units}")


def _num(x: float) -> str:
    if x is None or not math.isfinite(x):
        return "inf" if x is not None and x > 0 else "-"
    return f"{x:.3g}"


def _channels(v, channels):
    import numpy as np
    v = np.asarray(v, np.float64)
    if v.ndim == 2:
        v = v[..., None]
    return v[..., list(channels)] if channels else v


def _world(depth, scene):
    """World positions (H, W, 3) of depth values (H, W) in [0, 1] at texel centres, through
    the scene camera (the projection at the output's aspect)."""
    import numpy as np
    h, w = depth.shape
    cam = scene.camera
    vp = cam.projection(scene.aspect) @ cam.view_matrix()
    inv = np.linalg.inv(np.asarray(vp, np.float64))
    x = (np.arange(w) + 0.5) / w * 2 - 1
    y = (np.arange(h) + 0.5) / h * 2 - 1
    X, Y = np.meshgrid(x, y)
    clip = np.stack([X, Y, 2 * np.asarray(depth, np.float64) - 1, np.ones_like(X)], -1)
    p = clip @ inv.T
    return p[..., :3] / p[..., 3:4]


def _decoded(a: Attribute, fmt: F.Format, values, scene):
    """(per-pixel vectors to compare, "angle" | "distance" | "abs") for one side (values in
    stored units, row 0 at the bottom)."""
    import numpy as np
    from pipegen.packing.schemes import numpy_impl
    if a.kind == "depth":
        return _world(np.asarray(values, np.float64), scene), "distance"
    v = _channels(values, a.channels)
    if a.kind == "normal":
        mirror = numpy_impl(a.packing.scheme, dict(a.packing.options), fmt)
        return np.asarray(mirror["decode"](v.astype(np.float32)), np.float64), "angle"
    if a.kind == "value16":
        mirror = numpy_impl(a.packing.scheme, dict(a.packing.options), fmt)
        return np.asarray(mirror["unpack"](v.astype(np.float32)), np.float64)[..., None], "abs"
    if a.kind == "field":
        mirror = numpy_impl(a.packing.scheme, dict(a.packing.options), fmt)
        word = mirror["from_unorm"](v[..., 0]) if a.via_unorm else \
            np.rint(v[..., 0]).astype(np.uint32)
        return np.asarray(mirror[f"{a.field}_of"](word), np.float64)[..., None], "abs"
    if fmt.is_normalized and fmt.kind is not F.Kind.DEPTH_STENCIL:
        top = np.asarray([(1 << b) - 1 for b in fmt.bits], np.float64)
        v = v * (top[list(a.channels)] if a.channels else top[:v.shape[-1]])
    return v, "abs"


def _per_pixel(got, want, how: str):
    import numpy as np
    with np.errstate(invalid="ignore", over="ignore"):
        if how == "angle":
            cross = np.linalg.norm(np.cross(got, want), axis=-1)
            dot = np.sum(got * want, axis=-1)
            e = np.degrees(np.arctan2(cross, dot))
        elif how == "distance":
            e = np.linalg.norm(got - want, axis=-1)
        else:
            from pipegen.proof.f64_compare import error
            e = error(got, want).max(axis=-1)
    return np.where(np.isnan(e), np.inf, e)


def _show(v) -> list:
    import numpy as np
    return [round(float(x), 6) if np.isfinite(x) else None for x in np.atleast_1d(v)]


def compare_attribute(a: Attribute, fmt: F.Format, got_values, ref: Attribute,
                      ref_fmt: F.Format, ref_values, scene, worst: int = 3) -> AttributeError:
    """One attribute: ``got_values`` the float32 render's target in stored units (dequantised),
    ``ref_values`` the reference's same target at the same size (its own attribute ``ref``,
    decoded through its own packing)."""
    import numpy as np
    got, how = _decoded(a, fmt, got_values, scene)
    want, _ = _decoded(ref, ref_fmt, ref_values, scene)
    e = _per_pixel(got, want, how)
    finite = e[np.isfinite(e)]
    n = int(e.size)
    rmse = float(np.sqrt(np.mean(np.square(np.where(np.isfinite(e), e, 0.0))))) \
        if finite.size == n else math.inf
    p99 = float(np.percentile(np.where(np.isfinite(e), e, np.inf), 99)) if n else 0.0
    order = np.argsort(np.where(np.isfinite(e), e, np.inf).ravel(), kind="stable")[::-1][:worst]
    rows = []
    for k in order:
        y, x = np.unravel_index(int(k), e.shape)
        if e[y, x] == 0:
            break
        rows.append([int(x), int(e.shape[0] - 1 - y), _show(got[y, x]), _show(want[y, x])])
    return AttributeError(a.label, a.column, a.target, a.units(fmt), rmse, p99,
                          float(np.max(e)) if n else 0.0, n, int(np.count_nonzero(e)), rows)


def attribute_errors(technique: ir.Technique, codes: dict, ref_technique: ir.Technique,
                     ref_target, scene, worst: int = 3) -> tuple[list, list[str]]:
    """Every intermediate attribute of a float32 render (``codes``: the render's targets as
    stored) against the reference's same-named target holding the same kind of attribute.
    ``ref_target(name, shape) -> (float64 values or None, note)`` gives the reference's
    target (``Reference.target_at``; :func:`values_lookup` for a dict of values).  Returns
    (errors, notes: what could not be compared, and why)."""
    ref_attrs = {(a.target, a.kind, a.field): a for a in attributes(ref_technique)}
    ref_formats = {t.name: t.format for t in ref_technique.targets}
    targets = {t.name: t for t in technique.targets}
    errors, notes = [], []
    for a in attributes(technique):
        if a.target not in codes:
            continue
        fmt = targets[a.target].format
        ref = ref_attrs.get((a.target, a.kind, a.field))
        if ref is None:
            why = ("the reference has no target of that name" if a.target not in ref_formats
                   else "the reference's target holds something else")
            notes.append(f"{a.label}: not compared ({why})")
            continue
        values, note = ref_target(a.target, codes[a.target].shape)
        if values is None:
            notes.append(f"{a.label}: not compared ({note})")
            continue
        got = fmt.dequantize(codes[a.target])
        e = compare_attribute(a, fmt, got, ref, ref_formats[a.target], values, scene, worst)
        e.note = "; ".join(x for x in (note, e.note) if x)
        errors.append(e)
    return errors, notes


def values_lookup(values: dict):
    """``ref_target`` for :func:`attribute_errors` from a dict of float64 target values at
    the render's sizes (the variant's own float64 evaluation)."""
    def lookup(name, shape):
        v = values.get(name)
        if v is None:
            return None, f"no float64 values of '{name}'"
        if tuple(v.shape[:2]) != tuple(shape[:2]):
            return None, f"'{name}' is {v.shape[1]}x{v.shape[0]} there"
        return v, ""
    return lookup
