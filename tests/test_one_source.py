"""One source per fact (issue 23): what a pass does to its attachments (``ir/access.py``),
target memory (``ir/memory.py``), byte counts as text (``core/units.py``), the scene checks both
runtimes run (``runtime/common.check_scene``) and the interleaved timer (``tools/timing.py``).
Each test states the fact independently and holds every user to it."""

from __future__ import annotations

import dataclasses
import itertools
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core import formats as F
from pipegen.core.diagnostics import PipegenError
from pipegen.core.units import format_bytes, mebibytes
from pipegen.ir import access, memory, nodes as ir
from pipegen.passes import cull_unread
from pipegen.reference.fixed_function import stencil_update
from pipegen.runtime.common import check_scene
from pipegen.scene import Light, load_scene
from pipegen.tools.timing import interleave
from pipegen.views.graph import build_dot
from pipegen.views.info import describe
from pipegen.views.report import render_report

ROOT = Path(__file__).resolve().parents[1]

# ---- what a pass does to its attachments ---------------------------------------------------

# ``mark`` only marks the stencil (its depth test writes nothing); ``shade`` tests the mark
MARKED = """
technique marked "a stencil mark read by a later pass"
lights[4] { position: vec3, radius: float, color: vec3, type: uint }
target c  : rgba8 clear 0
target ds : d24s8 clear depth 1.0 stencil 0
output c
pass mark {
  draw scene.opaque
  depth ds less nowrite
  stencil { func always pass incr }
}
pass shade {
  draw fullscreen
  writes c
  depth ds off
  stencil { func notequal ref 0 }
  fragment { c = vec4(1.0); }
}
"""


def _with_write_mask(tech: ir.Technique, mask: int) -> ir.Technique:
    """``tech`` with pass ``mark``'s stencil write mask set to ``mask`` on both faces (the
    language takes 0..255; the IR, a plan read back or a later pass may hold more bits)."""
    def face(f):
        return dataclasses.replace(f, write_mask=mask)

    passes = []
    for p in tech.passes:
        if p.name == "mark":
            st = p.state.stencil
            stencil = ir.StencilState(face(st.front), face(st.back))
            p = dataclasses.replace(p, state=dataclasses.replace(p.state, stencil=stencil))
        passes.append(p)
    return dataclasses.replace(tech, passes=tuple(passes))


def _mark_edge(dot: str) -> str:
    (line,) = [x for x in dot.splitlines() if '"pass:mark"' in x and '"target:ds"' in x]
    return line


def test_a_write_mask_beyond_the_stencil_bits_writes_nothing():
    """GL masks the stencil write mask to the attachment's bits (8 for d24s8): 0x100 writes
    nothing, 0x1ff writes what 0xff writes.  Every user of the fact agrees: the access
    queries, cull_unread (the mark is dead when it writes nothing) and the graph's edges."""
    assert F.get("d24s8").stencil_bits == 8
    tech = compile_source(MARKED).technique
    for mask, writes in ((0xFF, True), (0x1FF, True), (0x01, True), (0x100, False),
                         (0xF00, False), (0, False)):
        t = _with_write_mask(tech, mask)
        mark = t.passes[0]
        assert access.stencil_bits(t, mark) == 8
        assert access.writes_stencil(t, mark) is writes, hex(mask)
        assert access.writes(t, mark) == ({"ds"} if writes else set()), hex(mask)
        assert access.depth_use(t, mark) == (["depth"], ["stencil"] if writes else [])
        assert (0 in cull_unread.live_passes(t)) is writes, hex(mask)
        edge = _mark_edge(build_dot(SimpleNamespace(technique=t), (64, 32)))
        assert ("stencil write" in edge) is writes, (hex(mask), edge)
    # the pass reading the mark reads the depth/stencil target, whatever the mask
    assert access.reads(tech.passes[1]) == {"ds"}


