"""The backend-neutral intermediate representation.

Frozen dataclasses (``records.record``) and enums only: no GL enums, no moderngl strings, no OpenCL types.  The front
end (``frontend/lower/``) builds it from the AST; compiler passes (``passes/``) rewrite it; backends
(``backends/``) turn it into text.  ``verify.py`` checks its invariants after every phase.

Spans (``Span``) are carried on user-visible objects so that later phases can still report
errors at the right place in the ``.pipe`` source.
"""

from __future__ import annotations

import enum
from dataclasses import field
from typing import Optional, Union

from pipegen.core.diagnostics import Span
from pipegen.core.formats import Format
from pipegen.core.records import record

# ---------------------------------------------------------------------------------------------
# Fixed-function state
# ---------------------------------------------------------------------------------------------


class CompareFunc(enum.Enum):
    NEVER = "never"
    LESS = "less"
    EQUAL = "equal"
    LEQUAL = "lequal"
    GREATER = "greater"
    NOTEQUAL = "notequal"
    GEQUAL = "gequal"
    ALWAYS = "always"


class StencilOp(enum.Enum):
    KEEP = "keep"
    ZERO = "zero"
    REPLACE = "replace"
    INCR = "incr"            # saturating
    DECR = "decr"            # saturating
    INCR_WRAP = "incr_wrap"
    DECR_WRAP = "decr_wrap"
    INVERT = "invert"


class BlendOp(enum.Enum):
    ADD = "add"
    SUB = "sub"              # src*sf - dst*df
    REVSUB = "revsub"        # dst*df - src*sf
    MIN = "min"              # factors ignored
    MAX = "max"              # factors ignored


class BlendFactor(enum.Enum):
    ZERO = "zero"
    ONE = "one"
    SRC_COLOR = "src_color"
    ONE_MINUS_SRC_COLOR = "one_minus_src_color"
    DST_COLOR = "dst_color"
    ONE_MINUS_DST_COLOR = "one_minus_dst_color"
    SRC_ALPHA = "src_alpha"
    ONE_MINUS_SRC_ALPHA = "one_minus_src_alpha"
    DST_ALPHA = "dst_alpha"
    ONE_MINUS_DST_ALPHA = "one_minus_dst_alpha"
    CONSTANT_COLOR = "constant_color"
    ONE_MINUS_CONSTANT_COLOR = "one_minus_constant_color"
    CONSTANT_ALPHA = "constant_alpha"
    ONE_MINUS_CONSTANT_ALPHA = "one_minus_constant_alpha"
    SRC_ALPHA_SATURATE = "src_alpha_saturate"


class CullMode(enum.Enum):
    NONE = "none"
    BACK = "back"
    FRONT = "front"
    # Light-volume draws only: per light, cull front faces (draw the back faces) when the
    # camera may be inside the light's volume or its near plane may cut it, else cull back
    # faces (``runtime.draws.volume_cull`` decides on the host).
    AUTO = "auto"


@record(frozen=True)
class DepthState:
    func: CompareFunc = CompareFunc.ALWAYS   # ALWAYS + write False == depth test off
    write: bool = False
    clamp: bool = False
    # `cull auto` passes: the test for the lights drawn with their back faces (None: ``func``)
    inside: Optional[CompareFunc] = None

    @property
    def enabled(self) -> bool:
        return self.func is not CompareFunc.ALWAYS or self.write


@record(frozen=True)
class StencilFace:
    func: CompareFunc = CompareFunc.ALWAYS
    ref: int = 0
    read_mask: int = 0xFF
    write_mask: int = 0xFF
    fail: StencilOp = StencilOp.KEEP     # stencil test fails
    zfail: StencilOp = StencilOp.KEEP    # stencil passes, depth fails
    zpass: StencilOp = StencilOp.KEEP    # both pass

    @property
    def is_noop(self) -> bool:
        return (self.func is CompareFunc.ALWAYS and self.fail is StencilOp.KEEP
                and self.zfail is StencilOp.KEEP and self.zpass is StencilOp.KEEP)


@record(frozen=True)
class StencilState:
    front: StencilFace = StencilFace()
    back: StencilFace = StencilFace()

    @property
    def enabled(self) -> bool:
        return not (self.front.is_noop and self.back.is_noop)


