"""The shader language's built-in vocabulary and typing rules.

- ``BUILTINS``: builtin functions with GLSL-style overloads (``genType`` = float, vec2, vec3,
  vec4; ``genIType`` / ``genUType`` the int / uint counterparts).  Arguments must match exactly:
  the language has no implicit conversions.
- ``STAGE_INPUTS``: the values a fragment body can read by name, and where they exist.
- ``LIGHT_FIELDS``: the light-table fields a ``lights[N] { … }`` schema may declare.
- ``TARGET_FUNCTIONS``: ``load`` / ``sample`` / ``size`` whose first argument names a target.
- ``unary_type`` / ``binary_type`` / ``construct_error``: operator and constructor rules, shared
  by the front end (which reports violations) and the IR verifier (which asserts them).
"""

from __future__ import annotations

import enum
from typing import Optional, Sequence

from pipegen.core.records import record
from pipegen.ir import nodes as ir
from pipegen.core.formats import Format

# ---------------------------------------------------------------------------------------------
# Builtin functions
# ---------------------------------------------------------------------------------------------

_GENERIC = {"genType": ir.Scalar.FLOAT, "genIType": ir.Scalar.INT, "genUType": ir.Scalar.UINT}


@record(frozen=True)
class Overload:
    """One signature. Parameter/return spellings are type names or a generic ``gen*Type``;
    every generic in one overload stands for the same type (sizes 1–4)."""

    params: tuple[str, ...]
    ret: str

    def match(self, args: Sequence[ir.Type]) -> Optional[ir.Type]:
        """The result type when ``args`` fit this signature exactly, else None.  Different
        generics in one overload (``genType -> genUType``) share the size."""
        if len(args) != len(self.params):
            return None
        size: Optional[int] = None
        for spelled, actual in zip(self.params, args):
            if spelled in _GENERIC:
                if actual.scalar is not _GENERIC[spelled] or actual.is_matrix:
                    return None
                if size is not None and size != actual.size:
                    return None
                size = actual.size
            elif ir.parse_type(spelled) != actual:
                return None
        if self.ret in _GENERIC:
            return ir.Type(_GENERIC[self.ret], size) if size > 1 else ir.Type(_GENERIC[self.ret])
        return ir.parse_type(self.ret)

    def __str__(self) -> str:
        return f"({', '.join(self.params)}) -> {self.ret}"


def _sigs(*specs: str) -> tuple[Overload, ...]:
    """``"genType, float -> genType"`` -> Overload(("genType", "float"), "genType")."""
    out = []
    for spec in specs:
        params, ret = spec.split("->")
        out.append(Overload(tuple(p.strip() for p in params.split(",") if p.strip()),
                            ret.strip()))
    return tuple(out)


_F1 = _sigs("genType -> genType")
_MINMAX = _sigs("genType, genType -> genType", "genType, float -> genType",
                "genIType, genIType -> genIType", "genIType, int -> genIType",
                "genUType, genUType -> genUType", "genUType, uint -> genUType")
_CLAMP = _sigs("genType, genType, genType -> genType", "genType, float, float -> genType",
               "genIType, genIType, genIType -> genIType", "genIType, int, int -> genIType",
               "genUType, genUType, genUType -> genUType", "genUType, uint, uint -> genUType")

BUILTINS: dict[str, tuple[Overload, ...]] = {
    **{name: _F1 for name in ("normalize", "exp", "exp2", "log", "log2", "sqrt", "inversesqrt",
                              "floor", "ceil", "round", "fract", "sin", "cos", "tan")},
    "abs": _sigs("genType -> genType", "genIType -> genIType"),
    "sign": _sigs("genType -> genType", "genIType -> genIType"),
    "atan": _sigs("genType -> genType", "genType, genType -> genType"),
    "pow": _sigs("genType, genType -> genType"),
    "mod": _sigs("genType, genType -> genType", "genType, float -> genType"),
    "min": _MINMAX,
    "max": _MINMAX,
    "clamp": _CLAMP,
    "mix": _sigs("genType, genType, genType -> genType", "genType, genType, float -> genType"),
    "step": _sigs("genType, genType -> genType", "float, genType -> genType"),
    "smoothstep": _sigs("genType, genType, genType -> genType",
                        "float, float, genType -> genType"),
    "length": _sigs("genType -> float"),
    "distance": _sigs("genType, genType -> float"),
    "dot": _sigs("genType, genType -> float"),
    "cross": _sigs("vec3, vec3 -> vec3"),
    # bit casts (the float32 bits; in the float64 evaluation the value rounded to float32
    # first) and half packing (GLSL 4.20 / ARB_shading_language_packing: round to nearest
    # even, llvmpipe's NaN codes; docs/language.md, "Bit casts and half packing")
    "floatBitsToUint": _sigs("genType -> genUType"),
    "floatBitsToInt": _sigs("genType -> genIType"),
    "uintBitsToFloat": _sigs("genUType -> genType"),
    "intBitsToFloat": _sigs("genIType -> genType"),
    "packHalf2x16": _sigs("vec2 -> uint"),
    "unpackHalf2x16": _sigs("uint -> vec2"),
}

