"""Packing schemes: generated pack/unpack functions, their capacity and quantisation error.

A ``pack NAME = SCHEME(key: value, …)`` declaration becomes a ``PackingSpec`` here.  Its
``functions_source`` is shader-language text (GLSL-flavoured, see docs/language.md) that the
front end parses like user code, so both backends emit it; every function is named
``NAME_fn`` and user code calls it as ``NAME.fn(…)``.

Every generated function has a numpy mirror (``numpy_impl``) that computes the same thing in
float32/uint32, so the schemes can be tested exhaustively without a GPU, and so the static
error of the normal encodings can be *measured* (``measurement``) rather than guessed.

Schemes:

* light indices (Trebilco 2007, "Light indexed deferred rendering"): ``bitplanes`` (bit
  shifting with blend ``ONE, CONSTANT_COLOR``), ``max_pairs`` (MAX blend of ``(i, 1-i)`` with
  the stencil), ``channel_slots`` (CPU-sorted light sets, one channel each), and beside
  bit-plane indices ``intensity_planes`` (a [0,1] value per light slot, bit-packed the same
  way: Trebilco's packed "shadow intensity");
* values: ``split16`` (a [0,1] value as 16 bits over two 8-bit channels), ``bitfield`` (e.g.
  Kircher's 8-bit object id | 8-bit normal group);
* normals: ``kircher`` (Kircher & Lawrance 2009, eq. 1–3), ``spheremap``, ``octahedral``.

Light indices are 1-based (``light.index + 1u``): 0 means "no light" in every index scheme.

The schemes live by concern: ``light_index``, ``intensity``, ``values`` and ``normals`` (on
``base``'s ``Scheme`` and helpers), Trebilco's table in ``capacity``, the measured figures in
``error_tables`` and the normal encodings' measurement in ``measurement``.  This module is the
entry point: the registry of scheme names, ``build`` and ``numpy_impl``.
"""

from __future__ import annotations

from dataclasses import field
from typing import Callable, Optional

from pipegen.core import formats
from pipegen.core.diagnostics import PipegenError, Span
from pipegen.core.formats import Format
from pipegen.core.records import record
from pipegen.ir import nodes as ir
from pipegen.packing.base import SCHEMES, Scheme
from pipegen.packing.intensity import IntensityPlanes
from pipegen.packing.light_index import BitPlanes, ChannelSlots, MaxPairs
from pipegen.packing.normals import Kircher, Octahedral, Spheremap
from pipegen.packing.values import Bitfield, Split16

# numpy is imported inside the mirrors and the measurements that use it: ``build`` (what
# compiling a technique calls) never needs it (tests/test_compile_imports.py).

_SCHEME_CLASSES: dict[str, type[Scheme]] = {
    "bitplanes": BitPlanes, "max_pairs": MaxPairs, "channel_slots": ChannelSlots,
    "intensity_planes": IntensityPlanes, "split16": Split16, "bitfield": Bitfield,
    "kircher": Kircher, "spheremap": Spheremap, "octahedral": Octahedral,
}
assert tuple(_SCHEME_CLASSES) == SCHEMES


@record(frozen=True)
class PackingSpec:
    """What the front end needs from a packing scheme (see docs/internals.md)."""

    name: str
    scheme: str
    functions_source: str
    functions: tuple[str, ...]                          # short names: ("plane_value", "unpack")
    constants: dict[str, tuple[ir.Type, object]] = field(default_factory=dict)
    capacity: Optional[int] = None
    error: Optional[float] = None
    notes: tuple[str, ...] = ()


def build(name: str, scheme: str, options: dict, target_format: Optional[Format],
          span: Optional[Span]) -> PackingSpec:
    """Configure scheme ``scheme`` with ``options`` for ``pack name = scheme(…)``.

    ``target_format`` is the format of the target named by the ``target`` option (the front
    end resolves the name); a format name given directly as ``target`` is accepted too.
    Raises ``PipegenError(span, …)`` for bad options and for packings that cannot fit their
    target.
    """
    s = _configure(scheme, options, target_format, span)
    fns = s.functions(name)
    source = "\n\n".join(fns.values()) + "\n"
    return PackingSpec(name=name, scheme=scheme, functions_source=source,
                       functions=tuple(fns), constants=dict(s.constants),
                       capacity=s.capacity, error=s.error, notes=tuple(s.notes))


def numpy_impl(scheme: str, options: dict,
               target_format: Optional[Format] = None) -> dict[str, Callable]:
    """Vectorised numpy mirrors of the generated functions, by short name.

    Arguments and results are arrays with the vector components last (``unpack(v, k)`` takes
    ``v`` of shape (..., 4) and a Python int ``k``); arithmetic is float32/uint32 like the
    shaders'.
    """
    return _configure(scheme, options, target_format, None).mirror()


def _configure(scheme: str, options: dict, target_format: Optional[Format],
               span: Optional[Span]) -> Scheme:
    cls = _SCHEME_CLASSES.get(scheme)
    if cls is None:
        raise PipegenError(span, f"unknown packing scheme '{scheme}'",
                           "packing schemes: " + ", ".join(SCHEMES))
    options = dict(options or {})
    unknown = sorted(set(options) - set(cls.OPTIONS))
    if unknown:
        allowed = ", ".join(cls.OPTIONS) or "none"
        raise PipegenError(span, f"{scheme} has no option '{unknown[0]}'",
                           f"options of {scheme}: {allowed}")
    fmt = target_format
    if fmt is None and isinstance(options.get("target"), str):
        fmt = formats.FORMATS.get(options["target"])   # a format name instead of a target
    return cls(options, fmt, span)
