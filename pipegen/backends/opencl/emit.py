"""The OpenCL C backend: a ``CStyleLanguage`` dialect (data plus a few hooks) and
``emit_cl(tech) -> Plan`` with one OpenCL program per pass.

The program of a pass (``pass["kernel"]``) is the software reference of that pass: the same
pipeline the GLSL backend describes, with the fixed-function stages written out.  It holds

- the prelude (``templates/cl_prelude.cl.j2``: matrices, GLSL-compatible builtins, format
  conversions, depth/stencil/blend building blocks);
- the pass's fixed-function state as ``S_*`` macros (literals: the compiler bakes them, and the
  OpenCL compiler folds every switch on them away);
- the fragment function ``bool pg_fragment(const pg_in *in, pg_out *out)`` generated from the IR
  through ``OpenCLLanguage`` (false = discarded);
- the kernels (``templates/cl_pass.cl.j2``): ``pg_vertex`` (one work-item per vertex: clip
  position and the varyings the fragment function reads) and ``pg_raster`` (one work-group
  per 16x16 tile, one work-item per tile row holding the row's pixels in registers, walking
  the tile's triangles in submission order and testing only the row's pixels inside each
  triangle's bounding box: edge functions in 8-sub-pixel fixed point with the top-left
  rule, llvmpipe's perspective-correct plane interpolation, early or late depth/stencil, the
  fragment function, blending in registers, colour masks, stores in the target formats);
  where the emitter could lower the fragment code to ``pg_fragment_w`` (``cl_wide.py``: 8
  pixels per call, explicit SIMD with the same per-pixel arithmetic), the row's pixels a
  triangle covers are shaded in batches of 8 instead, then blended pixel by pixel in order.
  The prelude routes the OpenCL builtins the generated code calls most (fma, fmin, fmax,
  min, max, clamp, sqrt, floor, fabs, copysign, sub_sat, vload_half*, vstore_half*_rtz) to
  inline equivalents of PoCL's library functions (which LLVM does not inline here: every one
  was a call); ``tests/test_cl_builtins.py`` checks them against the library.

Clipping, viewport snapping, culling, polygon offset and binning run on the host between the two
kernels (``pipegen/runtime/cl/setup.py``).  Conventions shared with the CL runtime:

- ``pass["cl"]`` = ``{"fragment": text or None, "inputs": [stage inputs read], "discard": bool,
  "sampled": [targets read with sample()]}``: enough for ``pass_program(plan, pass)`` to rebuild
  the program, e.g. in the tests' dynamic-state mode, where the ``S_*`` macros read a kernel
  argument instead (one compile serves every state).
- ``pass["sampled"]`` (targets read with ``sample()``) as in the GL plan.
- Buffers hold GL window rows (row 0 = window y 0, the bottom row), the order ``render``
  returns; a target with S samples holds S planes (plane k = sample k, llvmpipe's positions).
- Varyings are float4 slots ``vary[slot * nverts + v]`` in the order of ``varying_slots()``;
  the raster kernel reads a flat slot (the GLSL ``flat`` ones) at the provoking vertex and a
  smooth slot from its perspective plane (``coef[(t * ncoef + slot["coef"]) * 3 + k]``,
  k = a0, dadx, dady; ``tri_w``: the 1/w plane); flat integer values (object id, normal
  group, light index or stipple layer) travel per triangle.
- Blend counts: one ``uint`` per pixel per non-integer colour target (``bc_<target>``), to
  which the raster kernel adds the fragments it blended into the pixel (``CLPipeline.
  last_blend_counts``, the P of ``pipegen check``'s tolerance).

Choices mirrored from the GLSL backend (glsl.py's docstring): ``load`` clamps coordinates to the
target, outputs are zero-initialised, ``round`` is round-half-to-even (``rint``), scene
vertices ``proj * (view * p)``, light volumes and the full-screen triangle placed the same way.

Arithmetic follows llvmpipe where the two could differ (each measured bit-exact on Mesa 22.3):
no contraction of ``a * b + c`` (``FP_CONTRACT OFF``), correctly rounded ``/`` and ``sqrt``,
``inversesqrt`` = ``1 / sqrt``, ``dot`` = ``x + (y + (z + w))`` of unfused products (and
``length``, ``distance``, matrix products built on it), ``mix`` = ``a + (b - a) t`` or, for a
constant t, ``a (1 - t) + b t`` (``passes/lower_mix_constant``, run by ``emit_cl``),
``smoothstep`` = ``t (t (3 - 2t))``, gallivm's ``exp2`` / ``log2`` polynomials (so ``pow``,
``exp``, ``log``), unorm reads as ``code * (1 / max)``, unorm8 bilinear filtering in 8-bit fixed
point, bilinear filtering of other formats with llvmpipe's clamp-to-edge texel coordinates and
fused lerps (x then y), unorm16 stores ``x * (65535/65536) + 128`` (the low mantissa bits) and
narrower unorm channels store that 16-bit code scaled down (Mesa's ``scale_bits``: 10 bits
``>> 6``), snorm stores and reads as ``formats.Encode`` says, varyings interpolated with
llvmpipe's float32 planes (``cl_setup.attribute_planes``).  Not mirrored: ``atan``, ``sin``,
``cos`` (OpenCL's, within a few ulp) and NIR's constant reassociation (``(x * 3.0) * 0.7``
folded to ``x * 2.1``).
"""

from __future__ import annotations

import functools
import math
import re
import textwrap
from dataclasses import replace
from typing import Optional

