"""The OpenCL backend's wide fragment function: the fragment code of a pass evaluated for
``W`` pixels of one triangle at once, explicit SIMD over pixels (ISPC's model), because PoCL's
work-group vectoriser does not vectorise the raster kernel (its work-item loop encloses the
triangle and pixel loops, and LLVM 14 does not widen the ``float3``/``float4`` instructions of
the scalar code: "instruction return type cannot be vectorized").

``wide_fragment(tech, pass_, lang) -> str | None`` renders ``pg_fragment_w`` from the IR, or
None when the code uses what this form does not support (the pass then keeps the scalar
``pg_fragment`` only; nothing changes for it).  The lowering, in the spirit of Mesa's
``nir_lower_alu_to_scalar``:

- every value is a list of scalar *components* (a ``vec3`` is three values, matrices stay
  whole and must be uniform); arithmetic is per component in the scalar code's operation
  order: ``dot`` = ``x + (y + (z + w))`` of unfused products (``pipegen/ir/expand.py``'s
  trees for dot, length, distance, cross, mix and the matrix products), the guarded forms of
  ``cstyle`` (normalize, pow, inversesqrt, log, sqrt, ``uint(float)``) rendered from the same
  IR, the matrix products of the prelude component by component; ``FP_CONTRACT OFF`` holds, so
  each lane computes exactly what the scalar function computes for its pixel;
- a component is *uniform* (one ``float``/``int``/``uint``/``bool`` for all lanes: frame
  values, technique parameters, the light table at a uniform index, the triangle's flat
  inputs, loop counters) or *varying* (``float8``/``int8``/``uint8``, booleans as ``int8``
  masks -1/0: the interpolated inputs, ``frag_coord``, ``load``/``sample`` of targets and
  everything computed from them).  Locals start uniform and become varying when a varying
  value or a varying branch assigns them (the function is re-rendered until that settles);
  user functions are specialised per call by which arguments are varying;
- control flow on uniform conditions stays control flow (the per-light loops, light-type
  branches); an ``if`` on a varying condition is if-converted: both branches run under masks
  and assignments become ``select``; a varying ``?:`` evaluates both sides (pure code);
  ``discard`` under a varying condition clears lanes of the returned live mask; ``break``
  and ``continue`` under a varying condition make the loop keep masks of the lanes that left
  it (it ends when all have), ``return`` under one a mask of the lanes that returned and
  their values (the function is rendered again in that form);
- a table read at a varying index (``materials[id].f`` with ``id`` from the G-buffer, or
  ``lights[i].f`` in light-indexed shading: each lane its own record) is a gather: the row
  is loaded lane by lane into an array of ``W`` rows (``float4 r[8]``, lane ``j``'s the
  scalar code's read at lane ``j``'s index; a light's record clamped to the table, since
  lanes that do not use the light, under a mask, load one too), once per row per lane where
  ``light_rows.py`` groups the reads (material rows as well as light rows), at the read
  otherwise; a field is then ``(float8)(r[0].x, ..., r[7].x)``.
  Varying matrices, varying bit casts and integer division by a varying divisor are not
  supported (None: the scalar path).

Passes whose estimated work per pixel (``cost``) is below ``MIN_COST`` keep the scalar path
too (the batching does not pay there), and the raster kernel shades a triangle's row batch of
fewer than ``WMIN`` pixels with the scalar function (not in a run of lights drawn once for
all of them, ``pg_once``: there every batch is wide, the lanes interpolated once for all the
lights).  A ``load``/``sample`` counts
``GATHER_COST`` against the estimate (0 since the gathers are wide: see the constant), and a
pass must do at least ``LANE_GATHER_WORK`` of work per table row it gathers lane by lane
(counted by the emitter, loops times their bounds): deferred_calver's light passes (two
material rows against 237-1078 of work, general or specialised) pay wide, light-indexed
shading (LIDR's shade passes: 32-96 light rows, 54-98 of work per row) does not reliably and
stays scalar (the measurements at the constant).

Builtins the generated code calls with varying operands have ``W``-wide overloads in
``wide_helpers()`` (the prelude's definitions applied lane by lane, so the values are the
scalar ones).  ``load``/``sample`` are wide as well (``pgw_load_T`` / ``pgw_sample_T`` in
``cl_pass.cl.j2``): the scalar ``pg_load_T`` / ``pg_sample_T``'s edge clamps, pixel indices,
texel coordinates, weights and lerps as W-wide operations in the same order, only the
memory reads (and decodings other than half's) lane by lane.  The raster kernel batches the
pixels of a triangle's row that pass coverage (and early depth/stencil), fills ``pgw_in``
lane by lane with the scalar interpolation, calls ``pg_fragment_w`` and blends lane by lane,
in pixel order.

Here: the choice (the constants below, ``wide_fragment``, ``has_wide``) and the helpers'
text.  The lowering: ``values`` (components, uniform or varying), ``statements`` (function
bodies, control flow, user functions), ``expressions``, ``emitter`` (``WideEmitter``, the two
together); ``helpers`` (the wide builtins, rendered from the prelude's definitions) and
``cost`` (the work estimate).
"""

