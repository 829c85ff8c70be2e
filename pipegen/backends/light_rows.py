"""Each row of a light's record read once per body: where a function (or stage body) loads
the light-table rows its ``lights[i].FIELD`` reads need (rows: ``ir/light_layout.py``).

``shade_table_light`` reads seven fields of light ``i`` that sit in four rows; read field by
field it fetched seven texels.  Here its reads are grouped by (index, row): each group is loaded
once into a local (``pg_light_row0``) just before the first statement that needs it, in the
innermost block holding every read of it, and the reads take their components from the local.

A group is formed only where that is the value each read would fetch:

* the index is the light being drawn, or an expression of locals each declared once (a
  parameter, a ``for`` variable or one declaration) and never assigned, without calls of user
  functions: so it holds one value wherever the group's local is in scope;
* reads inside the arms of ``?:`` and the right of ``&&``/``||`` are not counted (loading for
  them would fetch rows the expression may never read: a guarded index may be out of range);
  they still use a group's local where one is already in scope.

Given the material layout (``ir/material_layout.py``), ``materials[id].FIELD`` reads are grouped
the same way, by (index, record row): the OpenCL wide path gathers each such row lane by lane
once where the index varies per pixel.  The scalar emitters do not ask for them (their text
reads each material field where it stands).

Statements are named by paths: the statement's index in its block, after the path of the
statement holding the block and the block's name (``then``, ``other``, ``body``):
``(2, "then", 0)`` is the first statement of the third statement's ``then``.  The emitters
(``cstyle.py``, the OpenCL wide path) track the path of the statement they render.
"""

from __future__ import annotations

from typing import Optional, Sequence

from pipegen.core.records import record
from pipegen.ir import nodes as ir
from pipegen.ir.light_layout import LightLayout, Place
from pipegen.ir.material_layout import MaterialLayout
from pipegen.ir.walk import child_exprs, walk_exprs, walk_stmts

Path = tuple

# a statement's nested blocks, by the name its path gives them
_BLOCKS = {ir.If: ("then", "other"), ir.For: ("body",)}


@record(frozen=True)
class RowLoad:
    """One row of one light, loaded into local ``name`` before the statement at ``path``."""

    name: str
    index: Optional[ir.Expr]      # None: the light being drawn
    row: int
    block: Path                   # the block it is declared in
    start: int                    # ... before its statement ``start``
    material: Optional[str] = None    # a material record's row: one field of it (the row's
                                      # reads share its record offset and row)


class RowPlan:
    """The row loads of one body, and which local each field read takes its value from."""

    def __init__(self, loads: Sequence[RowLoad], layout: LightLayout,
                 materials: Optional[MaterialLayout] = None):
        self.layout, self.materials = layout, materials
        self._before: dict[Path, list[RowLoad]] = {}
        self._groups: dict[tuple, RowLoad] = {}
        for load in loads:
            self._before.setdefault(load.block + (load.start,), []).append(load)
            key = load.row if load.material is None else _material_row(materials, load.material)
            self._groups[(load.index, key)] = load

    def loads_before(self, path: Path) -> list[RowLoad]:
        """The rows to load just before the statement at ``path``."""
        return self._before.get(path, [])

    def local_for(self, path: Path, e: "ir.LightField | ir.MaterialField"
                  ) -> Optional[tuple[str, Place]]:
        """(local, place) of read ``e`` in the statement at ``path``, or None where no load
        of its row is in scope there (the read fetches the row itself)."""
        if isinstance(e, ir.MaterialField):
            if self.materials is None:
                return None
            place = self.materials.place(e.field)[1]
            load = self._groups.get((e.index, _material_row(self.materials, e.field)))
        else:
            place = self.layout.place(e.field)
            load = self._groups.get((e.index, place.row))
        if load is None:
            return None
        n = len(load.block)
        if path[:n] != load.block or len(path) <= n or path[n] < load.start:
            return None
        return load.name, place