from pipegen.core import formats as F
from pipegen.ir import nodes as ir
from pipegen.ir.nodes import DrawKind, Scalar, Type
from pipegen.backends import plan as planlib
from pipegen.backends.plan import CLPassCode, PassPlan, Plan
from pipegen.backends.opencl import wide as cl_wide
from pipegen.backends import templating
from pipegen.ir.builtins import (
    BIT_CAST_BUILTINS, FLAT_SCENE_INPUTS, PREVIOUS_FRAME_INPUTS, VOLUME_LIGHT_FIELDS)
from pipegen.core.float32 import f32
from pipegen.passes import lower_mix_constant
from pipegen.backends.cstyle import FLT_MIN, CStyleLanguage, texel_select

TILE = 16

# ---- enumerations shared by the prelude and the state macros -------------------------------------

COMPARE = {"never": 0, "less": 1, "equal": 2, "lequal": 3, "greater": 4, "notequal": 5,
           "gequal": 6, "always": 7}
STENCIL_OP = {"keep": 0, "zero": 1, "replace": 2, "incr": 3, "decr": 4, "incr_wrap": 5,
              "decr_wrap": 6, "invert": 7}
BLEND_OP = {"add": 0, "sub": 1, "revsub": 2, "min": 3, "max": 4}
BLEND_FACTOR = {f.value: k for k, f in enumerate(ir.BlendFactor)}
CULL = {"none": 0, "back": 1, "front": 2}


def _enum_defines() -> list[tuple[str, int]]:
    out = [(f"PG_{k.upper()}", v) for k, v in COMPARE.items()]
    out += [(f"PG_SOP_{k.upper()}", v) for k, v in STENCIL_OP.items()]
    out += [(f"PG_BO_{k.upper()}", v) for k, v in BLEND_OP.items()]
    out += [(f"PG_BF_{k.upper()}", v) for k, v in BLEND_FACTOR.items()]
    return out


# ---- the dialect ----------------------------------------------------------------------------------

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

# stage input -> OpenCL expression (``in`` is the fragment context, see cl_pass.cl.j2)
INPUTS = {
    "frag_coord": "in->frag_coord", "camera_pos": "in->frame->camera_pos.xyz",
    "view": "in->frame->view", "proj": "in->frame->proj", "inv_view": "in->frame->inv_view",
    "inv_proj": "in->frame->inv_proj", "output_size": "in->frame->output_size.xy",
    "prev_view": "in->frame->prev_view", "prev_proj": "in->frame->prev_proj",
    "num_lights": "in->frame->num_lights", "ambient": "in->frame->ambient.xyz",
    "light_index": "in->light",
}
# scene varyings: input -> (OpenCL type, value in the vertex kernel; p = float4 position,
# n = float3 normal, vp = view-space position)
SCENE_VARYINGS = {
    "world_pos": ("float3", "p.xyz"),
    "view_pos": ("float3", "vp.xyz"),
    "normal": ("float3", "n"),
    "view_normal": ("float3", "pg_m3_mul_v3(pg_m3_from_m4(frame->view), n)"),
    "albedo": ("float3", "a_albedo[v].xyz"),
    "specular": ("float", "a_material[v].x"),
    "shininess": ("float", "a_material[v].y"),
    "alpha": ("float", "a_material[v].z"),
}
# the varyings passed flat (builtins.FLAT_SCENE_INPUTS: materials are per object): the provoking
# vertex's value; the others are perspective-corrected (llvmpipe: LP_INTERP_PERSPECTIVE)
FLAT_VARYINGS = FLAT_SCENE_INPUTS & frozenset(SCENE_VARYINGS)
# flat scene inputs -> component of the per-triangle ``tri_flat`` (x is the facing bit; w holds
# the light index in light draws and the stipple layer in scene draws)
SCENE_FLAT = {"object_id": "y", "normal_group": "z", "layer": "w"}

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
        self.light_fields = tuple(f.name for f in tech.lights.fields) if tech else ()
        self.in_body = False
        self.raw_helpers: dict[str, str] = {}   # BIT_HELPERS used, dependencies first

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
            return f"(({name})({a}))"
        # vectors
        if len(args) == 1:
            a, at = args[0], types[0]
            if at.is_scalar:
                if at.scalar is not t.scalar:
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
                    a = f"-(int)(({a}) != 0)" if t.scalar is Scalar.BOOL else f"({el})({a})"
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
        return f"convert_{name}({a})"

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

    def render_light_field(self, index: str, slot: int, t: Type) -> str:
        texel = f"in->lights[({index}) * PG_LIGHT_FIELDS + {slot}]{texel_select(t)}"
        if t.scalar is Scalar.FLOAT:
            return texel
        return self.render_construct(t, [texel], [Type(Scalar.FLOAT, t.size)])

    def render_load(self, target: str, coord: Optional[str], t: Type) -> str:
        coord = "in->pix" if coord is None else coord
        return f"pg_load_{target}(in, {coord}){texel_select(t)}"

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

INPUTS64 = {k: v.replace("in->frame->", "in->frame64->") for k, v in INPUTS.items()}
INPUTS64["frag_coord"] = "in->frag_coord"

# scene varyings in the float64 kernel: (type, value) over the parent triangle's attributes
# interpolated at the pixel with exact perspective-correct weights (``P``: position, ``N``:
# normal, double3) and its provoking vertex ``pv`` (flat values); a varying that is an affine
# function of an attribute (view-space position, view-space normal) is that function of the
# interpolated attribute -- the same value as interpolating it per vertex, without rounding
SCENE_VARYINGS64 = {
    "world_pos": ("double3", "P"),
    "view_pos": ("double3", "pg_dm4_mul_v4(frame64->view, (double4)(P, 1.0)).xyz"),
    "normal": ("double3", "N"),
    "view_normal": ("double3", "pg_dm3_mul_v3(pg_dm3_from_m4(frame64->view), N)"),
    "albedo": ("double3", "convert_double3(a_albedo[pv].xyz)"),
    "specular": ("double", "(double)a_material[pv].x"),
    "shininess": ("double", "(double)a_material[pv].y"),
    "alpha": ("double", "(double)a_material[pv].z"),
}


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


