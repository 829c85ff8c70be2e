"""The light table as the shaders read it: each light's fields packed into the vec4 rows that
``ir/light_layout.py`` lays out (the GL runtime's rgba32f texture has a texel column per row and
a line per light; the CL runtime's buffer holds ``rows`` float4s per light), then, for a
technique with a ``material { … }`` block, one material record per object id
(``ir/material_layout.py``)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from pipegen.ir.light_layout import schema_layout
from pipegen.ir.material_layout import material_layout


def table_records(lights) -> int:
    """Records (texture lines) of the table of a plan's ``lights`` (a ``LightTablePlan``)."""
    capacity = max(1, lights.capacity)
    if not lights.materials:
        return capacity
    return capacity + _materials_layout(lights).records


def light_rows(scene, fields: Sequence[Sequence[str]], capacity: int,
               materials: Sequence = ()) -> np.ndarray:
    """float32 (records, rows, 4): ``scene``'s light table for the schema ``fields`` ((name,
    type) pairs: a plan's ``lights.fields``), each field where the layout places it.  The values
    are ``Scene.light_table``'s (one field per slot), copied bit for bit.  With ``materials``
    (a plan's ``lights.materials``) the object ids' material records follow the lights."""
    fields = [tuple(f) for f in fields]
    layout = schema_layout(fields)
    slots = np.asarray(scene.light_table([list(f) for f in fields], capacity), np.float32)
    rows = np.zeros((capacity, layout.rows, 4), np.float32)
    for k, (name, _) in enumerate(fields):
        p = layout.place(name)
        rows[:, p.row, p.offset:p.offset + p.size] = slots[:, k, :p.size]
    if not materials:
        return rows
    return np.concatenate([rows, _material_records(scene, fields, capacity, materials)])


def _materials_layout(lights):
    return material_layout([(n, t) for n, t, _ in lights.materials], lights.fields,
                           lights.capacity)


def _material_records(scene, fields, capacity: int, materials: Sequence) -> np.ndarray:
    """float32 (MATERIAL_IDS * stride, light rows, 4): each object id's material record (the
    defaults where no object has the id or its material does not set a field)."""
    ml = material_layout([(n, t) for n, t, _ in materials], fields, capacity)
    values = scene.material_table([(n, t, d) for n, t, d in materials])
    out = np.zeros((ml.records, ml.light_rows, 4), np.float32)
    for object_id, record in enumerate(values):
        for (name, _, _), value in zip(materials, record):
            offset, p = ml.place(name)
            out[object_id * ml.stride + offset, p.row, p.offset:p.offset + p.size] = value[:p.size]
    return out
