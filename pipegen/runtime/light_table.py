"""The light table as the shaders read it: each light's fields packed into the vec4 rows that
``ir/light_layout.py`` lays out (the GL runtime's rgba32f texture has a texel column per row and
a line per light; the CL runtime's buffer holds ``rows`` float4s per light)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from pipegen.ir.light_layout import schema_layout


def light_rows(scene, fields: Sequence[Sequence[str]], capacity: int) -> np.ndarray:
    """float32 (capacity, rows, 4): ``scene``'s light table for the schema ``fields`` ((name,
    type) pairs: a plan's ``lights.fields``), each field where the layout places it.  The values
    are ``Scene.light_table``'s (one field per slot), copied bit for bit."""
    fields = [tuple(f) for f in fields]
    layout = schema_layout(fields)
    slots = np.asarray(scene.light_table([list(f) for f in fields], capacity), np.float32)
    rows = np.zeros((capacity, layout.rows, 4), np.float32)
    for k, (name, _) in enumerate(fields):
        p = layout.place(name)
        rows[:, p.row, p.offset:p.offset + p.size] = slots[:, k, :p.size]
    return rows
