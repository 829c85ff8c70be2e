"""The CL wide path's table reads at a per-pixel index (``backends/opencl/wide/``: a row of the
light table, or of the material records after it, gathered lane by lane): every lane reads what
the scalar ``pg_fragment`` reads, so the targets are bit-identical with and without the wide
function, for a technique of this file's own (material rows grouped in a function and in the
stage body, in a ``?:`` arm, at an index a loop changes; a light row per pixel, with lanes whose
slot is empty) and for deferred_calver, whose light passes read ``materials[material_id()]``.
Light-indexed shading (LIDR's shade passes) is kept scalar by the cost model
(``LANE_GATHER_WORK``), not because the wide form cannot lower it: forced wide, its images are
exact too (with --exhaustive).  Speed: benchmarks/cl_wide_passes.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.backends.opencl import wide as cl_wide
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.scene import load_scene

from test_cl_wide import _assert_same, _pipes, _scene, _wide_passes

ROOT = Path(__file__).resolve().parents[1]

TABLES = """
technique wide_tables "table reads at a per-pixel index for the wide fragment function"
lights[16] { position: vec3, radius: float, color: vec3 }
material { diffuse_fn: uint = 0, kspec_blend: float = 0, kamb: float = 1, kemm: float = 0,
           emissive: vec3 = vec3(0) }
target gid   : rgba8 clear 0
target color : rgba32f clear (0, 0, 0, 1)
target ds    : d24s8 clear depth 1.0 stencil 0
output color

pass ids {
  draw scene.opaque
  writes gid
  depth ds less write
  cull back
  fragment { gid = vec4(normalize(normal) * 0.5 + 0.5, float(object_id) / 255.0); }
}

// a material record's rows grouped in a function called with a per-pixel id
vec3 glow(uint id, float s) {
  vec3 e = materials[id].emissive + materials[id].kemm * vec3(s);
  if (materials[id].diffuse_fn == 1u) { e *= materials[id].kamb + 0.5; }
  return e;
}

pass shade {
  draw fullscreen
  reads gid
  writes color
  fragment {
    vec4 g = load(gid);
    uint id = uint(floor(g.w * 255.0 + 0.5));
    vec3 c = glow(id, g.x) + vec3(materials[id].kamb * 0.25);
    // a light per pixel: where i is 0 the scalar code reads no light, the wide one loads a
    // (clamped) row for that lane and drops it
    uint i = uint(frag_coord.x) % 5u;
    if (i != 0u) {
      vec3 n = g.xyz * 2.0 - 1.0;
      c += lights[i - 1u].color * max(dot(n, normalize(lights[i - 1u].position)), 0.0);
    }
    // not grouped: reads in a ?: arm, and at an index the loop changes
    c.x += g.y > 0.5 ? float(materials[id].diffuse_fn) * 0.25 : materials[id].kspec_blend;
    uint j = id;
    for (int k = 0; k < 3; k++) {
      c.y += materials[j].kspec_blend * 0.1 + float(materials[j].diffuse_fn) * 0.01;
      j = (j + 1u) % 6u;
    }
    color = vec4(c, g.w);
  }
}
"""


@pytest.mark.cl
def test_table_reads_at_a_varying_index_are_exact(monkeypatch):
    monkeypatch.setattr(cl_wide, "LANE_GATHER_WORK", 0)
    # MIN_COST kept: the ids pass (too little work) is one program for both pipelines
    scalar, wide = _pipes(lambda: compile_source(TABLES), monkeypatch, wmin=1)
    assert _wide_passes(wide) == ["shade"]
    frag = next(p for p in wide.plan.passes if p.name == "shade").code.fragment
    frag = frag[frag.index(cl_wide.MARK):]
    # grouped rows gathered once per lane (locals of light_rows.py's plan), the others where
    # they are read; the light rows clamped to the table (16 lights + 256 material records)
    for what in ("pg_material_row0[8] = {", "pg_material_row1[8] = {",
                 "pg_light1_row1[8] = {", ", 0, 271)) * PG_LIGHT_ROWS", "pg_wt"):
        assert what in frag, what
    scene = load_scene(ROOT / "examples/scenes/calver_materials.toml").with_size(64, 48)
    out = wide.render(scene)
    _assert_same(scalar.render(scene), out)
    ids = np.round(out["color"][..., 3] * 255).astype(int)
    assert len(np.unique(ids)) >= 5          # the background and several objects' records
    assert np.count_nonzero(out["color"][..., :3]) > 0.5 * out["color"][..., :3].size


@pytest.mark.cl
def test_deferred_calver_materials_are_exact(monkeypatch):
    """deferred_calver's light passes read the material record of each pixel's object: wide
    (the cost model's choice, no setting changed), every target as the scalar path's."""
    scalar, wide = _pipes(lambda: compile_file(ROOT / "pipelines/deferred_calver.pipe"),
                          monkeypatch, wmin=1)
    assert {"directional_lights", "point_lights", "spot_lights"} <= set(_wide_passes(wide))
    scene = load_scene(ROOT / "examples/scenes/calver_materials.toml").with_size(64, 48)
    _assert_same(scalar.render(scene), wide.render(scene))


def test_light_indexed_shading_stays_scalar_by_cost(monkeypatch):
    """LIDR's shade pass (each pixel its own lights) lowers wide, but the cost model keeps it
    scalar for its lane gathers (LANE_GATHER_WORK; benchmarks/cl_wide_passes.py)."""
    def shade_is_wide() -> bool:
        plan = compile_file(ROOT / "pipelines/lidr_bitplanes.pipe").plan("cl")
        shade = next(p for p in plan.passes if p.name == "shade")
        return cl_wide.MARK in shade.code.fragment
    assert not shade_is_wide()
    monkeypatch.setattr(cl_wide, "LANE_GATHER_WORK", 0)
    assert shade_is_wide()



def test_material_lookups_go_wide_when_specialised():
    """The rule is work per gathered row (``LANE_GATHER_WORK``), not work less a cost per row:
    deferred_calver's light passes compiled for a scene (237-333 of work on two material rows,
    their shadow and light-type branches cut) go wide as the general build's do, where the
    subtraction had kept them scalar (point lights on many_lights at 1280x720: 86.7 ms scalar,
    49.9 wide)."""
    general = compile_file(ROOT / "pipelines/deferred_calver.pipe")
    variant = general.specialise(load_scene(ROOT / "examples/scenes/calver_materials.toml"))
    for compiled in (general, variant):
        plan = compiled.plan("cl")
        wide = {p.name for p in plan.passes if cl_wide.has_wide(p.code.fragment)}
        assert {"directional_lights", "point_lights", "spot_lights"} <= wide

@pytest.mark.cl
@pytest.mark.exhaustive     # a wide program no build ships (15 s to build cold); in CI the
                            # per-pixel light of test_table_reads_... covers these gathers
def test_light_indexed_shading_forced_wide_is_exact(monkeypatch):
    """lidr_bitplanes forced wide: every lane shades with its own lights' rows (empty slots
    loading a clamped row they drop), bit for bit the scalar images (point, spot and
    directional lights)."""
    monkeypatch.setattr(cl_wide, "LANE_GATHER_WORK", 0)
    scalar, wide = _pipes(lambda: compile_file(ROOT / "pipelines/lidr_bitplanes.pipe"),
                          monkeypatch, wmin=1)
    assert "shade" in _wide_passes(wide)
    scene = _scene("mixed_lights", 64, 48)
    _assert_same(scalar.render(scene), wide.render(scene))
