"""The ``W``-wide builtins and helpers a program with ``pg_fragment_w`` starts with."""

from __future__ import annotations

from pipegen.backends.opencl.wide.values import W


def _lanes(n: int) -> str:
    args = ", ".join("abc"[:n])
    per = ", ".join("f(" + ", ".join(f"({x}).s{k}" for x in "abc"[:n]) + ")" for k in range(W))
    return f"#define PGW_LANES{n}(f, T, {args}) ((T##{W})({per}))"


# W-wide forms of the prelude builtins the wide code calls: the scalar definitions per lane
# (selects with the same comparisons; sqrt, floor, fma lane by lane through the same
# intrinsics), so every lane gets the scalar value
def wide_helpers(wmin: int) -> str:
    """The W-wide builtins and helpers a program with ``pg_fragment_w`` starts with."""
    return "\n".join(_helpers(wmin))


def _helpers(wmin: int) -> list:
    return ([
    f"/* ---- wide forms ({W} pixels per call) of the builtins: the scalar definitions per lane ---- */",
    f"#define PG_W {W}",
    f"#define PG_WMIN {wmin}   /* fewer pixels of a triangle's row than this: the scalar function */",
    _lanes(1), _lanes(2), _lanes(3),
    "/* select() as the ternary operator, which OpenCL C defines as select(exp3, exp2, exp1)",
    " * (the sign bit of each mask lane): PoCL's library select() is not inlined into the raster",
    " * kernel (90 out-of-line calls in inferred's material kernel, every live ymm register",
    " * spilled around each); the ternary is expanded in place. 10-18 % of a wide kernel */",
    "PG_INL float8 pg_sel(const float8 a, const float8 b, const int8 m) { return m ? b : a; }",
    "PG_INL int8 pg_sel(const int8 a, const int8 b, const int8 m) { return m ? b : a; }",
    "PG_INL uint8 pg_sel(const uint8 a, const uint8 b, const int8 m) { return m ? b : a; }",
    "PG_INL float8 pg_b_fmax(const float8 a, const float8 b) { return pg_sel(b, a, (b != b) | (a > b)); }",
    "PG_INL float8 pg_b_fmin(const float8 a, const float8 b) { return pg_sel(b, a, (b != b) | (a < b)); }",
    "PG_INL float8 pg_b_fmax(const float8 a, const float b) { return pg_b_fmax(a, (float8)(b)); }",
    "PG_INL float8 pg_b_fmin(const float8 a, const float b) { return pg_b_fmin(a, (float8)(b)); }",
    "PG_INL float8 pg_b_max(const float8 a, const float8 b) { return pg_sel(b, a, a > b); }",
    "PG_INL float8 pg_b_min(const float8 a, const float8 b) { return pg_sel(b, a, a < b); }",
    "PG_INL float8 pg_b_clamp(const float8 x, const float8 lo, const float8 hi) { return pg_b_fmin(pg_b_fmax(x, lo), hi); }",
    "PG_INL float8 pg_b_fma(const float8 a, const float8 b, const float8 c) { return PGW_LANES3(__builtin_fmaf, float, a, b, c); }",
    "PG_INL float8 pg_b_fma(const float8 a, const float8 b, const float c) { return pg_b_fma(a, b, (float8)(c)); }",
    "PG_INL float8 pg_b_sqrt(const float8 a) { return PGW_LANES1(__builtin_sqrtf, float, a); }",
    "PG_INL float8 pg_b_floor(const float8 a) { return PGW_LANES1(__builtin_floorf, float, a); }",
    "PG_INL float8 pg_b_fabs(const float8 x) { return as_float8(as_uint8(x) & 0x7fffffffu); }",
    "PG_INL float8 pg_b_copysign(const float8 x, const float8 y) { return as_float8((as_uint8(x) & 0x7fffffffu) | (as_uint8(y) & 0x80000000u)); }",
    *[line for T in ("int8", "uint8") for line in (
        f"PG_INL {T} pg_b_max(const {T} a, const {T} b) {{ return pg_sel(a, b, a < b); }}",
        f"PG_INL {T} pg_b_min(const {T} a, const {T} b) {{ return pg_sel(a, b, a > b); }}",
        f"PG_INL {T} pg_b_clamp(const {T} x, const {T} lo, const {T} hi) {{ return pg_b_min(pg_b_max(x, lo), hi); }}")],
    "PG_INL uint8 pg_b_sub_sat(const uint8 a, const uint8 b) { return pg_sel((uint8)(0u), a - b, a > b); }",
    "static inline int8 __attribute__((overloadable)) pg_abs(int8 x) { return pg_sel(x, -x, x < 0); }",
    "static inline float8 __attribute__((overloadable)) pg_abs(float8 x) { return pg_b_fabs(x); }",
    "static inline int8 __attribute__((overloadable)) pg_sign(int8 x) { return pg_sel((int8)(0), (int8)(1), x > 0) - pg_sel((int8)(0), (int8)(1), x < 0); }",
    "static inline float8 __attribute__((overloadable)) pg_sign(float8 x) { return PGW_LANES1(sign, float, x); }",
    "static inline float8 __attribute__((overloadable)) pg_smoothstep(const float8 e0, const float8 e1, const float8 x) {",
    "    const float8 t = pg_b_fmin(pg_b_fmax((x - e0) / (e1 - e0), 0.0f), 1.0f);",
    "    return t * (t * (3.0f - 2.0f * t));",
    "}",
    "static inline float8 __attribute__((overloadable)) pg_exp2(float8 x) {",
    "    x = pg_b_fmax(pg_b_fmin(x, 129.0f), -126.99999f);",
    "    const float8 ip = pg_b_floor(x);",
    "    const float8 f = x - ip;",
    "    const float8 ei = as_float8((convert_int8(ip) + 127) << 23);",
    "    const float8 f2 = f * f;",
    "    const float8 odd = pg_b_fma(f2, pg_b_fma(f2, ((float8)(0.0018775767f)), ((float8)(0.055826318f))), ((float8)(0.6931531f)));",
    "    const float8 even = pg_b_fma(f2, pg_b_fma(f2, ((float8)(0.00898934f)), ((float8)(0.24015361f))), ((float8)(1.0f)));",
    "    return ei * pg_b_fma(odd, f, even);",
    "}",
    "static inline float8 __attribute__((overloadable)) pg_log2(const float8 x) {",
    "    const int8 i = as_int8(x);",
    "    const float8 le = convert_float8(((i & 0x7f800000) >> 23) - 127);",
    "    const float8 m = as_float8((i & 0x007fffff) | 0x3f800000);",
    "    const float8 y = (m - 1.0f) / (m + 1.0f);",
    "    const float8 z = y * y;",
    "    const float8 z2 = z * z;",
    "    const float8 odd = pg_b_fma(z2, ((float8)(0.40334386f)), ((float8)(0.9617916f)));",
    "    const float8 even = pg_b_fma(z2, pg_b_fma(z2, ((float8)(0.40671805f)), ((float8)(0.5774403f))), ((float8)(2.88539f)));",
    "    return pg_b_fma(y, pg_b_fma(odd, z, even), le);",
    "}",
    "/* 8 half codes to floats: the prelude's pg_half_bits_to_float (vload_half) per lane; with",
    " * F16C vcvtph2ps, as the prelude's half4 form (exact, a NaN's payload kept and quieted: the",
    " * same bits for all 65536 codes, measured), else its branches as selects */",
    "#ifdef __F16C__",
    "PG_INL float8 pgw_half8_to_float8(const ushort8 h) {",
    "    typedef short pgw_v8hi __attribute__((__vector_size__(16)));",
    "    typedef float pgw_v8sf __attribute__((__vector_size__(32)));",
    "    union { ushort8 u; pgw_v8hi v; } a;",
    "    union { pgw_v8sf v; float8 f; } r;",
    "    a.u = h;",
    "    r.v = __builtin_ia32_vcvtph2ps256(a.v);",
    "    return r.f;",
    "}",
    "#else",
    "PG_INL float8 pgw_half8_to_float8(const ushort8 c) {",
    "    const uint8 h = __builtin_convertvector(c, uint8);",
    "    const uint8 s = (h & 0x8000u) << 16, e = (h >> 10) & 31u, m = h & 1023u;",
    "    const uint8 special = s | 0x7f800000u | (m << 13) | pg_sel((uint8)(0u), (uint8)(0x00400000u), m != 0u);",
    "    const uint8 small = s | as_uint8(convert_float8(m) * 5.9604644775390625e-8f);",
    "    const uint8 normal = s | ((e + 112u) << 23) | (m << 13);",
    "    return as_float8(pg_sel(pg_sel(normal, small, e == 0u), special, e == 31u));",
    "}",
    "#endif",
    f"typedef struct {{ float{W} c[4]; }} pgw_float{W}x4;",
    f"typedef struct {{ uint{W} c[4]; }} pgw_uint{W}x4;",
    f"PG_INL int pgw_all(const int{W} m) {{ return (" + " & ".join(f"m.s{k}" for k in range(W)) + ") != 0; }",
    ])
