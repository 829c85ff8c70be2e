"""What render targets cost in bytes: the one computation behind ``pipegen info``, the compile
report, ``pipegen graph``, ``pipegen specialise`` and ``pipegen sweep``'s ``target_bytes``.

A target holds ``Format.bytes_per_pixel`` bytes per sample (stencil bits included), at its size
resolved against the output size (``Size.resolve``: fixed, or a scale of the output), times its
sample count.  What a backend allocates on top (alignment, a multisample target's resolve
buffer) is not counted: the figure compares techniques, not drivers.
"""

from __future__ import annotations

from pipegen.ir import nodes as ir


def target_bytes(t: ir.Target, width: int, height: int) -> int:
    """Bytes of target ``t`` at output size ``width`` x ``height`` (samples included)."""
    tw, th = t.size.resolve(width, height)
    return tw * th * t.format.bytes_per_pixel * t.samples


def technique_bytes(tech: ir.Technique, width: int, height: int) -> int:
    """Bytes of all of ``tech``'s targets at output size ``width`` x ``height``."""
    return sum(target_bytes(t, width, height) for t in tech.targets)


def specialisation_bytes(general: ir.Technique, special: ir.Technique, width: int,
                         height: int) -> tuple[int, int]:
    """Target bytes before and after specialisation (``general`` -> ``special``); what it
    saves is the difference."""
    return technique_bytes(general, width, height), technique_bytes(special, width, height)
