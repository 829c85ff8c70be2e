"""Byte counts as text: the one formatter of every "1.23 MiB" pipegen prints.

Binary units (1 MiB = 2^20 bytes), the unit and the decimals fixed per unit so that columns of
figures line up and outputs stay comparable between versions: MiB with 2 decimals, KiB with 1,
bytes whole.
"""

from __future__ import annotations

from typing import Optional

KIB = 1 << 10
MIB = 1 << 20


def mebibytes(n: int) -> float:
    """``n`` bytes in MiB, unrounded (plots, sums)."""
    return n / MIB


def format_bytes(n: int, unit: Optional[str] = None, *, exact: bool = False,
                 suffix: bool = True) -> str:
    """``n`` bytes as text.

    ``unit``: None picks the largest of MiB, KiB and B that ``|n|`` reaches (``"4.0 KiB"``, a
    saving may be negative); ``"MiB"`` always MiB (``"0.00 MiB"``: a table's column).
    ``exact``: the byte count first, the unit figure in brackets (``"4096 (0.00 MiB)"``).
    ``suffix``: False leaves the unit off (a column whose header names it)."""
    if unit is None:
        unit = "MiB" if abs(n) >= MIB else "KiB" if abs(n) >= KIB else "B"
    if unit == "MiB":
        figure = f"{n / MIB:.2f}"
    elif unit == "KiB":
        figure = f"{n / KIB:.1f}"
    elif unit == "B":
        figure = f"{n}"
    else:
        raise ValueError(f"unknown unit {unit!r} (MiB, KiB, B)")
    text = f"{figure} {unit}" if suffix else figure
    return f"{n} ({text})" if exact else text
