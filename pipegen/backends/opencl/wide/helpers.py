"""The ``W``-wide builtins and helpers a program with ``pg_fragment_w`` starts with, rendered
from ``templates/cl_wide_helpers.cl.j2``: the prelude's definitions of the builtins
(``templates/cl_builtins.cl.j2``, the macros ``cl_prelude.cl.j2`` renders for the scalar types)
rendered for the ``W``-lane types, so that every lane gets the scalar value, and the wide
path's own helpers (``pg_sel``, ``PGW_LANESn``, the wide half decoding)."""

from __future__ import annotations

import functools

from pipegen.backends import templating
from pipegen.backends.opencl.wide.values import W


@functools.lru_cache(maxsize=None)
def wide_helpers(wmin: int) -> str:
    """The helpers' text (``wmin``: ``PG_WMIN``, the fewest pixels of a triangle's row shaded
    wide), without a last newline (the pass template puts it)."""
    return templating.render("cl_wide_helpers.cl.j2", W=W, wmin=wmin).removesuffix("\n")
