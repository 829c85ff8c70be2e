"""GL state transitions (``pipegen.runtime.gl.transitions``) render exactly what full state does.

* every shipped technique, on scenes with point, spot and directional lights and with shadow
  maps: a pipeline that sets only the differences between passes (the default) and one that
  sets all state before every pass (``transitions=False``, ``gl_state.apply_state``) give
  bit-identical targets, depth and stencil included, and so do their per-pass captures;
* the tracker's GL state read back with ``glGet*`` after every vector of random pass
  sequences (from random junk state) equals what each vector asks for, slot by slot, and what
  ``apply_state`` sets for the same pass;
* a frame starts from unknown state: another pipeline, or state left by anyone on the shared
  context (blending, scissor, masks, culling), changes nothing;
* GL errors: once per frame by default, naming the pass in debug mode;
* call counts (load-independent): transitions make far fewer PyOpenGL calls than full state.
"""

from __future__ import annotations

import random
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from pipegen.core import formats as F
from pipegen.ir import nodes as ir
from pipegen.compiler.driver import compile_file
from pipegen.scene import load_scene

try:
    from pipegen.runtime.gl.context import GL, get_context
    from pipegen.runtime.gl import state as GS
    from pipegen.runtime.gl import transitions as GT
    from pipegen.runtime.gl.pipeline import GLPipeline
    _CTX = get_context()
    _ERR = None
except Exception as e:  # pragma: no cover - machines without EGL
    _CTX, _ERR = None, e

pytestmark = [pytest.mark.gl, pytest.mark.skipif(_CTX is None, reason=f"no EGL/GL context: {_ERR}")]

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe"))


def _scene(name: str, w: int = 80, h: int = 45):
    return load_scene(ROOT / f"examples/scenes/{name}.toml").with_size(w, h)


@pytest.fixture(scope="module")
def plans():
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = compile_file(ROOT / f"pipelines/{name}.pipe").plan("gl")
        return cache[name]
    return get


def _assert_same(a: dict, b: dict, what: str) -> None:
    assert set(a) == set(b), what
    for k in b:
        assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, (what, k)
        diff = int(np.count_nonzero(a[k] != b[k]))
        assert diff == 0, f"{what}: target {k} differs in {diff} values"


@pytest.mark.parametrize("technique", SHIPPED)
@pytest.mark.parametrize("scene_name", ["mixed_lights", "many_lights", "shadows"])
def test_transitions_render_what_full_state_renders(plans, technique, scene_name):
    scene = _scene(scene_name)
    fast = GLPipeline(plans(technique))
    full = GLPipeline(plans(technique), transitions=False)
    try:
        want = full.render(scene)
        assert any(np.any(v) for v in want.values()), "nothing rendered"
        _assert_same(fast.render(scene), want, f"{technique} on {scene_name}")
        # a second frame starts from the state the first left behind
        _assert_same(fast.render(scene), want, f"{technique} on {scene_name}, frame 2")
    finally:
        fast.release()
        full.release()


@pytest.mark.parametrize("technique", ["deferred", "deferred_calver", "lidr_max_stencil",
                                       "inferred"])
def test_transitions_per_pass_captures(plans, technique):
    """Every pass execution (per light in repeat groups) leaves the same targets."""
    scene = _scene("mixed_lights", 48, 27)
    fast = GLPipeline(plans(technique))
    full = GLPipeline(plans(technique), transitions=False)
    try:
        _, caps_full = full.render(scene, capture_passes=True)
        _, caps_fast = fast.render(scene, capture_passes=True)
        assert [(c["pass"], c["light"]) for c in caps_fast] == \
            [(c["pass"], c["light"]) for c in caps_full]
        assert len({c["pass"] for c in caps_fast}) >= 3
        for cf, cs in zip(caps_full, caps_fast):
            _assert_same(cs["targets"], cf["targets"], f"{technique} after {cf['pass']} "
                                                       f"light {cf['light']}")
    finally:
        fast.release()
        full.release()


