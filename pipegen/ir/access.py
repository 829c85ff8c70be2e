"""What a pass does to its attachments, read from the IR: which targets it reads and writes,
and whether it tests or writes depth and stencil.  The one definition the scene passes
(``cull_unread``: what keeps a pass alive), the views (``pipegen graph``'s edges) and the
emitters read, so that a pass one of them thinks writes stencil is one they all do.

**Writes stencil.**  A face writes the stencil buffer when one of its ops is not ``keep`` and
its write mask keeps a bit the attachment has: GL masks the write mask to the stencil bits
(``glStencilMask``: "the s least significant bits", s = 8 for d24s8), as the GL runtime
(``& 0xFF``), the reference rasteriser and the OpenCL emitter do.  A mask of 0x100 on an 8-bit
stencil therefore writes nothing.  ``stencil.enabled`` holds whenever an op is not ``keep``
(``StencilState.enabled``), so the test needs no separate check.

**Writes depth** when ``depth.write`` (which turns the depth test on, ``DepthState.enabled``).
**Reads** its ``reads`` and, when it tests depth or stencil, its depth target: a pass whose
depth test is on (``write`` alone included) keeps the pass that wrote the depth before it.
"""

from __future__ import annotations

from typing import Optional

from pipegen.core.formats import stencil_mask
from pipegen.ir import nodes as ir




def stencil_bits(tech: ir.Technique, p: ir.Pass) -> int:
    """The stencil bits of ``p``'s depth attachment (0 without one, or for a depth-only
    format)."""
    if not p.depth_target:
        return 0
    (fmt,) = [t.format for t in tech.targets if t.name == p.depth_target]
    return fmt.stencil_bits


def face_writes_stencil(face: ir.StencilFace, bits: int) -> bool:
    """Whether ``face`` changes a stencil buffer of ``bits`` bits (module docstring)."""
    return (face.write_mask & stencil_mask(bits) != 0
            and any(op is not ir.StencilOp.KEEP for op in (face.fail, face.zfail, face.zpass)))


def state_writes_stencil(state: ir.PassState, bits: int) -> bool:
    """Whether a pass with ``state`` writes a stencil buffer of ``bits`` bits (either face)."""
    return any(face_writes_stencil(f, bits) for f in (state.stencil.front, state.stencil.back))


def state_tests_stencil(state: ir.PassState) -> bool:
    """Whether the stencil test can fail (a face compares with something other than
    ``always``)."""
    return state.stencil.enabled and any(f.func is not ir.CompareFunc.ALWAYS
                                         for f in (state.stencil.front, state.stencil.back))


def writes_stencil(tech: ir.Technique, p: ir.Pass) -> bool:
    """Whether ``p`` writes the stencil bits of its depth attachment."""
    return state_writes_stencil(p.state, stencil_bits(tech, p))


def writes_depth(p: ir.Pass) -> bool:
    return bool(p.depth_target) and p.state.depth.write


def depth_use(tech: ir.Technique, p: ir.Pass) -> tuple[list[str], list[str]]:
    """(tests, writes) of ``p`` on its depth attachment, each a list of "depth", "stencil"."""
    s = p.state
    tests, writes = [], []
    if s.depth.func is not ir.CompareFunc.ALWAYS:
        tests.append("depth")
    if s.depth.write:
        writes.append("depth")
    if state_tests_stencil(s):
        tests.append("stencil")
    if writes_stencil(tech, p):
        writes.append("stencil")
    return tests, writes


def depth_read(p: ir.Pass) -> Optional[str]:
    """``p``'s depth target when it tests depth or stencil (module docstring), else None."""
    s = p.state
    if p.depth_target and (s.depth.enabled or s.stencil.enabled):
        return p.depth_target
    return None


def reads(p: ir.Pass) -> set[str]:
    """The targets ``p`` reads: its ``reads`` and the depth target it tests."""
    out = set(p.reads)
    depth = depth_read(p)
    if depth:
        out.add(depth)
    return out


def writes(tech: ir.Technique, p: ir.Pass) -> set[str]:
    """The targets ``p`` writes: its colour targets, its clears, and its depth target when it
    writes depth or stencil."""
    out = set(p.writes) | {name for name, _ in p.clears}
    if writes_depth(p) or writes_stencil(tech, p):
        out.add(p.depth_target)
    return out
