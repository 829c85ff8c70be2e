"""The syntax tree of a ``.pipe`` file, as written: untyped, unresolved, with source spans.

``syntax.parse`` builds it from the lark parse tree; ``lower.lower`` resolves names, checks types
and turns it into ``ir``.  Every node carries ``span`` (keyword-only, so that node fields read in
source order); names the user wrote are ``Name`` nodes so errors can point at them exactly.

Keyword arguments in pass statements (``less``, ``incr_wrap``, ``one_minus_src_alpha``) are kept
as ``Word`` nodes: their spelling is already validated by the grammar.
"""

from __future__ import annotations

from dataclasses import field
from typing import Optional, Union

from pipegen.core.diagnostics import Span
from pipegen.core.records import record


@record
class Node:
    span: Span = field(kw_only=True, repr=False, compare=False)


# ---------------------------------------------------------------------------------------------
# Names, literals and expressions (shader code; declarations use a subset)
# ---------------------------------------------------------------------------------------------


@record
class Name(Node):
    name: str


@record
class Word(Node):
    """A keyword argument of a pass statement, e.g. ``less`` or ``one_minus_src_alpha``."""

    value: str


@record
class Number(Node):
    """A numeric literal. ``kind`` is "float", "int" or "uint" (``u`` suffix)."""

    value: Union[int, float]
    kind: str


@record
class Bool(Node):
    value: bool


@record
class UnaryOp(Node):
    op: str            # "-", "+", "!", "~"
    operand: "Expr"


@record
class BinaryOp(Node):
    op: str
    left: "Expr"
    right: "Expr"


@record
class Conditional(Node):
    cond: "Expr"
    then: "Expr"
    other: "Expr"


@record
class Call(Node):
    """``f(args)``: a builtin, a user function or a type constructor."""

    func: Name
    args: list["Expr"]


@record
class MethodCall(Node):
    """``obj.method(args)``: only packing functions (``slots.unpack(v, k)``) are valid."""

    obj: "Expr"
    method: Name
    args: list["Expr"]


@record
class Field(Node):
    """``base.name``: a swizzle, ``light.radius``, ``lights[i].radius`` or ``pack.constant``."""

    base: "Expr"
    name: Name


@record
class Subscript(Node):
    base: "Expr"
    index: "Expr"


@record
class TupleLit(Node):
    """``(0, 0, 0, 1)`` in declarations (clear colours, the blend constant)."""

    items: list["Expr"]


@record
class Option(Node):
    """``key: value`` in a pack declaration."""

    key: Name
    value: Union["Expr", str, "Record"]


@record
class Record(Node):
    """``(name: bits, …)``: a nested option list (``bitfield(fields: (id: 8, group: 8))``)."""

    options: list[Option]


Expr = Union[Name, Number, Bool, UnaryOp, BinaryOp, Conditional, Call, MethodCall, Field,
             Subscript, TupleLit]


# ---------------------------------------------------------------------------------------------
# Shader statements
# ---------------------------------------------------------------------------------------------


@record
class VarDecl(Node):
    type: Name
    name: Name
    init: Optional[Expr]


@record
class Assign(Node):
    target: Expr
    op: str            # "=", "+=", "-=", "*=", "/="
    value: Expr


@record
class ExprStmt(Node):
    expr: Expr


@record
class If(Node):
    cond: Expr
    then: list["Stmt"]
    other: Optional[list["Stmt"]]


@record
class For(Node):
    """``for (TYPE var = start; cond; step_var++)``; ``step`` is the increment (1 for ``++``)."""

    var_type: Name
    var: Name
    start: Expr
    cond: Expr
    step_var: Name
    step: Expr
    body: list["Stmt"]


@record
class Break(Node):
    pass


@record
class Continue(Node):
    pass


@record
class Return(Node):
    value: Optional[Expr]


@record
class Discard(Node):
    pass


Stmt = Union[VarDecl, Assign, ExprStmt, If, For, Break, Continue, Return, Discard]


# ---------------------------------------------------------------------------------------------
# Top-level declarations
# ---------------------------------------------------------------------------------------------


@record
class TechniqueDecl(Node):
    name: Name
    title: str


@record
class Include(Node):
    path: str


@record
class ParamDecl(Node):
    name: Name
    type: Optional[Name]
    value: Expr
    allowed: Optional[list[Expr]]
    accurate: Optional[Expr] = None     # `accurate VALUE`: the most accurate of its values


@record
class LightFieldDecl(Node):
    name: Name
    type: Name


@record
class LightsDecl(Node):
    capacity: Expr
    fields: list[LightFieldDecl]


@record
class MaterialFieldDecl(Node):
    name: Name
    type: Name
    default: Expr


@record
class MaterialDecl(Node):
    fields: list[MaterialFieldDecl]


@record
class SizeAbs(Node):
    width: Expr
    height: Expr


@record
class SizeRel(Node):
    scale: Optional[Expr]      # None: `size output` (scale 1)


@record
class Samples(Node):
    value: Expr


@record
class ClearSpec(Node):
    """One of: ``color`` (a tuple), ``all`` (one value for every channel), or depth/stencil."""

    color: Optional[TupleLit] = None
    all: Optional[Expr] = None
    depth: Optional[Expr] = None
    stencil: Optional[Expr] = None