@record(frozen=True)
class BlendEquation:
    op: BlendOp = BlendOp.ADD
    src: BlendFactor = BlendFactor.ONE
    dst: BlendFactor = BlendFactor.ZERO


@record(frozen=True)
class TargetBlend:
    """Blend and write-mask state for one colour attachment of a pass."""

    enabled: bool = False
    rgb: BlendEquation = BlendEquation()
    alpha: BlendEquation = BlendEquation()
    write_mask: tuple[bool, bool, bool, bool] = (True, True, True, True)


@record(frozen=True)
class PolygonOffset:
    factor: float = 0.0
    units: float = 0.0


@record(frozen=True)
class PassState:
    depth: DepthState = DepthState()
    stencil: StencilState = StencilState()
    blend: tuple[tuple[str, TargetBlend], ...] = ()   # (target name, state) per colour output
    blend_constant: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    cull: CullMode = CullMode.NONE
    polygon_offset: Optional[PolygonOffset] = None

    def blend_for(self, target: str) -> TargetBlend:
        for name, b in self.blend:
            if name == target:
                return b
        return TargetBlend()


# ---------------------------------------------------------------------------------------------
# Types of the shader sub-language
# ---------------------------------------------------------------------------------------------


class Scalar(enum.Enum):
    FLOAT = "float"
    INT = "int"
    UINT = "uint"
    BOOL = "bool"


@record(frozen=True)
class Type:
    """A scalar, vector (``size`` 2–4) or square matrix (``mat`` 3 or 4) type, or void."""

    scalar: Optional[Scalar]   # None: void
    size: int = 1
    mat: int = 0

    @property
    def is_void(self) -> bool:
        return self.scalar is None

    @property
    def is_scalar(self) -> bool:
        return self.scalar is not None and self.size == 1 and not self.mat

    @property
    def is_vector(self) -> bool:
        return self.size > 1 and not self.mat

    @property
    def is_matrix(self) -> bool:
        return bool(self.mat)

    def with_size(self, n: int) -> "Type":
        return Type(self.scalar, n)

    @property
    def element(self) -> "Type":
        if self.mat:
            return Type(Scalar.FLOAT, self.mat)
        return Type(self.scalar)

    def __str__(self) -> str:  # the language's own spelling (also GLSL's)
        if self.scalar is None:
            return "void"
        if self.mat:
            return f"mat{self.mat}"
        if self.size == 1:
            return self.scalar.value
        prefix = {Scalar.FLOAT: "", Scalar.INT: "i", Scalar.UINT: "u", Scalar.BOOL: "b"}
        return f"{prefix[self.scalar]}vec{self.size}"


VOID = Type(None)
FLOAT, INT, UINT, BOOL = (Type(s) for s in (Scalar.FLOAT, Scalar.INT, Scalar.UINT, Scalar.BOOL))
VEC2, VEC3, VEC4 = Type(Scalar.FLOAT, 2), Type(Scalar.FLOAT, 3), Type(Scalar.FLOAT, 4)
IVEC2, UVEC4 = Type(Scalar.INT, 2), Type(Scalar.UINT, 4)
MAT3, MAT4 = Type(Scalar.FLOAT, 3, 3), Type(Scalar.FLOAT, 4, 4)


def parse_type(name: str) -> Optional[Type]:
    """The language's type names -> Type (None when ``name`` is not a type)."""
    scalars = {"float": FLOAT, "int": INT, "uint": UINT, "bool": BOOL, "void": VOID}
    if name in scalars:
        return scalars[name]
    if name in ("mat3", "mat4"):
        n = int(name[-1])
        return Type(Scalar.FLOAT, n, n)
    prefixes = {"vec": Scalar.FLOAT, "ivec": Scalar.INT, "uvec": Scalar.UINT, "bvec": Scalar.BOOL}
    for p, s in prefixes.items():
        if name.startswith(p) and name[len(p):] in ("2", "3", "4"):
            return Type(s, int(name[len(p):]))
    return None


# ---------------------------------------------------------------------------------------------
# Shader expressions and statements (typed; every node knows its type)
# ---------------------------------------------------------------------------------------------


@record(frozen=True)
class Const:
    type: Type
    value: Union[float, int, bool, tuple]   # tuple for vector constants


