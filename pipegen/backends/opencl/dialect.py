"""The OpenCL C dialect of the shared C-style emitter (``cstyle.CStyleLanguage``): type names,
reserved words, the stage inputs' spellings, the builtins routed to the prelude's functions
(``templates/cl_prelude.cl.j2``: llvmpipe's evaluation order, see the package docstring), the
bit-cast helpers a program takes only when it uses them, and the float64 evaluation's dialect
(``precision="f64"``).  Data plus a few hooks; the expressions are ``cstyle``'s."""

from __future__ import annotations

import math
import re
from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.ir.light_layout import table_layout
from pipegen.ir.nodes import Scalar, Type
from pipegen.ir.builtins import BIT_CAST_BUILTINS, nudge_site
from pipegen.passes import lower_mix_constant
from pipegen.backends.cstyle import CStyleLanguage, texel_select

_T = ir.Type
_TYPE_NAMES = {ir.VOID: "void", ir.MAT3: "pg_mat3", ir.MAT4: "pg_mat4"}
for _s, _n in ((Scalar.FLOAT, "float"), (Scalar.INT, "int"), (Scalar.UINT, "uint")):
    _TYPE_NAMES[_T(_s)] = _n
    for _k in (2, 3, 4):
        _TYPE_NAMES[_T(_s, _k)] = f"{_n}{_k}"
_TYPE_NAMES[ir.BOOL] = "bool"
for _k in (2, 3, 4):
    _TYPE_NAMES[_T(Scalar.BOOL, _k)] = f"int{_k}"     # OpenCL relational results: -1 / 0

CL_RESERVED = frozenset("""
    auto break case char const continue default do double else enum extern float for goto if
    inline int long register restrict return short signed sizeof static struct switch typedef
    union unsigned void volatile while bool half uchar ushort uint ulong size_t ptrdiff_t
    intptr_t uintptr_t true false kernel __kernel global __global local __local constant
    __constant private __private read_only write_only read_write image2d_t image3d_t sampler_t
    event_t in out
    float2 float3 float4 float8 float16 int2 int3 int4 uint2 uint3 uint4 char2 char4 uchar2
    uchar4 short2 short4 ushort2 ushort4 long2 long4 ulong2 ulong4 double2 double4 bool2 bool4
    dot cross normalize length distance clamp mix step smoothstep pow exp exp2 log log2 sqrt
    rsqrt min max fmin fmax fabs abs sign floor ceil rint round fract fmod sin cos tan atan
    atan2 select all any convert_float convert_int convert_uint as_float as_uint as_int
    isnan isinf isless isgreater copysign vload_half vstore_half
""".split())

# stage input -> OpenCL expression (``in`` is the fragment context, see cl_pass.cl.j2), the
# frame's values through its pointer
_FRAME_INPUTS = {
    "frag_coord": "in->frag_coord", "camera_pos": "in->frame->camera_pos.xyz",
    "view": "in->frame->view", "proj": "in->frame->proj", "inv_view": "in->frame->inv_view",
    "inv_proj": "in->frame->inv_proj", "output_size": "in->frame->output_size.xy",
    "prev_view": "in->frame->prev_view", "prev_proj": "in->frame->prev_proj",
    "num_lights": "in->frame->num_lights", "ambient": "in->frame->ambient.xyz",
    "light_index": "in->light",
}
# float32: the frame's vectors from ``in`` (loaded once by the raster kernel, cl_pass.cl.j2)
INPUTS = {**_FRAME_INPUTS, "camera_pos": "in->camera_pos", "ambient": "in->ambient"}

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


