"""Per-target error bounds of a float32 render against the technique's own float64 evaluation.

The model (docs/tolerances.md, "The bound"), per target T, per pixel and channel, in value units
(the float a shader reads back):

    bound(T) = store(T) + P(T) * blend(T) + arith(T) + position(T) + reads(T)

- ``store``: one store of the format (two for a multisampled colour target, read through its
  resolve, which stores the average of the samples again): half a code (fixed point rounded to nearest), one code
  (the narrow channels of 16-bit-path formats: Mesa's ``scale_bits`` truncates), one float16
  ulp (llvmpipe stores half toward zero), half a float32 ulp, and 2 codes / 4 ulps of depth
  (the float32 plane equation of window depth, the float32-vs-float32 limit's allowance);
- ``blend``: each of the P fragments blended into the pixel (counted by the CL run,
  ``last_blend_counts``) re-stores the sum (one ``store``) and, for 8-bit unorm, llvmpipe's
  8-bit multiply is not round-to-nearest (one more code);
- ``arith``: the float32 arithmetic of the shader that produced the value, relative to it
  (``ARITH_REL``: a lighting expression of a few tens of operations, each within half an ulp,
  and llvmpipe's ``exp2``/``log2`` polynomials under ``pow``) plus an absolute floor
  (``ARITH_ABS``: differences of O(1) quantities, unit vectors);
- ``position``: float32 positions carry ulps of the scene's largest coordinate M (the
  interpolated world position, the camera position rounded to float32, their difference): the
  float64 evaluation rendered with the lights and the camera moved by ``POSITION_ULPS`` ulps
  of M (both signs) measures what that does to every target;
- ``reads``: what T inherits from the targets its passes read: the float64 evaluation rendered
  with every ``load``/``sample`` of a target R seeing R + bound(R) (and R - bound(R)), sampled
  targets also shifted by ``RESAMPLE`` of their local range (bilinear weights with 8
  fractional bits); the change of T is the propagated error, a measured derivative times
  bound(R).  Iterated as many times as the longest chain of reads, so bound(R) already holds
  what R inherits.

The two measured terms are first-order estimates with one perturbation direction each, so
they are doubled (``SAFETY``).  Integer targets, packed light indices and stencil are exact
(bound 0).  What the model leaves out is in docs/stress.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from pipegen.core import formats as F
from pipegen.views.outputs import packed_channels, target_hints

ARITH_REL = 2.0 ** -15        # relative float32 arithmetic allowance of one shader value
ARITH_ABS = 2.0 ** -20        # absolute floor (cancellation of O(1) terms, unit vectors)
POSITION_ULPS = 8             # position perturbation, in float32 ulps of the largest coordinate
RESAMPLE = 2.0 ** -8          # bilinear weight resolution (llvmpipe: 8 fractional bits)
SAFETY = 2.0                  # measured first-order terms: one direction each, doubled
D24_CODES = 2.0
D32_ULPS = 4.0


def ulp32(x) -> np.ndarray:
    a = np.abs(np.asarray(x, np.float64)).astype(np.float32)
    return (np.spacing(np.maximum(a, np.finfo(np.float32).tiny))).astype(np.float64)


def half_ulp_abs(x) -> np.ndarray:
    """One float16 ulp at |x| (2^-24 below the normal range)."""
    a = np.abs(np.asarray(x, np.float64))
    e = np.floor(np.log2(np.maximum(a, 2.0 ** -14)))
    return np.exp2(e - 10.0)


def store_error(fmt: F.Format, v: np.ndarray) -> np.ndarray:
    """What one store of values ``v`` (float64, the target's shape) may change them by."""
    v = np.asarray(v, np.float64)
    finite = np.where(np.isfinite(v), v, 0.0)
    if fmt.kind is F.Kind.DEPTH_STENCIL:
        return np.full(v.shape, D24_CODES / fmt.max_codes[0])
    if fmt.kind is F.Kind.DEPTH:
        return D32_ULPS * ulp32(finite)
    if fmt.is_normalized:
        bits = np.asarray(fmt._per_channel(fmt.bits), np.float64)
        top = np.asarray(fmt._per_channel(fmt.max_codes), np.float64)
        codes = 0.5 * (1 + 2.0 ** -10)
        if fmt.encode is F.Encode.UNORM16:
            # 16 bits: the low mantissa bits of x * 65535/65536 + 128 in float32, whose
            # product rounds too (measured: 0.5036 codes); narrower: truncated (< 1 code)
            codes = np.where(bits < 16, 1.0, 0.5 + 2.0 ** -7)
        return np.broadcast_to(codes / top, v.shape).astype(np.float64)
    if fmt.kind is F.Kind.FLOAT and max(fmt.bits) == 16:
        # toward zero: one ulp; below half's normal range the float32 runs flush to zero,
        # and a value up to twice that may be computed below it (its own error) and flushed
        a = np.abs(finite)
        return half_ulp_abs(finite) + np.where(a < 2.0 ** -13, a, 0.0)
    if fmt.kind is F.Kind.FLOAT:
        return 0.5 * ulp32(finite) + 2.0 ** -126
    return np.zeros(v.shape)


def blend_error(fmt: F.Format, v: np.ndarray) -> np.ndarray:
    """The extra error of one blend step into ``fmt`` holding about ``v``."""
    e = store_error(fmt, v)
    if fmt.blend_is_exact:       # 8-bit unorm: llvmpipe's 8-bit multiply, up to one code
        e = e + 1.0 / 255.0
    return e


def arith_error(v: np.ndarray) -> np.ndarray:
    a = np.abs(np.where(np.isfinite(v), v, 0.0))
    return ARITH_REL * a + ARITH_ABS


@dataclass(frozen=True)
class TargetInfo:
    """What the plan says about one target: who writes it, what its writers read."""
    name: str
    format: F.Format
    exact: bool                  # compared code for code (integers, packed indices)
    writers: tuple[str, ...]     # passes writing it (colour or depth attachment)
    reads: tuple[str, ...]       # targets read (load/sample) by its writers
    sampled: tuple[str, ...]     # ... of those, read with sample()
    is_depth: bool
    samples: int = 1             # a multisampled colour target is read through its resolve


def plan_targets(compiled) -> dict[str, TargetInfo]:
    tech = compiled.technique
    plan = compiled.plan("cl")
    hints = target_hints(tech)
    packed = packed_channels(tech)
    out = {}
    for t in plan.targets:
        writers = [p for p in plan.passes if t.name in p.writes or p.depth_target == t.name]
        reads = tuple(dict.fromkeys(r for p in writers for r in p.reads if r != t.name))
        sampled = tuple(dict.fromkeys(r for p in writers for r in p.sampled if r != t.name))
        fmt = t.format
        exact = fmt.is_integer or (hints.get(t.name) == "index"
                                   and all(packed.get(t.name, (False,))))
        out[t.name] = TargetInfo(t.name, fmt, exact, tuple(p.name for p in writers), reads,
                                 sampled, fmt.has_depth, t.samples)
    return out


def read_depth(info: dict[str, TargetInfo]) -> int:
    """The longest chain of reads (target -> target read by its writers -> ...)."""
    memo: dict[str, int] = {}

    def depth(name: str, seen: frozenset) -> int:
        if name in memo:
            return memo[name]
        if name in seen or name not in info:
            return 0
        d = max((1 + depth(r, seen | {name}) for r in info[name].reads), default=0)
        memo[name] = d
        return d
    return max((depth(n, frozenset()) for n in info), default=0)


def local_bound(t: TargetInfo, v: np.ndarray, blends: Optional[np.ndarray]) -> np.ndarray:
    """store + P * blend + arith of target values ``v`` (float64); ``blends``: (H, W) counts."""
    if t.exact:
        return np.zeros(np.shape(v))
    b = store_error(t.format, v)
    if t.samples > 1 and not t.is_depth:
        # the resolve stores the average of the sample values once more (llvmpipe: the mean
        # of the codes, rounded to a code; the float64 evaluation averages exactly)
        b = b + store_error(t.format, v)
    if not t.is_depth:
        b = b + arith_error(v)
    if blends is not None:
        p = np.asarray(blends, np.float64)
        if b.ndim == 3:
            p = p[..., None]
        b = b + p * blend_error(t.format, v)
    return b


def resample_term(v: np.ndarray) -> np.ndarray:
    """``RESAMPLE`` times the range of each pixel's 3x3 neighbourhood (bilinear weight error
    of a sampled read between texels that differ by that much)."""
    a = np.where(np.isfinite(v), v, 0.0)
    h, w = a.shape[:2]
    pad = [(1, 1), (1, 1)] + [(0, 0)] * (a.ndim - 2)
    p = np.pad(a, pad, mode="edge")
    hi = lo = a
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            s = p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            hi, lo = np.maximum(hi, s), np.minimum(lo, s)
    return RESAMPLE * (hi - lo)