@record(frozen=True)
class Var:
    """A local, a function parameter, a parameter of the technique or a stage input.

    ``kind`` says which: "local", "param" (technique parameter, a uniform), "input" (a stage
    input such as ``world_pos`` or ``frag_coord``; see ``builtins.STAGE_INPUTS``).
    """

    name: str
    type: Type
    kind: str = "local"


@record(frozen=True)
class Unary:
    op: str          # "-", "!", "~"
    operand: "Expr"
    type: Type


@record(frozen=True)
class Binary:
    op: str          # + - * / % == != < <= > >= && || & | ^ << >>
    left: "Expr"
    right: "Expr"
    type: Type
    span: Optional[Span] = field(default=None, compare=False, repr=False)


@record(frozen=True)
class Ternary:
    cond: "Expr"
    then: "Expr"
    other: "Expr"
    type: Type


@record(frozen=True)
class Call:
    """A builtin (``builtin=True``, name from ``builtins.BUILTINS``) or user function call."""

    name: str
    args: tuple["Expr", ...]
    type: Type
    builtin: bool = True
    span: Optional[Span] = field(default=None, compare=False, repr=False)


@record(frozen=True)
class Construct:
    """``vec3(x)``, ``vec4(v.xyz, 1.0)``, ``uint(f)``: a type constructor or conversion."""

    type: Type
    args: tuple["Expr", ...]
    span: Optional[Span] = field(default=None, compare=False, repr=False)


@record(frozen=True)
class Swizzle:
    base: "Expr"
    components: str   # over "xyzw"; the front end normalises rgba/stpq to xyzw
    type: Type


@record(frozen=True)
class Index:
    base: "Expr"      # vector or matrix (array of vectors)
    index: "Expr"
    type: Type


@record(frozen=True)
class LightField:
    """``lights[i].radius`` / ``light.radius``: one field of the light table.

    ``index`` is None for the light a light-volume pass (or ``repeat per light`` pass) is
    drawing; otherwise a uint/int expression indexing the light table.
    """

    index: Optional["Expr"]
    field: str
    type: Type


@record(frozen=True)
class MaterialField:
    """``material.model`` / ``materials[id].model``: one field of the material table, the
    record of object ``index`` (a uint/int object id; ``material`` is the drawn object's)."""

    index: "Expr"
    field: str
    type: Type


@record(frozen=True)
class Load:
    """Texel fetch of a target (``load(t)`` at this pixel, ``load(t, ivec2)`` elsewhere).

    The result type is the target's read type (vec4 for unorm/float, uvec4 for uint, float
    for depth); values are what the shader would read (unorm decoded to [0,1]).  ``sample``
    (an int; ``load_sample(t, s)``, ``load_sample(t, ivec2, s)``): sample ``s`` of a
    multisampled colour target itself; without it a multisampled target reads its resolve.
    """

    target: str
    coord: Optional["Expr"]
    type: Type
    sample: Optional["Expr"] = None


@record(frozen=True)
class Sample:
    """Bilinear sample of a target at normalised coordinates (clamp to edge)."""

    target: str
    uv: "Expr"
    type: Type


@record(frozen=True)
class TargetSize:
    """``size(t)``: the target's size in pixels as ivec2."""

    target: str
    type: Type


Expr = Union[Const, Var, Unary, Binary, Ternary, Call, Construct, Swizzle, Index, LightField,
             MaterialField, Load, Sample, TargetSize]


@record(frozen=True)
class Declare:
    name: str
    type: Type
    init: Optional[Expr]


@record(frozen=True)
class Assign:
    """``target op= value``; ``target`` is a Var, Swizzle-of-Var or Index-of-Var."""

    target: Expr
    op: str           # "=", "+=", "-=", "*=", "/="
    value: Expr


@record(frozen=True)
class Output:
    """Write of a colour target from a fragment body (``color = vec4(...)``).

    ``value`` already has the target's write type (vec4/uvec4, widened by the front end).
    """

    target: str
    value: Expr
    span: Optional[Span] = field(default=None, compare=False)


@record(frozen=True)
class If:
    cond: Expr
    then: tuple["Stmt", ...]
    other: tuple["Stmt", ...] = ()


@record(frozen=True)
class For:
    """``for (int i = start; i < bound; i++)``: bounded loops only (``bound`` constant after
    parameter folding, ``step`` +1)."""

    var: str
    type: Type
    start: Expr
    bound: Expr
    body: tuple["Stmt", ...]


