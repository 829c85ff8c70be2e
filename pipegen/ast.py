"""The syntax tree of a ``.pipe`` file, as written: untyped, unresolved, with source spans.

``syntax.parse`` builds it from the lark parse tree; ``lower.lower`` resolves names, checks types
and turns it into ``ir``.  Every node carries ``span`` (keyword-only, so that node fields read in
source order); names the user wrote are ``Name`` nodes so errors can point at them exactly.

Keyword arguments in pass statements (``less``, ``incr_wrap``, ``one_minus_src_alpha``) are kept
as ``Word`` nodes: their spelling is already validated by the grammar.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Union

from .diagnostics import Span


@dataclass
class Node:
    span: Span = field(kw_only=True, repr=False, compare=False)


# ---------------------------------------------------------------------------------------------
# Names, literals and expressions (shader code; declarations use a subset)
# ---------------------------------------------------------------------------------------------


@dataclass
class Name(Node):
    name: str


@dataclass
class Word(Node):
    """A keyword argument of a pass statement, e.g. ``less`` or ``one_minus_src_alpha``."""

    value: str


@dataclass
class Number(Node):
    """A numeric literal. ``kind`` is "float", "int" or "uint" (``u`` suffix)."""

    value: Union[int, float]
    kind: str


@dataclass
class Bool(Node):
    value: bool


@dataclass
class UnaryOp(Node):
    op: str            # "-", "+", "!", "~"
    operand: "Expr"


@dataclass
class BinaryOp(Node):
    op: str
    left: "Expr"
    right: "Expr"


@dataclass
class Conditional(Node):
    cond: "Expr"
    then: "Expr"
    other: "Expr"


@dataclass
class Call(Node):
    """``f(args)``: a builtin, a user function or a type constructor."""

    func: Name
    args: list["Expr"]


@dataclass
class MethodCall(Node):
    """``obj.method(args)``: only packing functions (``slots.unpack(v, k)``) are valid."""

    obj: "Expr"
    method: Name
    args: list["Expr"]


@dataclass
class Field(Node):
    """``base.name``: a swizzle, ``light.radius``, ``lights[i].radius`` or ``pack.constant``."""

    base: "Expr"
    name: Name


@dataclass
class Subscript(Node):
    base: "Expr"
    index: "Expr"


@dataclass
class TupleLit(Node):
    """``(0, 0, 0, 1)`` in declarations (clear colours, the blend constant)."""

    items: list["Expr"]


@dataclass
class Option(Node):
    """``key: value`` in a pack declaration."""

    key: Name
    value: Union["Expr", str, "Record"]


@dataclass
class Record(Node):
    """``(name: bits, …)``: a nested option list (``bitfield(fields: (id: 8, group: 8))``)."""

    options: list[Option]


Expr = Union[Name, Number, Bool, UnaryOp, BinaryOp, Conditional, Call, MethodCall, Field,
             Subscript, TupleLit]


# ---------------------------------------------------------------------------------------------
# Shader statements
# ---------------------------------------------------------------------------------------------


@dataclass
class VarDecl(Node):
    type: Name
    name: Name
    init: Optional[Expr]


@dataclass
class Assign(Node):
    target: Expr
    op: str            # "=", "+=", "-=", "*=", "/="
    value: Expr


@dataclass
class ExprStmt(Node):
    expr: Expr


@dataclass
class If(Node):
    cond: Expr
    then: list["Stmt"]
    other: Optional[list["Stmt"]]


@dataclass
class For(Node):
    """``for (TYPE var = start; cond; step_var++)``; ``step`` is the increment (1 for ``++``)."""

    var_type: Name
    var: Name
    start: Expr
    cond: Expr
    step_var: Name
    step: Expr
    body: list["Stmt"]


@dataclass
class Break(Node):
    pass


@dataclass
class Continue(Node):
    pass


@dataclass
class Return(Node):
    value: Optional[Expr]


@dataclass
class Discard(Node):
    pass


Stmt = Union[VarDecl, Assign, ExprStmt, If, For, Break, Continue, Return, Discard]


# ---------------------------------------------------------------------------------------------
# Top-level declarations
# ---------------------------------------------------------------------------------------------


@dataclass
class TechniqueDecl(Node):
    name: Name
    title: str


@dataclass
class Include(Node):
    path: str


@dataclass
class ParamDecl(Node):
    name: Name
    type: Optional[Name]
    value: Expr
    allowed: Optional[list[Expr]]


@dataclass
class LightFieldDecl(Node):
    name: Name
    type: Name


@dataclass
class LightsDecl(Node):
    capacity: Expr
    fields: list[LightFieldDecl]


@dataclass
class SizeAbs(Node):
    width: Expr
    height: Expr


@dataclass
class SizeRel(Node):
    scale: Optional[Expr]      # None: `size output` (scale 1)


@dataclass
class Samples(Node):
    value: Expr


@dataclass
class ClearSpec(Node):
    """One of: ``color`` (a tuple), ``all`` (one value for every channel), or depth/stencil."""

    color: Optional[TupleLit] = None
    all: Optional[Expr] = None
    depth: Optional[Expr] = None
    stencil: Optional[Expr] = None


@dataclass
class TargetDecl(Node):
    name: Name
    format: Name
    options: list[Union[SizeAbs, SizeRel, Samples, ClearSpec]]


@dataclass
class OutputDecl(Node):
    name: Name


@dataclass
class PackDecl(Node):
    name: Name
    scheme: Name
    options: list[Option]


@dataclass
class ParamDef(Node):
    type: Name
    name: Name


@dataclass
class FunctionDef(Node):
    ret: Name
    name: Name
    params: list[ParamDef]
    body: list[Stmt]


# ---------------------------------------------------------------------------------------------
# Pass statements
# ---------------------------------------------------------------------------------------------


@dataclass
class Draw(Node):
    kind: str                                  # "scene", "lights", "fullscreen"
    material: Optional[Name] = None            # scene.MATERIAL
    volume: Optional[Word] = None              # lights as VOLUME
    light_types: list[Word] = field(default_factory=list)
    light_set: Optional[tuple[Name, Expr]] = None   # in PACK[k]
    scissor: bool = False
    back_to_front: bool = False                # scene... back_to_front
    from_lights: Optional["DrawFrom"] = None  # scene... from lights TYPES [tiles N]


@dataclass
class DrawFrom(Node):
    """``from lights [TYPES …] [tiles N]`` after ``draw scene…``: shadow-map passes."""
    light_types: list[Word] = field(default_factory=list)
    tiles: Optional[Expr] = None


@dataclass
class Writes(Node):
    targets: list[Name]


@dataclass
class Reads(Node):
    targets: list[Name]


@dataclass
class Depth(Node):
    target: Name
    func: Optional[Word]          # None: `depth T off`
    flags: list[Word]             # write / nowrite / clamp
    inside: Optional[Word] = None  # `inside FUNC` (with `cull auto`)


@dataclass
class StencilItem(Node):
    key: str                      # func ref read write fail zfail pass (zpass is read as pass)
    value: Union[Word, Expr]


@dataclass
class Stencil(Node):
    face: Optional[Word]          # None: both faces
    items: list[StencilItem]


@dataclass
class BlendEq(Node):
    op: Word
    src: Optional[Word]
    dst: Optional[Word]


@dataclass
class Blend(Node):
    """``blend T eq`` (rgb and alpha alike), ``blend T rgb eq alpha eq``, ``blend T off``."""

    target: Name
    rgb: Optional[BlendEq]        # None (with alpha None): off
    alpha: Optional[BlendEq]


@dataclass
class BlendConstant(Node):
    value: Expr                   # a TupleLit or one value for all four channels


@dataclass
class Mask(Node):
    target: Name
    channels: Name


@dataclass
class Cull(Node):
    mode: Word


@dataclass
class Offset(Node):
    factor: Expr
    units: Expr


@dataclass
class PassClear(Node):
    target: Name
    clear: ClearSpec


@dataclass
class RepeatPerLight(Node):
    light_types: list[Word] = field(default_factory=list)   # `repeat per light spot …`


@dataclass
class Fragment(Node):
    body: list[Stmt]


PassStmt = Union[Draw, Writes, Reads, Depth, Stencil, Blend, BlendConstant, Mask, Cull, Offset,
                 PassClear, RepeatPerLight, Fragment]


@dataclass
class PassDecl(Node):
    name: Name
    stmts: list[PassStmt]


@dataclass
class RepeatBlock(Node):
    """``repeat per light { pass … pass … }``: the passes run in sequence once per light."""

    passes: list[PassDecl]
    light_types: list[Word] = field(default_factory=list)   # `repeat per light spot … { … }`


Item = Union[TechniqueDecl, Include, ParamDecl, LightsDecl, TargetDecl, OutputDecl, PackDecl,
             FunctionDef, PassDecl, RepeatBlock]


@dataclass
class Module(Node):
    items: list[Item]
    filename: str