def test_writes_stencil_agrees_with_the_reference_stencil_stage():
    """A face "writes stencil" exactly when the reference rasteriser's stencil stage (GL's
    rules, ``fixed_function.stencil_update``) changes some value: over write masks inside and
    beyond 8 bits, each op on the path it is reached by."""
    values = np.arange(256, dtype=np.uint8)
    ops = [ir.StencilOp.KEEP, ir.StencilOp.INCR, ir.StencilOp.INVERT, ir.StencilOp.ZERO]
    for mask, op, on in itertools.product((0, 1, 0x80, 0xFF, 0x100, 0x180, 0x3FF), ops,
                                          ("zpass", "zfail", "fail")):
        # reach the op: a test that never passes for ``fail``, a failing depth for ``zfail``
        func = ir.CompareFunc.NEVER if on == "fail" else ir.CompareFunc.ALWAYS
        face = ir.StencilFace(func=func, write_mask=mask, **{on: op})
        changed = False
        for depth_pass in (True, False):
            new, _ = stencil_update(values, ir.StencilState(face, face), depth_pass=depth_pass)
            changed |= bool((new != values).any())
        assert access.face_writes_stencil(face, 8) is changed, (hex(mask), op, on)


def test_depth_reads_and_writes():
    tech = compile_file(ROOT / "pipelines/deferred.pipe").technique
    by_name = {p.name: p for p in tech.passes}
    gbuffer, mark, shade = by_name["gbuffer"], by_name["mark"], by_name["shade_light_volume"]
    assert access.writes_depth(gbuffer) and not access.writes_depth(mark)
    assert access.writes(tech, gbuffer) == {"galbedo", "gnormal", "gpos", "ds"}
    assert access.writes(tech, mark) == {"ds"}          # its stencil ops (and its clear)
    assert access.reads(shade) == {"galbedo", "gnormal", "gpos", "ds"}   # the stencil test
    assert access.depth_use(tech, mark) == (["depth"], ["stencil"])
    assert access.depth_use(tech, shade) == (["stencil"], [])


# ---- target memory ---------------------------------------------------------------------------


def test_memory_of_shipped_techniques_and_every_view_of_it():
    # forward: color rgba8 and ds d24s8 at the output size, the shadow atlas d32f 1024x1024
    tech = compile_file(ROOT / "pipelines/forward.pipe").technique
    expected = (4 + 4) * 1280 * 720 + 4 * 1024 * 1024
    assert memory.technique_bytes(tech, 1280, 720) == expected == 11567104
    assert sum(t.format.bytes_per_pixel * w * h for t, (w, h) in zip(
        tech.targets, [(1280, 720), (1280, 720), (1024, 1024)])) == expected
    # inferred: its L-buffer at lbuffer_scale 0.625 of the output (800x450 for 1280x720)
    inferred = compile_file(ROOT / "pipelines/inferred.pipe").technique
    total = 0
    for t in inferred.targets:
        w, h = (1280, 720) if t.size.scale == 1.0 else (800, 450)
        assert memory.target_bytes(t, 1280, 720) == t.format.bytes_per_pixel * w * h * t.samples
        total += t.format.bytes_per_pixel * w * h * t.samples
    assert memory.technique_bytes(inferred, 1280, 720) == total
    assert any(t.size.scale != 1.0 for t in inferred.targets)

    compiled = compile_file(ROOT / "pipelines/forward.pipe")
    assert "targets at 1280x720: 11.03 MiB" in build_dot(compiled, (1280, 720))
    assert "  total: 11567104 (11.03 MiB)\n" in describe(compiled, (1280, 720))
    assert "  total target memory: 11.03 MiB\n" in render_report(compiled, (1280, 720))


def test_specialisation_saves_what_the_culled_targets_held():
    scene = load_scene(ROOT / "examples/scenes/small.toml")
    compiled = compile_file(ROOT / "pipelines/forward.pipe", scene=scene)
    spec = compiled.specialisation
    before, after = spec.memory(640, 360)
    assert before == memory.technique_bytes(spec.general, 640, 360)
    assert after == memory.technique_bytes(spec.special, 640, 360)
    kept = {t.name for t in spec.special.targets}
    assert before - after == sum(memory.target_bytes(t, 640, 360) for t in spec.general.targets
                                 if t.name not in kept)
    line = spec.report(640, 360)[-1]
    # in bytes and MiB, as pipegen info gives target memory
    assert line == (f"target memory at 640x360: {format_bytes(before, 'MiB', exact=True)} -> "
                    f"{format_bytes(after, 'MiB', exact=True)} "
                    f"({format_bytes(before - after, 'MiB')} saved)")


# ---- byte counts as text ---------------------------------------------------------------------


