"""Fixed-function state on the OpenCL reference vs the numpy oracle (fixed_function.py).

The pipelines here run in ``dynamic_state`` mode: the state reaches the kernel as an argument,
so one compiled program serves every parametrised case (production plans bake the state in as
constants; ``test_baked_and_dynamic_state_agree`` checks the two agree).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

pytest.importorskip("pyopencl")

pytestmark = [pytest.mark.cl]

from cl_util import TriScene, fullscreen, make_pass, make_plan, pixel_quad, target  # noqa: E402
from pipegen.core import formats as F  # noqa: E402
from pipegen.reference import fixed_function as ff  # noqa: E402
from pipegen.runtime.cl.pipeline import CLPipeline  # noqa: E402

W = H = 16
PER_PIXEL = ("static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n"
             "    out->o_color = in->lights[(in->pix.y * 16 + in->pix.x) * PG_LIGHT_ROWS];\n"
             "    return true;\n}\n")
FLAT = ("static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n"
        "    out->o_color = in->lights[in->object_id * PG_LIGHT_ROWS];\n"
        "    return true;\n}\n")

COMPARE = ["never", "less", "equal", "lequal", "greater", "notequal", "gequal", "always"]
OPS = ["keep", "zero", "replace", "incr", "decr", "incr_wrap", "decr_wrap", "invert"]
FACTORS = ["zero", "one", "src_color", "one_minus_src_color", "dst_color", "one_minus_dst_color",
           "src_alpha", "one_minus_src_alpha", "dst_alpha", "one_minus_dst_alpha",
           "constant_color", "one_minus_constant_color", "constant_alpha",
           "one_minus_constant_alpha", "src_alpha_saturate"]
BLEND_OPS = ["add", "sub", "revsub", "min", "max"]


def make(fmt, state, fragment=PER_PIXEL, inputs=(), depth=True, dynamic=True):
    targets = [target("color", fmt, clear_color=[0, 0, 0, 0])]
    if depth:
        targets.append(target("ds", "d24s8", clear_depth=1.0, clear_stencil=0))
    plan = make_plan(targets, [make_pass(depth_target="ds" if depth else None, state=state,
                                         fragment=fragment, inputs=inputs)])
    return CLPipeline(plan, dynamic_state=dynamic)


# -- depth -------------------------------------------------------------------------------------


@pytest.mark.parametrize("func", COMPARE)
@pytest.mark.parametrize("write", [True, False])
def test_depth_functions_d24(func, write):
    rng = np.random.default_rng(1)
    c0 = int(ff.depth_codes("d24s8", 0.5))
    stored = (c0 + rng.integers(-3, 4, size=(H, W))).astype(np.uint32)
    state = {"depth": {"func": func, "write": write, "clamp": False}}
    pipe = make("rgba8", state, fragment=FLAT, inputs=("object_id",))
    pipe.preset("ds", stored, np.zeros((H, W), np.uint8))
    out = pipe.render(TriScene(W, H, fullscreen(0.0), colors=[[1, 1, 1, 1]]))
    passed, new = ff.depth_update(func, write, 0.5, stored, "d24s8")
    np.testing.assert_array_equal(out["ds"], new)
    np.testing.assert_array_equal(out["color"][..., 0] == 255, passed)


def test_depth_clamp_and_far_plane_clipping():
    """Beyond the far plane: clipped away without clamp, drawn at depth 1 with it."""
    tri = fullscreen(1.5)
    for clamp, drawn in ((False, False), (True, True)):
        pipe = make("rgba8", {"depth": {"func": "always", "write": True, "clamp": clamp}},
                    fragment=FLAT, inputs=("object_id",))
        pipe.preset("ds", np.zeros((H, W), np.uint32), np.zeros((H, W), np.uint8))
        out = pipe.render(TriScene(W, H, tri, colors=[[1, 1, 1, 1]]))
        assert (out["color"][..., 0] == 255).all() == drawn
        assert (out["ds"] == (16777215 if drawn else 0)).all()


def test_polygon_offset_units_and_slope():
    """Offset = factor * max(|dz/dx|, |dz/dy|) + units * 2^-23 on d24 (llvmpipe: one unit is
    two d24 codes, measured)."""
    tri = [[-1, -1, -0.5], [3, -1, 0.5], [-1, 3, -0.5]]     # dz/dx = 1/(4 W) per pixel... in NDC
    res = {}
    for off in (None, [0.0, 4.0], [2.0, 0.0]):
        pipe = make("rgba8", {"depth": {"func": "always", "write": True, "clamp": False},
                              "polygon_offset": off}, fragment=FLAT, inputs=("object_id",))
        res[str(off)] = pipe.render(TriScene(W, H, tri, colors=[[1, 1, 1, 1]]))["ds"].astype(
            np.int64)
    base = res["None"]
    # units: 4 * 2^-23 -> +8 codes (up to rounding of the float z)
    assert np.abs(res["[0.0, 4.0]"] - base - 8).max() <= 1
    # slope: window z grows 0.5 per 4 NDC units in x = 0.5 / (2 W) per pixel
    slope = 0.5 * 2 / (4 * W)
    want = np.rint(2.0 * slope * 16777215)
    assert np.abs(res["[2.0, 0.0]"] - base - want).max() <= 1


# -- stencil -----------------------------------------------------------------------------------


def _stencil_cases():
    rng = np.random.default_rng(5)
    cases = []
    for k in range(8):   # every op in every slot, every func on both faces
        front = {"func": COMPARE[k], "ref": int(rng.integers(0, 256)),
                 "read_mask": int(rng.choice([255, 0x0F, 0xF0, 0x3C])),
                 "write_mask": int(rng.choice([255, 0x0F, 0xF0, 0x81])),
                 "fail": OPS[k], "zfail": OPS[(k + 3) % 8], "zpass": OPS[(k + 5) % 8]}
        back = {"func": COMPARE[(k + 4) % 8], "ref": int(rng.integers(0, 256)),
                "read_mask": int(rng.choice([255, 0x0F, 0xF0])),
                "write_mask": int(rng.choice([255, 0x0F, 0x7E])),
                "fail": OPS[(k + 1) % 8], "zfail": OPS[(k + 6) % 8], "zpass": OPS[(k + 2) % 8]}
        cases.append((front, back))
    return cases


@pytest.mark.parametrize("front, back", _stencil_cases())
def test_stencil_ops_per_face(front, back):
    rng = np.random.default_rng(9)
    stencil = rng.integers(0, 256, size=(H, W)).astype(np.uint8)
    stencil[0, :4] = [0, 255, 1, 254]                 # wrap / saturate corners
    c0 = int(ff.depth_codes("d24s8", 0.5))
    depth = (c0 + rng.integers(-1, 2, size=(H, W))).astype(np.uint32)
    state = {"depth": {"func": "less", "write": True, "clamp": False},
             "stencil": {"front": front, "back": back}}
    pipe = make("rgba8", state, fragment=FLAT, inputs=("object_id",))
    pipe.preset("ds", depth, stencil)
    left = pixel_quad(W, H, 0, 0, W // 2, H, 0.0)            # ccw: front facing
    q = pixel_quad(W, H, W // 2, 0, W, H, 0.0)
    right = [q[0], q[2], q[1], q[3], q[5], q[4]]              # cw: back facing
    out = pipe.render(TriScene(W, H, left + right, colors=[[1, 0, 0, 1]] * 2 + [[0, 1, 0, 1]] * 2))

    buffers = {"color": np.zeros((H, W, 4), np.uint8), "ds": depth, "ds.stencil": stencil}
    formats = {"color": "rgba8", "ds": "d24s8"}
    half = np.zeros((H, W), bool)
    half[:, :W // 2] = True
    for cov, ff_front, col in ((half, True, (1, 0, 0, 1)), (~half, False, (0, 1, 0, 1))):
        buffers = ff.process_fragments(buffers, state, ["color"], formats, coverage=cov,
                                       outputs={"color": np.broadcast_to(col, (H, W, 4))},
                                       depth=0.5, front_facing=ff_front, depth_target="ds")
    np.testing.assert_array_equal(out["ds.stencil"], buffers["ds.stencil"])
    np.testing.assert_array_equal(out["ds"], buffers["ds"])
    np.testing.assert_array_equal(out["color"], buffers["color"])


# -- blending ---------------------------------------------------------------------------------


def _blend_cases():
    cases = []
    for k, f in enumerate(FACTORS):    # every factor as source and as destination factor
        cases.append((["add", f, FACTORS[(k + 7) % 15]], ["add", FACTORS[(k + 3) % 15], f]))
        cases.append((["sub", FACTORS[(k + 11) % 15], f], ["revsub", f, FACTORS[(k + 5) % 15]]))
    for op in BLEND_OPS:
        cases.append(([op, "src_alpha", "one_minus_src_alpha"], [op, "one", "dst_color"]))
    cases.append((["min", "zero", "zero"], ["max", "constant_alpha", "zero"]))
    return cases


def _llvmpipe_blend8(s, d, c, rgb, alpha):
    """llvmpipe's unorm8 blending (measured): 8-bit codes everywhere, each product
    round(a * b / 255), saturating sums and differences."""
    s, d, c = (np.asarray(x, np.int64) for x in (s, d, c))

    def factor(name, ch):
        sl = slice(0, 3) if ch == "rgb" else slice(3, 4)
        one = np.full(s[..., sl].shape, 255)
        return {"zero": 0 * one, "one": one, "src_color": s[..., sl],
                "one_minus_src_color": 255 - s[..., sl], "dst_color": d[..., sl],
                "one_minus_dst_color": 255 - d[..., sl], "src_alpha": s[..., 3:] + 0 * one,
                "one_minus_src_alpha": 255 - s[..., 3:] + 0 * one,
                "dst_alpha": d[..., 3:] + 0 * one, "one_minus_dst_alpha": 255 - d[..., 3:] + 0 * one,
                "constant_color": c[..., sl] + 0 * one,
                "one_minus_constant_color": 255 - c[..., sl] + 0 * one,
                "constant_alpha": c[..., 3:] + 0 * one,
                "one_minus_constant_alpha": 255 - c[..., 3:] + 0 * one,
                "src_alpha_saturate": (np.minimum(s[..., 3:], 255 - d[..., 3:]) + 0 * one)
                if ch == "rgb" else one}[name]

    def mul(a, b):
        return np.floor(a * b / 255.0 + 0.5).astype(np.int64)

    out = np.zeros(s.shape, np.int64)
    for sl, (op, fs, fd), ch in ((slice(0, 3), rgb, "rgb"), (slice(3, 4), alpha, "alpha")):
        ss, dd = s[..., sl], d[..., sl]
        sp, dp = mul(ss, factor(fs, ch)), mul(dd, factor(fd, ch))
        out[..., sl] = {"add": np.minimum(sp + dp, 255), "sub": np.maximum(sp - dp, 0),
                        "revsub": np.maximum(dp - sp, 0), "min": np.minimum(ss, dd),
                        "max": np.maximum(ss, dd)}[op]
    return out.astype(np.uint8)


def _blend_inputs(fmt, seed=2):
    rng = np.random.default_rng(seed)
    f = F.get(fmt)
    if f.kind is F.Kind.UNORM:
        src = rng.uniform(-0.1, 1.1, size=(H, W, 4)).astype(np.float32)
        dst = ff.store(fmt, rng.uniform(0, 1, size=(H, W, 4)))
        const = (0.3, 1.7, -0.2, 0.55)           # clamped for fixed-point targets
    else:
        src = rng.uniform(-2, 4, size=(H, W, 4)).astype(np.float32)
        dst = ff.store(fmt, rng.uniform(-2, 4, size=(H, W, 4)))
        const = (0.3, 1.7, -0.2, 0.55)           # used as is for float targets
    src[0, :4] = [[0.5, 0.5, 0.5, 0.5], [1, 1, 1, 1], [0, 0, 0, 0], [0.25, 0.75, 1.0, 0.0]]
    return src, dst, const


def _render_blend(fmt, rgb, alpha, mask=(True, True, True, True)):
    src, dst, const = _blend_inputs(fmt)
    state = {"blend": {"color": {"enabled": True, "rgb": rgb, "alpha": alpha,
                                 "write_mask": list(mask)}},
             "blend_constant": list(const)}
    pipe = make(fmt, state, depth=False)
    pipe.preset("color", dst)
    out = pipe.render(TriScene(W, H, fullscreen(), colors=src.reshape(-1, 4)))
    return out["color"], src, dst, const


@pytest.mark.parametrize("rgb, alpha", _blend_cases())
def test_blend_unorm8_matches_llvmpipe_arithmetic(rgb, alpha):
    got, src, dst, const = _render_blend("rgba8", rgb, alpha)
    s8 = ff.store("rgba8", src)
    c8 = ff.store("rgba8", np.broadcast_to(np.clip(const, 0, 1), (H, W, 4)))
    np.testing.assert_array_equal(got, _llvmpipe_blend8(s8, dst, c8, rgb, alpha))
    # and within the cross-backend tolerance (1 + P codes, P = 1 blended pass) of the spec's
    # float formula: quantised inputs and two separately rounded products
    want = ff.store("rgba8", ff.blend(src, ff.load("rgba8", dst), rgb, alpha, const, "rgba8"))
    assert np.abs(got.astype(int) - want.astype(int)).max() <= F.get("rgba8").tolerance(1).limit


@pytest.mark.parametrize("rgb, alpha", _blend_cases()[::3])
@pytest.mark.parametrize("fmt", ["rgba16f", "rgba32f", "rgba16"])
def test_blend_float_and_unorm16_vs_oracle(fmt, rgb, alpha):
    got, src, dst, const = _render_blend(fmt, rgb, alpha)
    value = ff.blend(src.astype(np.float64), ff.load(fmt, dst), rgb, alpha, const, fmt)
    want = ff.store(fmt, value)
    if fmt == "rgba16":
        assert np.abs(got.astype(np.int64) - want.astype(np.int64)).max() <= 1
    elif fmt == "rgba16f":   # float32 vs float64 arithmetic, then round toward zero: 1 ulp
        g, w = got.view(np.int16).astype(np.int64), want.view(np.int16).astype(np.int64)
        assert np.abs(g - w).max() <= 1
    else:
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("mask", [(True, False, True, False), (False, False, False, True),
                                  (False, False, False, False)])
@pytest.mark.parametrize("fmt", ["rgba8", "rgba16f"])
def test_color_write_mask(fmt, mask):
    got, src, dst, const = _render_blend(fmt, ["add", "one", "one"], ["add", "one", "zero"],
                                         mask)
    blended = ff.store(fmt, ff.blend(src, ff.load(fmt, dst), ["add", "one", "one"],
                                     ["add", "one", "zero"], const, fmt))
    for ch in range(4):
        if mask[ch]:
            assert np.abs(got[..., ch].astype(np.float64) - blended[..., ch].astype(np.float64)).max() <= (1 if fmt == "rgba8" else 0.01)
        else:
            np.testing.assert_array_equal(got[..., ch], dst[..., ch])


def test_blend_disabled_ignores_factors_and_constant():
    got, src, dst, const = _render_blend("rgba8", ["add", "zero", "one"], ["add", "zero", "one"])
    state_free = ff.store("rgba8", src)
    # enabled: dst kept (zero * src + one * dst)
    np.testing.assert_array_equal(got, dst)
    pipe = make("rgba8", {"blend": {"color": {"enabled": False, "rgb": ["add", "zero", "one"],
                                              "alpha": ["add", "zero", "one"],
                                              "write_mask": [True] * 4}}}, depth=False)
    out = pipe.render(TriScene(W, H, fullscreen(), colors=src.reshape(-1, 4)))
    np.testing.assert_array_equal(out["color"], state_free)


def test_baked_and_dynamic_state_agree():
    """The production path (state baked as constants) gives the same result as the dynamic
    test path for a pass with depth, stencil and blending."""
    state = {"depth": {"func": "lequal", "write": True, "clamp": False},
             "stencil": {"front": {"func": "notequal", "ref": 3, "read_mask": 255,
                                   "write_mask": 255, "fail": "keep", "zfail": "incr",
                                   "zpass": "replace"},
                         "back": {"func": "always", "ref": 0, "read_mask": 255,
                                  "write_mask": 255, "fail": "keep", "zfail": "keep",
                                  "zpass": "keep"}},
             "blend": {"color": {"enabled": True, "rgb": ["add", "src_alpha", "one_minus_src_alpha"],
                                 "alpha": ["max", "one", "one"], "write_mask": [True] * 4}},
             "blend_constant": [0.25, 0.5, 0.75, 1.0]}
    rng = np.random.default_rng(4)
    tris, colors = [], []
    for k in range(12):
        c = rng.integers(0, 12, size=2)
        tris += pixel_quad(W, H, c[0], c[1], c[0] + 5, c[1] + 4, float(rng.uniform(-0.5, 0.5)))
        colors += [list(rng.uniform(0, 1, 4))] * 2
    results = []
    for dynamic in (False, True):
        pipe = make("rgba8", state, fragment=FLAT, inputs=("object_id",), dynamic=dynamic)
        results.append(pipe.render(TriScene(W, H, tris, colors=colors)))
    for key in ("color", "ds", "ds.stencil"):
        np.testing.assert_array_equal(results[0][key], results[1][key])
    assert results[0]["ds.stencil"].max() > 0