# ---- the tracker against GL's own state ----------------------------------------------------------

def _read_slot(slot):
    """The GL context's current value of one slot, in ``pass_vector``'s terms."""
    i32 = lambda e: int(np.ravel(GL.glGetIntegerv(e))[0])           # noqa: E731
    if isinstance(slot, tuple):
        kind, arg = slot
        if kind == "enable":
            return bool(GL.glIsEnabled(arg))
        if kind == "blend":
            return bool(GL.glIsEnabledi(GL.GL_BLEND, arg))
        if kind == "blend_eq":
            return (int(GL.glGetIntegeri_v(GL.GL_BLEND_EQUATION_RGB, arg)),
                    int(GL.glGetIntegeri_v(GL.GL_BLEND_EQUATION_ALPHA, arg)))
        if kind == "blend_func":
            return tuple(int(GL.glGetIntegeri_v(e, arg)) for e in (
                GL.GL_BLEND_SRC_RGB, GL.GL_BLEND_DST_RGB, GL.GL_BLEND_SRC_ALPHA,
                GL.GL_BLEND_DST_ALPHA))
        if kind == "color_mask":
            return tuple(bool(m) for m in GL.glGetBooleani_v(GL.GL_COLOR_WRITEMASK, arg))
    if slot == "stencil_func":
        # Mesa clamps the reported reference to the draw framebuffer's stencil bits, known
        # once the framebuffer was validated (stencil_fbo)
        GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        return ((i32(GL.GL_STENCIL_FUNC), i32(GL.GL_STENCIL_REF), i32(GL.GL_STENCIL_VALUE_MASK)),
                (i32(GL.GL_STENCIL_BACK_FUNC), i32(GL.GL_STENCIL_BACK_REF),
                 i32(GL.GL_STENCIL_BACK_VALUE_MASK)))
    if slot == "stencil_op":
        return ((i32(GL.GL_STENCIL_FAIL), i32(GL.GL_STENCIL_PASS_DEPTH_FAIL),
                 i32(GL.GL_STENCIL_PASS_DEPTH_PASS)),
                (i32(GL.GL_STENCIL_BACK_FAIL), i32(GL.GL_STENCIL_BACK_PASS_DEPTH_FAIL),
                 i32(GL.GL_STENCIL_BACK_PASS_DEPTH_PASS)))
    if slot == "stencil_mask":
        return ((i32(GL.GL_STENCIL_WRITEMASK) & 0xFF,),
                (i32(GL.GL_STENCIL_BACK_WRITEMASK) & 0xFF,))
    if slot == "depth_func":
        return i32(GL.GL_DEPTH_FUNC)
    if slot == "depth_mask":
        return bool(np.ravel(GL.glGetBooleanv(GL.GL_DEPTH_WRITEMASK))[0])
    if slot == "blend_color":
        return tuple(float(v) for v in GL.glGetFloatv(GL.GL_BLEND_COLOR))
    if slot == "cull_face":
        return i32(GL.GL_CULL_FACE_MODE)
    if slot == "polygon_offset":
        return (float(np.ravel(GL.glGetFloatv(GL.GL_POLYGON_OFFSET_FACTOR))[0]),
                float(np.ravel(GL.glGetFloatv(GL.GL_POLYGON_OFFSET_UNITS))[0]))
    if slot == "polygon_mode":
        return i32(GL.GL_POLYGON_MODE)
    if slot == "front_face":
        return i32(GL.GL_FRONT_FACE)
    if slot == "depth_range":
        return tuple(float(v) for v in GL.glGetFloatv(GL.GL_DEPTH_RANGE))
    raise KeyError(slot)


