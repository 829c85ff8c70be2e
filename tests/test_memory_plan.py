"""Target memory as a frame graph plans it (``ir.lifetimes``, ``runtime/aliasing.py``): target
lifetimes over the passes, which targets share storage, the three figures, and renders with
shared storage bit-identical to renders without it on both runtimes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.backends.plan import plan_from_dict
from pipegen.compiler.driver import compile_file
from pipegen.ir.lifetimes import START, Lifetime, Sharing, memory_plan, touched
from pipegen.runtime.aliasing import FrameClears

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "pipelines").glob("*.pipe"))


def small_plan(passes: list[dict], targets: list[tuple[str, str]], output: str = "out"):
    """A plan written by hand: ``targets`` as (name, format), all at the output size."""
    return plan_from_dict({"output": output, "passes": passes,
                           "targets": [{"name": n, "format": f} for n, f in targets]})


def plan_of(p, w: int = 1280, h: int = 720, sharing: Sharing = Sharing.BYTES, pinned=()):
    return memory_plan(p.passes, p.targets, p.output, w, h, sharing, pinned)


# ---- lifetimes --------------------------------------------------------------------------------


def test_a_target_read_after_another_was_written_never_shares_with_it():
    # a written, b written, a read: both live at pass 1, so no sharing; c starts after a's
    # last read and takes a's storage
    p = small_plan([{"name": "p0", "writes": ["a"]}, {"name": "p1", "writes": ["b"]},
                    {"name": "p2", "writes": ["out"], "reads": ["a", "b"]},
                    {"name": "p3", "writes": ["c"], "reads": ["out"]},
                    {"name": "p4", "writes": ["out"], "reads": ["c"]}],
                   [("a", "rgba8"), ("b", "rgba8"), ("c", "rgba8"), ("out", "rgba8")])
    m = plan_of(p, 4, 4)
    assert m.lifetimes == {"a": Lifetime(0, 2), "b": Lifetime(1, 2), "c": Lifetime(3, 4),
                           "out": Lifetime(2, len(p.passes))}
    assert m.shared() == [("a", "c")] or m.shared() == [("b", "c")]
    assert all(not {"a", "b"} <= set(s) for s in m.shared())
    assert m.total_bytes == 4 * 4 * 4 * 4
    assert m.peak_bytes == 3 * 64 and m.allocated_bytes == 3 * 64


def test_a_repeat_group_keeps_what_it_touches_alive_over_the_whole_group():
    # b is written by the group's second pass and read by its first: the next light reads
    # what the last one wrote, so b lives over the group and a (last read in the group) too
    group = {"repeat_group": 0}
    p = small_plan([{"name": "g0", "writes": ["a"]},
                    {"name": "r0", "writes": ["out"], "reads": ["b"], **group},
                    {"name": "r1", "writes": ["b"], "reads": ["a"], **group},
                    {"name": "after", "writes": ["c"]}],
                   [("a", "rgba8"), ("b", "rgba8"), ("c", "rgba8"), ("out", "rgba8")])
    m = plan_of(p, 2, 2)
    assert m.lifetimes["a"] == Lifetime(0, 2)
    assert m.lifetimes["b"] == Lifetime(1, 2)
    assert m.lifetimes["c"] == Lifetime(3, 3)
    assert m.shared() == [("a", "c")] or m.shared() == [("b", "c")]


def test_output_lives_to_the_end_and_pinned_targets_from_the_start():
    p = small_plan([{"name": "p0", "writes": ["out"]}, {"name": "p1", "writes": ["a"]},
                    {"name": "p2", "writes": ["b"], "reads": ["a"]}],
                   [("a", "rgba8"), ("b", "rgba8"), ("out", "rgba8")])
    m = plan_of(p, 2, 2)
    assert m.lifetimes["out"] == Lifetime(0, 3)
    assert m.shared() == []        # a is read by the pass writing b: (1, 2) and (2, 2) meet
    pinned = plan_of(p, 2, 2, pinned=["b"])
    assert pinned.lifetimes["b"] == Lifetime(START, 2)


def test_slot_reuse_takes_only_the_same_format_size_and_samples():
    p = small_plan([{"name": "p0", "writes": ["a"]},
                    {"name": "p1", "writes": ["out"], "reads": ["a"]},
                    {"name": "p2", "writes": ["f"], "reads": ["out"]},
                    {"name": "p3", "writes": ["g"], "reads": ["f"]},
                    {"name": "p4", "writes": ["out"], "reads": ["g"]}],
                   [("a", "rgba8"), ("f", "r32f"), ("g", "rgba8"), ("out", "rgba8")])
    by_bytes = plan_of(p, 8, 8, Sharing.BYTES)
    by_descriptor = plan_of(p, 8, 8, Sharing.DESCRIPTOR)
    assert by_bytes.shared() == [("a", "f")]          # any format: r32f into rgba8's bytes
    assert by_descriptor.shared() == [("a", "g")]     # only rgba8 after rgba8
    assert plan_of(p, 8, 8, Sharing.NONE).shared() == []
    assert by_descriptor.aliased == {"a"}


def test_a_slot_holds_its_largest_target():
    p = small_plan([{"name": "p0", "writes": ["small"]},
                    {"name": "p1", "writes": ["out"], "reads": ["small"]},
                    {"name": "p2", "writes": ["big"], "reads": ["out"]},
                    {"name": "p3", "writes": ["out"], "reads": ["big"]}],
                   [("small", "r8"), ("big", "rgba32f"), ("out", "rgba8")])
    m = plan_of(p, 10, 10)
    assert m.shared() == [("small", "big")]
    assert m.slot_of("big").bytes == 10 * 10 * 16
    assert m.allocated_bytes == 10 * 10 * (16 + 4)
    assert m.peak_bytes == 10 * 10 * (16 + 4)          # p2/p3: big and out


# ---- the shipped techniques ---------------------------------------------------------------------


def executions(passes, lights: int = 2) -> list[int]:
    """Pass indices in the order a frame with ``lights`` lights runs them (repeat groups
    looped), independent of ``lifetimes``'s own reading of the groups."""
    order, k = [], 0
    while k < len(passes):
        g = passes[k].repeat_group
        end = k + 1
        while g is not None and end < len(passes) and passes[end].repeat_group == g:
            end += 1
        order += list(range(k, end)) * (lights if g is not None else 1)
        k = end
    return order


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
@pytest.mark.parametrize("sharing", [Sharing.BYTES, Sharing.DESCRIPTOR])
def test_no_shipped_target_is_touched_after_its_storage_was_handed_on(path, sharing):
    tech = compile_file(path).technique
    m = memory_plan(tech.passes, tech.targets, tech.output, 1280, 720, sharing)
    for slot in m.slots:
        for before, after in zip(slot.targets, slot.targets[1:]):
            seen_after = False
            for k in executions(tech.passes):
                names = touched(tech.passes[k])
                seen_after |= after in names
                assert not (seen_after and before in names), (before, after, k)
        if sharing is Sharing.DESCRIPTOR:
            kinds = {(tech.target(n).format, tech.target(n).size, tech.target(n).samples)
                     for n in slot.targets}
            assert len(kinds) == 1
    assert tech.output not in m.aliased
    assert m.total_bytes >= m.allocated_bytes >= m.peak_bytes


