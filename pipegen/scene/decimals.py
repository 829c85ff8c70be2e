"""Numbers in text, separated by spaces and newlines, read with whole-array numpy operations.

An OBJ file is mostly numbers.  ``np.fromstring`` reads floats at about 250 ns each (the C
library's ``strtod``) and integers several times faster, so :func:`parse_floats` reads a plain
decimal such as ``-10.927240`` as the integer of its digits (``-10927240``, the point removed
from the text) and the count of digits after its point (6), both found for all tokens at once.
With at most 15 digits the integer ``M`` is exact in float64, and so is ``10**6``; then
``M / 10**6`` is one correctly rounded IEEE division of two exact values, which is the
correctly rounded value ``strtod`` returns for that text (Clinger's fast path), its sign
applied after (so ``-0.0`` stays negative).  The values are bit-identical to
``np.fromstring``'s.  A token that is not a plain decimal (an exponent, ``nan``, more than 15
digits, two points, a stray character) makes :func:`parse_floats` return ``None``, and the
caller falls back to ``np.fromstring``.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

MAX_DIGITS = 15                     # below 2**53: every such integer is exact in float64
_POW10 = np.array([float(10 ** k) for k in range(MAX_DIGITS + 1)])   # exact
_PLAIN_BYTES = b"0123456789.-+ \n"       # the bytes a text of plain decimals may hold
_SPACE, _NEWLINE, _DOT, _MINUS, _PLUS = 32, 10, 46, 45, 43


def tokens(text: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bytes of ``text`` (uint8) and the offsets where its tokens (runs of bytes other
    than space and newline) start and end."""
    t = np.frombuffer(text, dtype=np.uint8)
    blank = np.r_[True, (t == _SPACE) | (t == _NEWLINE), True]
    edges = np.flatnonzero(blank[1:] != blank[:-1])        # alternately a start, an end
    return t, edges[0::2], edges[1::2]


def parse_floats(text: bytes) -> Optional[np.ndarray]:
    """The float64 values of ``text``'s tokens, or ``None`` unless every token is a plain
    decimal: an optional sign, digits and at most one point; 1..15 digits."""
    t, starts, ends = tokens(text)
    if not len(starts):
        return np.zeros(0)
    if text.translate(None, _PLAIN_BYTES):
        return None                                         # a byte no plain decimal has
    first = t[starts]
    signed = (first == _MINUS) | (first == _PLUS)
    if text.count(b"-") + text.count(b"+") != np.count_nonzero(signed):
        return None                                         # a sign inside a token
    dots = np.flatnonzero(t == _DOT)
    if len(dots) == len(starts) and np.all(dots > starts) and np.all(dots < ends):
        dotted = np.arange(len(starts))                     # one point in every token
    else:
        dotted = np.searchsorted(starts, dots, side="right") - 1
        if np.any(np.diff(dotted) == 0):
            return None                                     # two points in a token
    has_dot = np.zeros(len(starts), dtype=bool)
    has_dot[dotted] = True
    digits = ends - starts - signed - has_dot
    if digits.min() < 1 or digits.max() > MAX_DIGITS:
        return None
    mantissa = np.fromstring(text.replace(b".", b""), dtype=np.int64, sep=" ")
    if mantissa.size != len(starts):
        return None
    places = np.zeros(len(starts), dtype=np.int64)
    places[dotted] = ends[dotted] - dots - 1                # digits after the point
    value = np.abs(mantissa).astype(np.float64) / _POW10[places]
    return np.where(first == _MINUS, -value, value)        # -0.0 for "-0.0", as strtod
