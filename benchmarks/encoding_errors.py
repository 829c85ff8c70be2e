"""Measured error bounds of the packing schemes: the normal encodings' angular error per
encoding, storage format and domain, split16's error, bitfield's exact widths per format and
the light-index decode under perturbation.

    python benchmarks/encoding_errors.py            # print the tables (Markdown)
    python benchmarks/encoding_errors.py --check    # exit 1 if the tables or the docs differ
    python benchmarks/encoding_errors.py --write    # rewrite them

``--write`` rewrites the generated tables in ``pipegen/packing/error_tables.py``
(``NORMAL_ERRORS`` and ``SPLIT16_ERROR``, the figures the compile report prints) and all of
``docs/encodings.md``.  Every figure comes from the measurement functions of
``pipegen.packing.measurement`` and ``pipegen.packing.values``; the tests
(tests/test_packing_exhaustive.py) repeat the measurements and compare.  Takes about a minute
(35 normal measurements of ~1.6 million normals each).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pipegen.core import formats  # noqa: E402
from pipegen.packing import error_tables, measurement, values  # noqa: E402

TABLES = ROOT / "pipegen" / "packing" / "error_tables.py"
DOCS = ROOT / "docs" / "encodings.md"
NORMAL_SCHEMES = ("kircher", "spheremap", "octahedral")
F32 = np.float32


def domains(scheme: str) -> tuple[bool, ...]:
    """Hemisphere flags measured for ``scheme``: Kircher's mapping is for z >= 0 only."""
    return (True,) if scheme == "kircher" else (False, True)


def measure_normals(verbose: bool = True) -> dict[tuple[str, str, str], measurement.NormalError]:
    out = {}
    for scheme in NORMAL_SCHEMES:
        for storage in error_tables.NORMAL_FORMATS:
            for hemi in domains(scheme):
                t0 = time.perf_counter()
                m = measurement.measure_normal_error(scheme, storage, hemi)
                out[(scheme, storage, m.domain)] = m
                if verbose:
                    print(f"  {scheme:10s} {storage:10s} {m.domain:10s} max {m.max:.4g} "
                          f"mean {m.mean:.4g}  ({time.perf_counter() - t0:.1f} s)",
                          file=sys.stderr)
    return out


def aliases(storage: str) -> list[str]:
    """Every format that stores normals as ``storage`` does (and accepts them)."""
    names = []
    for name, f in formats.FORMATS.items():
        if f.is_color and not f.is_integer and f.channels >= 2:
            if error_tables.normal_storage(f) == storage:
                names.append(name)
    return names


def component_bits(storage: str) -> str:
    f = formats.get(storage)
    b = f.bits[0]
    if f.kind is formats.Kind.SNORM:
        return f"{b} snorm ({b - 1} used: the encoders write [0,1])"
    if f.kind is formats.Kind.FLOAT:
        return f"{b}-bit float" + (" (stores round toward zero)" if b == 16 else "")
    return f"{b} unorm" + (" (llvmpipe's 16-bit conversion)" if f.encode is
                           formats.Encode.UNORM16 and b != 16 else "")


def normals_table(measured) -> str:
    rows = ["| encoding | formats | bits per component | domain | max error (°) | "
            "mean error (°) | worst normal |",
            "|---|---|---|---|---|---|---|"]
    for scheme in NORMAL_SCHEMES:
        for storage in error_tables.NORMAL_FORMATS:
            for hemi in domains(scheme):
                m = measured[(scheme, storage, "hemisphere" if hemi else "sphere")]
                w = ", ".join(f"{x:.4f}" for x in m.worst)
                dom = "z ≥ 0" if hemi else "sphere"
                rows.append(f"| {scheme} | {', '.join(aliases(storage))} | "
                            f"{component_bits(storage)} | {dom} | {m.max:.4g} | "
                            f"{m.mean:.4g} | ({w}) |")
    return "\n".join(rows)