# Builtins whose float arguments or results are bit patterns: the float64 evaluation rounds
# their float arguments to float32 and widens their float results (docs/internals.md).
BIT_CAST_BUILTINS = frozenset({"floatBitsToUint", "floatBitsToInt", "uintBitsToFloat",
                               "intBitsToFloat", "packHalf2x16", "unpackHalf2x16"})


def resolve_builtin(name: str, args: Sequence[ir.Type]) -> Optional[ir.Type]:
    """Result type of builtin ``name`` applied to ``args``; None when no overload fits."""
    for overload in BUILTINS.get(name, ()):
        result = overload.match(args)
        if result is not None:
            return result
    return None


# Functions whose first argument is a render target (typed by the front end from its format).
TARGET_FUNCTIONS: dict[str, str] = {
    "load": "load(T) / load(T, ivec2): texel of T at this pixel / at a pixel",
    "load_sample": "load_sample(T, int s) / load_sample(T, ivec2, int s): sample s of "
                   "multisampled T at this pixel / at a pixel",
    "sample": "sample(T, vec2 uv): bilinear sample of T, clamped to the edge",
    "size": "size(T) -> ivec2: T's size in pixels",
}


def target_read_type(fmt: Format) -> ir.Type:
    """What ``load``/``sample`` of a target return: vec4 (unorm/float), uvec4 (uint), float
    (depth)."""
    if fmt.has_depth:
        return ir.FLOAT
    return ir.UVEC4 if fmt.is_integer else ir.VEC4


def target_write_type(fmt: Format) -> ir.Type:
    """The type of ``ir.Output.value`` for a colour target (the front end widens to it)."""
    return ir.UVEC4 if fmt.is_integer else ir.VEC4


# ---------------------------------------------------------------------------------------------
# Stage inputs and the light table
# ---------------------------------------------------------------------------------------------


class Where(enum.Enum):
    EVERYWHERE = "everywhere"
    SCENE = "scene draws"                       # interpolated from scene geometry
    LIGHT = "light draws and repeat per light"  # the light being drawn


@record(frozen=True)
class StageInput:
    name: str
    type: ir.Type
    where: Where


def _inputs(where: Where, type_: ir.Type, *names: str) -> dict[str, StageInput]:
    return {n: StageInput(n, type_, where) for n in names}


STAGE_INPUTS: dict[str, StageInput] = {
    **_inputs(Where.EVERYWHERE, ir.VEC4, "frag_coord"),
    **_inputs(Where.EVERYWHERE, ir.VEC3, "camera_pos", "ambient"),
    **_inputs(Where.EVERYWHERE, ir.MAT4, "view", "proj", "inv_view", "inv_proj"),
    # the previous frame's camera (Scene.prev_camera): motion vectors
    **_inputs(Where.EVERYWHERE, ir.MAT4, "prev_view", "prev_proj"),
    **_inputs(Where.EVERYWHERE, ir.VEC2, "output_size"),
    **_inputs(Where.EVERYWHERE, ir.UINT, "num_lights"),
    # the sample being shaded (GL's gl_SampleID): reading it makes the pass run once per
    # covered sample, frag_coord and the scene inputs at that sample (multisampled passes)
    **_inputs(Where.EVERYWHERE, ir.INT, "sample_id"),
    # the fragment's coverage (GL's gl_SampleMaskIn[0]): bit k set when sample k of the pixel
    # is covered (and passed the early tests); all 1 bit on a single-sampled pass
    **_inputs(Where.EVERYWHERE, ir.UINT, "sample_mask"),
    **_inputs(Where.SCENE, ir.VEC3, "world_pos", "view_pos", "normal", "view_normal", "albedo"),
    **_inputs(Where.SCENE, ir.FLOAT, "specular", "shininess", "alpha"),
    **_inputs(Where.SCENE, ir.UINT, "object_id", "normal_group", "layer"),
}