@record(frozen=True)
class Break:
    pass


@record(frozen=True)
class Continue:
    pass


@record(frozen=True)
class Return:
    value: Optional[Expr]


@record(frozen=True)
class Discard:
    pass


@record(frozen=True)
class ExprStmt:
    expr: Expr


Stmt = Union[Declare, Assign, Output, If, For, Break, Continue, Return, Discard, ExprStmt]


@record(frozen=True)
class Function:
    """A user function (also the functions generated by packing schemes)."""

    name: str
    params: tuple[tuple[str, Type], ...]
    ret: Type
    body: tuple[Stmt, ...]
    span: Optional[Span] = field(default=None, compare=False)


# ---------------------------------------------------------------------------------------------
# Technique structure
# ---------------------------------------------------------------------------------------------


@record(frozen=True)
class Param:
    name: str
    type: Type
    default: Union[float, int, bool, str]
    allowed: tuple = ()        # empty: any value of the type
    span: Optional[Span] = field(default=None, compare=False)
    # `accurate VALUE`: the value that gives the most accurate image (the `self` reference,
    # pipegen/proof/references.py, evaluates the technique there); None: not declared
    accurate: Union[float, int, bool, str, None] = None


@record(frozen=True)
class Size:
    """Absolute (``width``/``height``) or relative to the output (``scale``) size."""

    scale: float = 1.0
    width: int = 0
    height: int = 0

    @property
    def relative(self) -> bool:
        return self.width == 0

    def resolve(self, out_w: int, out_h: int) -> tuple[int, int]:
        if not self.relative:
            return self.width, self.height
        return max(1, int(out_w * self.scale + 0.5)), max(1, int(out_h * self.scale + 0.5))


@record(frozen=True)
class Clear:
    color: Optional[tuple[float, float, float, float]] = None   # colour targets
    depth: Optional[float] = None
    stencil: Optional[int] = None


@record(frozen=True)
class Target:
    name: str
    format: Format
    size: Size = Size()
    samples: int = 1
    clear: Clear = Clear()
    span: Optional[Span] = field(default=None, compare=False)


@record(frozen=True)
class LightAttr:
    name: str
    type: Type


@record(frozen=True)
class LightTable:
    """The light table schema: which fields every light record has, and the capacity."""

    fields: tuple[LightAttr, ...]
    capacity: int
    span: Optional[Span] = field(default=None, compare=False)

    def field_type(self, name: str) -> Optional[Type]:
        for f in self.fields:
            if f.name == name:
                return f.type
        return None


@record(frozen=True)
class MaterialAttr:
    """A material field a scene object may set: its type and its default, as floats (one per
    component; a uint/int/bool field's value is stored as its integer value)."""

    name: str
    type: Type
    default: tuple[float, ...]


@record(frozen=True)
class MaterialTable:
    """The material schema (``material { … }``): one record per object id, laid out like the
    light table's records (``ir/light_layout.py``) and stored after the lights in its table."""

    fields: tuple[MaterialAttr, ...]
    span: Optional[Span] = field(default=None, compare=False)

    def field_type(self, name: str) -> Optional[Type]:
        return next((f.type for f in self.fields if f.name == name), None)


class DrawKind(enum.Enum):
    SCENE = "scene"              # scene geometry (filtered by material flags)
    LIGHTS = "lights"            # one light volume per light
    FULLSCREEN = "fullscreen"    # one full-screen triangle


class Volume(enum.Enum):
    SPHERE = "sphere"            # mesh circumscribing the light's radius
    CONE = "cone"                # spot-light cone
    QUAD = "quad"                # screen-aligned quad covering the light's screen bounds


class DrawOrder(enum.Enum):
    SCENE = "scene"                  # objects in scene order
    BACK_TO_FRONT = "back_to_front"  # farthest object first (view depth of its bounds centre)