def test_format_bytes():
    assert [format_bytes(n) for n in (0, 1023, 1024, 4096, 1048575, 1 << 20, 1293942)] == [
        "0 B", "1023 B", "1.0 KiB", "4.0 KiB", "1024.0 KiB", "1.00 MiB", "1.23 MiB"]
    assert format_bytes(-4096) == "-4.0 KiB"            # a saving that went the wrong way
    assert format_bytes(4096, "MiB") == "0.00 MiB"
    assert format_bytes(11567104, "MiB", exact=True) == "11567104 (11.03 MiB)"
    assert format_bytes(123456789, "MiB", suffix=False) == "117.74"
    assert format_bytes(5, "B") == "5 B" and format_bytes(1536, "KiB") == "1.5 KiB"
    assert mebibytes(3 << 19) == 1.5
    with pytest.raises(ValueError):
        format_bytes(1, "MB")


def test_no_view_spells_its_own_byte_unit():
    """The views, the sweep and the specialisation report format bytes with ``format_bytes``
    only: none divides by 2^20 itself."""
    sweep = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "pipegen/tools/sweep").glob("*.py"))
    for rel in ("pipegen/views/graph.py", "pipegen/views/info.py", "pipegen/views/report.py",
                *sweep, "pipegen/compiler/specialise.py"):
        text = (ROOT / rel).read_text()
        assert not re.search(r"1 << 20|2 \*\* 20|1 << 10|bytes_per_pixel \*", text), rel


# ---- the scene checks both runtimes run ------------------------------------------------------


def test_check_scene_refuses_what_the_plan_cannot_draw():
    plan = compile_file(ROOT / "pipelines/forward.pipe", params={"max_lights": 4}).plan("gl")
    base = load_scene(ROOT / "examples/scenes/small.toml")
    light = Light("point", (1, 1, 1), position=(0.0, 1.0, 0.0), radius=3.0)
    check_scene(plan, dataclasses.replace(base, lights=(light,) * 4))
    with pytest.raises(PipegenError, match="has 5 lights but technique 'forward' holds 4"):
        check_scene(plan, dataclasses.replace(base, lights=(light,) * 5))
    special = compile_file(ROOT / "pipelines/forward.pipe", scene=base).plan("gl")
    sun = Light("directional", (1, 1, 1), direction=(0.0, -1.0, 0.0))
    if "directional" not in special.scene.light_types:
        with pytest.raises(PipegenError, match="specialised for 0 directional lights"):
            check_scene(special, dataclasses.replace(base, lights=base.lights + (sun,)))


def test_both_runtimes_check_a_scene_with_the_one_function():
    for rel in ("pipegen/runtime/gl/pipeline.py", "pipegen/runtime/cl/pipeline.py"):
        text = (ROOT / rel).read_text()
        assert text.count("check_scene(self.plan, scene)") == 1, rel
        assert not re.search(r"check_(scene_facts|light_capacity|shadow_capacity)\(", text), rel


# ---- the interleaved timer -------------------------------------------------------------------


def test_interleave_alternates_and_returns_samples_per_candidate():
    calls, after = [], []
    fns = {k: (lambda k=k: calls.append(k)) for k in ("a", "b", "c")}
    clock = itertools.count()
    out = interleave(fns, 4, cpu=lambda: float(next(clock)), after_call=after.append)
    assert calls == ["a", "b", "c",                    # the untimed warm-up
                     "a", "b", "c", "c", "b", "a", "a", "b", "c", "c", "b", "a"]
    assert after == calls[3:]                          # after each timed call, not the warm-up
    assert list(out) == ["a", "b", "c"]
    for s in out.values():
        assert len(s.wall) == 4 and all(t >= 0.0 for t in s.wall)
        assert s.cpu == [1.0] * 4                      # the clock read around each call
    calls.clear()
    out = interleave(fns, 2, alternate=False, warmup=False)
    assert calls == ["a", "b", "c", "a", "b", "c"]
    assert all(s.cpu == [] and len(s.wall) == 2 for s in out.values())


def test_sweep_and_benchmarks_time_with_the_package_timer():
    assert "interleave(" in (ROOT / "pipegen/tools/sweep/jobs.py").read_text()
    bench = (ROOT / "benchmarks/common.py").read_text()
    assert "from pipegen.tools.timing import interleave" in bench
    assert "perf_counter" not in bench.split("def interleaved")[1].split("\ndef ")[0]
