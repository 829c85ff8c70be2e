"""The CL backend's wide fragment function (``backends/opencl/wide/``: the fragment code for 8
pixels at once, explicit SIMD over pixels) computes, lane for lane, what the scalar
``pg_fragment`` computes: every target of every shipped technique that has wide passes is
bit-identical with and without it, and so is a technique written to exercise what the wide
form lowers (if/else and ternaries on per-pixel conditions, loops left per pixel with break
and continue, a function returning under a per-pixel condition, discard, integer arithmetic,
load, sample).  The wide path's speed is in benchmarks/ (no timings here)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.backends.opencl import wide as cl_wide
from pipegen.backends.opencl.dialect import OpenCLLanguage
from pipegen.backends.opencl.programs import prelude_source
from pipegen.compiler.driver import compile_file, compile_source
from pipegen.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]

CONTROL = """
technique wide_control "per-pixel control flow for the wide fragment function"
lights[128] { position: vec3, radius: float, color: vec3 }
target color : rgba8 clear (0, 0, 0, 1)
target hdr   : rgba16f clear (0, 0, 0, 0)
target ds    : d24s8 clear depth 1.0 stencil 0
output color

float bump(float x, vec3 p) {
  if (x > 0.5) return x * 0.5;
  float s = 0.0;
  for (int i = 0; i < 8; i++) {
    if (s > p.y + 0.3) break;
    if (fract(p.x * float(i)) < 0.3) continue;
    s += 0.125 + 0.01 * float(i);
  }
  return s;
}

pass base {
  draw scene.opaque
  writes hdr
  depth ds less write
  cull back
  fragment {
    vec3 n = normalize(normal);
    float v = bump(abs(n.x), world_pos);
    vec3 c = vec3(0.0);
    for (int i = 0; i < 128; i++) {
      if (uint(i) >= num_lights) break;
      vec3 d = lights[i].position - world_pos;
      c += lights[i].color * max(dot(n, normalize(d)), 0.0) / (1.0 + length(d));
    }
    if (frag_coord.x < 20.0) { c.x = 1.0; } else if (v > 0.3) { c *= v; } else { c = c.zyx; }
    int k = int(frag_coord.y) % 3;
    uint u = uint(frag_coord.x) * 7u;
    c.y += float(k) * 0.1 + float(u & 3u) * 0.05;
    c.z = c.x > 0.5 ? pow(c.z, 2.2) : sqrt(c.z);
    if (fract(world_pos.z * 3.0) < 0.1) discard;
    hdr = vec4(c, v);
  }
}

