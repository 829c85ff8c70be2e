"""Where the material table sits: after the lights, in the light table itself.

A technique with a ``material { … }`` block reads one record per object id (0..255: scene ids
are 1..255, and id 0, the background, holds the defaults).  The records are stored in the
light table's texture / buffer after its ``capacity`` light records, so neither runtime binds
anything new and both backends read them with the light table's row fetch
(``render_light_row``).  A material record's fields are laid out like a light's
(``ir/light_layout.py``: vec4 rows, first-fit decreasing); when it needs more rows than a light
record has, it takes ``stride`` consecutive light records.
"""

from __future__ import annotations

from typing import Sequence

from pipegen.core.records import record
from pipegen.ir.light_layout import LightLayout, Place, schema_layout

MATERIAL_IDS = 256   # object ids 0..255 (scene/load.py caps ids at 255)


@record(frozen=True)
class MaterialLayout:
    layout: LightLayout   # the rows of one material record
    base: int             # the light record where object 0's material starts: the capacity
    light_rows: int       # rows of one light record (the table's width)

    @property
    def stride(self) -> int:
        """Light records per material record."""
        return -(-self.layout.rows // self.light_rows)

    @property
    def records(self) -> int:
        """Light records the material table adds after the lights."""
        return MATERIAL_IDS * self.stride

    def place(self, field: str) -> tuple[int, Place]:
        """(light record offset within a material record, place in that record's rows)."""
        p = self.layout.place(field)
        return p.row // self.light_rows, Place(p.row % self.light_rows, p.offset, p.size)


def material_layout(fields: Sequence[tuple[str, str]], light_fields: Sequence[tuple[str, str]],
                    capacity: int) -> MaterialLayout:
    """The layout of material schema ``fields`` ((name, type name) pairs) stored after a light
    table of schema ``light_fields`` holding ``capacity`` lights."""
    rows = schema_layout(light_fields).rows
    assert rows > 0, "a material table is stored in a light table"
    return MaterialLayout(schema_layout(fields), max(1, capacity), rows)


def technique_material_layout(tech) -> MaterialLayout:
    """The material layout of an ``ir.Technique`` with a material block."""
    return material_layout([(f.name, str(f.type)) for f in tech.materials.fields],
                           [(f.name, str(f.type)) for f in tech.lights.fields],
                           tech.lights.capacity)
