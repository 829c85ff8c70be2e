"""The wide path's values: a value is a list of scalar components (C expressions), each either
uniform (one ``float``/``int``/``uint``/``bool`` for all lanes) or varying (``float8``/``int8``/
``uint8``, booleans as ``int8`` masks -1/0), and the stage inputs that are varying."""

from __future__ import annotations

import functools

from pipegen.core.records import record
from pipegen.ir.builtins import FLAT_SCENE_INPUTS, STAGE_INPUTS, Where
from pipegen.ir.nodes import Scalar, Type

W = 8                       # lanes: llvmpipe shades 8 pixels at once as well (the helpers
                            # are written for 8)
MARK = "/* pg_fragment_w */"     # the first line of the wide function's text (has_wide)


@functools.cache
def varying_inputs() -> frozenset[str]:
    """The stage inputs that differ per pixel, the fields of ``pgw_in`` (cl_pass.cl.j2):
    ``frag_coord`` and the scene inputs both backends interpolate.  The others are uniform
    over a triangle: frame values, facing, the light, and the flat scene inputs (the
    provoking vertex's material and ids: ``builtins.FLAT_SCENE_INPUTS``)."""
    return frozenset({"frag_coord", *(name for name, inp in STAGE_INPUTS.items()
                                      if inp.where is Where.SCENE
                                      and name not in FLAT_SCENE_INPUTS)})


class Unsupported(Exception):
    """The code uses something the wide form does not support."""


class TooManyGathers(Exception):
    """The pass body gathers more table rows lane by lane than its work pays for: the wide
    form would be dropped (``wide_fragment``), so its rendering stops."""


@record
class Val:
    comps: list            # C expressions, one per component (a matrix: one, the matrix)
    type: Type
    varying: bool


C_TYPES = {Scalar.FLOAT: "float", Scalar.INT: "int", Scalar.UINT: "uint", Scalar.BOOL: "bool"}
C_TYPES_W = {Scalar.FLOAT: f"float{W}", Scalar.INT: f"int{W}", Scalar.UINT: f"uint{W}",
             Scalar.BOOL: f"int{W}"}


def ctype(s: Scalar, varying: bool) -> str:
    """The C type of a uniform or varying component of scalar type ``s``."""
    return (C_TYPES_W if varying else C_TYPES)[s]


def widen(c: str, s: Scalar) -> str:
    """A uniform component as a varying one."""
    if s is Scalar.BOOL:
        return f"((int{W})(-(int)({c})))"
    return f"(({C_TYPES_W[s]})({c}))"