pass resolve {
  draw fullscreen
  reads hdr
  writes color
  fragment {
    vec4 a = load(hdr);
    vec4 b = sample(hdr, frag_coord.xy / output_size + vec2(0.01, 0.0));
    vec3 m = mix(a.xyz, b.xyz, a.w);
    color = vec4(m + vec3(smoothstep(0.2, 0.8, a.w) * 0.1), 1.0);
  }
}
"""


def _pipes(compile_fn, monkeypatch, min_cost=None, wmin=None):
    """The CL pipeline with the scalar fragment functions only, and with the wide ones."""
    if min_cost is not None:
        monkeypatch.setattr(cl_wide, "MIN_COST", min_cost)
        monkeypatch.setattr(cl_wide, "GATHER_COST", 0)
    if wmin is not None:
        monkeypatch.setattr(cl_wide, "WMIN", wmin)
    monkeypatch.setattr(cl_wide, "ENABLED", False)
    scalar = compile_fn().pipeline("cl")
    monkeypatch.setattr(cl_wide, "ENABLED", True)
    wide = compile_fn().pipeline("cl")
    return scalar, wide


def _wide_passes(pipe) -> list[str]:
    return [p.name for p in pipe.plan.passes
            if p.code.fragment and cl_wide.MARK in p.code.fragment]


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        x, y = np.asarray(a[k]), np.asarray(b[k])
        assert x.dtype == y.dtype and x.shape == y.shape, k
        diff = np.count_nonzero(x.view(np.uint8) != y.view(np.uint8))
        assert diff == 0, f"{k}: {diff} bytes differ between the scalar and the wide path"


def _scene(name: str, w: int = 96, h: int = 54):
    return load_scene(ROOT / f"examples/scenes/{name}.toml").with_size(w, h)


@pytest.mark.cl
@pytest.mark.parametrize("wmin", [1, cl_wide.WMIN])
def test_control_flow_lowering_is_exact(monkeypatch, wmin):
    scalar, wide = _pipes(lambda: compile_source(CONTROL), monkeypatch, min_cost=0, wmin=wmin)
    assert _wide_passes(wide) == ["base", "resolve"]
    frag = next(p for p in wide.plan.passes if p.name == "base").code.fragment
    # the lowerings this technique is here to exercise
    for what in ("pg_wdone", "pg_wbrk", "pg_wcont", "pg_live &= ", "pg_sel("):
        assert what in frag, what
    for name in ("many_lights", "mixed_lights"):
        scene = _scene(name)
        out = wide.render(scene)
        _assert_same(scalar.render(scene), out)
        assert np.count_nonzero(out["color"][..., :3]) > 0.3 * out["color"][..., :3].size


def _ci(names, exhaustive):
    """``names`` as parameters, those in ``exhaustive`` only with --exhaustive: their wide
    passes (full-screen and light-volume passes reading a G-buffer) go through the lowerings
    of the ones CI keeps, each tested construct by construct above (CI's 10-minute budget)."""
    return [pytest.param(*n if isinstance(n, tuple) else (n,),
                         marks=pytest.mark.exhaustive if (n[0] if isinstance(n, tuple) else n)
                         in exhaustive else ()) for n in names]


@pytest.mark.cl
@pytest.mark.parametrize("technique", _ci(["forward", "forward_multipass", "light_prepass",
                                           "inferred", "deferred", "deferred_calver"],
                                          {"forward_multipass", "light_prepass", "deferred"}))
def test_shipped_techniques_are_exact(monkeypatch, technique):
    scalar, wide = _pipes(lambda: compile_file(ROOT / f"pipelines/{technique}.pipe"),
                          monkeypatch, wmin=1)
    for name in ("many_lights", "mixed_lights"):
        scene = _scene(name)
        _assert_same(scalar.render(scene), wide.render(scene))


@pytest.mark.cl
@pytest.mark.parametrize("technique,wmin", _ci([("deferred_calver", 1), ("light_prepass", None),
                                                ("inferred", None), ("deferred", 1),
                                                ("forward", 1), ("forward_multipass", None)],
                                               {"inferred", "deferred"}))
def test_cross_triangle_batches_are_exact(monkeypatch, technique, wmin):
    """Light passes batch the pixels of consecutive triangles with the same flat words, and
    scene passes those with the same flat words and flat varyings, each lane interpolating
    its own triangle's smooth ones (cl_pass.cl.j2): every target and blend count as with
    batches of one triangle's row (point, spot and directional lights, ``cull auto``'s inside
    lights, quads, ``repeat per light``, materials changing between objects, a run of lights
    in one launch; with every batch wide and with the scalar function for small ones)."""
    if wmin is not None:
        monkeypatch.setattr(cl_wide, "WMIN", wmin)
    path = ROOT / f"pipelines/{technique}.pipe"
    monkeypatch.setattr(cl_wide, "CROSS_TRIANGLE", False)
    one = compile_file(path).pipeline("cl")
    monkeypatch.setattr(cl_wide, "CROSS_TRIANGLE", True)
    cross = compile_file(path).pipeline("cl")
    batched = [p.name for k, p in enumerate(cross.plan.passes) if "lane_t[" in cross.source(k)]
    assert batched and not any("lane_t[" in one.source(k) for k in range(len(one.plan.passes)))
    for name in ("many_lights", "mixed_lights"):
        scene = _scene(name)
        _assert_same(one.render(scene), cross.render(scene))
        _assert_same(one.last_blend_counts, cross.last_blend_counts)


@pytest.mark.cl
def test_light_runs_draw_each_row_once(monkeypatch):
    """Multi-pass forward's light pass draws all its lights in one launch, and rasterises,
    depth-tests and interpolates each row of a tile once for all of them (``pg_once`` in
    cl_pass.cl.j2): bit for bit the scalar path's light-by-light draw, targets and blend
    counts.  On small.toml; and with the box drawn twice in one place in two colours, where
    pixels get two fragments per light, so those rows are drawn light by light (blending the
    row's fragments once per row would sum them in another order: 15 of accum's values here
    differ when it does)."""
    import dataclasses
    scalar, wide = _pipes(lambda: compile_file(ROOT / "pipelines/forward_multipass.pipe"),
                          monkeypatch)
    assert "per_light" in _wide_passes(wide)
    scene = _scene("small")
    box = scene.objects[1]
    twin = dataclasses.replace(box, name="box_twin", id=max(o.id for o in scene.objects) + 1,
                               material=dataclasses.replace(box.material, albedo=(0.2, 0.8, 0.3)))
    twice = dataclasses.replace(scene, objects=list(scene.objects) + [twin])
    for s, most in ((scene, len(scene.lights)), (twice, 2 * len(scene.lights))):
        _assert_same(scalar.render(s), wide.render(s))
        counts = wide.last_blend_counts
        _assert_same(scalar.last_blend_counts, counts)
        assert int(counts["accum"].max()) == most     # the twin's pixels: two per light


def test_which_passes_batch_across_triangles():
    """Wide passes batch across triangles: light volumes, and scene passes with varyings
    (each lane its own triangle's, a batch's flat ones equal) unless shaded per sample; a
    pass that is not wide does not."""
    def batched(t):
        plan = compile_file(ROOT / f"pipelines/{t}.pipe").plan("cl")
        return {p.name for p in plan.passes if p.code.kernel and "lane_t[" in p.code.kernel}
    assert {"point_lights", "spot_lights"} <= batched("deferred_calver")
    assert "light_accumulation" in batched("light_prepass")
    assert "material" in batched("inferred") and "shade" in batched("forward")
    assert "per_light" in batched("forward_multipass")      # inside its run of lights
    assert "gbuffer" not in batched("deferred_calver")      # scalar: nothing to batch


def test_what_stays_scalar():
    """Light-indexed shading (each pixel its own lights) and trivial fragments keep the
    scalar function; the per-light loops of forward shading get the wide one."""
    def wide_passes(t):
        plan = compile_file(ROOT / f"pipelines/{t}.pipe").plan("cl")
        return {p.name for p in plan.passes if p.code.fragment and cl_wide.MARK in p.code.fragment}
    assert "shade" in wide_passes("forward")
    assert "per_light" in wide_passes("forward_multipass")
    assert not {"shade", "depth_prepass"} & wide_passes("lidr_bitplanes")
    assert "gbuffer" not in wide_passes("deferred")
    # the gathers are wide too: tabulated lighting, most of its work gathers, pays wide
    # (cl_wide.GATHER_COST); a fullscreen pass of little work does not (MIN_COST)
    assert "point_lights" in wide_passes("deferred_calver")
    assert "global_lights" not in wide_passes("deferred_calver")


def test_pow_counts_its_polynomials():
    """``pow`` is two polynomials (exp2 of log2) that the scalar path runs pixel by pixel: the
    work estimate counts them (``BUILTIN_WORK``), so multi-pass forward's light pass
    specialised to point lights (Blinn-Phong's specular ``pow``, no light-type branches) is
    wide as its general build is (counted as one node it came to 97 and stayed scalar; its
    raster kernel measured 530 ms scalar against 301 ms wide at 640x360)."""
    from pipegen.backends import plan as planlib
    from pipegen.backends.opencl.wide.cost import BUILTIN_WORK
    general = compile_file(ROOT / "pipelines/forward_multipass.pipe")
    point_only = general.specialise(load_scene(ROOT / "examples/scenes/many_lights.toml"))
    tech = point_only.technique
    per_light = next(p for p in tech.passes if p.name == "per_light")
    fmap = {f.name: f for f in planlib.pass_functions(tech, per_light.body)}
    work = cl_wide.cost(per_light.body, fmap)
    assert cl_wide.MIN_COST <= work < cl_wide.MIN_COST + BUILTIN_WORK["pow"]
    for compiled in (general, point_only):
        plan = compiled.plan("cl")
        assert cl_wide.has_wide(next(p for p in plan.passes if p.name == "per_light").code.fragment)


def test_unsupported_code_falls_back():
    """What the wide form does not lower gives no wide function, never a wrong one."""
    src = CONTROL.replace("vec3 c = vec3(0.0);", "vec3 c = vec3(0.0); mat3 q = mat3(n, n, n);"
                          " c += q * n;")
    tech = compile_source(src).technique
    p = next(p for p in tech.passes if p.name == "base")
    assert cl_wide.wide_fragment(tech, p, OpenCLLanguage(tech, p)) is None


SAMPLES = """
technique wide_samples "bilinear and nearest sample() of every filtered storage class"
target h4 : rgba16f size 37 x 11
target h1 : r16f size 37 x 11
target h2 : rg16f size 37 x 11
target f4 : rgba32f size 37 x 11
target f1 : r32f size 37 x 11
target u8 : rgba8 size 37 x 11
target u16 : rgba16 size 37 x 11
target sn : rg8_snorm size 37 x 11
target ds : d24s8 clear depth 1.0 stencil 0
target oh : rgba32f
target of : rgba32f
target ou : rgba32f
target on : rgba32f
output oh

pass prepass {
  draw scene.opaque
  depth ds less write
  cull back
}

pass tabulate {
  draw fullscreen
  writes h4, h1, h2, f4, f1, u8, u16, sn
  fragment {
    uint h = (uint(frag_coord.x) * 2654435761u) ^ (uint(frag_coord.y) * 40503u + 12345u);
    h = h ^ (h >> 13);
    float v = float(h & 65535u) / 65536.0;
    vec4 q = vec4(v * 7.0 - 3.0, v * v * 100.0, 1.0 - v, v * 0.001);
    h4 = q;
    h1 = q.x;
    h2 = q.yz;
    f4 = q;
    f1 = q.y;
    u8 = vec4(v, v * v, 1.0 - v, fract(v * 3.5));
    u16 = vec4(v, v * v, 1.0 - v, fract(v * 3.5));
    sn = vec2(v * 2.0 - 1.0, 0.5 - v);
  }
}

pass probe {
  draw fullscreen
  reads h4, h1, h2, f4, f1, u8, u16, sn, ds
  writes oh, of, ou, on
  fragment {
    vec2 uv = frag_coord.xy / output_size * 1.4 - 0.2 + vec2(0.00123, 0.00071) * frag_coord.yx;
    if (frag_coord.x < 4.0) { uv.x = (frag_coord.y - 20.0) * 1e30 * 1e10; }
    if (frag_coord.y < 3.0) { uv.y = -uv.y * 3.0e38 * (frag_coord.x - 30.0); }
    float big = frag_coord.y * 1e30 * 1e30;
    if (frag_coord.x > 90.0) { uv.y = big - big; }
    vec4 a = sample(h4, uv);
    vec4 b = sample(h1, uv.yx);
    vec4 c = sample(h2, uv);
    oh = vec4(a.x + a.w, a.y - a.z, b.x, c.x * 2.0 + c.y);
    of = sample(f4, uv) + vec4(sample(f1, uv * 0.9).x)
         + vec4(0.0, 0.0, 0.0, load(u8, ivec2(frag_coord.xy) - ivec2(20, 20)).y);
    ou = sample(u8, uv) * 2.0 + sample(u16, uv.yx);
    on = vec4(sample(sn, uv).xy, sample(ds, uv), uv.y);    // .w: the coordinates, NaN included
  }
}
"""


@pytest.mark.cl
def test_wide_gathers_are_exact(monkeypatch):
    """The wide ``load``/``sample`` (address arithmetic, clamps, weights and lerps W-wide,
    the reads lane by lane) give every lane the scalar function's value: bilinear samples of
    half (1, 2 and 4 channels), float, unorm16 and snorm targets, the 8-bit-weight filter of
    unorm8, nearest samples of a depth target, at coordinates inside, outside, infinite and
    NaN; every target bit for bit."""
    scalar, wide = _pipes(lambda: compile_source(SAMPLES), monkeypatch, min_cost=0, wmin=1)
    assert _wide_passes(wide) == ["tabulate", "probe"]
    k = [p.name for p in wide.plan.passes].index("probe")
    src = wide.source(k)
    for what in ("pgw_codes_u8(", "pgw_sample_ds(", "pgw_half8_to_float8((ushort8)",
                 "pgw_sample_f4(", "pgw_sample_sn("):
        assert what in src, what
    scene = _scene("many_lights")
    out = wide.render(scene)
    _assert_same(scalar.render(scene), out)
    assert np.isnan(out["on"][..., 3]).any() and np.count_nonzero(out["ou"]) > 0.5 * out["ou"].size


@pytest.mark.cl
@pytest.mark.parametrize("f16c", [True, False])
def test_wide_half_decoding_is_exact(f16c):
    """``pgw_half8_to_float8`` (the wide half reads: vcvtph2ps where the compiler targets
    F16C, else selects) gives the prelude's ``pg_half_bits_to_float`` bits for all 65536
    codes (NaN payloads and half denormals included)."""
    import pyopencl as cl
    from pipegen.runtime.cl import context as cl_context

    src = (prelude_source() + ("" if f16c else "\n#undef __F16C__\n")
           + cl_wide.wide_helpers() + """
__kernel void k(__global const ushort *p, __global uint *wide, __global uint *scalar) {
    const int g = get_global_id(0);
    vstore8(as_uint8(pgw_half8_to_float8(vload8(g, p))), g, wide);
    for (int j = 0; j < 8; ++j) scalar[8 * g + j] = as_uint(pg_half_bits_to_float(p[8 * g + j]));
}
""")
    ctx, queue = cl_context.get_context()
    prog = cl_context.build_program(src)
    codes = np.arange(65536, dtype=np.uint16)
    mf = cl.mem_flags
    src_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=codes)
    outs = [np.zeros(65536, np.uint32) for _ in range(2)]
    bufs = [cl.Buffer(ctx, mf.WRITE_ONLY, o.nbytes) for o in outs]
    prog.k(queue, (65536 // 8,), None, src_buf, *bufs)
    for o, b in zip(outs, bufs):
        cl.enqueue_copy(queue, o, b)
    queue.finish()
    assert np.array_equal(outs[0], outs[1])
    finite = np.isfinite(codes.view(np.float16))
    exact = codes.view(np.float16)[finite].astype(np.float32).view(np.uint32)
    assert np.array_equal(outs[1][finite], exact)
