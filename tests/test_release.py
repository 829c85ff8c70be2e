"""Resources released (issue 29 item 2): a pipeline is closed with ``close()`` or ``with``, and
what a long-lived process keeps per pipeline it builds is bounded.  The soak itself (memory
over 1,000 renders) is ``benchmarks/soak.py``; these tests hold the mechanisms it measured:
pyopencl's generated argument setters no longer pile up in ``linecache``, equal GL state
vectors share their id (so the process-wide transition table does not grow with each
pipeline), the IR facts cache is bounded, and closed GL pipelines delete their objects."""

from __future__ import annotations

import linecache
from pathlib import Path

import pytest

from pipegen.compiler.driver import compile_file
from pipegen.scene import default_scene

ROOT = Path(__file__).resolve().parents[1]
DEFERRED = str(ROOT / "pipelines/deferred.pipe")


@pytest.mark.cl
def test_cl_pipelines_leave_no_generated_sources_behind():
    from pipegen.runtime.cl.context import _INVOKER_SOURCES
    compiled = compile_file(DEFERRED)
    scene = default_scene().with_size(32, 18)

    def generated() -> int:
        return sum(isinstance(k, str) and k.startswith(_INVOKER_SOURCES)
                   for k in linecache.cache)
    for _ in range(3):
        with compiled.pipeline("cl") as pipe:
            pipe.render(scene)
            # what pytools files for a kernel's setter (whether it does depends on its
            # version and caches), and one standing in for it: both go with the pipeline
            linecache.cache[_INVOKER_SOURCES + "test'>"] = (1, None, ["x\n"], "test")
            assert generated() >= 1
        assert generated() == 0             # dropped when it is closed
    assert pipe.store is None               # closed: its buffers dropped


@pytest.mark.gl
def test_equal_gl_state_shares_an_id_and_closing_deletes_the_objects():
    from pipegen.runtime.gl import transitions as GT
    from pipegen.runtime.gl.context import GL
    compiled = compile_file(DEFERRED)
    scene = default_scene().with_size(32, 18)
    with compiled.pipeline("gl") as first:
        first.render(scene)
        ids = [p.vector.id for p in first.passes]
        textures = [t.tex for t in first.targets.values()]
    table = len(GT.TRACKER.table) if hasattr(GT, "TRACKER") else None
    with compiled.pipeline("gl") as second:
        second.render(scene)
        assert [p.vector.id for p in second.passes] == ids
    if table is not None:
        assert len(GT.TRACKER.table) == table     # no new transitions for the same states
    assert not any(GL.glIsTexture(t) for t in textures)


def test_the_ir_facts_cache_is_bounded():
    from pipegen.ir import facts
    for name in ("deferred", "inferred", "lidr_transparent", "deferred_calver", "forward"):
        compile_file(str(ROOT / "pipelines" / f"{name}.pipe")).plan("cl")
        assert len(facts._FACTS) <= facts._FACTS_MAX