# the three figures at 1280x720, counted by hand from `pipegen info`'s targets and passes
FIGURES = {
    # galbedo 3686400 + gnormal 7372800 + gpos 14745600 + accum 7372800 + color 3686400
    # + ds 3686400; peak while the lights shade: all but color; color takes galbedo's place
    "deferred": (40550400, 36864000, 36864000, 36864000),
    # accum 7372800 + color 3686400 + ds 3686400: resolve (color) runs after ds's last use;
    # GL: no texture of color's kind to reuse
    "forward_multipass": (14745600, 11059200, 11059200, 14745600),
    # nothing ends before the shade pass, which reads the shadow atlas and draws with ds
    "forward": (11567104, 11567104, 11567104, 11567104),
}


@pytest.mark.parametrize("name", sorted(FIGURES))
def test_the_three_figures_of_shipped_techniques(name):
    tech = compile_file(ROOT / "pipelines" / f"{name}.pipe").technique
    total, peak, cl_bytes, gl_bytes = FIGURES[name]
    cl = memory_plan(tech.passes, tech.targets, tech.output, 1280, 720, Sharing.BYTES)
    gl = memory_plan(tech.passes, tech.targets, tech.output, 1280, 720, Sharing.DESCRIPTOR)
    assert (cl.total_bytes, cl.peak_bytes, cl.allocated_bytes) == (total, peak, cl_bytes)
    assert (gl.total_bytes, gl.peak_bytes, gl.allocated_bytes) == (total, peak, gl_bytes)