def plan_rows(body: Sequence[ir.Stmt], layout: LightLayout, params: Sequence[str] = (),
              materials: Optional[MaterialLayout] = None) -> RowPlan:
    """The row loads of ``body`` (a function's, with parameter names ``params``, or a stage's);
    with ``materials`` (the technique's material layout) its material rows too."""
    unstable = _unstable_locals(body, params)
    uses: dict[tuple, list[Path]] = {}
    fields: dict[tuple, str] = {}       # a material row's group -> one field of the row

    def visit(e: ir.Expr, path: Path, counted: bool) -> None:
        if isinstance(e, ir.LightField):
            if e.field != "index" and counted and _stable(e.index, unstable):
                uses.setdefault((e.index, layout.place(e.field).row), []).append(path)
        if isinstance(e, ir.MaterialField) and materials is not None:
            if counted and _stable(e.index, unstable):
                key = (e.index, _material_row(materials, e.field))
                uses.setdefault(key, []).append(path)
                fields.setdefault(key, e.field)
        if isinstance(e, ir.Ternary):
            visit(e.cond, path, counted)
            visit(e.then, path, False)
            visit(e.other, path, False)
            return
        if isinstance(e, ir.Binary) and e.op in ("&&", "||"):
            visit(e.left, path, counted)
            visit(e.right, path, False)
            return
        for c in child_exprs(e):
            visit(c, path, counted)

    def block(stmts: Sequence[ir.Stmt], prefix: Path) -> None:
        for k, s in enumerate(stmts):
            path = prefix + (k,)
            for e in child_exprs(s):
                visit(e, path, True)
            for name in _BLOCKS.get(type(s), ()):
                block(getattr(s, name), path + (name,))

    block(body, ())
    several = len({index for index, _ in uses}) > 1
    keys = {index: n for n, index in enumerate(dict.fromkeys(index for index, _ in uses))}
    loads = []
    for (index, key), paths in uses.items():
        where, start = _placement(paths)
        light = f"{keys[index]}" if several else ""
        field = fields.get((index, key))
        if field is None:
            loads.append(RowLoad(f"pg_light{light}_row{key}", index, key, where, start))
        else:                           # a material record's row: its number in the record
            offset, row = key
            row += offset * materials.light_rows
            loads.append(RowLoad(f"pg_material{light}_row{row}", index, row, where, start, field))
    loads.sort(key=lambda l: (l.block, l.start, keys[l.index], l.material is not None, l.row))
    return RowPlan(loads, layout, materials)


def _material_row(materials: MaterialLayout, field: str) -> tuple[int, int]:
    """The group key of a material field's row: (light record offset, row in that record)."""
    offset, place = materials.place(field)
    return offset, place.row


def _placement(paths: list[Path]) -> tuple[Path, int]:
    """The innermost block holding every path, and the first of its statements holding one."""
    common: list = []
    for parts in zip(*paths):
        if any(p != parts[0] for p in parts):
            break
        common.append(parts[0])
    n = len(common)
    if n % 2:                       # ends at a statement: the block around it
        return tuple(common[:-1]), common[-1]
    return tuple(common), min(p[n] for p in paths)


def _unstable_locals(body: Sequence[ir.Stmt], params: Sequence[str]) -> set[str]:
    """Locals that may hold more than one value where they are in scope: assigned, or
    declared more than once (two loops' ``i``: one name, two variables)."""
    declared = list(params)
    assigned = set()
    for s in walk_stmts(body):
        if isinstance(s, ir.Declare):
            declared.append(s.name)
        elif isinstance(s, ir.For):
            declared.append(s.var)
        elif isinstance(s, ir.Assign):
            root = s.target
            while not isinstance(root, ir.Var):
                root = root.base           # a swizzle or index of a local
            assigned.add(root.name)
    twice = {n for n in declared if declared.count(n) > 1}
    return assigned | twice


def _stable(index: Optional[ir.Expr], unstable: set[str]) -> bool:
    if index is None:
        return True
    for e in walk_exprs([ir.ExprStmt(index)]):
        if isinstance(e, ir.Call) and not e.builtin:
            return False
        if isinstance(e, ir.Var) and e.kind == "local" and e.name in unstable:
            return False
    return True