def normal_errors_literal(measured) -> str:
    lines = ["NORMAL_ERRORS: dict[tuple[str, str, str], tuple[float, float]] = {"]
    for key, m in measured.items():
        lines.append(f"    {key!r}: ({error_tables.round_significant(m.max)!r}, "
                     f"{error_tables.round_significant(m.mean)!r}),")
    lines.append("}")
    return "\n".join(lines)


def bitfield_table() -> str:
    rows = ["| formats | exact bits (claimed) | measured | first failing value one bit wider |",
            "|---|---|---|---|"]
    seen = {}
    for name, f in formats.FORMATS.items():
        if not f.is_color or f.is_integer:
            continue
        key = (f.kind, f.bits[0], f.encode)
        seen.setdefault(key, []).append(name)
    for names in seen.values():
        f = formats.get(names[0])
        bits, bad = values.measure_exact_bits(f)
        rows.append(f"| {', '.join(names)} | {values.exact_bits(f)} | {bits} | "
                    f"{bad} of {bits + 1} bits |")
    return "\n".join(rows)


def perturbation_table() -> tuple[str, dict]:
    """Which 8-bit codes each decoder gets wrong when the stored value is off by d codes."""
    codes = np.arange(256)
    rows = ["| perturbation d (codes) | floor(x*255+0.5) wrong | ceil(x*254.5) wrong |",
            "|---|---|---|"]
    wrong = {}
    for d in (-0.49, -0.25, -0.01, 0.0, 0.01, 0.1, 0.25, 0.49):
        x = ((codes + d) / 255.0).astype(F32)
        ours = np.floor(x * F32(255) + F32(0.5)).astype(int)
        paper = np.ceil(x * F32(254.5)).astype(int)
        wrong[d] = (codes[ours != codes], codes[paper != codes])
        rows.append(f"| {d:+.2f} | {_ranges(wrong[d][0])} | {_ranges(wrong[d][1])} |")
    return "\n".join(rows), wrong


def _ranges(values) -> str:
    values = list(map(int, values))
    if not values:
        return "none"
    out, start, prev = [], values[0], values[0]
    for v in values[1:] + [None]:
        if v is not None and v == prev + 1:
            prev = v
            continue
        out.append(f"{start}" if start == prev else f"{start}..{prev}")
        if v is not None:
            start = prev = v
    return ", ".join(out)


def bitplane_rows() -> str:
    rows = ["| packing | target | capacity | per-channel chunk sequences (lengths 0..capacity) | "
            "whole index sequences checked directly |", "|---|---|---|---|---|"]
    for B, target in [(4, "r8"), (8, "r8"), (4, "rg8"), (8, "rg8"), (4, "rgba8"), (8, "rgba8"),
                      (16, "rgba8")]:
        C = formats.get(target).channels
        b, cap = B // C, 8 // (B // C)
        chunk_seqs = sum((1 << b) ** n for n in range(cap + 1))
        full = sum((2 ** B - 1) ** n for n in range(cap + 1))
        direct = f"all {full:,}" if full <= 70000 else "a covering set (see above)"
        rows.append(f"| bitplanes(index_bits: {B}) | {target} | {cap} | {chunk_seqs:,} per "
                    f"channel | {direct} |")
    return "\n".join(rows)