# ---- formats on the device --------------------------------------------------------------------------


# numpy element type -> OpenCL C scalar type
_CL_SCALAR = {"uint8": "uchar", "int8": "char", "uint16": "ushort", "int16": "short",
              "uint32": "uint", "float16": "half", "float32": "float"}


def cl_format(name: str) -> dict:
    """How a target format lives in an OpenCL buffer and in the raster kernel's registers,
    derived from ``formats.Format`` (no format is named here).

    ``cls``: unorm8 | unorm | snorm | half | float | uint | d24 | d32f (depth bits).
    ``storage``: the buffer's element type (one per pixel).  ``reg``: the register type (uint4
    codes for unorm/uint, the int codes' bits for snorm, float4 values for float formats,
    uint / float for depth).  ``load``/``store``: expression / statement templates over ``b`` (buffer),
    ``i`` (pixel index) and ``r`` (register).  ``read``: the decoded float4 (uint4 for integer
    formats) a shader sees, over ``b``/``i``.  ``code``: the prelude function turning a float4
    into unorm codes; ``encode``: snorm's float4 ``r`` -> register expression.
    """
    fmt = F.get(name)
    n = fmt.channels
    np_name = fmt.element_dtype_name
    el = _CL_SCALAR[np_name]
    if fmt.kind is F.Kind.DEPTH_STENCIL:
        top = f"{fmt.max_codes[0]}.0f"
        return {"name": name, "cls": f"d{fmt.bits[0]}", "storage": el, "reg": el, "np": np_name,
                "load": "b[i]", "store": "b[i] = r;",
                "read": f"(float4)((float)b[i] / {top}, 0.0f, 0.0f, 1.0f)", "vec": "float4"}
    if fmt.kind is F.Kind.DEPTH:
        return {"name": name, "cls": f"d{fmt.bits[0]}f", "storage": el, "reg": el,
                "np": np_name, "load": "b[i]", "store": "b[i] = r;",
                "read": "(float4)(b[i], 0.0f, 0.0f, 1.0f)", "vec": "float4"}
    assert n in (1, 2, 4), f"{name}: OpenCL has no {n}-component storage of the same size"
    if fmt.kind is F.Kind.FLOAT:
        return _cl_float(fmt, el)
    storage = el if fmt.elements == 1 else f"{el}{n}"
    if fmt.packed:
        load, store = _packed_load_store(fmt)
    elif fmt.is_signed:
        load, store = _signed_load_store(fmt, el)
    else:
        load, store = _unsigned_load_store(fmt, el)
    out = {"name": name, "storage": storage, "reg": "uint4", "np": np_name, "load": load,
           "store": store, "read": None}
    if fmt.kind is F.Kind.UINT:
        return {**out, "cls": "uint", "vec": "uint4", "mask": f"{(1 << max(fmt.bits)) - 1}u"}
    rcpv = _rcp(_four(list(fmt.max_codes), n))
    out.update(vec="float4", rcpv=rcpv)
    if fmt.is_signed:
        ints = _signed_ints(fmt)
        return {**out, "cls": "snorm", "code": None, "encode": _snorm_encode(fmt),
                "read": f"fmax(convert_float4({ints}) * {rcpv}, -1.0f)"}
    if fmt.blend_is_exact:
        return {**out, "cls": "unorm8", "code": "pg_unorm8_code4"}
    assert fmt.encode is F.Encode.UNORM16, f"{name}: no OpenCL conversion for {fmt.encode}"
    narrow = any(b < 16 for b in fmt.bits)
    return {**out, "cls": "unorm", "code": f"pg_{name}_code4" if narrow else "pg_unorm16_code4"}


def cl_format64(name: str) -> dict:
    """``cl_format`` for the float64 evaluation: every non-integer target holds its values as
    doubles (one ``double``/``double2``/``double4`` per pixel, ``cls`` "f64"; depth ``cls``
    "d64", the window depth), unquantised; integer formats keep their codes (``cl_format``).
    ``src_clamp``: the function applied to a shader output (and the blend constant) before
    blending and storing, ``store_clamp`` to the stored result: the format's value range
    ([0, 1] unorm, [-1, 1] snorm, +-65504 for finite half values; none for float32)."""
    fmt = F.get(name)
    if fmt.kind is F.Kind.UINT:
        return cl_format(name)
    if fmt.kind in (F.Kind.DEPTH, F.Kind.DEPTH_STENCIL):
        return {"name": name, "cls": "d64", "storage": "double", "reg": "double",
                "np": "float64", "load": "b[i]", "store": "b[i] = r;",
                "read": "(double4)(b[i], 0.0, 0.0, 1.0)", "vec": "double4"}
    n = fmt.channels
    assert n in (1, 2, 4), name
    if n == 1:
        load, store = "(double4)(b[i], 0.0, 0.0, 1.0)", "b[i] = r.x;"
    elif n == 2:
        load, store = "(double4)(b[i], 0.0, 1.0)", "b[i] = r.xy;"
    else:
        load, store = "b[i]", "b[i] = r;"
    if fmt.kind is F.Kind.UNORM:
        src = store_clamp = "pg_dclamp01"
    elif fmt.kind is F.Kind.SNORM:
        src = store_clamp = "pg_dclamp11"
    elif max(fmt.bits) == 16:
        src, store_clamp = "", "pg_dclamp_half"
    else:
        src = store_clamp = ""
    return {"name": name, "cls": "f64", "storage": "double" if n == 1 else f"double{n}",
            "reg": "double4", "np": "float64", "load": load, "store": store, "read": load,
            "vec": "double4", "src_clamp": src, "store_clamp": store_clamp}