# ---- when a runtime clears ----------------------------------------------------------------------


def test_frame_clears_start_late_targets_at_the_first_execution_reaching_them():
    p = small_plan([{"name": "p0", "writes": ["a"]},
                    {"name": "p1", "writes": ["out"], "reads": ["a"]},
                    {"name": "p2", "writes": ["b"], "reads": ["out"]},
                    {"name": "p3", "writes": ["out"], "reads": ["b"]}],
                   [("a", "rgba8"), ("b", "rgba8"), ("out", "rgba8")])
    m = plan_of(p, 2, 2)
    assert m.shared() == [("a", "b")]
    clears = FrameClears(m)
    assert sorted(clears.start()) == ["a", "out"]
    assert clears.before_pass(0) == [] and clears.before_pass(1) == []
    assert sorted(clears.holding()) == ["a", "out"]
    assert clears.before_pass(3) == ["b"]         # p2 skipped: b cleared before p3
    assert sorted(clears.holding()) == ["b", "out"]
    assert clears.finish() == []
    # a frame that never reaches b's passes clears it at its end: render keeps b, not a
    clears.start()
    assert clears.before_pass(1) == []
    assert clears.finish() == ["b"]
    assert sorted(clears.holding()) == ["b", "out"]
    unshared = FrameClears(plan_of(p, 2, 2, sharing=Sharing.NONE))
    assert sorted(unshared.start()) == ["a", "b", "out"]
    assert unshared.before_pass(3) == [] and unshared.finish() == []


# ---- renders: shared storage changes no value -----------------------------------------------------


def compare_renders(backend: str, path: Path, scene) -> None:
    compiled = compile_file(path)
    plain = compiled.pipeline(backend)
    ref, ref_caps = plain.render(scene, capture_passes=True)
    shared = compiled.pipeline(backend)
    shared.alias = True
    got, caps = shared.render(scene, capture_passes=True)
    again = shared.render(scene)                  # the frame path without captures, reused
    memory = shared.memory if backend == "gl" else shared.store.memory
    kept = {n for n in ref if n.split(".")[0] not in memory.aliased}
    assert set(got) == kept and set(again) == kept
    for name in kept:
        assert np.array_equal(got[name], ref[name]), name
        assert np.array_equal(again[name], ref[name]), name
    assert [(c["pass"], c["light"]) for c in caps] == \
        [(c["pass"], c["light"]) for c in ref_caps]
    for c, r in zip(caps, ref_caps):              # what the storage holds after each pass
        assert c["targets"], c["pass"]
        for name, codes in c["targets"].items():
            assert np.array_equal(codes, r["targets"][name]), (c["pass"], c["light"], name)


@pytest.fixture(scope="module")
def scene():
    from pipegen.scene import load_scene
    return load_scene(ROOT / "examples/scenes/small.toml")


@pytest.mark.cl
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_cl_true_aliasing_renders_identical_targets(path, scene):
    pytest.importorskip("pyopencl")
    compare_renders("cl", path, scene)


@pytest.mark.gl
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_gl_slot_reuse_renders_identical_targets(path, scene):
    try:
        from pipegen.runtime.gl.context import get_context
        get_context()
    except Exception as exc:      # no EGL / llvmpipe here
        pytest.skip(f"no OpenGL context: {exc}")
    compare_renders("gl", path, scene)