# ---- bit casts and half packing --------------------------------------------------------------
#
# ``packHalf2x16`` / ``unpackHalf2x16`` as llvmpipe computes them (measured on Mesa 22.3,
# tests/test_bitcasts.py; docs/language.md "Bit casts and half packing"): round to nearest
# even, overflow (|x| >= 65520) to +-inf, float32 values below 2^-14 to half denormals, a NaN to
# sign | 0x7fff; unpacking is exact, except that a half NaN becomes sign | 0x7fffffff.  Integer
# code, so the runtime's denormals-are-zero mode cannot touch it.  These functions go into the
# programs that use them only (the prelude, in every program, stays as it is).
BIT_HELPERS = {
    "pg_half_bits_rte": """\
static inline uint pg_half_bits_rte(const float f) {
    const uint u = as_uint(f), s = (u >> 16) & 0x8000u, a = u & 0x7fffffffu;
    if (a > 0x7f800000u) return s | 0x7fffu;                /* NaN: llvmpipe's code */
    if (a >= 0x477ff000u) return s | 0x7c00u;               /* 65520 and up: inf */
    if (a >= 0x38800000u) {                                 /* normal half */
        const uint r = a - 0x38000000u;
        return s | ((r + 0x0fffu + ((r >> 13) & 1u)) >> 13);
    }
    if (a <= 0x33000000u) return s;                         /* 2^-25 and below: zero */
    const uint m = (a & 0x007fffffu) | 0x00800000u, sh = 126u - (a >> 23);   /* 14..24 */
    const uint q = m >> sh, rem = m & ((1u << sh) - 1u), mid = 1u << (sh - 1u);
    return s | (q + ((rem > mid || (rem == mid && (q & 1u))) ? 1u : 0u));   /* denormal */
}""",
    "pg_half_bits_to_float_gl": """\
static inline float pg_half_bits_to_float_gl(const uint h) {
    const uint s = (h & 0x8000u) << 16, e = (h >> 10) & 31u, m = h & 1023u;
    if (e == 31u) return as_float(s | (m ? 0x7fffffffu : 0x7f800000u));   /* NaN: llvmpipe's */
    if (e == 0u) return as_float(s | as_uint((float)m * 5.9604644775390625e-8f));  /* exact */
    return as_float(s | ((e + 112u) << 23) | (m << 13));
}""",
    "pg_pack_half2x16": """\
static inline uint pg_pack_half2x16(const float2 v) {
    return pg_half_bits_rte(v.x) | (pg_half_bits_rte(v.y) << 16);
}""",
    "pg_unpack_half2x16": """\
static inline float2 pg_unpack_half2x16(const uint p) {
    return (float2)(pg_half_bits_to_float_gl(p & 0xffffu), pg_half_bits_to_float_gl(p >> 16));
}""",
}
_BIT_HELPER_DEPS = {"pg_pack_half2x16": ("pg_half_bits_rte",),
                    "pg_unpack_half2x16": ("pg_half_bits_to_float_gl",)}


def _bitcast(name: str):
    """The ``builtin_map`` entry of a bit cast: the float32 bits (``OpenCLLanguage64`` rounds
    its double arguments to float32 first and widens float results back)."""
    def render(self, args, types, ret):
        a, t = args[0], types[0]
        n = "" if t.size == 1 else str(t.size)
        if name in ("floatBitsToUint", "floatBitsToInt", "packHalf2x16"):
            if self.real == "double":
                a = f"convert_float{n}({a})"
            if name == "packHalf2x16":
                return f"{self.use_helper('pg_pack_half2x16')}({a})"
            return f"as_{self.type_name(ret)}({a})"
        if name == "unpackHalf2x16":
            v, n = f"{self.use_helper('pg_unpack_half2x16')}({a})", "2"
        else:
            v = f"as_float{n}({a})"
        return f"convert_double{n}({v})" if self.real == "double" else v
    return render


def saturates(src: Scalar, dst: Scalar) -> bool:
    """float (or double) to uint: converted saturating (``convert_uint*_sat``), so that a value
    of 2^32 or more gives 0xffffffff as llvmpipe's GL does, on every path (the one-pixel and
    the wide one); the plain cast (LLVM's fptoui) is poison there, and the scalar and vector
    conversions gave different words (cstyle.py's table: the negative side is guarded by
    ``max(x, 0)``)."""
    return src is Scalar.FLOAT and dst is Scalar.UINT


def _saturates(at: Type, t: Type) -> bool:
    return saturates(at.scalar, t.scalar)