def _four(values: list, n: int) -> list:
    """Per-channel values of an n-channel format, padded to 4 (missing channels repeat the
    last value, whose lanes are never used)."""
    return values + values[-1:] * (4 - n)


def _unsigned_load_store(fmt: F.Format, el: str) -> tuple[str, str]:
    n = fmt.channels
    one = fmt.max_codes[-1] if fmt.is_normalized else 1      # GL reads missing alpha as 1
    if n == 1:
        return f"(uint4)(b[i], 0u, 0u, {one}u)", f"b[i] = ({el})r.x;"
    if n == 2:
        return f"(uint4)(convert_uint2(b[i]), 0u, {one}u)", f"b[i] = convert_{el}2(r.xy);"
    if el == "uint":
        return "b[i]", "b[i] = r;"
    return "convert_uint4(b[i])", f"b[i] = convert_{el}4(r);"


def _signed_ints(fmt: F.Format) -> str:
    """int4 codes of an snorm pixel (``b[i]``); GL reads missing channels as (0, 1)."""
    n, one = fmt.channels, fmt.max_codes[-1]
    if n == 1:
        return f"(int4)(b[i], 0, 0, {one})"
    if n == 2:
        return f"(int4)(convert_int2(b[i]), 0, {one})"
    return "convert_int4(b[i])"


def _signed_load_store(fmt: F.Format, el: str) -> tuple[str, str]:
    """snorm: registers hold the int codes' bits (uint4, so masks and moves are shared)."""
    n = fmt.channels
    if n == 1:
        store = f"b[i] = ({el})as_int(r.x);"
    elif n == 2:
        store = f"b[i] = convert_{el}2(as_int2(r.xy));"
    else:
        store = f"b[i] = convert_{el}4(as_int4(r));"
    return f"as_uint4({_signed_ints(fmt)})", store


def _packed_load_store(fmt: F.Format) -> tuple[str, str]:
    """Channels packed into one word, channel 0 in the low bits."""
    loads, stores = [], []
    for k, (bits, shift) in enumerate(zip(fmt.bits, fmt.shifts)):
        mask = f" & {(1 << bits) - 1}u" if shift + bits < fmt.word_bits else ""
        word = f"(b[i] >> {shift})" if shift and mask else f"b[i] >> {shift}" if shift else "b[i]"
        loads.append(word + mask)
        value = f"r.{'xyzw'[k]}"
        value = f"({value}{mask})" if mask else value
        stores.append(f"({value} << {shift})" if shift else value)
    loads += ["0u", "0u", "0u", f"{fmt.max_codes[-1]}u"][len(loads):]
    return f"(uint4)({', '.join(loads)})", f"b[i] = {' | '.join(stores)};"


def _snorm_encode(fmt: F.Format) -> str:
    """float4 ``r`` -> snorm register (the codes' bits), as ``Format.quantize`` (``Encode``)."""
    m = _rcp_literal(fmt.max_codes[0])
    if fmt.encode is F.Encode.ROUND_SAT:     # round x * max, saturate to [-max - 1, max]
        lo = _rcp_literal(-fmt.max_codes[0] - 1)
        return f"as_uint4(convert_int4_rte(fmin(fmax(r * {m}, {lo}), {m})))"
    assert fmt.encode is F.Encode.ROUND, fmt.encode
    return f"as_uint4(convert_int4_rte(fmin(fmax(r, -1.0f), 1.0f) * {m}))"


def _rcp_literal(x: float) -> str:
    return OpenCLLanguage().render_float(float(x))


def _cl_float(fmt: F.Format, el: str) -> dict:
    n, name = fmt.channels, fmt.name
    if el == "half":
        suffix = "" if n == 1 else str(n)
        if n == 1:
            load = "(float4)(vload_half(i, b), 0.0f, 0.0f, 1.0f)"
            store = "vstore_half_rtz(r.x, i, b);"
        elif n == 2:
            load = "(float4)(vload_half2(i, b), 0.0f, 1.0f)"
            store = "vstore_half2_rtz(r.xy, i, b);"
        else:
            load = "vload_half4(i, b)"
            store = "vstore_half4_rtz(r, i, b);"
        return {"name": name, "cls": "half", "storage": "half", "reg": "float4",
                "np": "float16", "load": load, "store": store, "read": load, "vec": "float4",
                "suffix": suffix}
    storage = "float" if n == 1 else f"float{n}"
    if n == 1:
        load, store = "(float4)(b[i], 0.0f, 0.0f, 1.0f)", "b[i] = r.x;"
    elif n == 2:
        load, store = "(float4)(b[i], 0.0f, 1.0f)", "b[i] = r.xy;"
    else:
        load, store = "b[i]", "b[i] = r;"
    return {"name": name, "cls": "float", "storage": storage, "reg": "float4",
            "np": "float32", "load": load, "store": store, "read": load, "vec": "float4"}


