"""The light table in vec4 rows (issue 26 item 6): where ``ir/light_layout.py`` places each
field, the packed upload (``runtime/light_table.light_rows``), and the row loads a body makes
(``backends/light_rows.py``): each row once, where every read of it sees the same light."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.backends.glsl import GLSLLanguage
from pipegen.ir import nodes as ir
from pipegen.ir.light_layout import Place, light_layout, schema_layout
from pipegen.ir.nodes import BOOL, FLOAT, INT, UINT, VEC3, VEC4
from pipegen.runtime.light_table import light_rows
from pipegen.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = [("position", "vec3"), ("radius", "float"), ("color", "vec3"), ("type", "uint"),
           ("direction", "vec3"), ("cos_inner", "float"), ("cos_outer", "float"),
           ("shadow_tile", "float"), ("shadow_m0", "vec4"), ("shadow_m1", "vec4"),
           ("shadow_m2", "vec4"), ("shadow_m3", "vec4")]


def test_shipped_schema_takes_eight_rows():
    layout = schema_layout(SHIPPED)
    assert layout.rows == 8                      # 30 floats; one field per texel took 12
    p = layout.places
    assert (p["position"], p["radius"]) == (Place(0, 0, 3), Place(0, 3, 1))
    assert (p["color"], p["type"]) == (Place(1, 0, 3), Place(1, 3, 1))
    assert (p["direction"], p["cos_inner"]) == (Place(2, 0, 3), Place(2, 3, 1))
    assert (p["cos_outer"], p["shadow_tile"]) == (Place(3, 0, 1), Place(3, 1, 1))
    assert [p[f"shadow_m{k}"] for k in range(4)] == [Place(4 + k, 0, 4) for k in range(4)]
    assert p["direction"].components == "xyz" and p["shadow_tile"].components == "y"


@pytest.mark.parametrize("seed", range(20))
def test_first_fit_never_overlaps_or_straddles(seed):
    rng = np.random.default_rng(seed)
    sizes = [(f"f{k}", int(s)) for k, s in enumerate(rng.integers(1, 5, rng.integers(1, 14)))]
    layout = light_layout(sizes)
    used = np.zeros((layout.rows, 4), int)
    for name, size in sizes:
        place = layout.place(name)
        assert place.size == size and place.offset + size <= 4
        used[place.row, place.offset:place.offset + size] += 1
    assert used.max() == 1
    # first-fit decreasing: as few rows as the largest fields force, and at most one row more
    # than the floats need
    total = sum(s for _, s in sizes)
    assert -(-total // 4) <= layout.rows <= -(-total // 4) + sum(1 for _, s in sizes if s == 3)


def test_rows_hold_the_scene_table_bit_for_bit():
    scene = load_scene(ROOT / "examples/scenes/shadows.toml")
    slots = scene.light_table([list(f) for f in SHIPPED], 8)
    rows = light_rows(scene, SHIPPED, 8)
    layout = schema_layout(SHIPPED)
    assert rows.shape == (8, layout.rows, 4) and rows.dtype == np.float32
    for k, (name, _) in enumerate(SHIPPED):
        p = layout.place(name)
        assert np.array_equal(rows[:, p.row, p.offset:p.offset + p.size], slots[:, k, :p.size])
    assert np.count_nonzero(rows) == sum(np.count_nonzero(slots[:, k]) for k in range(len(SHIPPED)))


# -- the row loads of a body ------------------------------------------------------------------

TABLE = ir.LightTable(tuple(ir.LightAttr(n, ir.parse_type(t)) for n, t in SHIPPED), 8)


def _lang() -> GLSLLanguage:
    tech = ir.Technique("t", "", (), (), TABLE, (), (), (), "color", "t.pipe")
    return GLSLLanguage(tech)


def _field(index, name: str) -> ir.LightField:
    return ir.LightField(index, name, TABLE.field_type(name))


def _function(body, params=(("i", UINT),)) -> str:
    return _lang().function(ir.Function("f", tuple(params), FLOAT, tuple(body)))


I = ir.Var("i", UINT)


def test_one_fetch_per_row_before_its_first_reader():
    body = [ir.If(ir.Binary("<", _field(I, "shadow_tile"), ir.Const(FLOAT, 0.0), BOOL),
                  (ir.Return(ir.Const(FLOAT, 1.0)),)),
            ir.Declare("r", FLOAT, ir.Binary("*", _field(I, "radius"), ir.Swizzle(
                _field(I, "position"), "x", FLOAT), FLOAT)),
            ir.Return(ir.Binary("*", ir.Var("r", FLOAT), _field(I, "shadow_tile"), FLOAT))]
    text = _function(body)
    assert text.count("texelFetch") == 2
    lines = text.splitlines()
    assert lines[1] == "    vec4 pg_light_row3 = texelFetch(u_lights, ivec2(3, int(i)), 0);"
    assert lines[2] == "    if (pg_light_row3.y < 0.0) {"
    # row 0 is fetched only past the early return, where it is first read
    assert lines[5] == "    vec4 pg_light_row0 = texelFetch(u_lights, ivec2(0, int(i)), 0);"
    assert lines[6] == "    float r = pg_light_row0.w * pg_light_row0.xyz.x;"
    assert lines[7] == "    return r * pg_light_row3.y;"


def test_reads_in_one_branch_load_inside_it():
    body = [ir.If(ir.Binary(">", I, ir.Const(UINT, 2), BOOL),
                  (ir.Return(_field(I, "radius")),), (ir.Return(ir.Const(FLOAT, 0.0)),))]
    lines = _function(body).splitlines()
    assert lines[1] == "    if (i > 2u) {"
    assert lines[2].strip().startswith("vec4 pg_light_row0 = texelFetch")


def test_an_assigned_index_reads_where_it_is_used():
    # i changes between the reads: each read fetches its own texel, as before
    body = [ir.Declare("r", FLOAT, _field(I, "radius")),
            ir.Assign(I, "+=", ir.Const(UINT, 1)),
            ir.Return(ir.Binary("+", ir.Var("r", FLOAT), _field(I, "radius"), FLOAT))]
    text = _function(body)
    assert "pg_light" not in text and text.count("texelFetch(u_lights, ivec2(0, int(i)), 0).w") == 2


def test_two_loops_with_one_name_are_two_variables():
    loop = lambda: ir.For("k", INT, ir.Const(INT, 0), ir.Const(INT, 2), (  # noqa: E731
        ir.Assign(ir.Var("s", FLOAT), "+=", _field(ir.Var("k", INT), "radius")),))
    body = [ir.Declare("s", FLOAT, ir.Const(FLOAT, 0.0)), loop(), loop(),
            ir.Return(ir.Var("s", FLOAT))]
    text = _function(body, params=())
    assert "pg_light" not in text and text.count("texelFetch") == 2


def test_one_loop_variable_loads_inside_the_loop():
    body = [ir.Declare("s", VEC3, ir.Const(VEC3, (0.0, 0.0, 0.0))),
            ir.For("k", INT, ir.Const(INT, 0), ir.Const(INT, 2), (
                ir.Assign(ir.Var("s", VEC3), "+=", ir.Binary(
                    "*", _field(ir.Var("k", INT), "color"), _field(ir.Var("k", INT), "radius"),
                    VEC3)),)),
            ir.Return(ir.Swizzle(ir.Var("s", VEC3), "x", FLOAT))]
    lines = _function(body, params=()).splitlines()
    assert lines[2].startswith("    for (int k = 0; k < 2; k++) {")
    assert lines[3:5] == ["        vec4 pg_light_row0 = texelFetch(u_lights, ivec2(0, k), 0);",
                          "        vec4 pg_light_row1 = texelFetch(u_lights, ivec2(1, k), 0);"]
    assert lines[5] == "        s += pg_light_row1.xyz * pg_light_row0.w;"


def test_a_guarded_read_is_not_hoisted_out_of_its_guard():
    # i < 4 ? lights[i].radius : 0.0 -- loading it before the statement could read past the table
    guarded = ir.Ternary(ir.Binary("<", I, ir.Const(UINT, 4), BOOL), _field(I, "radius"),
                         ir.Const(FLOAT, 0.0), FLOAT)
    text = _function([ir.Return(guarded)])
    assert "pg_light" not in text
    assert "i < 4u ? texelFetch(u_lights, ivec2(0, int(i)), 0).w : 0.0" in text


def test_the_light_being_drawn_and_a_vec4_field():
    body = [ir.Return(ir.Call("dot", (_field(None, "shadow_m0"), ir.Construct(VEC4, (
        _field(None, "position"), ir.Const(FLOAT, 1.0)))), FLOAT))]
    lang = _lang()
    lang.current_light = "u_light"
    text = lang.function(ir.Function("f", (), FLOAT, tuple(body)))
    assert "vec4 pg_light_row4 = texelFetch(u_lights, ivec2(4, int(u_light)), 0);" in text
    assert "return dot(pg_light_row4, vec4(pg_light_row0.xyz, 1.0));" in text