class OpenCLLanguage(CStyleLanguage):
    """OpenCL C 1.2 (PoCL).  User functions take the fragment context ``in`` as a hidden first
    parameter, since OpenCL has no program-scope uniforms."""

    type_names = _TYPE_NAMES
    builtin_map = {
        # llvmpipe's inversesqrt is the correctly rounded 1/sqrt(x) (measured)
        "inversesqrt": "(1.0f / sqrt({0}))", "mod": "pg_mod", "fract": "pg_fract", "round": "rint",
        "abs": "pg_abs", "sign": "pg_sign", "dot": "pg_dot", "length": "pg_length",
        "distance": "pg_distance", "cross": "pg_cross", "mix": "pg_mix",
        "smoothstep": "pg_smoothstep",
        # llvmpipe's exp2/log2 polynomials (prelude; bit-exact, and ~5x faster than PoCL's
        # libm): pow = exp2(log2(x) * y), exp = exp2(log2(e) x), log = ln(2) log2(x)
        "pow": "pg_pow({0}, {1})", "exp2": "pg_exp2", "log2": "pg_log2", "exp": "pg_exp",
        "log": "pg_log",
        "atan": lambda self, a, t, r: f"atan2({a[0]}, {a[1]})" if len(a) == 2 else f"atan({a[0]})",
        **{n: _bitcast(n) for n in sorted(BIT_CAST_BUILTINS)},
    }
    # llvmpipe (NIR) lowers mix(x, y, constant t) to x * (1 - t) + y * t (measured); emit_cl
    # runs the pass on the technique, this catches expressions rendered on their own
    builtin_lowerings = {"mix": lower_mix_constant.lower_call}
    vector_ops: dict = {}
    float_suffix = "f"
    inf_literal = "INFINITY"
    nan_literal = "NAN"
    function_qualifier = "static inline "
    reserved = CL_RESERVED
    real = "float"                 # the scalar type of the language's float
    inputs = INPUTS                # stage input -> OpenCL expression
    matrix_prefix = "pg_"          # prelude matrix functions: pg_m4_mul_v4 ...

    def __init__(self, tech: Optional[ir.Technique] = None, pass_: Optional[ir.Pass] = None):
        super().__init__()
        self.tech, self.pass_ = tech, pass_
        self.light_layout = table_layout(tech.lights) if tech else None
        self.in_body = False
        self.raw_helpers: dict[str, str] = {}   # BIT_HELPERS used, dependencies first

    def fresh(self) -> "OpenCLLanguage":
        return type(self)(self.tech, self.pass_)

    def absorb(self, other: "OpenCLLanguage") -> None:
        super().absorb(other)
        for name, helper in other.raw_helpers.items():
            self.raw_helpers.setdefault(name, helper)

    def use_helper(self, name: str) -> str:
        """Name a function of ``BIT_HELPERS``, recording it (and what it calls) for the program."""
        for dep in _BIT_HELPER_DEPS.get(name, ()) + (name,):
            self.raw_helpers.setdefault(dep, BIT_HELPERS[dep])
        return name

    # -- names and hidden context parameter ------------------------------------------------------
    def signature(self, f: ir.Function) -> str:
        ctx = [] if f.name in self.helpers else ["const pg_in *in"]   # guard helpers: pure
        params = ", ".join(ctx + [f"{self.type_name(t)} {self.ident(n)}" for n, t in f.params])
        return f"{self.function_qualifier}{self.type_name(f.ret)} {self.ident(f.name)}({params})"

    def render_call(self, name: str, args: list[str], ret: Type) -> str:
        if name not in self.helpers:         # user functions take the fragment context
            args = ["in"] + args
        return super().render_call(name, args, ret)

    def render_return(self, value: Optional[str]) -> str:
        if self.in_body:                     # the fragment function: true = not discarded
            return "return true;"
        return super().render_return(value)

    # -- expressions that differ -------------------------------------------------------------------
    def render_vector_equality(self, op: str, left: str, right: str) -> str:
        # GLSL ==/!= on vectors give one bool; OpenCL gives a component mask.
        return f"all({left} == {right})" if op == "==" else f"any({left} != {right})"

    def render_construct(self, t: Type, args: list[str], types: list[Type]) -> str:
        name = self.type_name(t)
        if t.is_matrix:
            return self._construct_matrix(t, args, types)
        if t.is_scalar:
            (a,), (at,) = args, types
            if at == t:
                return a
            if t.scalar is Scalar.BOOL:
                return f"(({a}) != 0)"
            if _saturates(at, t):
                return f"convert_uint_sat({a})"
            return f"(({name})({a}))"
        # vectors
        if len(args) == 1:
            a, at = args[0], types[0]
            if at.is_scalar:
                if _saturates(at, t):
                    a = f"convert_uint_sat({a})"
                elif at.scalar is not t.scalar:
                    a = f"({self.type_name(Type(t.scalar)) if t.scalar is not Scalar.BOOL else 'int'})({a})"
                    if t.scalar is Scalar.BOOL:
                        a = f"-(int)(({args[0]}) != 0)"
                return f"(({name})({a}))"
            if at.size > t.size:   # truncation: vec3(v4)
                a, at = f"({a}).{'xyzw'[:t.size]}", Type(at.scalar, t.size)
            if at.scalar is t.scalar:
                return a if at.size == t.size else f"(({name})({a}))"
            return self._convert_vec(a, at, t)
        parts = []
        for a, at in zip(args, types):
            if at.scalar is not t.scalar:
                if at.is_scalar:
                    el = "int" if t.scalar is Scalar.BOOL else self.type_name(Type(t.scalar))
                    a = f"-(int)(({a}) != 0)" if t.scalar is Scalar.BOOL else \
                        f"convert_uint_sat({a})" if _saturates(at, t) else f"({el})({a})"
                else:
                    a = self._convert_vec(a, at, Type(t.scalar, at.size))
            parts.append(a)
        return f"(({name})({', '.join(parts)}))"

    def _convert_vec(self, a: str, at: Type, t: Type) -> str:
        name = self.type_name(t)
        if t.scalar is Scalar.BOOL:
            return f"(({a}) != 0)"
        if at.scalar is Scalar.BOOL:      # int mask -1/0 -> 1/0
            return f"convert_{name}(-({a}))"
        return f"convert_{name}_sat({a})" if _saturates(at, t) else f"convert_{name}({a})"

    def _construct_matrix(self, t: Type, args: list[str], types: list[Type]) -> str:
        n = t.mat
        m = self.matrix_prefix
        if len(args) == 1 and types[0].is_matrix:
            if types[0].mat == n:
                return args[0]
            return f"{m}m{n}_from_m{types[0].mat}({args[0]})"
        if len(args) == 1 and types[0].is_scalar:
            return f"{m}m{n}_diag(({self.real})({args[0]}))"
        if len(args) == n and all(a.is_vector and a.size == n for a in types):
            return f"{m}m{n}_cols({', '.join(args)})"
        if len(args) == n * n:
            cols = [f"({self.real}{n})({', '.join(args[i * n:(i + 1) * n])})" for i in range(n)]
            return f"{m}m{n}_cols({', '.join(cols)})"
        raise AssertionError(f"matrix constructor {t} from {[str(x) for x in types]}")

    def render_index(self, base: str, index: str, base_type: Type) -> str:
        if base_type.is_matrix:
            return f"{base}.c[{index}]"
        if index.isdigit():
            return f"{base}.s{index}"
        if _IDENT.match(base):       # a local: addressable, works as an lvalue too
            el = self.type_name(Type(base_type.scalar)) if base_type.scalar is not Scalar.BOOL else "int"
            return f"((({el} *)&{base})[{index}])"
        return f"pg_index({base}, {index})"

    def render_matrix_op(self, op, left, right, lt, rt, result) -> str:
        m = self.matrix_prefix
        if op == "*":
            if lt.is_matrix and rt.is_matrix:
                return f"{m}m{lt.mat}_mul_m{rt.mat}({left}, {right})"
            if lt.is_matrix and rt.is_vector:
                return f"{m}m{lt.mat}_mul_v{rt.size}({left}, {right})"
            if lt.is_vector and rt.is_matrix:
                return f"{m}v{lt.size}_mul_m{rt.mat}({left}, {right})"
            if lt.is_matrix:
                return f"{m}m{lt.mat}_scale({left}, {right})"
            return f"{m}m{rt.mat}_scale({right}, {left})"
        if op == "/" and lt.is_matrix and rt.is_scalar:
            return f"{m}m{lt.mat}_scale({left}, {self.literal(1.0, ir.FLOAT)} / ({right}))"
        if op in ("+", "-") and lt.is_matrix and rt.is_matrix:
            return f"{m}m{lt.mat}_{'add' if op == '+' else 'sub'}({left}, {right})"
        raise AssertionError(f"matrix operation {lt} {op} {rt}")

    # -- hooks ---------------------------------------------------------------------------------------
    def render_discard(self) -> str:
        return "return false;"

    def render_param(self, name: str, t: Type) -> str:
        default = next(p.default for p in self.tech.params if p.name == name)
        return self.literal(default, t)

    def render_input(self, name: str, t: Type) -> str:
        return self.inputs.get(name, f"in->{name}")

    def render_current_light(self) -> str:
        return "in->light"

    def render_light_row(self, index: str, row: int) -> str:
        return f"in->lights[({index}) * PG_LIGHT_ROWS + {row}]"

    def render_load(self, target: str, coord: Optional[str], t: Type) -> str:
        coord = "in->pix" if coord is None else coord
        return f"pg_load_{target}(in, {coord}){texel_select(t)}"

    def render_load_sample(self, target: str, coord: Optional[str], sample: str,
                           t: Type) -> str:
        coord = "in->pix" if coord is None else coord
        return f"pg_load_sample_{target}(in, {coord}, {sample}){texel_select(t)}"

    def render_sample(self, target: str, uv: str, t: Type) -> str:
        return f"pg_sample_{target}(in, {uv}){texel_select(t)}"

    def render_target_size(self, target: str) -> str:
        return f"in->size_{target}"

    def render_output(self, target: str, value: str) -> str:
        return f"out->o_{target} = {value};"