def _random_state(rng: random.Random) -> ir.PassState:
    funcs, sops = list(ir.CompareFunc), list(ir.StencilOp)
    ops, factors = list(ir.BlendOp), list(ir.BlendFactor)

    def face():
        return ir.StencilFace(rng.choice(funcs), rng.randrange(256), rng.randrange(256),
                              rng.randrange(256), rng.choice(sops), rng.choice(sops),
                              rng.choice(sops))

    def eq():
        return ir.BlendEquation(rng.choice(ops), rng.choice(factors), rng.choice(factors))

    blend = tuple((f"t{i}", ir.TargetBlend(rng.random() < 0.6, eq(), eq(),
                                           tuple(rng.random() < 0.8 for _ in range(4))))
                  for i in range(rng.randrange(5)))
    plain = rng.random() < 0.3
    return ir.PassState(
        depth=ir.DepthState(rng.choice(funcs), rng.random() < 0.5, rng.random() < 0.2),
        stencil=ir.StencilState() if plain else ir.StencilState(face(), face()),
        blend=blend,
        blend_constant=tuple(round(rng.uniform(0, 2), 3) for _ in range(4)),
        cull=rng.choice([ir.CullMode.NONE, ir.CullMode.BACK, ir.CullMode.FRONT]),
        polygon_offset=(ir.PolygonOffset(rng.uniform(-2, 2), rng.uniform(-4, 4))
                        if rng.random() < 0.3 else None))


def _junk(rng: random.Random) -> None:
    """Random values in every slot, behind the tracker's back."""
    for slot in GT.SLOTS:
        if isinstance(slot, tuple) and slot[0] in ("enable", "blend"):
            on = rng.random() < 0.5
            if slot[0] == "blend":
                (GL.glEnablei if on else GL.glDisablei)(GL.GL_BLEND, slot[1])
            elif slot[1] != GL.GL_RASTERIZER_DISCARD or not on:
                (GL.glEnable if on else GL.glDisable)(slot[1])
    GL.glDepthFunc(GL.GL_GREATER)
    GL.glDepthMask(GL.GL_TRUE)
    GL.glStencilFuncSeparate(GL.GL_FRONT, GL.GL_NEVER, 7, 3)
    GL.glStencilMaskSeparate(GL.GL_BACK, 0x0F)
    for i in range(GT.MAX_DRAW_BUFFERS):
        GL.glColorMaski(i, False, True, False, True)
        GL.glBlendFuncSeparatei(i, GL.GL_DST_COLOR, GL.GL_ONE, GL.GL_ZERO, GL.GL_SRC_ALPHA)
    GL.glBlendColor(0.5, 0.25, 0.125, 2.0)
    GL.glCullFace(GL.GL_FRONT_AND_BACK)
    GL.glPolygonOffset(3.0, 5.0)
    GL.glFrontFace(GL.GL_CW)


@pytest.fixture(scope="module")
def stencil_fbo():
    """GL reports the stencil reference clamped to the bound draw framebuffer's stencil bits:
    queries run with a d24s8 attachment bound."""
    from pipegen.runtime.gl import formats as GF
    tex = GF.create_texture("d24s8", 4, 4)
    ids = np.zeros(1, np.uint32)
    GL.glCreateFramebuffers(1, ids)
    GL.glNamedFramebufferTexture(int(ids[0]), GL.GL_DEPTH_STENCIL_ATTACHMENT, tex, 0)
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, int(ids[0]))
    yield int(ids[0])
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
    GL.glDeleteFramebuffers(1, ids)
    GF.delete_texture(tex)


def _assert_context_satisfies(vector) -> None:
    for slot, want in vector.as_dict().items():
        got = _read_slot(slot)
        if isinstance(want, tuple) and want and isinstance(want[0], float):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-6, err_msg=str(slot))
        else:
            assert got == want, (slot, got, want)


