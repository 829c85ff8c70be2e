"""float32 scalars without numpy: rounding to float32 and the shortest text of a float32.

The compiler folds constants and writes float literals in float32, the precision the shaders
compute in.  It used to do so with ``numpy.float32``; importing numpy costs ``pipegen compile``
about a third of its time, so these are the same operations in plain Python, bit for bit
(tests/test_float32.py compares them with numpy over every exponent and random bit patterns):

- ``f32(x)``: ``float(numpy.float32(x))``, round to nearest even, ±inf beyond the float32
  range;
- ``f32_str(x)``: ``str(numpy.float32(x))`` as numpy 2 prints it: the shortest digits that
  identify the float32 (Dragon4 in its unique mode, as numpy's ``dragon4.c``), positional
  between 1e-4 and 1e6 (``0.001``, ``100.0``), scientific outside (``1e-05``, ``1.5e+07``).

Sums, differences, products and quotients of two float32 values computed in double and then
rounded by ``f32`` are the float32 results: a double holds more than twice float32's 24 bits
of precision, so rounding twice cannot differ from rounding once.
"""

from __future__ import annotations

import functools
import math
import struct

_F32 = struct.Struct("<f")
_U32 = struct.Struct("<I")


def f32(x: float) -> float:
    """``x`` rounded to the nearest float32 (ties to even), as a Python float; values beyond
    the float32 range become ±inf (numpy's cast), NaN stays NaN."""
    try:
        return _F32.unpack(_F32.pack(x))[0]
    except OverflowError:          # finite, but rounds beyond FLT_MAX
        return math.copysign(math.inf, x)


def f32_bits(x: float) -> int:
    """The IEEE bits of ``f32(x)`` as an unsigned 32-bit integer."""
    return _U32.unpack(_F32.pack(f32(x)))[0]


def f32_str(x: float) -> str:
    """``str(numpy.float32(x))`` (numpy 2): the shortest decimal that rounds back to the same
    float32; ``nan``, ``inf``, ``-inf`` for the non-finite values."""
    return _bits_str(f32_bits(x))


@functools.lru_cache(maxsize=4096)
def _bits_str(bits: int) -> str:
    """``f32_str`` of the float32 with IEEE bits ``bits``.  Cached by the bits (not the float:
    0.0 and -0.0 are equal keys): a compile prints a few dozen distinct constants about a
    thousand times (deferred_calver: 29 and 907), and Dragon4 in Python costs about 5 us each."""
    sign = "-" if bits >> 31 else ""
    biased, frac = (bits >> 23) & 0xFF, bits & 0x7FFFFF
    if biased == 0xFF:
        return "nan" if frac else sign + "inf"
    if biased == 0 and frac == 0:
        return sign + "0.0"
    digits, exp10 = _shortest_digits(biased, frac)
    value = abs(_F32.unpack(_U32.pack(bits))[0])
    if 1e-4 <= value < 1e6:
        return sign + _positional(digits, exp10)
    return sign + _scientific(digits, exp10)


def _shortest_digits(biased: int, frac: int) -> tuple[str, int]:
    """Dragon4's unique mode for a positive finite float32 (numpy's ``Dragon4`` with no
    cutoff): the digits and the decimal exponent of the first one.

    The value is ``r / s``; ``m_lo / s`` and ``m_hi / s`` are half the distances to the
    neighbouring float32 values below and above (the one below is half as far at the bottom
    of a binade).  Digits are produced until the rest of the value lies within a margin
    (inclusive when the mantissa is even: round-half-even would read the decimal back as this
    value), then the last digit is rounded to the nearer side, ties to the even digit.
    """
    if biased:
        mantissa, exponent = frac | 0x800000, biased - 150
        unequal = biased != 1 and frac == 0
    else:
        mantissa, exponent, unequal = frac, -149, False
    even = mantissa % 2 == 0
    # value = r / s; margins m_lo / s and m_hi / s (numpy's scaledValue, scale, scaledMargin*)
    if unequal:
        if exponent > 0:
            r, s, m_lo = mantissa << (exponent + 2), 4, 1 << exponent
        else:
            r, s, m_lo = mantissa << 2, 1 << (2 - exponent), 1
        m_hi = 2 * m_lo
    else:
        if exponent > 0:
            r, s, m_lo = mantissa << (exponent + 1), 2, 1 << exponent
        else:
            r, s, m_lo = mantissa << 1, 1 << (1 - exponent), 1
        m_hi = m_lo
    # the first digit's exponent: 10^k <= value < 10^(k + 1)
    k = math.floor(math.log10(mantissa) + exponent * math.log10(2))
    while _scaled_ge(r, s, k + 1):
        k += 1
    while not _scaled_ge(r, s, k):
        k -= 1
    if k >= 0:
        s *= 10 ** k
    else:
        p = 10 ** -k
        r, m_lo, m_hi = r * p, m_lo * p, m_hi * p
    out = []
    while True:
        digit, r = divmod(r, s)
        low = r <= m_lo if even else r < m_lo
        high = r + m_hi >= s if even else r + m_hi > s
        if low or high:
            break
        out.append(digit)
        r, m_lo, m_hi = r * 10, m_lo * 10, m_hi * 10
    round_down = low
    if low == high:
        twice = 2 * r
        round_down = twice < s or (twice == s and digit % 2 == 0)
    if not round_down:
        digit += 1
        while digit == 10:        # 0.999… rounds up to the next power of ten
            if not out:
                digit, k = 1, k + 1
                break
            digit = out.pop() + 1
    out.append(digit)
    return "".join(map(str, out)), k


def _scaled_ge(r: int, s: int, k: int) -> bool:
    """``r / s >= 10^k``."""
    return r >= s * 10 ** k if k >= 0 else r * 10 ** -k >= s


def _positional(digits: str, exp10: int) -> str:
    """numpy's positional format with one trailing zero left (``100.0``, ``0.001``)."""
    if exp10 >= 0:
        whole, fraction = digits[:exp10 + 1].ljust(exp10 + 1, "0"), digits[exp10 + 1:]
    else:
        whole, fraction = "0", "0" * (-exp10 - 1) + digits
    return f"{whole}.{fraction.rstrip('0') or '0'}"


def _scientific(digits: str, exp10: int) -> str:
    """numpy's scientific format, trailing zeros and a bare point trimmed, at least two
    exponent digits (``1e-05``, ``1.5e+07``)."""
    mantissa = digits[0] + ("." + digits[1:] if len(digits) > 1 else "")
    if "." in mantissa:
        mantissa = mantissa.rstrip("0").rstrip(".")
    return f"{mantissa}e{'-' if exp10 < 0 else '+'}{abs(exp10):02d}"