@record(frozen=True)
class Draw:
    kind: DrawKind
    material: tuple[str, ...] = ()      # SCENE: required material flags ("opaque", "translucent")
    volume: Optional[Volume] = None     # LIGHTS
    light_types: tuple[str, ...] = ()   # LIGHTS: which light types ("point", "spot", ...); () all
    light_set: Optional[tuple[str, int]] = None  # LIGHTS: (channel_slots pack, slot k)
    scissor: bool = False               # LIGHTS: rasterise only inside the light's screen rect
    order: DrawOrder = DrawOrder.SCENE  # SCENE: object order (runtime/draws.scene_order)
    # SCENE ``from lights TYPES tiles N``: a shadow-map draw, the scene from each shadow-casting
    # light of ``light_types`` into its tile of an N x N atlas (pipegen/scene/shadows.py); 0: not one
    shadow_tiles: int = 0
    # ``first K``: only light indices 0..K-1 may cast (lights after them are drawn unshadowed,
    # runtime/common.scene_as_drawn; compiler/mismatches names them); 0: every index may
    shadow_first: int = 0
    # SCENE ``shadow_volumes``: the stencil shadow volumes of the objects (material filter as
    # above) from the pass's light, in a ``repeat per light`` pass (pipegen/scene/shadow_volumes.py)
    shadow_volumes: bool = False
    # SCENE ``within light radius``, in a ``repeat per light`` pass: each light's draw submits
    # only the objects whose bounds come within its radius (a directional light: every object),
    # the multi-pass forward renderer's object-light selection (Trebilco 2007 lists it against
    # multi-pass: "Object->Light interactions ... calculated on the CPU").  The pass's output
    # must add nothing beyond the radius (the shipped attenuation is 0 there): the objects left
    # out would only have added zeros (runtime/draws.py's reach_table)
    within: bool = False

    @property
    def shadow(self) -> bool:
        """A shadow-map draw: the scene seen from each shadow-casting light."""
        return self.shadow_tiles > 0

    def describe(self) -> str:
        """The draw as the language spells it (for reports and shader header comments)."""
        if self.kind is DrawKind.SCENE:
            return "scene" + "".join("." + m for m in self.material) + (
                " back_to_front" if self.order is DrawOrder.BACK_TO_FRONT else "") + (
                " from lights " + " ".join(self.light_types) +
                (f" first {self.shadow_first}" if self.shadow_first else "") +
                f" tiles {self.shadow_tiles}" if self.shadow else "") + (
                " shadow_volumes" if self.shadow_volumes else "") + (
                " within light radius" if self.within else "")
        if self.kind is DrawKind.LIGHTS:
            text = f"lights as {(self.volume or Volume.SPHERE).value}"
            if self.light_types:
                text += " " + " ".join(self.light_types)
            if self.light_set:
                text += f" in {self.light_set[0]}[{self.light_set[1]}]"
            return text + (" scissor" if self.scissor else "")
        return "fullscreen"


@record(frozen=True)
class Pass:
    name: str
    draw: Draw
    state: PassState
    writes: tuple[str, ...]             # colour targets written (in attachment order)
    reads: tuple[str, ...]              # targets read with load/sample
    depth_target: Optional[str]         # the depth(/stencil) attachment, if any
    body: tuple[Stmt, ...]              # fragment body; empty: depth/stencil only
    repeat_group: Optional[int] = None  # consecutive passes sharing a group repeat per light
    clears: tuple[tuple[str, Clear], ...] = ()   # targets cleared before this pass draws
    span: Optional[Span] = field(default=None, compare=False)
    repeat_types: tuple[str, ...] = ()  # repeat only for lights of these types; () all

    @property
    def repeat_per_light(self) -> bool:
        return self.repeat_group is not None


@record(frozen=True)
class Packing:
    """A packing scheme: generated functions plus its static properties.

    ``scheme`` names the kind (``bitplanes``, ``max_pairs``, ``channel_slots``, ``split16``,
    ``bitfield``, ``kircher``, ``spheremap``, ``octahedral``); ``options`` are its arguments;
    ``functions`` are the pack/unpack functions it generates (named ``<pack>_<fn>``);
    ``capacity`` (light-index schemes) and ``error`` (quantisation bound) feed the report.
    """

    name: str
    scheme: str
    options: tuple[tuple[str, object], ...]
    functions: tuple[Function, ...]
    constants: tuple[tuple[str, Const], ...] = ()   # e.g. slots.capacity
    capacity: Optional[int] = None
    error: Optional[float] = None
    notes: tuple[str, ...] = ()
    span: Optional[Span] = field(default=None, compare=False)