@pytest.mark.parametrize("seed", range(6))
def test_tracker_state_is_gl_state(seed, stencil_fbo):
    rng = random.Random(seed)
    tracker = GT.StateTracker()
    fmts = [None, F.get("d24s8"), F.get("d32f")]
    vectors = []
    for _ in range(12):
        state = _random_state(rng)
        writes = [name for name, _ in state.blend]
        vectors.append(GT.pass_vector(state, writes, depth_format=rng.choice(fmts)))
    _junk(rng)
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, stencil_fbo)
    tracker.invalidate()
    for _ in range(60):        # random sequences: mostly new transitions
        v = rng.choice(vectors)
        tracker.apply(v)
        _assert_context_satisfies(v)
    cycle = vectors[:6]        # a frame's pass sequence repeats: so do its transitions
    for k in range(4):
        if k == 2:
            known = len(tracker.table)
        for v in cycle:
            tracker.apply(v)
            _assert_context_satisfies(v)
    assert len(tracker.table) == known
    GS.reset_state()           # leave the shared context sane


@pytest.mark.parametrize("seed", range(4))
def test_vector_agrees_with_apply_state(seed, stencil_fbo):
    """``apply_state`` sets every slot the pass's vector names to the vector's value."""
    rng = random.Random(100 + seed)
    for _ in range(10):
        state = _random_state(rng)
        writes = [name for name, _ in state.blend]
        fmt = rng.choice([None, F.get("d24s8")])
        _junk(rng)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, stencil_fbo)
        GS.apply_state(state, writes, depth_format=fmt)
        vector = GT.pass_vector(state, writes, depth_format=fmt)
        for slot, want in vector.as_dict().items():
            got = _read_slot(slot)
            if slot == ("enable", GL.GL_DEPTH_TEST) and not want:
                # apply_state keeps the test on with ALWAYS / no writes: the same results
                assert not state.depth.enabled or fmt is None
            elif slot == ("enable", GL.GL_STENCIL_TEST) and not want:
                assert not state.stencil.enabled or fmt is None or not fmt.has_stencil
            elif isinstance(want, tuple) and want and isinstance(want[0], float):
                np.testing.assert_allclose(got, want, atol=1e-6, err_msg=str(slot))
            else:
                assert got == want, (slot, got, want)


def test_unwritten_draw_buffers_and_disabled_tests_are_left_out():
    state = ir.PassState(blend=(("a", ir.TargetBlend()),))
    v = GT.pass_vector(state, ["a"], depth_format=F.get("d24s8")).as_dict()
    assert ("color_mask", 0) in v and ("blend", 0) in v
    assert not any(isinstance(s, tuple) and s[0] in ("blend", "blend_eq", "blend_func",
                                                     "color_mask") and s[1] > 0 for s in v)
    assert ("blend_eq", 0) not in v and "blend_color" not in v      # blending off
    assert v[("enable", GL.GL_DEPTH_TEST)] is False and "depth_func" not in v   # depth off
    assert v[("enable", GL.GL_STENCIL_TEST)] is False and "stencil_op" not in v
    assert "cull_face" not in v and "polygon_offset" not in v


def test_transition_sets_only_differences():
    tracker = GT.StateTracker()
    a = GT.pass_vector(ir.PassState(depth=ir.DepthState(ir.CompareFunc.LESS, True)), ["c"],
                       depth_format=F.get("d24s8"))
    b = GT.pass_vector(ir.PassState(depth=ir.DepthState(ir.CompareFunc.LEQUAL, True)), ["c"],
                       depth_format=F.get("d24s8"))
    first = tracker.apply(a)
    assert first >= len(a.items)           # everything, from unknown state
    assert tracker.apply(a) == 0
    assert tracker.apply(b) == 1           # glDepthFunc only
    assert tracker.apply(a) == 1
    tracker.invalidate()
    assert tracker.apply(a) == first
    GS.reset_state()


# ---- the shared context ------------------------------------------------------------------------

