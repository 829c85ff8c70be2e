"""Trebilco's capacity table: how many lights per fragment a light index of so many bits holds
in so many 8-bit channels (Trebilco 2007, "Light indexed deferred rendering", the bit-packing
table), and the row ``bitplanes`` quotes in its notes."""

from __future__ import annotations

from pipegen.core.records import record


@record(frozen=True)
class CapacityRow:
    lights_per_fragment: int
    scene_lights: int            # 2^index_bits - 1 (index 0 = no light)
    index_bits: int
    channels: int                # 8-bit channels in all, over every surface
    surfaces: str
    bits_per_channel: float      # bits of one light in one channel (< 1: light split over targets)
    passes: int                  # passes of the light volumes
    stencil: bool
    details: str
    bitplanes: bool              # what build("bitplanes") can generate (one target, 1 pass)


def _surfaces(c: int) -> str:
    if c == 1:
        return "1 x 8bit channel"
    if c < 4 or c % 4:
        return f"{c} x 8bit channels"
    if c == 4:
        return "1 x RGBA8 surface"
    return f"{c // 4} x RGBA8 surfaces ({c // 4} render targets)"


def capacity_row(index_bits: int, channels: int) -> CapacityRow:
    B, C = index_bits, channels
    lights = 8 * C // B                       # total bits / bits per light
    bpc = B / C
    if bpc >= 1:
        b = int(bpc)
        passes, stencil = 1, False
        details = (f"light index written directly out ({B} bits)" if C == 1
                   else f"light index split into {C}x{b}bit values")
    else:
        # Fewer than one bit per channel: each light goes 1 bit per channel into B channels
        # (B/4 targets); the stencil moves writes to the next targets once those are full.
        passes, stencil = C // B, True
        at_once = B // 4
        details = (f"light index split into {B}x1bit values; output to {at_once} render "
                   f"target{'s' if at_once > 1 else ''} at a time and use the stencil as in the "
                   f"max blend method when 8 overlaps are reached "
                   f"({passes} passes of the light volumes)")
    return CapacityRow(lights, 2 ** B - 1, B, C, _surfaces(C), bpc, passes, stencil, details,
                       bitplanes=(C <= 4 and bpc >= 1 and bpc.is_integer() and 8 % int(bpc) == 0))


def capacity_table(index_bits_options=(4, 8, 16), targets=(1, 2, 4, 8, 16)) -> list[CapacityRow]:
    """Trebilco's bit-packing table: lights per fragment for each light index size and each
    amount of 8-bit channels (``targets``: 1 = r8, 2 = rg8, 4 = one rgba8, 8 and 16 = two and
    four rgba8 render targets).  Combinations that do not hold one index (fewer bits than the
    index) or that need less than half a bit per channel (not in the paper) are left out; with
    the defaults the rows are exactly the paper's 13."""
    rows = []
    for B in index_bits_options:
        for C in targets:
            if 8 * C >= B and 2 * B >= C:
                rows.append(capacity_row(B, C))
    return rows


def format_capacity_table(rows: list[CapacityRow]) -> str:
    """The table as Markdown (for reports and docs)."""
    out = ["| lights per fragment | scene lights | surfaces | details |",
           "|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r.lights_per_fragment} | {r.scene_lights} | {r.surfaces} | "
                   f"{r.details} |")
    return "\n".join(out)