#: Scene inputs constant over an object (its material, ids and stipple layer): both backends
#: pass them flat, the provoking vertex's value, so that no interpolation noise rounds a value
#: sitting on a unorm tie (albedo 0.7 = code 178.5) one way on llvmpipe and the other on CL.
#: The other scene inputs are interpolated perspective-correctly.
FLAT_SCENE_INPUTS = frozenset({"albedo", "specular", "shininess", "alpha", "object_id",
                               "normal_group", "layer"})

# Stage inputs a backend passes only to the passes that read them (so adding them changed no
# other shader): the previous frame's camera.
PREVIOUS_FRAME_INPUTS = ("prev_view", "prev_proj")

# The run-time nudges of the discontinuity search (proof/discontinuity.py): ``nudge[k]``, the
# amount step site ``k`` is moved by in this render, 0 for a site left alone.  Never written
# by a user (not in STAGE_INPUTS); only the float64 evaluation's CL programs read them, from a
# buffer the runtime fills before each render, so one program serves every nudge.
NUDGE_INPUT = "nudge"


def nudge_input(k: int) -> str:
    """The stage input name of site ``k``'s nudge."""
    return f"{NUDGE_INPUT}[{int(k)}]"


def nudge_site(name: str) -> Optional[int]:
    """The site index of a ``nudge_input`` name, else None."""
    if name.startswith(NUDGE_INPUT + "[") and name.endswith("]"):
        return int(name[len(NUDGE_INPUT) + 1:-1])
    return None


def reads_nudges(inputs) -> bool:
    """Whether code reading the stage inputs ``inputs`` reads a run-time nudge."""
    return any(nudge_site(n) is not None for n in inputs)

# ``light.FIELD`` (where: Where.LIGHT) and ``lights[i].FIELD`` (everywhere) read these fields.
# A schema lists the ones a technique uses; the scene loader fills them per light.
LIGHT_FIELDS: dict[str, ir.Type] = {
    "position": ir.VEC3,
    "radius": ir.FLOAT,
    "color": ir.VEC3,
    "direction": ir.VEC3,
    "type": ir.UINT,            # 0 point, 1 spot, 2 directional
    "cos_inner": ir.FLOAT,
    "cos_outer": ir.FLOAT,
    "shadow_tile": ir.FLOAT,    # the light's shadow-atlas tile, -1: it casts no shadow
    "shadow_m0": ir.VEC4,       # rows of the light's shadow projection @ view (shadows.py)
    "shadow_m1": ir.VEC4,
    "shadow_m2": ir.VEC4,
    "shadow_m3": ir.VEC4,
}

# ``light.index``: the 0-based table index of the light being drawn.  Lowered to
# ``ir.LightField(None, "index", uint)``; it is not a table field.
LIGHT_INDEX = "index"
LIGHT_TYPES = ("point", "spot", "directional")

# The light fields each light volume's vertex stage places the volume with: a pass drawing a
# volume needs them in the light schema (both backends read this table).
VOLUME_LIGHT_FIELDS: dict[str, tuple[str, ...]] = {
    "sphere": ("position", "radius"),
    "quad": ("position", "radius"),
    "cone": ("position", "radius", "direction", "cos_outer"),
}

TYPE_NAMES = ("void", "float", "int", "uint", "bool", "vec2", "vec3", "vec4", "ivec2", "ivec3",
              "ivec4", "uvec2", "uvec3", "uvec4", "bvec2", "bvec3", "bvec4", "mat3", "mat4")

# ---------------------------------------------------------------------------------------------
# Operators (GLSL rules without implicit conversions)
# ---------------------------------------------------------------------------------------------

ARITHMETIC = ("+", "-", "*", "/")
BITWISE = ("&", "|", "^")
SHIFTS = ("<<", ">>")
ORDERING = ("<", "<=", ">", ">=")
EQUALITY = ("==", "!=")
LOGICAL = ("&&", "||")
BINARY_OPS = ARITHMETIC + ("%",) + BITWISE + SHIFTS + ORDERING + EQUALITY + LOGICAL

_INTEGER = (ir.Scalar.INT, ir.Scalar.UINT)
_NUMERIC = (ir.Scalar.FLOAT, ir.Scalar.INT, ir.Scalar.UINT)


def unary_type(op: str, t: ir.Type) -> Optional[ir.Type]:
    if op in ("-", "+"):
        return t if t.scalar in _NUMERIC else None
    if op == "!":
        return t if t == ir.BOOL else None
    if op == "~":
        return t if t.scalar in _INTEGER and not t.is_matrix else None
    return None