def test_frames_start_from_unknown_state(plans):
    """Other pipelines and state left on the shared context do not leak into a frame."""
    scene = _scene("mixed_lights", 64, 36)
    a = GLPipeline(plans("deferred"))
    b = GLPipeline(plans("lidr_bitplanes"))
    ref_a = GLPipeline(plans("deferred"), transitions=False)
    try:
        want = ref_a.render(scene)
        b.render(scene)
        _assert_same(a.render(scene), want, "after another pipeline")
        # somebody's state on the shared context between frames
        GL.glEnablei(GL.GL_BLEND, 0)
        GL.glBlendFunc(GL.GL_ONE, GL.GL_ONE)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        GL.glScissor(0, 0, 3, 3)
        GL.glColorMaski(0, False, True, True, True)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glStencilMask(0x01)
        GL.glBindTextureUnit(1, 0)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        _assert_same(a.render(scene), want, "after foreign state")
    finally:
        for p in (a, b, ref_a):
            p.release()


# ---- errors ------------------------------------------------------------------------------------

@pytest.mark.parametrize("debug", [False, True])
def test_gl_errors_are_reported(plans, debug):
    scene = _scene("small", 32, 18)
    pipe = GLPipeline(plans("deferred"), debug=debug)
    try:
        pipe.render(scene)
        # a deleted framebuffer name: binding it is GL_INVALID_OPERATION
        victim = next(p for p in pipe.passes if p.name == "ambient_pass")
        GL.glDeleteFramebuffers(1, np.array([victim.fbo], np.uint32))
        with pytest.raises(RuntimeError) as e:
            pipe.render(scene)
        msg = str(e.value)
        assert "OpenGL error 0x0502 GL_INVALID_OPERATION" in msg
        if debug:
            assert "in pass 'ambient_pass'" in msg and "PIPEGEN_GL_DEBUG" not in msg
        else:
            assert "rendering a frame" in msg and "PIPEGEN_GL_DEBUG=1" in msg
        victim.fbo = None
    finally:
        pipe.release()


# ---- PyOpenGL calls ----------------------------------------------------------------------------

def _count_calls(fn) -> Counter:
    import OpenGL.GL as G
    from pipegen.runtime.gl import pipeline as GP
    counts: Counter = Counter()

    def wrap(name, f):
        def counted(*args, **kw):
            counts[name] += 1
            return f(*args, **kw)
        return counted
    saved = {n: getattr(G, n) for n in dir(G) if n.startswith("gl") and callable(getattr(G, n))}
    raw = {n: getattr(GP, n) for n in ("_CLEAR_TEX", "_CLEAR_FBO_IV", "_CLEAR_FBO_FV")}
    table = GT.TRACKER.table
    try:
        for n, f in saved.items():
            setattr(G, n, wrap(n, f))
        for n, f in raw.items():
            setattr(GP, n, wrap(n, f))
        GT.TRACKER.table = GT.TransitionTable()     # transitions hold the functions they call
        fn()
    finally:
        for n, f in saved.items():
            setattr(G, n, f)
        for n, f in raw.items():
            setattr(GP, n, f)
        GT.TRACKER.table = table
    return counts


def test_transitions_make_fewer_calls(plans):
    """deferred on many_lights: 81 lights x (mark + shade).  Full state per pass makes ~90
    calls a pass; transitions only what changes (about 6 a pass inside the light loop)."""
    scene = _scene("many_lights", 32, 18)
    fast = GLPipeline(plans("deferred"))
    full = GLPipeline(plans("deferred"), transitions=False)
    try:
        fast.frame(scene)
        full.frame(scene)
        n_fast = sum(_count_calls(lambda: fast.frame(scene)).values())
        n_full = sum(_count_calls(lambda: full.frame(scene)).values())
        passes = 5 + 2 * 81
        assert n_full > 80 * passes
        assert n_fast < 8 * passes, n_fast
        assert n_fast * 10 < n_full
    finally:
        fast.release()
        full.release()