def document(measured) -> str:
    split_err, split_x = values.measure_split16_error()
    ptable, wrong = perturbation_table()
    n = measurement.NORMAL_GRID
    return f"""# Error bounds of the packing schemes

Generated by `python benchmarks/encoding_errors.py --write` from the measurement functions
in `pipegen/packing/` (`measurement.py`, `values.py`); do not edit by hand, except below the
marker that ends the generated part (`--write` keeps what follows it). The compile
report prints the same figures (`error bound`, and the notes), and
`tests/test_packing_exhaustive.py` repeats every measurement and checks that it reproduces
these tables and the report's figures.

## Normal encodings

Angular error in degrees of encode → store → decode: the encoders of `kircher`, `spheremap`
and `octahedral` (their numpy mirrors, float32 like the shaders; `tests/test_packing.py`
checks the mirrors against the generated GLSL on llvmpipe) write two values in [0, 1], the
target's store quantises them as llvmpipe does (`formats.Format.quantize`: round to nearest
for unorm/snorm, llvmpipe's 16-bit conversion for rg16 and rgb10a2, round toward zero for
half floats), and the decoder reads them back. `tests/test_packing_exhaustive.py` checks
that model end to end on llvmpipe for every storage in the table (rg8, rgb10a2, rg16,
rg8_snorm, rg16_snorm, rg16f, rg32f): the generated encode drawn into a real target of the format stores the model's codes
(a code apart on fewer than 0.1 % of the values, where the shader's float32 rounding differs
by an ulp), the generated decode reads them back as the mirror does, and the error of 100,000
normals stays below the table's maximum with the grid's mean.

Normals measured, per encoding, format and domain:

- a Fibonacci grid of {n:,} normals on the domain (the whole sphere, or the hemisphere
  z ≥ 0 of camera-facing view-space normals: all Kircher's mapping is meant for);
- the hard spots: the axes, (0,0,±1), the diagonals, on the whole sphere 512,000 normals on
  rings around (0,0,-1) from 1e-5° to 30° (the singular point of spheremap/Kircher, where
  spheremap's error peaks at a distance that depends on the format's step) and 18,018
  normals on both sides of the octahedral seams (x = 0 or y = 0 below the equator) at
  offsets 1e-7 to 1e-2;
- a deterministic local search from the 48 worst normals (14 rounds of 192 steps, shrinking
  radius), which climbs into the worst quantisation cell: it adds up to ~3 % to the grid's
  maximum. Where it ends depends on its path: six other seeds find maxima within 0.6 % of
  these for every storage but rg32f, whose errors (~3e-5°) are float32 rounding noise with
  many near-equal peaks (−9 % to +5 %; `python benchmarks/encoding_errors.py --path-spread 6`).

**Max** is the largest error found (a lower bound of the supremum, close to it as above),
**mean** the mean over the equal-area grid. Figures have 4 significant digits. rgba
variants of a format store a normal like the rg format (same bits and conversion).

The measurement is reproducible by construction, so every machine computes this table to the
bit: the grid and the hard spots use the C library's cos/sin/exp (through Python's `math`),
the search compares squared chords |n − d/|d||² (correctly rounded arithmetic only), ranks
ties by position and takes its steps from numpy's seeded generator; numpy's own
transcendental kernels, which differ between CPUs and numpy versions, convert chords to
degrees only after the search (`measure_normal_error`; `python
benchmarks/encoding_errors.py --check` passes with numpy's dispatch limited to x86-64-v2).

{normals_table(measured)}

Reading the table: spheremap (Lambert azimuthal) spreads (0,0,-1) over the whole rim of the
disk, where a code step spans a large angle: its whole-sphere maximum lies within 12° of -z
(for rg8 at 11.6° from it, a normal that decodes to -z itself); over the camera-facing
hemisphere it is as good as octahedral.
Kircher's encoding is the same map (the tables agree over z ≥ 0 to the last digit or two;
float32 rounding differs). Octahedral's error is nearly uniform over the sphere; its seams
decode identically from both sides and are no worse than the rest. The snorm formats lose a
bit per component (the encoders write [0,1]) and so double the error of the unorm format of
their width. Half floats space values 2^-11 apart in [0.5, 1) and 2^-12 in [0.25, 0.5)
(where the encoders put most normals: about an 11-bit unorm) and round toward zero.

### Published figures

Cigolle, Donow, Evangelakos, Mara, McGuire and Meyer, "A Survey of Efficient Representations
for Independent Unit Vectors", *Journal of Computer Graphics Techniques* 3(2), 1–30, 2014
(<http://jcgt.org/published/0003/02/01/>), tabulate the mean and maximum angular error of the
octahedral (`oct16`, `oct24`, `oct32` and their precise `P` variants), spherical, Lambert
azimuthal (spheremap), hemisphere and other encodings at 16 to 32 bits per vector, in snorm
storage. Their numbers could not be checked while writing this page, so none are quoted;
compare against the paper itself. Note the differences when doing so: our octahedral
encoding stores `p * 0.5 + 0.5` in unorm (the survey's `oct16` stores `p` in 8-bit snorm, a
lattice that contains 0; ours contains ±1 instead); the survey's `P` variants search the
neighbouring codes for the best decode, which ours do not; and our figures include llvmpipe's
store conversions (rg16, rgb10a2, half floats round toward zero). Meyer, Süßmuth, Sußner,
Stamminger and Greiner, "On Floating-Point Normal Vectors", *Computer Graphics Forum* 2010
(EGSR), who introduced octahedron normal vectors, state in their abstract that these need
only 1 bit more than the theoretically optimal discretization with the same error; their
tables are not quoted here either. Kircher and Lawrance 2009 give no error figures for their
hemisphere mapping, to our knowledge.

## split16

Every 16-bit code round-trips exactly through rg8 (and every other target split16 accepts:
rgba8, rg16, rgba16, rgb10a2, rg16f, rgba16f, rg32f, rgba32f, rg16_snorm; 8-bit snorm holds
7 bits for values in [0,1] and is refused). The error of an x is then |c/65535 − x| for the
code c it rounds to, largest at the ends of c's interval: measured at every code's rounding
boundaries (`values.measure_split16_error`), the maximum is **{split_err:.4g}** =
{split_err * 65535:.4g} of a 16-bit step (at x = {split_x!r}), not 0.5/65535 =
{0.5 / 65535:.4g}: the float32 rounding of `x*65535 + 0.5` moves the boundaries by up to
0.0039 of a step.

## bitfield: exact widths per format

The widest bitfield every value of which survives `to_unorm` → one channel of the format →
`from_unorm` (exhaustive over every value of every width up to one bit more), next to what
`build` allows (`_exact_bits`):

{bitfield_table()}

Half floats keep 10 bits, not 11: llvmpipe's half store rounds toward zero. Every one of the
63,488 finite half values stores unchanged through rg16f (tested), so the loss is in the
rounding of values that are not half values.

## Light-index packings: what "every sequence up to capacity" covers

- **bitplanes**: channel c of a pixel depends only on chunk c (index bits [c·b, (c+1)·b)) of
  each light written to it: `plane_value` puts chunk c, and nothing else, in channel c
  (checked for every index of 4, 8 and 16 bits), the blend works per channel, and `unpack`
  reads chunk c of the k-th newest light from channel c alone (checked in GLSL for every
  code of every channel). So a sequence of L ≤ capacity indices decodes correctly if and only
  if, in every channel, its sequence of chunks does; the tests run every chunk sequence of
  every length 0..capacity through the blend (the numpy models of llvmpipe's fixed-point
  blend and of the float blend rounded once) and decode it, as whole index sequences
  assembled so that every channel sees every chunk sequence (for rgba8 also blended by
  llvmpipe itself and decoded by the generated GLSL), plus, where there are few enough,
  every index sequence outright:

{bitplane_rows()}

  Together: every ordered sequence of 0..capacity indices in 1..2^B−1, repeats included,
  decodes to itself, newest first, and the slots past the sequence read 0.
- **max_pairs**: pass 1 takes the first two lights into RG, pass 2 the others into BA; each
  pair is decoded from its own two channels. Checked: every ordered pair (a, b), a single
  light and the empty pair, for every index 1..255 (rgba8), through the MAX blend and both
  stencil passes, so every sequence of up to 4 lights decodes to its set of indices (a repeated
  index reads once); for rgba16, every code 0..65535 of each channel decodes exactly, and the
  MAX blend and the decode of a pair are the same code-level operations.
- **channel_slots**: one index per slot and channel, no blending: every index 0..255 (rgba8) /
  0..65535 (rgba16) in every slot decodes exactly, so every combination does.

## Light-index decode under perturbation

A stored code c read back as x = (c + d)/255 (float32) with |d| < 0.5 codes. The decode the
packings generate, `floor(x*255 + 0.5)`, recovers c for every code and every |d| ≤ 0.49;
Trebilco's `ceil(x*254.5)` computes ceil(c + d − (c + d)/510) and returns c + 1 whenever the
value comes in high by more than (c + d)/510 — code 0 ("no light") included:

{ptable}

With d = +0.49, `ceil(x*254.5)` misreads codes {_ranges(wrong[0.49][1])}: every light index
below 250, and an empty slot reads as light 1. `tests/test_packing_exhaustive.py` shows both
on numpy, in GLSL on llvmpipe and in the OpenCL the compiler emits, on PoCL.
"""