@record
class Condition(Node):
    """``if EXPR`` after a pass's, a repeat block's or a target's name: the declaration is
    present only where EXPR, over parameters, holds (frontend/lower/conditions.py)."""

    expr: Expr


@record
class TargetDecl(Node):
    name: Name
    format: Name
    options: list[Union[SizeAbs, SizeRel, Samples, ClearSpec]]
    condition: Optional[Condition] = None


@record
class OutputDecl(Node):
    name: Name


@record
class PackDecl(Node):
    name: Name
    scheme: Name
    options: list[Option]


@record
class ParamDef(Node):
    type: Name
    name: Name


@record
class FunctionDef(Node):
    ret: Name
    name: Name
    params: list[ParamDef]
    body: list[Stmt]


# ---------------------------------------------------------------------------------------------
# Pass statements
# ---------------------------------------------------------------------------------------------


@record
class Draw(Node):
    kind: str                                  # "scene", "lights", "fullscreen"
    material: Optional[Name] = None            # scene.MATERIAL
    volume: Optional[Word] = None              # lights as VOLUME
    light_types: list[Word] = field(default_factory=list)
    light_set: Optional[tuple[Name, Expr]] = None   # in PACK[k]
    scissor: bool = False
    back_to_front: bool = False                # scene... back_to_front
    from_lights: Optional["DrawFrom"] = None  # scene... from lights TYPES [first K] [tiles N]
    shadow_volumes: Optional["DrawVolumes"] = None   # scene... shadow_volumes
    within: Optional["DrawWithin"] = None    # scene... within light radius


@record
class DrawFrom(Node):
    """``from lights [TYPES …] [first K] [tiles N]`` after ``draw scene…``: shadow-map passes."""
    light_types: list[Word] = field(default_factory=list)
    tiles: Optional[Expr] = None
    first: Optional[Expr] = None      # only light indices 0..K-1 may cast


@record
class DrawVolumes(Node):
    """``shadow_volumes`` after ``draw scene…``: the scene's shadow volumes from the pass's light."""


@record
class DrawWithin(Node):
    """``within light radius`` after ``draw scene…``: only the objects the pass's light reaches."""


@record
class Writes(Node):
    targets: list[Name]


@record
class Reads(Node):
    targets: list[Name]


@record
class Depth(Node):
    target: Name
    func: Optional[Word]          # None: `depth T off`
    flags: list[Word]             # write / nowrite / clamp
    inside: Optional[Word] = None  # `inside FUNC` (with `cull auto`)


@record
class StencilItem(Node):
    key: str                      # func ref read write fail zfail pass (zpass is read as pass)
    value: Union[Word, Expr]


@record
class Stencil(Node):
    face: Optional[Word]          # None: both faces
    items: list[StencilItem]


@record
class BlendEq(Node):
    op: Word
    src: Optional[Word]
    dst: Optional[Word]


@record
class Blend(Node):
    """``blend T eq`` (rgb and alpha alike), ``blend T rgb eq alpha eq``, ``blend T off``."""

    target: Name
    rgb: Optional[BlendEq]        # None (with alpha None): off
    alpha: Optional[BlendEq]


@record
class BlendConstant(Node):
    value: Expr                   # a TupleLit or one value for all four channels


@record
class Mask(Node):
    target: Name
    channels: Name


@record
class Cull(Node):
    mode: Word


@record
class Offset(Node):
    factor: Expr
    units: Expr


@record
class PassClear(Node):
    target: Name
    clear: ClearSpec


@record
class RepeatPerLight(Node):
    light_types: list[Word] = field(default_factory=list)   # `repeat per light spot …`


@record
class Fragment(Node):
    body: list[Stmt]


PassStmt = Union[Draw, Writes, Reads, Depth, Stencil, Blend, BlendConstant, Mask, Cull, Offset,
                 PassClear, RepeatPerLight, Fragment]


@record
class PassDecl(Node):
    name: Name
    stmts: list[PassStmt]
    condition: Optional[Condition] = None     # `pass NAME if COND { … }`


@record
class RepeatBlock(Node):
    """``repeat per light { pass … pass … }``: the passes run in sequence once per light."""

    passes: list[PassDecl]
    light_types: list[Word] = field(default_factory=list)   # `repeat per light spot … { … }`
    condition: Optional[Condition] = None     # `repeat per light … if COND { … }`


@record
class Expect(Node):
    """``expect SUBJECT CHECK [on "scene"] [at W x H]`` (frontend/expect_syntax.py reads it).

    ``check`` is "agrees" (``against``: the backends, ``agrees gl cl``), "vs" (``against``:
    ``f64``) or "count" (``SUBJECT OP VALUE``, the subject a count such as ``lights_dropped``).
    ``statistic``/``op``/``value``: the bound (``p99 <= 2``); a count has ``op`` and ``value``
    only; None where the derived tolerance decides.  ``text``: the words as written."""

    subject: Name
    check: str
    against: list[Name]
    statistic: Optional[Name]
    op: Optional[Word]
    value: Optional[Number]
    scene: Optional[Word]          # the path as written (``value``), spanning the string
    size: Optional[SizeAbs]
    text: str


Item = Union[TechniqueDecl, Include, ParamDecl, LightsDecl, TargetDecl, OutputDecl, PackDecl,
             FunctionDef, PassDecl, RepeatBlock, Expect]


@record
class Module(Node):
    items: list[Item]
    filename: str
