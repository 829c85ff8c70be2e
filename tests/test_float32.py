"""pipegen.core.float32 gives numpy's float32 results without numpy, bit for bit: the rounding
(``f32``), the text of a literal (``f32_str`` == ``str(numpy.float32(x))``), and through them
the constant folds (opt_fold_constants, lower_mix_constant) that used numpy before.  The
references below are the numpy formulas the compiler used until it stopped importing numpy."""

from __future__ import annotations

import math
import operator
import random
import struct

import numpy as np
import pytest

from pipegen.ir import nodes as ir
from pipegen.core.float32 import f32, f32_str
from pipegen.passes import lower_mix_constant, opt_fold_constants

RNG = random.Random(20261201)


def from_bits(bits: int) -> float:
    return struct.unpack("<f", struct.pack("<I", bits))[0]


def bits_of(x: float) -> int:
    """float32 bits of a value that is already a float32 (NaNs compared as one)."""
    if math.isnan(x):
        return 0x7FC00000
    return struct.unpack("<I", struct.pack("<f", x))[0]


def sample_bits(random_count: int) -> list[int]:
    """Every exponent with mantissas at and next to the binade ends (where the margins of the
    shortest-digits search are unequal), subnormals, both signs, and random patterns."""
    out = []
    for e in range(256):
        for frac in (0, 1, 2, 3, 0x400000, 0x400001, 0x7FFFFE, 0x7FFFFF, 0x2AAAAA):
            out += [(e << 23) | frac, 0x80000000 | (e << 23) | frac]
    out += [RNG.getrandbits(32) for _ in range(random_count)]
    out += [RNG.getrandbits(23) for _ in range(random_count // 10)]       # subnormals
    return out


# f32_str is numpy 2's str of a float32; numpy 1.x writes values from 1e6 up to 1e16
# positionally ("1000000.0" where numpy 2 writes "1e+06"), so the comparisons with numpy's own
# str hold from numpy 2 on (the package accepts numpy 1.24: its emitted text does not depend
# on numpy's str, only on f32_str)
NUMPY_2 = np.lib.NumpyVersion(np.__version__) >= "2.0.0"


@pytest.mark.skipif(not NUMPY_2, reason="f32_str is numpy 2's str (numpy 1.x prints 1e6..1e16 "
                                        "positionally)")
def test_f32_str_is_numpys_str_of_float32():
    bits = sample_bits(30000)
    values = np.array(bits, dtype=np.uint32).view(np.float32)
    wrong = [(hex(b), f32_str(float(v)), str(v)) for b, v in zip(bits, values)
             if f32_str(float(v)) != str(v)]
    assert not wrong, wrong[:10]


@pytest.mark.parametrize("x, text", [
    (0.0, "0.0"), (-0.0, "-0.0"), (1.0, "1.0"), (0.1, "0.1"), (100.0, "100.0"),
    (1e-4, "1e-04"), (1.00000005e-4, "0.000100000005"), (999999.9375, "999999.94"),
    (1e6, "1e+06"), (123456789.0, "1.2345679e+08"), (2.0 ** -149, "1e-45"),
    (3.4028234663852886e38, "3.4028235e+38"), (1e39, "inf"), (-1e39, "-inf"),
    (math.nan, "nan"), (1 / 3, "0.33333334"), (16777217.0, "1.6777216e+07"),
])
def test_f32_str_examples(x, text):
    assert f32_str(x) == text
    if NUMPY_2:
        with np.errstate(over="ignore"):
            assert str(np.float32(x)) == text


def test_f32_str_cache_keeps_zeros_and_roundings_apart():
    # f32_str is cached by float32 bits: 0.0 == -0.0 as floats, and doubles that round to one
    # float32 share its text
    assert [f32_str(0.0), f32_str(-0.0), f32_str(0.0)] == ["0.0", "-0.0", "0.0"]
    assert f32_str(0.1) == f32_str(0.10000000149011612) == "0.1"


def test_f32_rounds_as_numpy_casts():
    doubles = [RNG.uniform(-1, 1) * 10.0 ** RNG.randint(-50, 50) for _ in range(20000)]
    flt_max = float(np.finfo(np.float32).max)
    half_ulp = 2.0 ** 103
    doubles += [flt_max, flt_max + half_ulp * 0.999, flt_max + half_ulp, -(flt_max + half_ulp),
                1e39, -1e39, 2.0 ** -150, 2.0 ** -150 * 1.0001, -(2.0 ** -151), 1e-50,
                math.inf, -math.inf, 0.0, -0.0, 16777217.0, 0.1]
    with np.errstate(over="ignore"):
        wrong = [x for x in doubles if bits_of(f32(x)) != bits_of(float(np.float32(x)))]
    assert not wrong, wrong[:10]
    assert math.isnan(f32(math.nan))


def _specials() -> list[float]:
    return [0.0, -0.0, 1.0, -1.0, 0.5, 3.0, 1e-45, -1e-45, 1e-38, 3.4028234663852886e38,
            -3.4028234663852886e38, math.inf, -math.inf, math.nan, 1e-50, 1e39, 0.1, 1 / 3]


def _float_pairs(count: int) -> list[tuple[float, float]]:
    randoms = [from_bits(RNG.getrandbits(32)) for _ in range(count)]
    randoms += [RNG.uniform(-4, 4) for _ in range(count)]      # doubles: rounded first
    pairs = [(a, b) for a in _specials() for b in _specials()]
    pairs += [(RNG.choice(randoms), RNG.choice(randoms)) for _ in range(count)]
    pairs += [(a, a * (1 + 2.0 ** -23)) for a in randoms[:200]]          # cancellation
    return pairs


def _numpy_fold(op: str, x: float, y: float):
    """opt_fold_constants._fold_binary for floats, as it was with numpy."""
    arith = {"+": operator.add, "-": operator.sub, "*": operator.mul}
    compare = {"==": operator.eq, "<": operator.lt, ">=": operator.ge}
    with np.errstate(all="ignore"):
        if op in compare:
            return bool(compare[op](np.float32(x), np.float32(y)))
        if op in arith:
            r = arith[op](np.float32(x), np.float32(y))
            return float(r) if np.isfinite(r) else None
        if op == "/" and y != 0:
            return float(np.float32(x) / np.float32(y))
    return None


@pytest.mark.parametrize("op", ["+", "-", "*", "/", "==", "<", ">="])
def test_float_folds_are_numpys(op):
    wrong = []
    for x, y in _float_pairs(4000):
        got = opt_fold_constants._fold_binary(op, ir.Const(ir.FLOAT, x), ir.Const(ir.FLOAT, y))
        want = _numpy_fold(op, x, y)
        same = got == want if isinstance(want, bool) or want is None or got is None \
            else bits_of(got) == bits_of(want)
        if not same or type(got) is not type(want):
            wrong.append((x, y, got, want))
    assert not wrong, wrong[:10]


def test_negation_and_conversion_folds_are_numpys():
    with np.errstate(all="ignore"):
        for x in _specials() + [RNG.uniform(-1e6, 1e6) for _ in range(2000)]:
            neg = opt_fold_constants.fold_expr(ir.Unary("-", ir.Const(ir.FLOAT, x), ir.FLOAT))
            assert bits_of(neg.value) == bits_of(float(-np.float32(x))), x
        for v in [0, 1, 7, 16777217, 2 ** 31 - 1, -(2 ** 31), 2 ** 32 - 1]:
            c = opt_fold_constants._fold_conversion(ir.FLOAT, ir.Const(ir.INT, v))
            assert c.value == float(np.float32(v)), v


def test_integer_wrap_is_twos_complement():
    values = [0, 1, -1, 2 ** 31 - 1, 2 ** 31, -(2 ** 31), -(2 ** 31) - 1, 2 ** 32, 2 ** 62,
              -(2 ** 62)] + [RNG.randint(-(2 ** 63), 2 ** 63 - 1) for _ in range(2000)]
    for v in values:
        assert opt_fold_constants._wrap(v, ir.INT) == int(np.int64(v).astype(np.int32)), v


def test_mix_weight_complement_is_numpys():
    with np.errstate(all="ignore"):
        for t in _specials() + [RNG.random() for _ in range(2000)]:
            call = ir.Call("mix", (ir.Var("a", ir.FLOAT, "local"), ir.Var("b", ir.FLOAT, "local"),
                                   ir.Const(ir.FLOAT, t)), ir.FLOAT, builtin=True)
            lowered = lower_mix_constant.lower_call(call)
            one_minus = lowered.left.right.value
            assert bits_of(one_minus) == bits_of(float(np.float32(1.0) - np.float32(t))), t