# ---- the float64 evaluation (``precision="f64"``) ---------------------------------------------
#
# The same dialect with another type map: ``float`` is ``double`` (vectors ``doubleN``, matrices
# the prelude's ``pg_dmatN``), literals are the decimal value itself (not its float32), and the
# builtins whose OpenCL spelling mirrors llvmpipe's float32 arithmetic (gallivm's exp2/log2
# polynomials, pow through them) are the library's double functions.  The fragment context
# reads the frame (matrices, camera, ambient) and the light table in double.

PRECISIONS = ("f32", "f64")

_TYPE_NAMES64 = dict(_TYPE_NAMES)
_TYPE_NAMES64[ir.FLOAT] = "double"
for _k in (2, 3, 4):
    _TYPE_NAMES64[_T(Scalar.FLOAT, _k)] = f"double{_k}"
_TYPE_NAMES64[ir.MAT3] = "pg_dmat3"
_TYPE_NAMES64[ir.MAT4] = "pg_dmat4"

INPUTS64 = {k: v.replace("in->frame->", "in->frame64->") for k, v in _FRAME_INPUTS.items()}
INPUTS64["frag_coord"] = "in->frag_coord"


class OpenCLLanguage64(OpenCLLanguage):
    """The float64 evaluation's dialect: ``OpenCLLanguage`` with double types (data only, plus
    the literal spelling)."""

    type_names = _TYPE_NAMES64
    builtin_map = {
        **OpenCLLanguage.builtin_map,
        "inversesqrt": "(1.0 / sqrt({0}))", "cross": "cross",
        "pow": "pow({0}, {1})", "exp2": "exp2", "log2": "log2", "exp": "exp", "log": "log",
    }
    # mix(x, y, t) = x + (y - x) t, the same value as llvmpipe's split in exact arithmetic
    builtin_lowerings: dict = {}
    float_suffix = ""
    real = "double"
    inputs = INPUTS64
    matrix_prefix = "pg_d"

    def _convert_vec(self, a: str, at: Type, t: Type) -> str:
        if t.scalar is Scalar.BOOL and at.scalar is Scalar.FLOAT:
            # double comparisons give long masks; bvecs are int masks
            return f"convert_{self.type_name(t)}(({a}) != 0)"
        return super()._convert_vec(a, at, t)

    def render_input(self, name: str, t: Type) -> str:
        k = nudge_site(name)      # the discontinuity search's run-time nudge of site k
        return f"in->nudges[{k}]" if k is not None else super().render_input(name, t)

    def render_float(self, x: float) -> str:
        """The literal's own value (the shortest decimal that reads back as the same double)."""
        x = float(x)
        if math.isnan(x):
            return self.nan_literal
        if math.isinf(x):
            return self.inf_literal if x > 0 else "-" + self.inf_literal
        s = repr(x)
        if "." not in s and "e" not in s:
            s += ".0"
        return s


def dialect(precision: str = "f32") -> type[OpenCLLanguage]:
    """The dialect class of a precision (``PRECISIONS``)."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision {precision!r}: expected one of {', '.join(PRECISIONS)}")
    return OpenCLLanguage64 if precision == "f64" else OpenCLLanguage

