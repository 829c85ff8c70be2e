"""The OpenCL reference's rasteriser and format stores (tiny renders, hand-built plans).

Coverage follows GL's rules as llvmpipe implements them (8 sub-pixel bits, pixel centres at .5,
top-left fill rule in image space); attributes are interpolated perspective-correctly; primitive
order is preserved per pixel; stores round like llvmpipe (unorm: half to even; half floats:
toward zero, overflow -> 65504).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pyopencl")

pytestmark = [pytest.mark.cl]

from cl_util import FLAT_COLOR, TriScene, fullscreen, make_pass, make_plan, pixel_quad, quad, target  # noqa: E402
from pipegen.reference import fixed_function as ff  # noqa: E402
from pipegen.reference.raster import rasterize_triangles  # noqa: E402
from pipegen.runtime.cl.pipeline import CLPipeline  # noqa: E402
from pipegen.scene import Camera  # noqa: E402

_PIPES: dict = {}


def pipeline(plan_key, plan_fn):
    """One CLPipeline per distinct plan per test session (PoCL compiles are slow)."""
    if plan_key not in _PIPES:
        _PIPES[plan_key] = CLPipeline(plan_fn())
    return _PIPES[plan_key]


def color_pipe(fmt="rgba8", depth=None, fragment=FLAT_COLOR, inputs=("object_id",), blend=None,
               constant=(0, 0, 0, 0), cull="none", key=None):
    def build():
        targets = [target("color", fmt, clear_color=[0, 0, 0, 0])]
        st = {"cull": cull, "blend_constant": list(constant)}
        if blend:
            st["blend"] = {"color": blend}
        if depth:
            targets.append(target("ds", "d24s8", clear_depth=1.0, clear_stencil=0))
            st["depth"] = {"func": depth, "write": True, "clamp": False}
        return make_plan(targets, [make_pass(depth_target="ds" if depth else None, state=st,
                                             fragment=fragment, inputs=inputs)])
    return pipeline(key or (fmt, depth, fragment, tuple(inputs), str(blend), tuple(constant), cull),
                    build)


def ndc(px, py, W, H):
    """GL window position (y up) -> NDC."""
    return 2.0 * px / W - 1.0, 2.0 * py / H - 1.0


# -- coverage ------------------------------------------------------------------------------------

# Measured on Mesa 22.3 llvmpipe: an 8x8 target, triangles with edges through pixel centres.
LLVMPIPE_TRI1 = """
00000000
00000000
01000000
01100000
01110000
01111000
01111100
00000000"""
LLVMPIPE_TRI2 = """
00000000
00000000
00111100
00011100
00001100
00000100
00000000
00000000"""


def _bits(s):
    return np.array([[int(c) for c in row] for row in s.split()], dtype=bool)


@pytest.mark.parametrize("verts, expected", [
    ([(1.5, 1.5), (6.5, 1.5), (1.5, 6.5)], LLVMPIPE_TRI1),
    ([(6.5, 6.5), (1.5, 6.5), (6.5, 1.5)], LLVMPIPE_TRI2),
])
def test_fill_rule_matches_llvmpipe(verts, expected):
    tri = [[*ndc(x, y, 8, 8), 0.0] for x, y in verts]
    out = color_pipe().render(TriScene(8, 8, tri, colors=[[1, 1, 1, 1]]))
    # the strings are printed with the top row first; results are in GL row order
    np.testing.assert_array_equal(out["color"][..., 0] > 0, _bits(expected)[::-1])


def _analytic_coverage(v, W, H):
    """Pixels (GL row order) whose centre a triangle with vertices ``v`` (GL window coords, on
    the half-pixel grid so everything is exact in float64) covers under the rule measured on
    llvmpipe: a centre on an edge counts when the edge is a left edge (interior at larger x) or
    a horizontal edge with the interior at larger GL y ("top" in GL memory order, row 0 = y 0;
    in image order, where row 0 is on top, that is the *bottom* edge)."""
    v = np.asarray(v, np.float64)
    area = (v[1, 0] - v[0, 0]) * (v[2, 1] - v[0, 1]) - (v[2, 0] - v[0, 0]) * (v[1, 1] - v[0, 1])
    cov = np.zeros((H, W), bool)
    if area == 0:
        return cov
    y, x = np.mgrid[0:H, 0:W] + 0.5
    cov[:] = True
    for k in range(3):
        a, b = v[(k + 1) % 3], v[(k + 2) % 3]
        nx, ny = -(b[1] - a[1]) * np.sign(area), (b[0] - a[0]) * np.sign(area)   # inward
        e = nx * (x - a[0]) + ny * (y - a[1])
        inclusive = nx > 0 or (nx == 0 and ny > 0)
        cov &= (e >= 0) if inclusive else (e > 0)
    return cov


def test_top_left_rule_random_triangles_on_half_pixel_grid():
    W = H = 32
    rng = np.random.default_rng(7)
    tris, expected = [], np.zeros((H, W), np.int64)
    for t in range(60):
        v = rng.integers(-4, 2 * W + 4, size=(3, 2)) / 2.0   # many vertices/edges on centres
        tris.append([[*ndc(x, y, W, H), 0.0] for x, y in v])
        expected[_analytic_coverage(v, W, H)] = t + 1   # later triangles win
    colors = [[(t + 1) / 255.0, 0, 0, 1] for t in range(60)]
    out = color_pipe().render(TriScene(W, H, tris, colors=colors))
    np.testing.assert_array_equal(out["color"][..., 0].astype(np.int64), expected)


def test_shared_edges_cover_every_pixel_exactly_once():
    """A jittered grid of triangles (plus a fan through pixel centres) tiling the viewport,
    blended ONE + ONE with 1/255 each: every pixel must end at exactly one code."""
    W = H = 48
    rng = np.random.default_rng(3)
    n = 7
    gx = np.linspace(-1.0, 1.0, n + 1)
    P = np.stack(np.meshgrid(gx, gx, indexing="ij"), axis=-1)
    inner = (slice(1, n), slice(1, n))
    P[inner] += rng.uniform(-0.08, 0.08, P[inner].shape)
    for i, j in ((2, 3), (4, 4), (5, 2)):     # some vertices exactly on pixel centres
        P[i, j] = ndc(np.floor((P[i, j, 0] + 1) * W / 2) + 0.5,
                      np.floor((P[i, j, 1] + 1) * H / 2) + 0.5, W, H)
    tris = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = P[i, j], P[i + 1, j], P[i + 1, j + 1], P[i, j + 1]
            if (i + j) % 2:
                tris += [[*a, 0], [*b, 0], [*c, 0], [*a, 0], [*c, 0], [*d, 0]]
            else:
                tris += [[*a, 0], [*b, 0], [*d, 0], [*b, 0], [*c, 0], [*d, 0]]
    T = len(tris) // 3
    t = np.array(tris).reshape(T, 3, 3)
    e, f = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    assert (e[:, 0] * f[:, 1] - e[:, 1] * f[:, 0] > 0).all()     # a tiling, no folds
    one = [[1 / 255.0, 1 / 255.0, 1 / 255.0, 1 / 255.0]] * T
    blend = {"enabled": True, "rgb": ["add", "one", "one"], "alpha": ["add", "one", "one"],
             "write_mask": [True] * 4}
    out = color_pipe(blend=blend).render(TriScene(W, H, tris, colors=one))
    np.testing.assert_array_equal(out["color"], np.ones((H, W, 4), np.uint8))


def test_culling_and_facing():
    W = H = 16
    ccw = pixel_quad(W, H, 0, 0, 8, 16)                     # left half, counter-clockwise
    q = pixel_quad(W, H, 8, 0, 16, 16)                      # right half, clockwise
    cw = [q[0], q[2], q[1], q[3], q[5], q[4]]
    colors = [[1, 0, 0, 1]] * 2 + [[0, 1, 0, 1]] * 2
    for cull, left, right in (("none", True, True), ("back", True, False), ("front", False, True)):
        out = color_pipe(cull=cull).render(TriScene(W, H, ccw + cw, colors=colors))
        c = out["color"]
        assert (c[:, :8, 0] == 255).all() == left and (c[:, :8, 0] == 0).all() != left
        assert (c[:, 8:, 1] == 255).all() == right and (c[:, 8:, 1] == 0).all() != right


# -- primitive order ---------------------------------------------------------------------------


def test_bitplane_packing_is_bit_exact_and_order_preserving():
    """Trebilco's bit shifting: blend add(one, constant_color) with constant 0.25 into rgba8;
    each quad writes its 2-bit index into the top bits; earlier writes shift down two bits."""
    W, H = 32, 16
    boxes = [(0, 0, 20, 16), (6, 0, 26, 12), (12, 4, 32, 16), (2, 6, 30, 10)]
    index = [1, 2, 3, 2]
    tris, colors = [], []
    for (c0, r0, c1, r1), i in zip(boxes, index):
        tris += pixel_quad(W, H, c0, r0, c1, r1)
        v = (i << 6) / 255.0
        colors += [[v, v, v, v]] * 2
    blend = {"enabled": True, "rgb": ["add", "one", "constant_color"],
             "alpha": ["add", "one", "constant_color"], "write_mask": [True] * 4}
    out = color_pipe(blend=blend, constant=(0.25, 0.25, 0.25, 0.25)).render(
        TriScene(W, H, tris, colors=colors))
    expected = np.zeros((H, W), np.int64)
    for (c0, r0, c1, r1), i in zip(boxes, index):
        expected[r0:r1, c0:c1] = (i << 6) | (expected[r0:r1, c0:c1] >> 2)
    for ch in range(4):
        np.testing.assert_array_equal(out["color"][..., ch].astype(np.int64), expected)


def test_depth_test_keeps_primitive_order_on_ties():
    """Equal depths with ``less``: the first primitive stays; with ``lequal`` the last wins."""
    W = H = 8
    tris = pixel_quad(W, H, 0, 0, 8, 8, 0.25) + pixel_quad(W, H, 0, 0, 8, 8, 0.25)
    colors = [[1, 0, 0, 1]] * 2 + [[0, 1, 0, 1]] * 2
    out = color_pipe(depth="less").render(TriScene(W, H, tris, colors=colors))
    assert (out["color"][..., 0] == 255).all()
    out = color_pipe(depth="lequal").render(TriScene(W, H, tris, colors=colors))
    assert (out["color"][..., 1] == 255).all()
    np.testing.assert_array_equal(out["ds"], ff.depth_codes("d24s8", np.full((H, W), 0.625)))


# -- interpolation and depth ----------------------------------------------------------------------

WORLD_POS = ("static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n"
             "    out->o_color = (float4)(in->world_pos, in->frag_coord.z);\n"
             "    return true;\n}\n")


def _camera_scene(W, H, tris_world, near=0.5):
    cam = Camera(position=(0.3, 1.2, 3.0), target=(0.0, 0.0, 0.0), fov_y_deg=60, near=near,
                 far=20.0)
    view, proj = cam.view_matrix(), cam.projection(W / H)
    return TriScene(W, H, tris_world, colors=[[1, 1, 1, 1]], view=view, proj=proj), view, proj


def _ray_plane(view, proj, W, H, point, normal):
    """World position where the ray through each pixel centre meets a plane (float64)."""
    inv = np.linalg.inv(proj @ view)
    xs = (np.arange(W) + 0.5) / W * 2 - 1
    ys = (np.arange(H) + 0.5) / H * 2 - 1
    X, Y = np.meshgrid(xs, ys)
    a = np.stack([X, Y, -np.ones_like(X), np.ones_like(X)], -1) @ inv.T
    b = np.stack([X, Y, np.ones_like(X), np.ones_like(X)], -1) @ inv.T
    a, b = a[..., :3] / a[..., 3:], b[..., :3] / b[..., 3:]
    t = ((np.asarray(point) - a) @ normal) / ((b - a) @ normal)
    return a + (b - a) * t[..., None]


def test_perspective_correct_interpolation_and_depth():
    W, H = 40, 30
    # a big slanted quad (world space), seen in perspective
    p = np.array([[-3, -0.5, -4], [3, -0.5, -4], [3, 0.5, 2], [-3, 0.5, 2]], np.float64)
    tris = [p[0], p[1], p[2], p[0], p[2], p[3]]
    scene, view, proj = _camera_scene(W, H, tris)
    out = color_pipe(fmt="rgba32f", fragment=WORLD_POS, inputs=("world_pos",),
                     depth="less").render(scene)
    normal = np.cross(p[1] - p[0], p[3] - p[0])
    expect = _ray_plane(view, proj, W, H, p[0], normal / np.linalg.norm(normal))
    got = out["color"].astype(np.float64)
    cov = out["ds"] < 16777215
    inside = cov.copy()
    inside[1:-1, 1:-1] &= cov[:-2, 1:-1] & cov[2:, 1:-1] & cov[1:-1, :-2] & cov[1:-1, 2:]
    assert inside.sum() > 300
    err = np.abs(got[..., :3] - expect)[inside]
    assert err.max() < 2e-4, err.max()
    # window depth is linear in screen space: compare with the projected exact position
    clip = np.concatenate([expect, np.ones(expect.shape[:2] + (1,))], -1) @ (proj @ view).T
    z = clip[..., 2] / clip[..., 3] * 0.5 + 0.5
    dz = np.abs(out["ds"].astype(np.float64) - np.rint(z * 16777215))[inside]
    assert dz.max() <= 2, dz.max()
    assert np.abs(got[..., 3] - z)[inside].max() < 2e-6


def test_near_plane_clipping_matches_reference_coverage():
    W, H = 40, 30
    # a floor that passes under and behind the camera: crosses the near plane
    p = np.array([[-6, -0.8, 6], [6, -0.8, 6], [6, -0.8, -8], [-6, -0.8, -8]], np.float64)
    tris = [p[0], p[1], p[2], p[0], p[2], p[3]]
    scene, view, proj = _camera_scene(W, H, tris)
    out = color_pipe(fmt="rgba32f", fragment=WORLD_POS, inputs=("world_pos",),
                     depth="less").render(scene)
    frags = rasterize_triangles(np.array(tris).reshape(-1, 3, 3), np.zeros((2, 3, 3)),
                                proj @ view, W, H, cull="none")
    ref = np.zeros(W * H, bool)
    ref[frags.pixel] = True
    ref = ref.reshape(H, W)[::-1]            # the reference raster is in image row order
    cov = out["ds"] < 16777215
    assert ref.sum() > 200
    # coverage may differ only where the reference sees an edge
    tri_img = np.full(W * H, -1)
    tri_img[frags.pixel] = frags.triangle
    from pipegen.reference.raster import edge_mask
    edges = edge_mask(tri_img.reshape(H, W))[::-1]
    assert not ((cov != ref) & ~edges).any()
    expect = _ray_plane(view, proj, W, H, p[0], np.array([0.0, 1.0, 0.0]))
    err = np.abs(out["color"][..., :3] - expect)[ref & cov & ~edges]
    assert err.max() < 2e-3 * np.abs(expect).max()


# -- stores ------------------------------------------------------------------------------------

PER_PIXEL = ("static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n"
             "    out->o_color = in->lights[(in->pix.y * 16 + in->pix.x) * PG_LIGHT_ROWS];\n"
             "    return true;\n}\n")


def _per_pixel(fmt, values):
    """Render a 16x16 target whose pixel (x, y) (GL window coords) gets values[y*16 + x]."""
    pipe = color_pipe(fmt=fmt, fragment=PER_PIXEL, inputs=())
    v = np.zeros((256, 4), np.float32)
    v[:len(values)] = values
    out = pipe.render(TriScene(16, 16, fullscreen(), colors=v))
    return out["color"].reshape(256, -1)   # pixel-major


def test_unorm8_rounds_half_to_even():
    k = np.arange(255)
    x = ((k + 0.5) / 255.0).astype(np.float32)
    codes = _per_pixel("rgba8", np.repeat(x[:, None], 4, 1))[:255, 0].astype(np.int64)
    prod = x * np.float32(255.0)              # the float32 product the store rounds
    ties = prod == k + 0.5
    assert ties.sum() > 50
    np.testing.assert_array_equal(codes, np.rint(prod.astype(np.float64)).astype(np.int64))
    assert (codes[ties] % 2 == 0).all()


def test_unorm8_clamps_and_maps_nan_to_zero():
    vals = np.array([[-1.0, 2.0, np.nan, 0.5], [np.inf, -np.inf, 1.0, 0.0]], np.float32)
    codes = _per_pixel("rgba8", vals)[:2]
    np.testing.assert_array_equal(codes, [[0, 255, 0, 128], [255, 0, 255, 0]])


def test_half_store_rounds_toward_zero_like_llvmpipe():
    # measured on llvmpipe: round toward zero, overflow -> +-65504, inf/nan kept, half
    # denormals kept
    x = np.array([1 + 2 ** -11, 1 + 3 * 2 ** -12, 70000, -70000, 65519, 65520, 1e-6,
                  -(1 + 3 * 2 ** -12), np.inf, -np.inf, np.nan], np.float32)
    want = np.array([1.0, 1.0, 65504, -65504, 65504, 65504, 9.5367431640625e-07, -1.0,
                     np.inf, -np.inf, np.nan], np.float16)
    got = _per_pixel("rgba16f", np.repeat(x[:, None], 4, 1))[:len(x), 0]
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got, ff.half_store(x)[:len(x)])


@pytest.mark.parametrize("fmt", ["r8", "rg8", "rgba16", "r16f", "rg32f", "rgb10a2", "r32ui",
                                 "rgba8ui"])
def test_store_matches_oracle(fmt):
    from pipegen.core import formats as F
    f = F.get(fmt)
    rng = np.random.default_rng(11)
    if f.is_integer:
        vals = rng.integers(0, 1 << 20, size=(256, 4)).astype(np.float32)
        frag = ("static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n"
                "    out->o_color = convert_uint4(in->lights[(in->pix.y * 16 + in->pix.x) * PG_LIGHT_ROWS]);\n"
                "    return true;\n}\n")
        pipe = color_pipe(fmt=fmt, fragment=frag, inputs=())
        out = pipe.render(TriScene(16, 16, fullscreen(), colors=vals))["color"]
        # llvmpipe saturates unsigned integer outputs to the format's range (measured: 2047
        # written to rgba8ui reads back 255), so the reference does too
        top = (1 << max(f.bits)) - 1
        want = np.minimum(vals.astype(np.int64), top).astype(f.dtype).reshape(16, 16, 4)
        want = want[..., 0] if f.channels == 1 else want
    else:
        vals = rng.uniform(-0.2, 1.2, size=(256, 4)).astype(np.float32)
        out = _per_pixel(fmt, vals).reshape(ff.store(fmt, vals.reshape(16, 16, 4)).shape)
        want = ff.store(fmt, vals.reshape(16, 16, 4).astype(np.float64))
        if fmt == "rgb10a2":
            want = _rgb10a2_llvmpipe(vals.reshape(16, 16, 4)).astype(want.dtype)
    np.testing.assert_array_equal(out, want)


def _rgb10a2_llvmpipe(x):
    """rgb10a2 codes as llvmpipe stores them (measured, Mesa 22.3; ``Format.quantize``'s
    rint(x * 1023) is off by one for about a quarter of the values): the float is converted
    to llvmpipe's 16-bit blend type, x * (65535/65536) + 128 in float32 keeping the low 16
    mantissa bits, then scaled down by lp_state_fs.c's scale_bits: rgb c16 >> 6, alpha
    ((c16 >> 2) * 3 + 2^13) >> 14."""
    f32 = np.float32
    c = np.clip(np.nan_to_num(np.asarray(x, f32), nan=0.0), 0, 1).astype(f32)
    c16 = ((c * f32(65535 / 65536)).astype(f32) + f32(128)).astype(f32).view(np.uint32) & 0xFFFF
    out = c16 >> 6
    out[..., 3] = ((c16[..., 3] >> 2) * 3 + 8192) >> 14
    return out


def test_clear_values_and_capture_passes():
    targets = [target("color", "rgba16f", clear_color=[0.25, -2.0, 70000.0, 1.0]),
               target("ds", "d24s8", clear_depth=0.5, clear_stencil=7),
               target("z", "d32f", clear_depth=0.25)]
    p = make_pass(writes=("color",), depth_target="ds",
                  state={"depth": {"func": "less", "write": True, "clamp": False}})
    pipe = pipeline("clears", lambda: make_plan(targets, [p]))
    out, captures = pipe.render(TriScene(8, 4, pixel_quad(8, 4, 0, 0, 4, 4, z=-0.5),
                                         colors=[[1, 2, 3, 4]] * 2), capture_passes=True)
    c = out["color"]
    np.testing.assert_array_equal(c[:, 4:], np.broadcast_to(
        np.array([0.25, -2.0, 65504.0, 1.0], np.float16), (4, 4, 4)))
    np.testing.assert_array_equal(c[:, :4], np.broadcast_to(np.array([1, 2, 3, 4], np.float16),
                                                            (4, 4, 4)))
    assert out["ds"].dtype == np.uint32 and out["ds.stencil"].dtype == np.uint8
    assert (out["ds"][:, 4:] == ff.depth_codes("d24s8", 0.5)).all()
    assert (out["ds"][:, :4] == ff.depth_codes("d24s8", 0.25)).all()
    assert (out["ds.stencil"] == 7).all()
    assert out["z"].dtype == np.float32 and (out["z"] == 0.25).all()
    assert [(c["pass"], c["light"]) for c in captures] == [("p", None)]
    for key in ("color", "ds", "ds.stencil", "z"):
        np.testing.assert_array_equal(captures[0]["targets"][key], out[key])


# -- multisampling -------------------------------------------------------------------------------

LLVMPIPE_4X = [(0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875)]


def test_msaa_coverage_per_sample_and_resolve():
    """4x MSAA at llvmpipe's sample positions: each covered sample blends 64 codes in, the
    resolve averages the samples (here: 16 codes per covered sample)."""
    W = H = 24
    targets = [target("color", "rgba8", clear_color=[0, 0, 0, 0], samples=4)]
    blend = {"enabled": True, "rgb": ["add", "one", "one"], "alpha": ["add", "one", "one"],
             "write_mask": [True] * 4}
    pipe = pipeline("msaa", lambda: make_plan(targets, [make_pass(
        state={"blend": {"color": blend}})]))
    rng = np.random.default_rng(8)
    for _ in range(6):
        v = np.round(rng.uniform(0, W, (3, 2)) * 8) / 8          # edges through sample points
        tri = [[*ndc(x, y, W, H), 0.0] for x, y in v]
        out = pipe.render(TriScene(W, H, tri, colors=[[0.25] * 4]))["color"][..., 0]
        count = np.zeros((H, W), np.int64)
        for ox, oy in LLVMPIPE_4X:
            # the analytic rule on the sample grid: shift the triangle by -offset + 1/2
            count += _analytic_coverage(v - np.array([ox - 0.5, oy - 0.5]), W, H)
        np.testing.assert_array_equal(out.astype(np.int64), 16 * count)


def test_msaa_depth_is_per_sample_and_resolves_to_sample_0():
    W = H = 8
    targets = [target("color", "rgba8", clear_color=[0, 0, 0, 0], samples=4),
               target("ds", "d24s8", clear_depth=1.0, clear_stencil=0, samples=4)]
    p = make_pass(depth_target="ds", state={"depth": {"func": "always", "write": True,
                                                      "clamp": False}})
    pipe = pipeline("msaa_depth", lambda: make_plan(targets, [p]))
    tri = [[-1, -1, -1.0], [3, -1, 3.0], [-1, 3, -1.0]]           # window z = x_ndc/2 + 1/2
    out = pipe.render(TriScene(W, H, tri, colors=[[1, 1, 1, 1]]))
    x = np.arange(W) + LLVMPIPE_4X[0][0]
    want = ff.depth_codes("d24s8", (2 * x / W - 1) * 0.5 + 0.5)
    assert np.abs(out["ds"].astype(np.int64) - want[None, :]).max() <= 1