def replace_block(text: str, name: str, body: str) -> str:
    pattern = re.compile(rf"(# BEGIN {name}\n).*?(# END {name}\n)", re.S)
    assert pattern.search(text), name
    return pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text)


def path_spread(seeds: int) -> int:
    """The table's maxima against the same search with seeds 1..``seeds``: where a search ends
    depends on its path, so this is how tight a lower bound of the supremum each figure is."""
    print(f"{'encoding':<10} {'storage':<10} {'domain':<10} {'min':>8} {'max':>8}  (vs the table)")
    worst = {}
    for (scheme, storage, domain), (table_max, _) in error_tables.NORMAL_ERRORS.items():
        ratios = [measurement.measure_normal_error(scheme, storage, domain == "hemisphere",
                                               seed=seed).max / table_max - 1
                  for seed in range(1, seeds + 1)]
        print(f"{scheme:<10} {storage:<10} {domain:<10} {100 * min(ratios):+7.2f}% "
              f"{100 * max(ratios):+7.2f}%")
        group = "rg32f" if storage == "rg32f" else "others"
        lo, hi = worst.get(group, (0.0, 0.0))
        worst[group] = (min(lo, min(ratios)), max(hi, max(ratios)))
    for group, (lo, hi) in sorted(worst.items()):
        print(f"{group}: {100 * lo:+.2f}% .. {100 * hi:+.2f}%")
    return 0