from __future__ import annotations

import os
from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.backends import plan as planlib
from pipegen.backends.opencl.wide import helpers
from pipegen.backends.opencl.wide.cost import cost, gathers
from pipegen.backends.opencl.wide.emitter import WideEmitter
from pipegen.backends.opencl.wide.values import MARK, W, TooManyGathers, Unsupported

__all__ = ["W", "MARK", "MIN_COST", "GATHER_COST", "LANE_GATHER_WORK", "WMIN", "ENABLED",
           "CROSS_TRIANGLE", "CROSS_TRIANGLE_VARYINGS", "wide_fragment", "has_wide", "wide_helpers", "cost", "gathers"]

# Measured (one pass's raster kernel alone, its scalar and wide programs interleaved in one
# process, 640x360, 2 PoCL threads, medians of 15-21 runs on a shared 2-core machine; scalar
# -> wide ms, two rounds on scene many_lights / two on mixed_lights), pass (cost, gathers):
#   deferred_calver point_lights (226, 9)    60.3 -> 47.6, 45.7 -> 38.0 / 23.1 -> 15.3, 22.2 -> 15.5
#   deferred directional_lights (178, 3)     - / 10.4 -> 8.8, 11.9 -> 10.1
#   deferred shade_cone (173, 3)             - / 0.80 -> 0.58, 1.15 -> 0.80
#   inferred lighting (184, 3)               6.1 -> 5.8, 7.5 -> 7.0 / 2.37 -> 2.30, 4.3 -> 5.0
#   light_prepass light_accumulation (129, 2)  19.7 -> 19.1, 22.1 -> 20.8 / 8.7 -> 6.9, 7.0 -> 5.7
#   lidr_bitplanes spot_indices (122, 1)     - / 4.0 -> 3.4, 3.0 -> 2.4
#   lidr_bitplanes light_indices (86, 1)     16.9 -> 18.0, 19.6 -> 20.0 / 7.2 -> 6.5, 7.7 -> 7.0
#   deferred shade_light_volume (84, 3)      0.29 -> 0.26, 0.30 -> 0.27 / 0.85 -> 0.79, 0.95 -> 0.85
#   deferred_calver global_lights (46, 3)    5.5 -> 7.4, 5.5 -> 8.2 / 8.1 -> 9.5, 5.9 -> 8.5
# ("-": no such light in the scene).  The wide form pays from a cost of about 100 on, gathers
# or not (no shipped pass without gathers has a cost between 84 and 150: that range's bound
# is not measured for gather-free code)
MIN_COST = 100              # below this estimated work per pixel, the scalar function only
# what a load()/sample() costs the wide form more: nothing measurable since the gathers are
# wide (lane by lane through the scalar functions, 25 kept point_lights scalar, and forcing it
# wide measured 35 vs 30 ms; with the wide gathers its kernel is 17-34 % faster wide, above)
GATHER_COST = 0
# the work per pixel a pass must do for each table row it reads at a varying index (gathered
# lane by lane: W row loads; counted per pixel, loops times their bounds, by the emitter) to go
# wide.  A ratio, as a time model gives it: wide shading saves a share of the work, each
# gathered row costs the wide form W scattered loads, so the wide form pays where work per row
# exceeds a constant (the subtraction used before, work - 200 x rows >= MIN_COST, kept the
# specialised deferred_calver's light passes scalar: 237-333 of work on 2 rows).  Measured with
# benchmarks/cl_wide_passes.py (raster kernel, scalar and wide builds' frames interleaved,
# 2 PoCL threads, medians), wide/scalar, pass (cost, gathered rows; costs before ``pow``
# counted its polynomials unless marked new):
#   deferred_calver general, calver_materials 320x180: directional_lights (1441, 2) 0.28,
#     point_lights (1515, 2) 0.22, spot_lights (1537, 2) 0.18; many_lights: point_lights 0.73
#   deferred_calver specialised (new costs; 5-11 frames): many_lights point_lights (311, 2)
#     1280x720 86.7 -> 49.9 ms, 160x90 3.24 -> 2.45 ms; calver_materials 320x180
#     directional_lights (237, 2) 4.98 -> 2.06, point_lights (311, 2) 3.35 -> 1.50,
#     spot_lights (333, 2) 2.58 -> 1.07
#   LIDR shade passes forced wide (--force), 640x360, many_lights / mixed_lights:
#     lidr_bitplanes shade (1826, 32)       0.85 [0.21-1.14] / 0.63 [0.41-1.05]
#     lidr_shadow_indexed shade (11594, 96) 1.36 [0.64-3.13] / 1.10 [0.76-1.76]
#     lidr_transparent shade_opaque (3649, 64) 1.05 [0.64-1.43] / 0.77 [0.40-1.92]
#   and at 320x180 (15-31 frames): lidr_max_stencil shade (1730, 32) 1.02-1.03, lidr_cpu_sort
#     shade (1662, 32) 0.90, lidr_bitplanes shade 0.95-0.99 / 0.43-0.67; again after the row
#     and inlining changes (new costs): 640x360 many_lights 0.91-0.97 (bitplanes 1890/32,
#     shadow_prepass 2733/32, shadow_indexed 2026/32), 160x90 many_lights 1.17-1.21 (bitplanes,
#     cpu_sort, shadow_indexed), 320x180 mixed_lights 0.7-1.05
# Light-indexed shading is a loss as often as a gain, at 54-98 of work per gathered row (new
# costs); material lookups, at 118-539 per row, pay 1.7-5x: 108 lies between
LANE_GATHER_WORK = 108
WMIN = 4                    # a row's batch of fewer pixels is shaded pixel by pixel
# False (or PIPEGEN_CL_WIDE=0 in the environment): every pass keeps the scalar path (tests,
# before/after benchmarks); the emitted text then is the scalar path's alone
ENABLED = os.environ.get("PIPEGEN_CL_WIDE", "1") != "0"
# False (or PIPEGEN_CL_XBATCH=0): a wide pass batches the pixels of one triangle's row only,
# never across triangles (cl_pass.cl.j2's cross-triangle batches; comparisons)
CROSS_TRIANGLE = os.environ.get("PIPEGEN_CL_XBATCH", "1") != "0"
# ... for passes with varyings too (scene draws: small triangles cover a few pixels of a row
# each; each lane interpolates its own triangle's varyings, a batch's flat ones are equal)
CROSS_TRIANGLE_VARYINGS = os.environ.get("PIPEGEN_CL_XBATCH_VARYINGS", "1") != "0"


