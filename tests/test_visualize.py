"""Pictures of targets (pipegen/views/visualize.py): what they show, checked on pixel values.

Most tests picture synthetic codes through the real techniques' declarations (compiling is
cheap, rendering is not); one renders a tiny frame end to end through ``write_render``.
"""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from pipegen.core import formats
from pipegen.packing import light_index, schemes
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.views.visualize import (
    DEPTH_FAR, category_color, compose, target_label, target_panels, target_views, to_rgb8,
    write_pictures)

ROOT = Path(__file__).resolve().parent.parent
NEAR, FAR = 0.5, 40.0


@pytest.fixture(scope="module")
def lidr():
    return compile_file(ROOT / "pipelines/lidr_bitplanes.pipe").technique


@pytest.fixture(scope="module")
def inferred():
    return compile_file(ROOT / "pipelines/inferred.pipe").technique


def _window_depth(distance):
    """Window depth of points at ``distance`` along the view axis (gluPerspective)."""
    d = np.asarray(distance, dtype=np.float64)
    ndc = (FAR + NEAR - 2.0 * NEAR * FAR / d) / (FAR - NEAR)
    return ndc * 0.5 + 0.5


def _depth_scene():
    """(4, 6) window depths: a near band, a middle band, a far band, one row cleared (1.0)."""
    w = np.empty((4, 6))
    w[0], w[1], w[2] = _window_depth(2.0), _window_depth(5.0), _window_depth(20.0)
    w[3] = 1.0
    return w


# -- depth ------------------------------------------------------------------------------------


def test_near_depth_is_brighter_than_far_for_d24s8_and_r32f_alike(lidr):
    w = _depth_scene()
    d24 = formats.get("d24s8").quantize(w)                      # ds: d24s8
    r32 = w.astype(np.float32)                                  # zcopy: r32f, frag_coord.z
    pic_ds = target_panels("ds", d24, lidr, NEAR, FAR)[0].rgb
    pic_z = target_panels("zcopy", r32, lidr, NEAR, FAR)[0].rgb
    for pic in (pic_ds, pic_z):
        near, middle, far, cleared = (int(pic[r, 0, 0]) for r in range(4))
        assert near == 255 > middle > far > cleared == 0
        # stretched over the drawn range: the farthest drawn pixel is DEPTH_FAR grey, not black
        assert far == round(DEPTH_FAR * 255)
        assert (pic[..., 0] == pic[..., 1]).all() and (pic[..., 1] == pic[..., 2]).all()
    # the same picture whatever the format (d24 quantisation aside)
    assert np.abs(pic_ds.astype(int) - pic_z.astype(int)).max() <= 1


def test_depth_without_the_technique_is_near_bright_too():
    w = _depth_scene()
    for fmt, codes in (("d24s8", formats.get("d24s8").quantize(w)),
                       ("r32f", w.astype(np.float32)), ("d32f", w.astype(np.float32))):
        pic = to_rgb8(codes, formats.get(fmt), "depth", NEAR, FAR)
        assert pic[0, 0, 0] > pic[1, 0, 0] > pic[2, 0, 0] > pic[3, 0, 0] == 0, fmt


def test_depth_is_stretched_over_the_drawn_range_only(lidr):
    # everything drawn lies between 10 and 11 units: full contrast anyway
    w = np.full((2, 2), 1.0)
    w[0, 0], w[0, 1], w[1, 0] = _window_depth(10.0), _window_depth(11.0), _window_depth(10.5)
    pic = target_panels("zcopy", w.astype(np.float32), lidr, NEAR, FAR)[0].rgb[..., 0]
    assert pic[0, 0] == 255 and pic[0, 1] == round(DEPTH_FAR * 255) and pic[1, 1] == 0
    assert 255 > pic[1, 0] > pic[0, 1]


def test_a_linear_depth_channel_is_shown_as_depth(inferred):
    gdsf = np.zeros((2, 3, 2), np.uint16)
    gdsf[..., 0] = [[1000, 2000, 65535], [3000, 4000, 65535]]   # -view_pos.z / max_depth; 1 = clear
    depth = target_panels("gdsf", gdsf, inferred, NEAR, FAR)[0]
    assert depth.title == "depth"
    g = depth.rgb[..., 0]
    assert g[0, 0] == 255 and g[1, 1] == round(DEPTH_FAR * 255) and g[0, 2] == g[1, 2] == 0
    assert g[0, 0] > g[0, 1] > g[1, 0] > g[1, 1]


# -- stencil and integer targets --------------------------------------------------------------