KEEP_MARKER = "<!-- end of the generated part: what follows is kept by --write -->"


def kept_sections() -> str:
    """The hand-written sections after KEEP_MARKER in the current docs/encodings.md (the
    G-buffer layouts, measured by tests/test_gbuffer_layouts.py), marker included."""
    text = DOCS.read_text() if DOCS.exists() else ""
    at = text.find(KEEP_MARKER)
    return "" if at < 0 else "\n" + text[at:]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="rewrite error_tables.py and "
                    "docs/encodings.md")
    ap.add_argument("--check", action="store_true", help="exit 1 if they differ from a fresh "
                    "measurement")
    ap.add_argument("--path-spread", type=int, metavar="N", default=0,
                    help="measure the maxima again with N other seeds of the local search and "
                    "print how far each lands from the table (how tight a lower bound it is)")
    args = ap.parse_args()
    if args.path_spread:
        return path_spread(args.path_spread)
    measured = measure_normals()
    split_err, _ = values.measure_split16_error()
    src = TABLES.read_text()
    new_src = replace_block(src, "NORMAL_ERRORS", normal_errors_literal(measured))
    new_src = replace_block(new_src, "SPLIT16_ERROR", f"SPLIT16_ERROR = {split_err!r}")
    doc = document(measured) + kept_sections()
    if args.write:
        TABLES.write_text(new_src)
        DOCS.write_text(doc)
        print(f"wrote {TABLES.relative_to(ROOT)} (tables) and {DOCS.relative_to(ROOT)}")
        return 0
    if args.check:
        stale = [p.relative_to(ROOT).as_posix() for p, old, new in
                 [(TABLES, src, new_src), (DOCS, DOCS.read_text() if DOCS.exists() else "", doc)]
                 if old != new]
        print("up to date" if not stale else "stale: " + ", ".join(stale))
        return 1 if stale else 0
    print(doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