def scaled16_conversions() -> list[dict]:
    """The prelude's ``pg_NAME_code4`` of the unorm formats narrower than 16 bits that llvmpipe
    stores through its 16-bit blend type (``formats.Encode.UNORM16``): ``expr`` narrows the
    16-bit codes ``c`` with Mesa's ``scale_bits`` (``formats.scale_bits16``), ``doc`` says so."""
    out = []
    for fmt in F.FORMATS.values():
        if fmt.kind is not F.Kind.UNORM or fmt.encode is not F.Encode.UNORM16 \
                or all(b >= 16 for b in fmt.bits):
            continue
        assert fmt.channels == 4, fmt.name
        exprs, docs = [], []
        k = 0
        while k < 4:           # runs of channels with the same bits: one swizzle each
            j = k
            while j < 4 and fmt.bits[j] == fmt.bits[k]:
                j += 1
            b, d, sw = fmt.bits[k], 16 - fmt.bits[k], "xyzw"[k:j]
            who = "alpha" if sw == "w" else "rgba"[k:j]
            if d <= b:
                exprs.append(f"c.{sw} >> {d}")
                docs.append(f'{who} c16 >> {d} (truncating, "wrong rounding" in Mesa\'s words)')
            else:
                exprs.append(f"((c.{sw} >> {b}) * {(1 << b) - 1}u + {1 << (d - 1)}u) >> {d}")
                docs.append(f"{who} ((c16 >> {b}) * {(1 << b) - 1} + 2^{d - 1}) >> {d}")
            k = j
        out.append({"name": fmt.name, "expr": ", ".join(exprs), "doc": ", ".join(docs)})
    return out


@templating.template_filter
def c_comment(text: str, width: int = 95) -> str:
    """``text`` as a C block comment wrapped at ``width`` columns."""
    lines = textwrap.wrap(text + " */", width, initial_indent="/* ", subsequent_indent=" * ",
                          break_on_hyphens=False, break_long_words=False)
    return "\n".join(lines)


@functools.lru_cache(maxsize=None)
def prelude_source(tile: int = TILE, precision: str = "f32", previous: bool = False) -> str:
    """The prelude every pass program starts with (``templates/cl_prelude.cl.j2``); with
    ``precision="f64"`` followed by the float64 evaluation's building blocks; ``previous``:
    the frame structs end with the previous frame's camera (``prev_view``, ``prev_proj``).
    Rendered once per arguments (every pass program of a plan starts with the same one)."""
    return templating.render("cl_prelude.cl.j2", tile=tile, enums=_enum_defines(),
                             scaled16=scaled16_conversions(), f64=precision == "f64",
                             previous=previous)


def _rcp(maxima) -> str:
    """float4 literal of the float32 reciprocals 1/max: llvmpipe turns unorm codes into floats
    as ``code * (1/max)`` (measured; 196 * (1/255) is one ulp above 196 / 255)."""
    lang = OpenCLLanguage()
    vals = [lang.render_float(f32(1.0 / f32(m))) for m in maxima]
    return f"(float4)({', '.join(vals)})"


def _read_expr(f: dict) -> str:
    """Decoded value a shader reads (float4 / uint4) over buffer ``b`` and index ``i``."""
    if f["read"] is not None:
        return f["read"]
    if f["cls"] == "uint":
        return f["load"]
    return f"convert_float4({f['load']}) * {f['rcpv']}"


# ---- state macros ---------------------------------------------------------------------------------


def state_values(pass_: PassPlan) -> list[tuple[str, str, object]]:
    """The pass state as (macro name, kind "i"/"f", value) rows, in the dynamic-state order."""
    st = pass_.state
    depth = st.depth
    has_depth = pass_.depth_target is not None
    enabled = has_depth and depth.enabled
    rows: list[tuple[str, str, object]] = [
        ("S_DEPTH_TEST", "i", int(enabled)),
        ("S_DEPTH_FUNC", "i", COMPARE[depth.func.value] if enabled else COMPARE["always"]),
        ("S_DEPTH_WRITE", "i", int(enabled and depth.write)),
    ]
    faces = [st.stencil.front, st.stencil.back]
    rows.append(("S_STENCIL", "i", int(st.stencil.enabled)))
    for tag, f in zip("FB", faces):
        rows += [(f"S_ST_FUNC_{tag}", "i", COMPARE[f.func.value]),
                 (f"S_ST_REF_{tag}", "i", min(max(int(f.ref), 0), 255)),
                 (f"S_ST_RMASK_{tag}", "i", int(f.read_mask) & 255),
                 (f"S_ST_WMASK_{tag}", "i", int(f.write_mask) & 255),
                 (f"S_ST_FAIL_{tag}", "i", STENCIL_OP[f.fail.value]),
                 (f"S_ST_ZFAIL_{tag}", "i", STENCIL_OP[f.zfail.value]),
                 (f"S_ST_ZPASS_{tag}", "i", STENCIL_OP[f.zpass.value])]
    rows += [(f"S_BCONST_{c}", "f", float(v)) for c, v in zip("RGBA", st.blend_constant)]
    for k, name in enumerate(pass_.writes):
        b = st.blend_for(name)
        mask = sum(1 << i for i, m in enumerate(b.write_mask) if m)
        rows += [(f"S_BLEND_{k}", "i", int(b.enabled)),
                 (f"S_RGB_OP_{k}", "i", BLEND_OP[b.rgb.op.value]),
                 (f"S_RGB_SRC_{k}", "i", BLEND_FACTOR[b.rgb.src.value]),
                 (f"S_RGB_DST_{k}", "i", BLEND_FACTOR[b.rgb.dst.value]),
                 (f"S_A_OP_{k}", "i", BLEND_OP[b.alpha.op.value]),
                 (f"S_A_SRC_{k}", "i", BLEND_FACTOR[b.alpha.src.value]),
                 (f"S_A_DST_{k}", "i", BLEND_FACTOR[b.alpha.dst.value]),
                 (f"S_WMASK_{k}", "i", mask)]
    inside = _inside_func(pass_)
    if inside is not None:
        # `cull auto` + `depth … inside FUNC`: the test of the triangles of lights drawn with
        # their back faces (the runtime sets bit 1 of their tri_flat.x, `pg_inside`)
        on = has_depth and (inside is not ir.CompareFunc.ALWAYS or depth.write)
        rows += [("S_DEPTH_TEST_IN", "i", int(on)),
                 ("S_DEPTH_FUNC_IN", "i", COMPARE[inside.value] if on else COMPARE["always"]),
                 ("S_DEPTH_WRITE_IN", "i", int(on and depth.write))]
    return rows


