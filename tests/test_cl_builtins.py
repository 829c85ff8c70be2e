"""The prelude's inline forms of OpenCL builtins (fma, fmin, fmax, min, max, clamp, sqrt,
floor, fabs, copysign, sub_sat, vload_half*, vstore_half*_rtz) against PoCL's own library
functions, on special values (signed zeros, denormals, infinities, NaNs, half-float
boundaries) and random bit patterns.

Both run in one kernel built with the runtime's options, so under the same floating-point
mode (PoCL runs ``-cl-denorms-are-zero`` kernels with denormal operands read as zero).  Results
must agree bit for bit, except for what the machine code of either side leaves open: which
NaN an operation with NaN operands returns (the operand order of the chosen instruction) and
whether a denormal operand passed through unchanged (a compare and blend) or as the zero the
denormals-are-zero mode reads it as (maxss), which every later float operation reads alike.
The half conversions are integer code (or the same F16C instructions) and agree exactly.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

pytest.importorskip("pyopencl")

pytestmark = [pytest.mark.gl, pytest.mark.cl]

SPECIAL = np.array([
    0x0, 0x80000000, 0x1, 0x80000001, 0x7fffff, 0x807fffff, 0x800000, 0x80800000, 0x400000,
    0x3f800000, 0xbf800000, 0x3fc00000, 0x3f000000, 0xbf000000, 0x3effffff, 0x3f7fffff,
    0xbfc00000, 0x4b000000, 0x4b7fffff, 0xcb000001, 0x4affffff, 0x7f7fffff, 0xff7fffff,
    0x7f800000, 0xff800000, 0x7fc00000, 0xffc00000, 0x7f800001, 0x7fa00000, 0xff812345,
    0x477fe000, 0x477fefff, 0x477ff000, 0x47800000, 0x38800000, 0x387fffff, 0x33800000,
    0x337fffff, 0x33000000, 0x32ffffff, 0x40490fdb, 0xc2280001], np.uint32)

FUNCS1 = ["sqrt", "floor", "fabs", "half_rtz", "half_load", "half_sw"]
FUNCS2 = ["fmax", "fmin", "max", "min", "copysign"]
FUNCS3 = ["fma", "clamp"]
WIDTHS = ["", "2", "3", "4"]


def _vec(n: str, args: list) -> str:
    """A float<n> built from the first n expressions (n "" = scalar)."""
    return args[0] if not n else f"(float{n})({', '.join(args[:int(n)])})"


def _lanes(n: str, v: str) -> list:
    return [v] if not n else [f"{v}.{c}" for c in "xyzw"[:int(n)]]


def _store(slot: int, lib: list, inl: list, conv: str = "as_uint") -> str:
    """Statements writing library lanes to out[(i * S + slot) * 8 + c], inline ones to + 4."""
    out = [f"out[(i * S + {slot}) * 8 + {c}] = {conv}({v});" for c, v in enumerate(lib)]
    out += [f"out[(i * S + {slot}) * 8 + 4 + {c}] = {conv}({v});" for c, v in enumerate(inl)]
    return "\n        ".join(out)


HALVES = ("ushort h[4] = {(ushort)as_uint(x[i]), (ushort)(as_uint(x[i]) >> 16),\n"
          "                     (ushort)as_uint(x[(i + 1) % nx]), "
          "(ushort)(as_uint(x[(i + 1) % nx]) >> 16)};")


def _unary(f: str, n: str, slot: int) -> str:
    a = _vec(n, ["x[i]", "-x[i]", "x[i] * 0.5f", "x[(i + 1) % nx]"])
    if f == "half_rtz":            # library vstore_half*_rtz vs the inline codes
        if n == "3":
            return ""
        lib = [f"t[{c}]" for c in range(int(n or 1))]
        if n == "4":
            return (f"{{ ushort t[4]; vstore_half4_rtz({a}, 0, (__private half *)t);\n"
                    f"        const ushort4 v = pg_float4_to_half4_bits_rtz({a});\n        "
                    + _store(slot, lib, _lanes(n, "v"), "") + " }")
        return (f"{{ ushort t[4]; vstore_half{n}_rtz({a}, 0, (__private half *)t);\n"
                f"        const float{n} v = {a};\n        "
                + _store(slot, lib, [f"pg_float_to_half_bits_rtz({v}, false)"
                                     for v in _lanes(n, "v")], "") + " }")
    if f == "half_sw":             # the software conversions (used where F16C is missing)
        if n == "4":
            return (f"{{ ushort t[4]; vstore_half4_rtz({a}, 0, (__private half *)t);\n"
                    f"        const float4 v = {a};\n        "
                    + _store(slot, [f"t[{c}]" for c in range(4)],
                             [f"pg_float_to_half_bits_rtz({v}, true)" for v in _lanes(n, "v")],
                             "") + " }")
        if not n:
            return (f"{{ {HALVES}\n"
                    "        const float4 l = vload_half4(0, (__private const half *)h);\n        "
                    + _store(slot, _lanes("4", "l"),
                             [f"pg_half_bits_to_float(h[{c}])" for c in range(4)]) + " }")
        return ""
    if f == "half_load":           # library vload_half* vs the inline decoding
        if n == "3":
            return ""
        if not n:
            return ("{ const ushort h = (ushort)(as_uint(x[i]) >> (i & 1 ? 16 : 0));\n        "
                    + _store(slot, ["vload_half(0, (__private const half *)&h)"],
                             ["pg_half_bits_to_float(h)"]) + " }")
        inl = ("pg_half4_bits_to_float4(vload4(0, h))" if n == "4" else
               "(float2)(pg_half_bits_to_float(h[0]), pg_half_bits_to_float(h[1]))")
        return (f"{{ {HALVES}\n"
                f"        const float{n} l = vload_half{n}(0, (__private const half *)h);\n"
                f"        const float{n} m = {inl};\n        "
                + _store(slot, _lanes(n, "l"), _lanes(n, "m")) + " }")
    return (f"{{ const float{n} l = {f}({a}), m = pg_b_{f}({a});\n        "
            + _store(slot, _lanes(n, "l"), _lanes(n, "m")) + " }")


def _kernels() -> str:
    """Kernels writing library and inline results side by side: out[(i * S + slot) * 8 + c],
    lanes 0-3 library, 4-7 inline (vector widths 1-4 cover all call forms)."""
    body = [_unary(f, n, f_i * 4 + w_i)
            for f_i, f in enumerate(FUNCS1) for w_i, n in enumerate(WIDTHS)]
    un = ("__kernel void un(const int nx, __global const float *x, __global uint *out) {\n"
          f"    const int i = get_global_id(0); const int S = {len(FUNCS1) * 4};\n    "
          + "\n    ".join(b for b in body if b) + "\n}")
    body = []
    for f_i, f in enumerate(FUNCS2):
        for w_i, n in enumerate(WIDTHS):
            for s_i, scalar_b in enumerate((False, True) if n and f != "copysign" else (False,)):
                a = _vec(n, ["x[i]", "y[i]", "-x[i]", "y[(i + 7) % nx]"])
                b = "y[i]" if scalar_b else _vec(n, ["y[i]", "x[i]", "y[i]", "x[(i + 3) % nx]"])
                body.append(f"{{ const float{n} l = {f}({a}, {b}), m = pg_b_{f}({a}, {b});\n"
                            "        " + _store((f_i * 4 + w_i) * 2 + s_i, _lanes(n, "l"),
                                                _lanes(n, "m")) + " }")
    bin_ = ("__kernel void bin(const int nx, __global const float *x, __global const float *y,\n"
            "                  __global uint *out) {\n"
            f"    const int i = get_global_id(0); const int S = {len(FUNCS2) * 8};\n    "
            + "\n    ".join(body) + "\n}")
    body = []
    for f_i, f in enumerate(FUNCS3):
        for w_i, n in enumerate(WIDTHS):
            for s_i, scalar in enumerate((False, True) if n and f == "clamp" else (False,)):
                a = _vec(n, ["x[i]", "y[i]", "z[i]", "x[(i + 5) % nx]"])
                b = "y[i]" if scalar else _vec(n, ["y[i]", "z[i]", "x[i]", "y[(i + 5) % nx]"])
                c = "z[i]" if scalar else _vec(n, ["z[i]", "x[i]", "y[i]", "z[(i + 5) % nx]"])
                body.append(f"{{ const float{n} l = {f}({a}, {b}, {c}),\n"
                            f"                     m = pg_b_{f}({a}, {b}, {c});\n"
                            "        " + _store((f_i * 4 + w_i) * 2 + s_i, _lanes(n, "l"),
                                                _lanes(n, "m")) + " }")
    ter = ("__kernel void ter(const int nx, __global const float *x, __global const float *y,\n"
           "                  __global const float *z, __global uint *out) {\n"
           f"    const int i = get_global_id(0); const int S = {len(FUNCS3) * 8};\n    "
           + "\n    ".join(body) + "\n}")
    ints = """__kernel void ints(__global const int *x, __global const int *y,
                   __global const int *z, __global int *out) {
    const int i = get_global_id(0); const int a = x[i], b = y[i], c = z[i];
    out[i * 16 + 0] = max(a, b); out[i * 16 + 8] = pg_b_max(a, b);
    out[i * 16 + 1] = min(a, b); out[i * 16 + 9] = pg_b_min(a, b);
    out[i * 16 + 2] = clamp(a, b, c); out[i * 16 + 10] = pg_b_clamp(a, b, c);
    out[i * 16 + 3] = (int)max((uint)a, (uint)b);
    out[i * 16 + 11] = (int)pg_b_max((uint)a, (uint)b);
    out[i * 16 + 4] = (int)min((uint)a, (uint)b);
    out[i * 16 + 12] = (int)pg_b_min((uint)a, (uint)b);
    const int2 l = clamp((int2)(a, b), (int2)(b, c), (int2)(c, a));
    const int2 m = pg_b_clamp((int2)(a, b), (int2)(b, c), (int2)(c, a));
    out[i * 16 + 5] = l.x; out[i * 16 + 13] = m.x; out[i * 16 + 6] = l.y; out[i * 16 + 14] = m.y;
    const uint4 p = sub_sat(min((uint4)(a, b, c, a), (uint4)(255u)), (uint4)(b, c, a, b));
    const uint4 q = pg_b_sub_sat(pg_b_min((uint4)(a, b, c, a), (uint4)(255u)), (uint4)(b, c, a, b));
    out[i * 16 + 7] = (int)(p.x ^ p.y * 3u ^ p.z * 7u ^ p.w * 11u);
    out[i * 16 + 15] = (int)(q.x ^ q.y * 3u ^ q.z * 7u ^ q.w * 11u);
}"""
    return "\n".join([un, bin_, ter, ints])


@pytest.fixture(scope="module")
def prog():
    from pipegen.backends.opencl.programs import prelude_source
    from pipegen.runtime.cl import context as cl_context
    pre = prelude_source()
    return cl_context.build_program("#define PG_LIBRARY_BUILTINS\n" + pre + _kernels())


def _run(prog, name, args, width, dtype=np.uint32):
    import pyopencl as cl
    from pipegen.runtime.cl import context as cl_context
    ctx, q = cl_context.get_context()
    mf = cl.mem_flags
    n = len(args[0])
    bufs = [cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
            for a in args]
    out = cl.Buffer(ctx, mf.READ_WRITE, n * width * 8 * 4)
    cl.enqueue_fill_buffer(q, out, np.uint32(0), 0, n * width * 8 * 4)
    kern = cl.Kernel(prog, name)
    lead = [] if name == "ints" else [np.int32(n)]
    kern(q, (n,), None, *lead, *bufs, out)
    res = np.empty((n, width, 8), dtype)
    cl.enqueue_copy(q, res, out)
    return res[..., :4], res[..., 4:]


def _canonical(bits: np.ndarray) -> np.ndarray:
    """float32 bit patterns with every NaN made one NaN and denormals made signed zeros."""
    b = bits.astype(np.uint32)
    mag = b & 0x7FFFFFFF
    b = np.where(mag > 0x7F800000, np.uint32(0x7FC00000), b)
    return np.where(mag < 0x00800000, b & 0x80000000, b)


def _values(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 2 ** 32, n, dtype=np.uint64).astype(np.uint32)
    normal = (rng.standard_normal(n) * 10.0 ** rng.integers(-8, 8, n)).astype(np.float32)
    halfish = rng.integers(0, 2 ** 16, n).astype(np.float32) * np.float32(2.0 ** -10)
    return np.concatenate([bits, normal.view(np.uint32), halfish.view(np.uint32)])


def _check(lib, inl, inputs, what):
    bad = np.nonzero(lib != inl)
    assert len(bad[0]) == 0, (what, [(tuple(hex(int(v[i])) for v in inputs), int(s), int(c),
                                        hex(int(lib[i, s, c])), hex(int(inl[i, s, c])))
                                       for i, s, c in list(zip(*bad))[:6]])


def test_unary_builtins(prog):
    x = np.concatenate([SPECIAL, _values(30000, 1)])
    lib, inl = _run(prog, "un", [x.view(np.float32)], len(FUNCS1) * 4)
    # the half conversions are exact integer code: bit for bit, NaNs included
    exact = np.zeros(lib.shape[1], bool)
    exact[FUNCS1.index("half_rtz") * 4:] = True
    _check(np.where(exact[None, :, None], lib, _canonical(lib)),
           np.where(exact[None, :, None], inl, _canonical(inl)), [x], "unary")


def test_binary_builtins(prog):
    a, b = (v.ravel() for v in np.meshgrid(SPECIAL, SPECIAL))
    a = np.concatenate([a, _values(20000, 2)])
    b = np.concatenate([b, _values(20000, 3)])
    lib, inl = _run(prog, "bin", [a.view(np.float32), b.view(np.float32)], len(FUNCS2) * 8)
    _check(_canonical(lib), _canonical(inl), [a, b], "binary")


def test_ternary_builtins(prog):
    t = np.array(list(itertools.product(SPECIAL, SPECIAL, SPECIAL)), np.uint32).T
    xs = [np.concatenate([t[k], _values(10000, 4 + k)]) for k in range(3)]
    lib, inl = _run(prog, "ter", [v.view(np.float32) for v in xs], len(FUNCS3) * 8)
    _check(_canonical(lib), _canonical(inl), xs, "ternary")


def test_integer_builtins(prog):
    special = np.array([0, 1, -1, 2 ** 31 - 1, -2 ** 31, 5, -7, 255, 256], np.int64)
    t = np.array(list(itertools.product(special, special, special)), np.int64).T
    rng = np.random.default_rng(7)
    r = rng.integers(-2 ** 31, 2 ** 31, (3, 20000))
    xs = [np.concatenate([t[k], r[k]]).astype(np.int32) for k in range(3)]
    lib, inl = _run(prog, "ints", xs, 2, np.int32)       # (n, 2, 4): lib in row 0, inline 1
    _check(np.concatenate([lib[:, 0], inl[:, 0]], 1)[:, None], np.concatenate(
        [lib[:, 1], inl[:, 1]], 1)[:, None], xs, "integer")
