"""The shipped techniques, for the tests that run once per technique.

``ALL``: every ``pipelines/*.pipe``, by name.  ``params(...)``: them as pytest parameters, the
variants (``VARIANTS``) marked ``exhaustive``: CI runs the expensive generic per-technique
checks (stress, quiet builds, float32 within a code of float64, specialised = general, either
blend order, image hashes, set-up reuse) on one technique of each family, and ``--exhaustive`` on all.  Each variant is its base
technique plus one feature, checked in its own test file (GL = CL on four scenes, its float64
bounds, what it adds); fifteen techniques through every generic check would not fit CI's
10 minutes on two cores (each costs PoCL builds of its kernels in a clean clone).
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ALL = sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe"))

# variant -> (its base, the test file that checks what it adds)
VARIANTS = {
    "lidr_shadow_volumes": ("lidr_bitplanes", "tests/test_lidr_shadow_volumes.py"),
    "lidr_shadow_prepass": ("lidr_bitplanes", "tests/test_lidr_shadow_prepass.py"),
    "lidr_shadow_indexed": ("lidr_bitplanes", "tests/test_lidr_shadow_indexed.py"),
    "lidr_msaa_texture": ("lidr_transparent", "tests/test_lidr_msaa.py"),
    "lidr_nearest_edge": ("lidr_transparent", "tests/test_lidr_msaa.py"),
}


def params(names=None, path: bool = False) -> list:
    """``names`` (default ``ALL``) as pytest parameters (the name, or with ``path`` the
    .pipe's path), each variant marked ``exhaustive``."""
    out = []
    for name in names or ALL:
        value = ROOT / "pipelines" / f"{name}.pipe" if path else name
        marks = (pytest.mark.exhaustive,) if name in VARIANTS else ()
        out.append(pytest.param(value, id=name, marks=marks))
    return out