def _inside_func(pass_: PassPlan) -> Optional[ir.CompareFunc]:
    """The `inside FUNC` depth test of a `cull auto` pass (None when it has none)."""
    if not pass_.cull_auto or not pass_.depth_target:
        return None
    return pass_.state.depth.inside


def state_words(pass_: PassPlan) -> list[int]:
    """The dynamic-state argument (int32 words) matching ``state_values`` order."""
    import struct
    out = []
    for _, kind, value in state_values(pass_):
        if kind == "f":
            out.append(struct.unpack("<i", struct.pack("<f", float(value)))[0])
        else:
            out.append(int(value))
    return out


def _state_defines(pass_: PassPlan, dynamic: bool,
                   precision: str = "f32") -> list[tuple[str, str]]:
    lang = dialect(precision)()
    out = []
    for k, (name, kind, value) in enumerate(state_values(pass_)):
        if dynamic:
            out.append((name, f"as_float(pg_st[{k}])" if kind == "f" else f"(pg_st[{k}])"))
        else:
            out.append((name, lang.render_float(value) if kind == "f" else str(value)))
    names = {name for name, _ in out}
    for i, (name, value) in enumerate(out):
        if name + "_IN" in names:     # per triangle: the `inside` test or the pass's own
            out[i] = (name, f"(pg_inside ? {name}_IN : {value})")
    return out


# llvmpipe's multisample positions (GL_SAMPLE_POSITION, measured; GL window space, y up)
SAMPLE_POSITIONS = {1: [(0.5, 0.5)],
                    4: [(0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875)]}


def sample_positions(samples: int) -> tuple[list[int], list[int]]:
    """Sample offsets within a pixel in 1/256 pixel (x list, y list)."""
    pos = SAMPLE_POSITIONS.get(samples)
    if pos is None:
        raise ValueError(f"{samples} samples per pixel: the reference supports 1 and 4 "
                         "(llvmpipe's GL_MAX_SAMPLES is 4)")
    return [int(x * 256) for x, _ in pos], [int(y * 256) for _, y in pos]


# ---- per-pass program --------------------------------------------------------------------------------


def varying_slots(pass_: PassPlan) -> list[dict]:
    """Varyings of a pass, in slot order: name, OpenCL type, vertex-kernel value, ``flat``
    (the provoking vertex's value) and, for the others, ``coef``: the index of the slot's
    perspective plane among the smooth slots (``Triangles.coef``)."""
    if pass_.draw.kind is not DrawKind.SCENE:
        return []
    inputs = set(pass_.code.inputs if pass_.code is not None else ())
    out = []
    smooth = 0
    for k, n in enumerate(n for n in SCENE_VARYINGS if n in inputs):
        t, v = SCENE_VARYINGS[n]
        flat = n in FLAT_VARYINGS
        out.append({"name": n, "type": t, "value": v, "slot": k, "flat": flat,
                    "coef": None if flat else smooth})
        smooth += not flat
    return out


def prelude_file(precision: str = "f32", previous: bool = False) -> str:
    """The file name ``pipegen compile`` writes a prelude to (``prelude_source``'s arguments;
    the pass programs ``#include`` it, see ``CLPassCode.included``)."""
    return "prelude" + ("_previous_frame" if previous else "") + \
        ("" if precision == "f32" else f"_{precision}") + ".cl"


def _pass_prelude(pass_: PassPlan, tile: int, precision: str) -> tuple[str, str]:
    """(file name, text) of the prelude the program of ``pass_`` starts with."""
    code = pass_.code if pass_.code is not None else CLPassCode("", None)
    previous = bool(set(code.inputs) & set(PREVIOUS_FRAME_INPUTS))
    return prelude_file(precision, previous), prelude_source(tile, precision, previous)


