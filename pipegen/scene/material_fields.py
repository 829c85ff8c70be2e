"""Material fields a technique declares (``material { model: uint = 0, … }``) and a scene sets.

The scene is loaded before any technique is known, so the loaders keep every material key that
is not pipegen's own (``albedo``, ``specular``, …) as a :class:`MaterialSetting`, with where the
file sets it; a technique that renders the scene checks them against its schema
(:func:`material_table`): a field it does not declare, or a value of the wrong type, is an
error at that position in the scene file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional, Sequence

import numpy as np

from pipegen.core.diagnostics import PipegenError, Span
from pipegen.ir.material_layout import MATERIAL_IDS


@dataclass(frozen=True)
class MaterialSetting:
    """One material key a scene object sets beyond pipegen's own: ``value`` as the file gave
    it (a number, a bool, or a list as a tuple, so that a material stays hashable), ``where``
    its position (None: not known)."""

    name: str
    value: Any
    where: Optional[Span] = None
    source: str = "the scene"      # what set it, for messages ("objects[2].material", a glTF material)
    # False for what a glTF file says of every material (emissiveFactor, extras): used where
    # the technique declares the field, ignored where it does not
    required: bool = True


def material_table(objects, schema: Sequence[tuple[str, str, Sequence[float]]]) -> np.ndarray:
    """float64 (MATERIAL_IDS, len(schema), 4): each object id's value of each schema field
    ((name, type name, default) triples), components first; ids no object has, and fields an
    object does not set, hold the defaults."""
    types = {name: type_name for name, type_name, _ in schema}
    table = np.zeros((MATERIAL_IDS, len(schema), 4))
    for k, (_, _, default) in enumerate(schema):
        table[:, k, :len(default)] = default
    column = {name: k for k, (name, _, _) in enumerate(schema)}
    for obj in objects:
        for s in obj.material.settings:
            if s.name not in types:
                if not s.required:
                    continue
                raise PipegenError(s.where, f"{s.source} sets material field '{s.name}', "
                                   f"which the technique does not declare",
                                   _declared_hint(s.name, list(types)))
            v = field_value(s, types[s.name])
            table[obj.id, column[s.name], :len(v)] = v
    return table


def field_value(s: MaterialSetting, type_name: str) -> tuple[float, ...]:
    """``s``'s value as the components of a ``type_name`` field, or a positioned error."""
    size = int(type_name[-1]) if type_name[-1].isdigit() else 1
    kind = {"u": "uint", "i": "int"}.get(type_name[0], "float") if size > 1 else type_name
    is_list = isinstance(s.value, (list, tuple))
    values = list(s.value) if is_list else [s.value]
    if (size > 1) != is_list or len(values) != size:
        shape = f"a list of {size} numbers" if size > 1 else "one number"
        raise PipegenError(s.where, f"{s.source}: material field '{s.name}' is a {type_name}, "
                           f"so its value is {shape}, not {_show(s.value)}",
                           f"e.g. {s.name} = {_example(size)}")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise PipegenError(s.where, f"{s.source}: material field '{s.name}' is a "
                               f"{type_name}, not {_show(s.value)}", f"e.g. {s.name} = {_example(size)}")
        if kind != "float" and (float(v) != int(v) or (kind == "uint" and v < 0)):
            whole = "a whole number >= 0" if kind == "uint" else "a whole number"
            raise PipegenError(s.where, f"{s.source}: material field '{s.name}' is a "
                               f"{type_name}: {_show(v)} is not {whole}", "write a whole number")
    return tuple(float(v) for v in values)


def _declared_hint(name: str, declared: list[str]) -> str:
    import difflib
    own = ["albedo", "specular", "shininess", "alpha", "translucent"]   # scene/load.py's keys
    close = difflib.get_close_matches(name, declared + own, n=1)
    if close:
        return f"did you mean '{close[0]}'?"
    if declared:
        return "the technique's material block declares: " + ", ".join(declared)
    return "the technique has no `material { … }` block: remove the field or render with one"


def _example(size: int) -> str:
    return "1" if size == 1 else "[" + ", ".join(["0.0"] * size) + "]"


def _show(v: Any) -> str:
    """``v`` as the scene file writes it."""
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_show(x) for x in v) + "]"
    return repr(v) if not isinstance(v, str) else f'"{v}"'