@record(frozen=True)
class SceneFacts:
    """What a scene-specialised technique assumes of every scene it renders (``scene/features.py``
    computes them; the runtimes refuse a scene that breaks one).  Set by the ``assume_scene``
    phase; the scene passes read them."""

    light_types: tuple[str, ...]        # the light types present ("point", "spot", ...)
    lights: int                         # the most lights a scene may have
    translucent: bool                   # whether any object is translucent
    opaque: bool = True                 # whether any object is opaque
    shadows: bool = True                # whether any light casts shadows (``shadows = true``)

    def describe(self) -> str:
        types = ", ".join(self.light_types) or "no lights"
        return (f"{types}; at most {self.lights} lights; "
                f"{'translucent objects' if self.translucent else 'nothing translucent'}"
                + ("" if self.shadows else "; no shadows"))


@record(frozen=True)
class Cut:
    """Something scene specialisation removed, and why: ``kind`` is "pass", "target",
    "branch" or "table"; ``reason`` names the scene fact or the earlier cut it follows from."""

    kind: str
    name: str
    reason: str
    reads: tuple[str, ...] = ()         # a culled pass: the targets it read (for later reasons)

    def describe(self) -> str:
        verb = {"pass": "culled", "target": "culled", "table": "shrunk"}.get(self.kind,
                                                                             "removed")
        return f"{self.kind} `{self.name}` {verb}: {self.reason}"


@record(frozen=True)
class Expectation:
    """An ``expect`` statement (docs/language.md, Expectations): what ``pipegen test`` and the
    pytest plugin check of the technique (``testing/expectations.py``).  Never emitted.

    ``check``: "agrees" (``subject``, a target, rendered on each backend of ``against``
    agrees within the derived tolerance), "vs" (each float32 backend against the float64
    evaluation, ``against == ("f64",)``) or "count" (``subject`` one of ``COUNTS``).
    ``statistic``/``op``/``value``: the bound (``p99 <= 2``; a count: ``op`` and ``value``);
    ``statistic`` None: the derived tolerance, no discontinuity.  ``scene``: a path (relative
    paths resolved against the .pipe file's folder), None for the built-in scene; ``size``:
    None for the scene's own (the built-in scene: ``pipegen.testing``'s ``TEST_SIZE``)."""

    BACKENDS = ("gl", "cl")
    REFERENCES = ("f64",)
    #: |a - b| in the target's units (codes for fixed point, values for float): the largest,
    #: percentiles, the root mean square; pixels beyond the derived bound that are (not)
    #: discontinuities
    STATISTICS = ("max", "p50", "p90", "p95", "p99", "p99.9", "rmse", "discontinuities", "over")
    #: lights no light set of a packing takes (whole lights, unlit); what the technique will
    #: not render of the scene (``Compiled.mismatches``)
    COUNTS = ("lights_dropped", "mismatches")

    subject: str
    check: str
    against: tuple[str, ...] = ()
    statistic: Optional[str] = None
    op: Optional[str] = None
    value: Optional[float] = None
    scene: Optional[str] = None
    size: Optional[tuple[int, int]] = None
    text: str = ""                      # as written after `expect`
    span: Optional[Span] = field(default=None, compare=False)


@record(frozen=True)
class Technique:
    name: str
    title: str
    params: tuple[Param, ...]
    targets: tuple[Target, ...]
    lights: LightTable
    packings: tuple[Packing, ...]
    functions: tuple[Function, ...]     # user functions (packing functions live in packings)
    passes: tuple[Pass, ...]
    output: str                         # the target that is the technique's final image
    source: str = ""                    # path of the .pipe file
    scene: Optional[SceneFacts] = None  # scene specialisation: what every scene must satisfy
    cuts: tuple[Cut, ...] = ()          # what scene specialisation removed, with reasons
    expectations: tuple[Expectation, ...] = ()   # `expect` statements (never emitted)
    materials: Optional[MaterialTable] = None    # `material { … }`: per-object fields

    def target(self, name: str) -> Target:
        for t in self.targets:
            if t.name == name:
                return t
        raise KeyError(name)

    def all_functions(self) -> tuple[Function, ...]:
        """Packing functions first (user code may call them), then user functions."""
        return tuple(f for p in self.packings for f in p.functions) + self.functions