def pass_program(plan: Plan, pass_: PassPlan, dynamic: bool = False, tile: int = TILE) -> str:
    """The complete OpenCL program of one pass (``dynamic``: state from a kernel argument),
    in the plan's precision (``plan.precision``: "f32", or "f64" for the float64 evaluation:
    the same program with double arithmetic and storage, docs/internals.md)."""
    if not 1 <= int(tile) <= 64:       # pg_raster keeps a row's drawn pixels in a ulong mask
        raise ValueError(f"tile size {tile}: the raster kernel supports 1 to 64")
    precision = plan.precision
    f64 = precision == "f64"
    fmt_of = cl_format64 if f64 else cl_format
    code = pass_.code if pass_.code is not None else CLPassCode("", None)
    writes = []
    for k, name in enumerate(pass_.writes):
        f = fmt_of(plan.target(name).format.name)
        writes.append({**f, "k": k, "name": name, "format": f["name"],
                       "bpp": plan.target(name).format.bytes_per_pixel})
    depth = None
    stencil = False
    if pass_.depth_target:
        fmt = plan.target(pass_.depth_target).format
        depth = fmt_of(fmt.name)
        stencil = fmt.has_stencil
    reads = []
    for name in pass_.reads:
        f = fmt_of(plan.target(name).format.name)
        reads.append({**f, "name": name, "format": f["name"], "decoded": _read_expr(f),
                      "integer": f["cls"] == "uint",
                      "linear": f["cls"] in ("unorm8", "unorm", "snorm", "half", "float", "f64"),
                      "sampled": name in code.sampled})
    inputs = set(code.inputs)
    draw = pass_.draw
    fields = [f[0] for f in plan.lights.fields]
    volume = (draw.volume or ir.Volume.SPHERE).value
    slots = {f: k for k, f in enumerate(fields)}
    # the previous frame's camera: in the frame struct of the programs that read it only
    # (the host's frame buffer always holds it, after the common fields)
    prelude = _pass_prelude(pass_, tile, precision)[1]
    samples = plan.pass_samples(pass_)
    sx, sy = sample_positions(samples)
    varyings = varying_slots(pass_)
    # the wide fragment function (cl_wide.py: PG_W pixels per call), when the emitter made one
    wide = not f64 and cl_wide.has_wide(code.fragment)
    early_z = code.discard and not _writes_stencil(pass_, stencil, dynamic)
    depth_store = dynamic or _writes_depth(pass_)
    # batches across triangles (cl_pass.cl.j2): wide passes without varyings, unless a
    # fragment's late depth write could be one a later triangle's early test must see
    xbatch = wide and cl_wide.CROSS_TRIANGLE and not varyings and not (early_z and depth_store)
    if f64:
        for v in varyings:
            v["type64"], v["value64"] = SCENE_VARYINGS64[v["name"]]
    return templating.render(
        "cl_pass.cl.j2",
        technique=plan.technique, pass_name=pass_.name, prelude=prelude,
        dynamic=dynamic, state=_state_defines(pass_, dynamic, precision),
        kind=draw.kind.value, volume=volume, slots=slots, light_fields=len(fields),
        varyings=varyings,
        flats=[{"name": n, "component": c} for n, c in SCENE_FLAT.items() if n in inputs],
        writes=writes, depth=depth, stencil=stencil, reads=reads,
        fragment=code.fragment, discard=code.discard, early_z=early_z, depth_store=depth_store,
        stencil_load=stencil and (dynamic or pass_.state.stencil.enabled),
        stencil_store=_writes_stencil(pass_, stencil, dynamic),
        flt_min=OpenCLLanguage().render_float(FLT_MIN),
        scissor=draw.scissor, samples=samples, sample_x=sx, sample_y=sy,
        inside=_inside_func(pass_) is not None, f64=f64, real="double" if f64 else "float",
        wide=wide, xbatch=xbatch, wide_helpers=cl_wide.wide_helpers() if wide else "",
        wide_w=cl_wide.W)


def _writes_depth(pass_: PassPlan) -> bool:
    """Whether a pass (its baked state) may write its depth attachment: the raster kernel
    stores the depth it keeps per row only then."""
    rows = {name: value for name, _, value in state_values(pass_)}
    return bool(rows.get("S_DEPTH_WRITE") or rows.get("S_DEPTH_WRITE_IN"))


def _writes_stencil(pass_: PassPlan, stencil: bool, dynamic: bool) -> bool:
    """Whether a pass may write its stencil attachment.  A pass whose fragment function may
    discard tests depth and stencil before shading and writes depth after it (llvmpipe's
    EARLY_DEPTH_TEST | LATE_DEPTH_WRITE, lp_state_fs.c) unless it writes stencil: a stencil op
    runs on the test's outcome, which a later discard must undo.  Dynamic-state programs
    (tests) take any state, so any stencil attachment counts."""
    if not stencil:
        return False
    if dynamic:
        return True
    keep = ir.StencilOp.KEEP
    return any(f.write_mask & 0xFF and (f.fail, f.zfail, f.zpass) != (keep, keep, keep)
               for f in (pass_.state.stencil.front, pass_.state.stencil.back))


# ---- runtime programs: triangle set-up, binning and multisample resolve ---------------------

# "auto": per triangle, bit 2 of its flat input word says whether its light is drawn with its
# back faces (``cull auto``: the host decides per light, ``draws.light_runs``)
SETUP_CULL = {"none": 0, "back": 1, "front": 2, "auto": 3}
SUBPIXEL = 256       # window coordinates snap to 1/256 pixel (GL_SUBPIXEL_BITS = 8)