# ---- figures a user reads: pipegen info, the report, the bandwidth estimate -----------------------


MIB_720P = 1280 * 720          # pixels of the output: a 1-byte-per-pixel target's bytes


def test_bandwidth_estimate_of_deferred_by_the_stated_rule():
    from pipegen.ir.traffic import frame_traffic, gbuffer
    tech = compile_file(ROOT / "pipelines/deferred.pipe").technique
    per_pass, total = frame_traffic(tech.passes, tech.targets, 1280, 720)
    got = {t.name: (t.read_bytes // MIB_720P, t.write_bytes // MIB_720P, t.repeated)
           for t in per_pass}
    # bytes per pixel: galbedo 4, gnormal 8, gpos 16, accum 8, color 4, ds 4
    assert got["gbuffer"] == (4, 28 + 4, False)          # depth test reads ds; writes all
    assert got["ambient_pass"] == (4, 8, False)          # reads galbedo, writes accum
    assert got["directional_lights"] == (28 + 8, 8, False)   # + accum blended (read)
    assert got["shade_light_volume"] == (28 + 8 + 4, 8, True)   # + ds stencil test
    assert got["resolve"] == (8, 4, False)
    # the clears at the frame's start write every target once (40550400 bytes), then each
    # pass once
    assert total == 40550400 + sum(t.read_bytes + t.write_bytes for t in per_pass)
    assert [t.name for t in gbuffer(tech.passes, tech.targets, tech.output)] == \
        ["galbedo", "gnormal", "gpos"]


def test_gbuffer_bytes_per_pixel_of_inferred_scale_with_its_size():
    from pipegen.ir.traffic import gbuffer, gbuffer_bytes_per_output_pixel
    tech = compile_file(ROOT / "pipelines/inferred.pipe").technique
    assert [t.name for t in gbuffer(tech.passes, tech.targets, tech.output)] == \
        ["gnormal", "gmaterial", "gdsf"]
    # 4 + 2 + 4 bytes at 800x450 over 1280x720 output pixels
    assert gbuffer_bytes_per_output_pixel(tech.passes, tech.targets, tech.output, 1280, 720) \
        == pytest.approx(10 * 800 * 450 / (1280 * 720), abs=1e-12)


def test_info_and_report_give_the_three_figures(capsys):
    from pipegen.cli.main import main
    assert main(["info", str(ROOT / "pipelines/deferred.pipe")]) == 0
    text = capsys.readouterr().out
    assert "sum of all targets  40550400 (38.67 MiB)" in text
    assert "peak live at once   36864000 (35.16 MiB)" in text
    assert "allocated, CL       36864000 (35.16 MiB)  saves 9.1 %" in text
    assert "allocated, GL       36864000 (35.16 MiB)  saves 9.1 %" in text
    assert "G-buffer: galbedo rgba8 4 + gnormal rgba16f 8 + gpos rgba32f 16 = 28 B/px" in text
    report = compile_file(ROOT / "pipelines/deferred.pipe").report()
    assert "peak live at once   36864000 (35.16 MiB)" in report
    assert "5. shade_light_volume  35.16 MiB" in text and "per light" in text


def test_sweep_bandwidth_counts_each_pass_as_often_as_the_scene_runs_it():
    from pipegen.ir.traffic import frame_traffic
    from pipegen.scene import load_scene
    from pipegen.tools.sweep.run import SHARING, frame_bandwidth
    scene = load_scene(ROOT / "examples/scenes/small.toml")
    tech = compile_file(ROOT / "pipelines/forward_multipass.pipe").technique
    per_pass, once = frame_traffic(tech.passes, tech.targets, scene.width, scene.height)
    per_light = next(t for t in per_pass if t.repeated)
    lights = len(scene.lights)
    assert lights > 1
    assert frame_bandwidth(tech, scene) == once + (lights - 1) * per_light.total
    assert SHARING == {"cl": Sharing.BYTES, "gl": Sharing.DESCRIPTOR}