def test_a_stencil_value_is_drawn_in_its_legend_colour(lidr):
    stencil = np.array([[0, 3, 3], [1, 3, 200]], np.uint8)
    (panel,) = target_panels("ds.stencil", stencil, lidr, NEAR, FAR)
    legend = dict(panel.legend)
    assert set(legend) == {"0", "1", "3", "200"}
    assert tuple(panel.rgb[0, 1]) == legend["3"] == tuple(category_color(3))
    assert tuple(panel.rgb[1, 0]) == legend["1"] != legend["3"]
    assert tuple(panel.rgb[1, 2]) == legend["200"]
    assert legend["0"] == (0, 0, 0) and tuple(panel.rgb[0, 0]) == (0, 0, 0)
    # the same value has the same colour in every picture
    assert tuple(category_color(np.array([[7, 3]]))[0, 1]) == legend["3"]


def test_neighbouring_values_get_clearly_different_colours():
    c = category_color(np.arange(1, 17)).astype(int)
    for a in range(15):
        assert np.abs(c[a] - c[a + 1]).sum() > 60


def test_integer_targets_have_a_legend_and_many_values_are_counted():
    tech = compile_source("""
technique t "ids"
target color : rgba8 clear 0
target ids : r32ui clear 0
pass p {
  draw scene
  writes color, ids
  fragment { color = vec4(albedo, 1.0); ids = object_id * 1000u; }
}
""").technique
    assert target_views(tech)["ids"].kind == "integer"
    codes = np.arange(40, dtype=np.uint32).reshape(5, 8) * 1000
    (panel,) = target_panels("ids", codes, tech, NEAR, FAR)
    labels = [label for label, _ in panel.legend]
    assert labels[-1] == "+28 more" and len(labels) == 13
    legend = dict(panel.legend)
    for label in labels[:-1]:
        v = int(label)
        assert tuple(panel.rgb.reshape(-1, 3)[v // 1000]) == legend[label]


# -- packed targets ---------------------------------------------------------------------------


def test_inferred_dsf_target_is_depth_and_id_fields(inferred):
    view = target_views(inferred)["gdsf"]
    assert [(r.kind, r.channels) for r in view.roles] == [("linear_depth", (0,)),
                                                          ("bitfield", (1,))]
    assert target_views(inferred)["gnormal"].roles[0].kind == "normal"


def test_a_target_written_by_several_passes_keeps_its_packing():
    tech = compile_file(ROOT / "pipelines/lidr_max_stencil.pipe").technique
    (role,) = target_views(tech)["lightidx"].roles      # rg in one pass, ba in the next
    assert role.kind == "index" and role.packing.scheme == "max_pairs"


def test_bitfield_decode_separates_the_fields(inferred):
    impl = schemes.numpy_impl("bitfield", {"fields": (("object", 8), ("group", 8))})
    H, W = 6, 8
    obj = np.broadcast_to(np.arange(W) + 1, (H, W))              # object id: by column
    group = np.broadcast_to((np.arange(H) * 7)[:, None], (H, W))  # normal group: by row
    packed = impl["pack"](obj, group)
    gdsf = np.zeros((H, W, 2), np.uint16)
    gdsf[..., 0] = 5000
    gdsf[..., 1] = formats.get("r16").quantize(impl["to_unorm"](packed))
    panels = target_panels("gdsf", gdsf, inferred, NEAR, FAR)
    assert [p.title for p in panels] == ["depth", "id.object", "id.group"]
    o, g = panels[1].rgb, panels[2].rgb
    assert (o == o[:1]).all(), "the object panel varies only by column"
    assert (g == g[:, :1]).all(), "the group panel varies only by row"
    assert len({tuple(x) for x in o[0]}) == W and len({tuple(x) for x in g[:, 0]}) == H
    assert tuple(o[0, 2]) == tuple(category_color(3)) == dict(panels[1].legend)["3"]
    assert tuple(g[2, 0]) == dict(panels[2].legend)["14"]


def test_bitfield_in_an_integer_target_is_decoded_from_the_integer():
    tech = compile_source("""
technique t "ids"
pack id = bitfield(fields: (object: 8, group: 8))
target color : rgba8 clear 0
target ids : r32ui clear 0
pass p {
  draw scene
  writes color, ids
  fragment { color = vec4(albedo, 1.0); ids = id.pack(object_id, normal_group); }
}
""").technique
    (role,) = target_views(tech)["ids"].roles
    assert role.kind == "bitfield" and role.raw
    codes = np.array([[0x0102, 0x0105], [0x0302, 0x0000]], np.uint32)
    obj, group = target_panels("ids", codes, tech, NEAR, FAR)
    legend_o, legend_g = dict(obj.legend), dict(group.legend)
    assert set(legend_o) == {"0", "1", "3"} and set(legend_g) == {"0", "2", "5"}
    assert tuple(obj.rgb[0, 0]) == tuple(obj.rgb[0, 1]) == legend_o["1"]
    assert tuple(group.rgb[0, 0]) == tuple(group.rgb[1, 0]) == legend_g["2"]


def test_light_index_target_shows_light_sets_and_counts(lidr):
    # pixel 0: lights 1 and 3 (0-based 0 and 2); pixel 1: light 2 only; pixel 2: none
    v = light_index.emulate_bitplanes(np.array([[1, 2, 0], [3, 0, 0]]), 8, "rgba8")
    codes = np.rint(v * 255).astype(np.uint8)[None]             # (1, 3, 4)
    sets, counts = target_panels("lightidx", codes, lidr, NEAR, FAR)
    assert dict(counts.legend).keys() == {"0", "1", "2"}
    assert tuple(counts.rgb[0, 0]) == dict(counts.legend)["2"]
    assert tuple(counts.rgb[0, 1]) == dict(counts.legend)["1"]
    labels = dict(sets.legend)
    assert set(labels) == {"L0+L2", "L1", "none"}
    assert tuple(sets.rgb[0, 0]) == labels["L0+L2"] and tuple(sets.rgb[0, 2]) == (0, 0, 0)


# -- files ------------------------------------------------------------------------------------


class _Camera:
    near, far = NEAR, FAR


class _Scene:
    name, width, height, camera = "synthetic", 12, 8, _Camera()


class _Compiled:
    def __init__(self, technique):
        self.technique = technique


def test_write_pictures_writes_every_target_and_a_labelled_contact_sheet(tmp_path, inferred):
    rng = np.random.default_rng(1)
    lo = (8, 5)    # low-resolution targets (lbuffer_scale) and full-resolution ones
    targets = {
        "gnormal": rng.random(lo + (2,)).astype(np.float16),
        "gdsf": rng.integers(0, 65535, lo + (2,), dtype=np.uint16),
        "gds": formats.get("d24s8").quantize(rng.random(lo)),
        "gds.stencil": np.zeros(lo, np.uint8),
        "color": rng.integers(0, 255, (8, 12, 4), dtype=np.uint8),
    }
    sheet = write_pictures(tmp_path, _Compiled(inferred), _Scene(), targets)
    assert sheet == tmp_path / "contact_sheet.png"
    for name in targets:
        assert (tmp_path / f"{name}.png").exists()
    # a picture without anything to explain keeps the target's pixels, top row first
    color = np.asarray(Image.open(tmp_path / "color.png"))
    assert color.shape == (8, 12, 3) and (color == targets["color"][::-1, :, :3]).all()
    # panels with titles and legends are laid out wider than the target
    assert Image.open(tmp_path / "gdsf.png").size[0] > 3 * 5
    img = Image.open(sheet)
    assert img.size[0] >= 256 and img.size[1] > 5 * 20
    # each tile is labelled with the target's name, format and size
    assert target_label("gds.stencil", inferred, targets["gds.stencil"]) == \
        "gds.stencil  d24s8 stencil  5x8"
    assert target_label("gdsf", inferred, targets["gdsf"]) == "gdsf  rg16  5x8"


def test_compose_puts_legends_under_the_panels(lidr):
    stencil = np.array([[0, 3], [1, 3]], np.uint8)
    img = compose(target_panels("ds.stencil", stencil, lidr, NEAR, FAR))
    assert img.size[1] > 2 + 2 * 10       # title and a legend row under a 2-pixel picture
    px = np.asarray(img)
    assert tuple(px[0, 1]) == tuple(category_color(3))     # top row of the target: row 1


@pytest.mark.gl
def test_run_writes_a_contact_sheet(tmp_path):
    from pipegen.views.outputs import write_render
    from pipegen.scene import load_scene

    compiled = compile_file(ROOT / "pipelines/lidr_bitplanes.pipe")
    scene = load_scene(ROOT / "examples/scenes/small.toml").with_size(64, 36)
    targets = compiled.pipeline("gl").render(scene)
    out = write_render(compiled, scene, targets, tmp_path / "out")
    assert (Path(out) / "contact_sheet.png").exists()
    ds = np.asarray(Image.open(Path(out) / "ds.png"))
    zcopy = np.asarray(Image.open(Path(out) / "zcopy.png"))
    assert ds.shape == zcopy.shape == (36, 64, 3)
    assert np.abs(ds.astype(int) - zcopy.astype(int)).max() <= 1
    assert ds[-1].mean() > ds[ds.shape[0] // 2].mean()   # the floor nearest the camera is brightest