def setup_program(cull: str, depth_clamp: bool, samples: Optional[int], has_flat: bool,
                  has_scissor: bool, w_plane: bool, with_zq: bool, smooth: tuple,
                  slots: int) -> str:
    """The device set-up program (``cl_setup.cl.j2``: ``pg_setup``, ``pg_clip_setup``) for one
    combination of the set-up's switches (``runtime/cl_setup_device.py``)."""
    lo, hi = (SUBPIXEL // 2, SUBPIXEL // 2) if samples == 1 else (SUBPIXEL - 1, 1)
    return templating.render(
        "cl_setup.cl.j2", cull=SETUP_CULL[cull], depth_clamp=int(depth_clamp), box_lo=lo,
        box_hi=hi, has_flat=int(has_flat), has_scissor=int(has_scissor), w_plane=int(w_plane),
        with_zq=int(with_zq), smooth=list(smooth), slots=int(slots))


def bin_program() -> str:
    """The device binning program (``cl_bin.cl.j2``: ``pg_bin_count``, ``pg_bin_starts``,
    ``pg_bin_write``; ``runtime/cl_bin.py``)."""
    return templating.render("cl_bin.cl.j2", subpixel=SUBPIXEL)


def resolve_program(format_name: str, samples: int) -> Optional[str]:
    """The device multisample resolve (``cl_resolve.cl.j2``, ``pg_resolve``) of a target
    format, or None for the formats it does not take (float32, snorm, integer: the runtime
    resolves those in numpy)."""
    fmt = F.get(format_name)
    f = cl_format(format_name)
    if not (f["cls"] in ("unorm8", "unorm", "half")
            or (fmt.kind is F.Kind.DEPTH_STENCIL and fmt.bits[0] == 24)):
        return None
    top = _rcp_literal(1.0)
    if f["cls"] in ("unorm8", "unorm"):
        tops = _four([float((1 << b) - 1) for b in fmt.bits], len(fmt.bits))
        top = "(float4)(" + ", ".join(_rcp_literal(v) for v in tops) + ")"
    return templating.render(
        "cl_resolve.cl.j2", prelude=prelude_source(TILE, "f32", False), f=f,
        stencil=fmt.kind is F.Kind.DEPTH_STENCIL, samples=samples,
        inv_samples=_rcp_literal(float(f32(1.0 / samples))), top=top,
        d24_rcp=_rcp_literal(float(f32(1.0 / 16777215.0))))


# ---- emission from the IR -----------------------------------------------------------------------------


def emit_cl(tech: ir.Technique, precision: str = "f32") -> Plan:
    """The plan of ``tech`` with one OpenCL program (``CLPassCode.kernel``) per pass;
    ``precision="f64"``: the float64 evaluation of the technique (``plan.precision``)."""
    lang = dialect(precision)
    if precision == "f32":
        tech = lower_mix_constant.run(tech)     # llvmpipe's split of mix(x, y, constant)
    rendered: dict = {}
    frags = [emit_fragment(tech, p, lang, rendered=rendered) for p in tech.passes]
    codes = [CLPassCode("", f["fragment"], tuple(f["inputs"]), f["discard"], tuple(f["sampled"]))
             for f in frags]
    sampled = [tuple(r for r in p.reads if r in f["sampled"]) for p, f in zip(tech.passes, frags)]
    plan = planlib.technique_plan(tech, "cl", codes, sampled)
    if precision != "f32":
        plan = replace(plan, precision=precision)
    return replace(plan, passes=tuple(
        replace(p, code=replace(p.code, kernel=pass_program(plan, p),
                                prelude=_pass_prelude(p, TILE, plan.precision)))
        for p in plan.passes))


def _functions(lang: OpenCLLanguage, functions, rendered: dict) -> list[str]:
    """The user functions a pass calls, as text, each rendered once per technique: a
    function's OpenCL text does not depend on the pass (the dialect reads only technique-wide
    facts; ``in_body`` is off), only the guard and bit helpers it uses must join the pass's
    program.  Each is rendered by a language of its own, which then holds exactly the helpers
    it uses, in the order it first uses them; merged in function order they are the helpers
    one shared language would have collected.  ``rendered``: (language, function) -> (the
    function, text, helpers, raw helpers), filled here (the function is kept so that its
    ``id`` stays its own)."""
    code = []
    for f in functions:
        key = (type(lang), id(f))
        if key not in rendered:
            own = type(lang)(lang.tech, lang.pass_)
            rendered[key] = (f, own.function(f), own.helpers, own.raw_helpers)
        _, text, helpers, raw = rendered[key]
        for name, helper in helpers.items():
            lang.helpers.setdefault(name, helper)
        for name, helper in raw.items():
            lang.raw_helpers.setdefault(name, helper)
        code.append(text)
    return code


def emit_fragment(tech: ir.Technique, p: ir.Pass,
                  language: type[OpenCLLanguage] = OpenCLLanguage, wide: bool = True,
                  rendered: Optional[dict] = None) -> dict:
    """The fragment function of a pass (OpenCL C) and what it reads (``language``: the
    dialect, ``OpenCLLanguage64`` for the float64 evaluation; ``rendered``: user functions
    already rendered for other passes of ``tech``, see ``_functions``)."""
    lang = language(tech, p)
    functions = planlib.pass_functions(tech, p.body)
    inputs = planlib.stage_inputs(p.body, functions)
    kind = p.draw.kind
    scene_only = sorted(n for n in inputs if n in SCENE_VARYINGS or n in SCENE_FLAT)
    # lower.py rejects these programs: here they are invariants
    assert not scene_only or kind is DrawKind.SCENE, (p.name, scene_only)
    assert not (inputs & {"light", "light_index"}) or kind is DrawKind.LIGHTS \
        or p.repeat_per_light, p.name
    if kind is DrawKind.LIGHTS:
        names = {f.name for f in tech.lights.fields}
        assert all(f in names for f in
                   VOLUME_LIGHT_FIELDS[(p.draw.volume or ir.Volume.SPHERE).value]), p.name
    sampled = sorted(planlib.sampled_targets(p.body, functions))
    discard = planlib.may_discard(p.body, functions)
    if not p.body:
        return {"fragment": None, "inputs": sorted(inputs), "discard": False, "sampled": sampled}
    code = _functions(lang, functions, {} if rendered is None else rendered)
    lang.in_body = True
    body = lang.stmts(p.body, 1)
    lang.in_body = False
    if lang.helpers:
        code = [lang.helper_source()] + code
    if lang.raw_helpers:
        code = ["\n\n".join(lang.raw_helpers.values())] + code
    main = "\n".join(["static inline bool pg_fragment(const pg_in *in, pg_out *out) {", *body,
                      "    return true;", "}"])
    text = "\n\n".join(code + [main]) + "\n"
    if language is OpenCLLanguage and wide:
        # the same code for PG_W pixels at once (explicit SIMD over pixels), where it can
        wtext = cl_wide.wide_fragment(tech, p, OpenCLLanguage(tech, p))
        if wtext is not None:
            text += "\n" + wtext
    return {"fragment": text, "inputs": sorted(inputs), "discard": discard, "sampled": sampled}
