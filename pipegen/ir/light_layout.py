"""Where each field of the light table sits: rows of four floats, fields packed into them.

A light's record is a run of vec4 rows (the GL runtime's rgba32f texture has one texel column
per row, the CL runtime's buffer ``rows`` float4s per light).  Fields are placed largest first,
each into the first row with room for it at its end (first-fit decreasing; ties keep the
schema's order), so the shipped schema's position, colour and direction each share a row with
a float (radius, type, cos_inner), cos_outer and shadow_tile share a row, and the shadow
matrix rows fill rows of their own: 8 rows where one field per row took 12.  Rows are numbered
in the order the schema first names one of their fields.  A field never straddles two rows,
so a shader reads a field with one fetch and a swizzle, and every field of a row with that
same fetch.

This module is the one place the layout is decided: the scene fills the table
(``Scene.light_table``), the backends read it (``backends/cstyle.py``, the light-volume vertex
stages), and both runtimes size their uploads from it.
"""

from __future__ import annotations

from typing import Sequence

from pipegen.core.records import record
from pipegen.ir.nodes import LightTable, parse_type

ROW = 4   # floats per row: one rgba32f texel, one float4


@record(frozen=True)
class Place:
    """Where one field sits: ``size`` components of row ``row`` from component ``offset``."""

    row: int
    offset: int
    size: int

    @property
    def components(self) -> str:
        """The swizzle taking the field out of its row (``"xyz"``, ``"w"``, ``"xyzw"``)."""
        return "xyzw"[self.offset:self.offset + self.size]


@record(frozen=True)
class LightLayout:
    """The rows of one light's record and where each field sits in them."""

    places: dict[str, Place]
    rows: int

    def place(self, field: str) -> Place:
        return self.places[field]


def light_layout(fields: Sequence[tuple[str, int]]) -> LightLayout:
    """The layout of a schema given as ``(name, components)`` in schema order (1..4 each)."""
    fill: list[int] = []                       # components used in each row so far
    placed: dict[str, tuple[int, int]] = {}    # field -> (bin, offset)
    for name, size in sorted(fields, key=lambda f: -f[1]):   # stable: schema order in ties
        assert 1 <= size <= ROW, f"light field {name} has {size} components"
        row = next((r for r, used in enumerate(fill) if used + size <= ROW), len(fill))
        if row == len(fill):
            fill.append(0)
        placed[name] = (row, fill[row])
        fill[row] += size
    # rows numbered in the order the schema first names a field of theirs (position's row
    # first in the shipped schema): the table reads in the order it was declared
    order = {}
    for name, _ in fields:
        order.setdefault(placed[name][0], len(order))
    places = {name: Place(order[placed[name][0]], placed[name][1], size) for name, size in fields}
    return LightLayout(places, len(fill))


def schema_layout(fields: Sequence[tuple[str, str]]) -> LightLayout:
    """The layout of a schema given as ``(name, type name)`` pairs (a plan's ``lights.fields``,
    ``LightTable.fields`` as ``(f.name, str(f.type))``)."""
    sizes = []
    for name, type_name in fields:
        t = parse_type(type_name)
        assert t is not None and (t.is_scalar or t.is_vector), f"light field {name}: {type_name}"
        sizes.append((name, t.size))
    return light_layout(sizes)


def table_layout(table: LightTable) -> LightLayout:
    """The layout of a technique's light table schema."""
    return light_layout([(f.name, f.type.size) for f in table.fields])