def wide_fragment(tech: ir.Technique, p: ir.Pass, lang,
                  shared: Optional[dict] = None) -> Optional[str]:
    """``pg_fragment_w`` of pass ``p`` (OpenCL C), or None when the wide form does not
    support its code (see the module docstring).  ``shared``: one dict for all the passes of
    ``tech``, where the specialised user functions rendered for one pass are kept for the
    others (``WideEmitter.shared``)."""
    if not p.body or not ENABLED:
        return None
    functions = planlib.pass_functions(tech, p.body)
    if planlib.shades_per_sample(p.body, functions) or \
            "sample_mask" in planlib.stage_inputs(p.body, functions):
        return None     # per-sample shading, coverage: the kernel calls the scalar function
    fmap = {f.name: f for f in functions}
    work = cost(p.body, fmap) - GATHER_COST * gathers(p.body, fmap)
    if work < MIN_COST:
        return None
    def too_many(lane_gathers: int) -> bool:
        return work < LANE_GATHER_WORK * lane_gathers

    emitter = WideEmitter(tech, p, lang, too_many, shared)
    try:
        text = emitter.fragment(functions)
    except (Unsupported, TooManyGathers):
        return None
    if too_many(emitter.pass_gathers):
        return None
    return text


def has_wide(fragment: Optional[str]) -> bool:
    """Whether a pass's fragment text (``CLPassCode.fragment``) holds ``pg_fragment_w``, so
    its program needs the wide helpers and batching.  Read from the text, which is what
    the program compiles: a plan's plain-data spelling, old ones included, carries it."""
    return bool(fragment) and MARK in fragment


def wide_helpers() -> str:
    """The W-wide builtins and helpers a program with ``pg_fragment_w`` starts with (the
    prelude's definitions applied lane by lane, so every lane gets the scalar value)."""
    return helpers.wide_helpers(WMIN)