def binary_type(op: str, a: ir.Type, b: ir.Type) -> Optional[ir.Type]:
    """Result type of ``a op b``, or None when GLSL (without conversions) rejects it."""
    if a.is_void or b.is_void:
        return None
    if op in LOGICAL:
        return ir.BOOL if a == b == ir.BOOL else None
    if op in EQUALITY:
        return ir.BOOL if a == b else None
    if op in ORDERING:
        return ir.BOOL if a == b and a.is_scalar and a.scalar in _NUMERIC else None
    if op in SHIFTS:
        # The shift count may be int or uint whatever the shifted type (GLSL 4.x rule).
        if a.scalar not in _INTEGER or b.scalar not in _INTEGER or a.is_matrix or b.is_matrix:
            return None
        return a if b.is_scalar or b.size == a.size else None
    if op in BITWISE or op == "%":
        if a.scalar not in _INTEGER or a.is_matrix or b.is_matrix:
            return None
        return _componentwise(a, b)
    if op in ARITHMETIC:
        if a.scalar not in _NUMERIC or b.scalar not in _NUMERIC:
            return None
        if a.is_matrix or b.is_matrix:
            return _matrix_arith(op, a, b)
        return _componentwise(a, b)
    return None


def _componentwise(a: ir.Type, b: ir.Type) -> Optional[ir.Type]:
    """Same type, or a scalar with a vector of its scalar type."""
    if a.scalar is not b.scalar:
        return None
    if a == b:
        return a
    if a.is_scalar:
        return b
    if b.is_scalar:
        return a
    return None


def _matrix_arith(op: str, a: ir.Type, b: ir.Type) -> Optional[ir.Type]:
    if a.scalar is not ir.Scalar.FLOAT or b.scalar is not ir.Scalar.FLOAT:
        return None
    if a == b:
        return a                                    # component-wise, or mat * mat
    if a.is_matrix and b.is_scalar or a.is_scalar and b.is_matrix:
        return a if a.is_matrix else b
    if op == "*" and a.is_matrix and b.is_vector and b.size == a.mat:
        return b                                    # mat * column vector
    if op == "*" and a.is_vector and b.is_matrix and a.size == b.mat:
        return a                                    # row vector * mat
    return None


# ---------------------------------------------------------------------------------------------
# Constructors in the IR's normal form
# ---------------------------------------------------------------------------------------------


def construct_error(t: ir.Type, args: Sequence[ir.Type]) -> Optional[str]:
    """Why ``Construct(t, args)`` is not in normal form (None when it is).

    The front end rewrites every constructor the user writes into one of these shapes, so the
    backends need not know GLSL's conversion rules:

    - ``scalar(s)``: conversion between any two scalar types;
    - ``vecN(s)``: broadcast of a scalar of the vector's scalar type;
    - ``vecN(v)``: element-wise conversion of a vector of the same size (any scalar type);
    - ``vecN(a, b, …)`` (2+ args): scalars/vectors of the vector's scalar type, N components;
    - ``matN(f)``: diagonal from a float; ``matN(c0, …)``: N float column vectors of size N;
      ``matN(m)``: from a matrix of another size (upper-left part, identity-extended).
    """
    if t.is_void or not args:
        return f"{t} takes at least one argument"
    if any(a.is_void for a in args):
        return "void value"
    if t.is_scalar:
        if len(args) == 1 and args[0].is_scalar:
            return None
        return f"{t}(…) converts exactly one scalar"
    if t.is_matrix:
        return _matrix_construct_error(t, args)
    if len(args) == 1:
        a = args[0]
        if a.is_scalar and a.scalar is t.scalar:
            return None
        if a.is_vector and a.size == t.size:
            return None
        return f"{t}(…) of one {a} is not a broadcast or a conversion"
    if any(a.is_matrix or a.scalar is not t.scalar for a in args):
        return f"arguments of {t}(…) must be {t.element} scalars or vectors"
    if sum(a.size for a in args) != t.size:
        return f"{t}(…) needs {t.size} components"
    return None


def _matrix_construct_error(t: ir.Type, args: Sequence[ir.Type]) -> Optional[str]:
    n = t.mat
    if len(args) == 1 and (args[0] == ir.FLOAT or (args[0].is_matrix and args[0] != t)):
        return None
    if len(args) == n and all(a == ir.Type(ir.Scalar.FLOAT, n) for a in args):
        return None
    return f"{t}(…) takes a float, another matrix, or {n} vec{n} columns"


def describe_overloads(name: str) -> str:
    """``clamp(genType, genType, genType), clamp(genType, float, float), …`` for messages."""
    return ", ".join(f"{name}({', '.join(o.params)})" for o in BUILTINS.get(name, ()))
