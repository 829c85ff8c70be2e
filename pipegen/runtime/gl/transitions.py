"""GL state *transitions*: each pass's fixed-function state lowered once, applied as differences.

``gl_state.apply_state`` sets every piece of state, about 90 PyOpenGL calls, before every
pass.  The GL runtime instead lowers each pass's ``ir.PassState`` (with its attachments) once,
when a pipeline is built, to a ``StateVector``: the GL values of the *slots* the pass depends on,
already converted to GL enums.  A slot is one independently settable piece of state
(``("enable", GL_DEPTH_TEST)``, ``("blend_func", 2)``, ``"blend_color"``, ...); a pass leaves
out the slots that cannot affect it:

* blend enable/equations/factors and the colour mask of draw buffers the pass does not write
  (its framebuffer maps them to ``GL_NONE``);
* blend equations and factors of a draw buffer whose blending is off, the blend constant unless
  an enabled blend uses a constant factor;
* depth function and mask when the depth test is off (GL neither tests nor writes depth then),
  stencil functions, operations and masks when the stencil test is off; a depth test that
  always passes without writing (``depth ds off``) and a stencil state that always passes and
  keeps every value are switched off (the same results, fewer changes);
* the cull face when culling is off, polygon offset values when the offset is off.

Depth clamp is always included (it also disables near/far clipping), and so are the switches
pipegen never turns on (dithering, sRGB writes, logic ops, ... ``RESET``).

``StateTracker`` knows the state of the context as a tuple of slot values (None: unknown).
``apply(vector)`` looks the pair (current state, vector) up in its ``TransitionTable``: the GL
calls that take that state to one satisfying the vector, and the resulting state.  Each
transition is computed once (a pass sequence has few distinct pairs: consecutive passes,
the last pass of a repeat group to its first, a pass skipped for some lights, the two faces of
a ``cull auto`` pass) and applied afterwards with one dictionary look-up; ``prime`` computes
the transitions of a plan's pass sequence when a pipeline is built.  States are interned as
integers, so a look-up hashes two integers.

The context is shared with moderngl and user code, so a frame starts from *unknown* state
(``invalidate``): its first pass sets every slot of its vector, the ``RESET`` switches included,
and each later pass only what differs.  Framebuffer, viewport, scissor, texture-unit and sampler
bindings are tracked the same way (compare with the last value set, call GL when it differs).
Anything else that changes tracked state inside a frame must go through the tracker
(``apply`` a vector with the slots it needs, e.g. ``CLEAR_DEPTH`` before a depth clear).

``SLOTS`` lists every slot; ``calls(slot, value)`` gives the GL calls that set one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional, Sequence

from pipegen.core import formats as F
from pipegen.ir import nodes as ir
from pipegen.runtime.gl.context import GL

__all__ = ["StateVector", "StateTracker", "TransitionTable", "TRACKER", "pass_vector",
           "slot_vector", "calls", "SLOTS", "RESET", "CLEAR_DEPTH", "CLEAR_STENCIL",
           "MAX_DRAW_BUFFERS"]

MAX_DRAW_BUFFERS = 8

# The switches pipegen never turns on (gl_state.reset_state): value False unless noted.
_OFF = (GL.GL_DITHER, GL.GL_FRAMEBUFFER_SRGB, GL.GL_COLOR_LOGIC_OP,
        GL.GL_SAMPLE_ALPHA_TO_COVERAGE, GL.GL_SAMPLE_ALPHA_TO_ONE, GL.GL_SAMPLE_COVERAGE,
        GL.GL_SAMPLE_MASK, GL.GL_SAMPLE_SHADING, GL.GL_RASTERIZER_DISCARD,
        GL.GL_PRIMITIVE_RESTART, GL.GL_PRIMITIVE_RESTART_FIXED_INDEX,
        GL.GL_POLYGON_OFFSET_LINE, GL.GL_POLYGON_OFFSET_POINT,
        *(GL.GL_CLIP_DISTANCE0 + i for i in range(8)))
RESET: tuple[tuple[Any, Any], ...] = (
    *((("enable", cap), False) for cap in _OFF),
    (("enable", GL.GL_MULTISAMPLE), True),         # only matters for MSAA attachments
    ("polygon_mode", GL.GL_FILL),
    ("front_face", GL.GL_CCW),
    ("depth_range", (0.0, 1.0)),
)

SLOTS: tuple = (
    *(s for s, _ in RESET),
    ("enable", GL.GL_DEPTH_TEST), "depth_func", "depth_mask", ("enable", GL.GL_DEPTH_CLAMP),
    ("enable", GL.GL_STENCIL_TEST), "stencil_func", "stencil_op", "stencil_mask",
    *((kind, i) for i in range(MAX_DRAW_BUFFERS)
      for kind in ("blend", "blend_eq", "blend_func", "color_mask")),
    "blend_color",
    ("enable", GL.GL_CULL_FACE), "cull_face",
    ("enable", GL.GL_POLYGON_OFFSET_FILL), "polygon_offset",
)
_INDEX = {s: k for k, s in enumerate(SLOTS)}


_STENCIL = {"stencil_func": "glStencilFuncSeparate", "stencil_op": "glStencilOpSeparate",
            "stencil_mask": "glStencilMaskSeparate"}


def calls(slot, value, old=None) -> list[tuple[Callable, tuple]]:
    """The GL calls ``(function, args)`` that set ``slot`` to ``value`` (from ``old``, None when
    unknown: the stencil slots hold ``(front, back)`` and set only the face that changes, or
    both faces in one call when they are equal)."""
    if slot in _STENCIL:
        fn = getattr(GL, _STENCIL[slot])
        front, back = value
        if old is not None and old[0] == front:
            return [(fn, (GL.GL_BACK, *back))]
        if old is not None and old[1] == back:
            return [(fn, (GL.GL_FRONT, *front))]
        if front == back:
            return [(fn, (GL.GL_FRONT_AND_BACK, *front))]
        return [(fn, (GL.GL_FRONT, *front)), (fn, (GL.GL_BACK, *back))]
    if isinstance(slot, tuple):
        kind, arg = slot
        if kind == "enable":
            return [(GL.glEnable if value else GL.glDisable, (arg,))]
        if kind == "blend":
            return [(GL.glEnablei if value else GL.glDisablei, (GL.GL_BLEND, arg))]
        if kind == "blend_eq":
            return [(GL.glBlendEquationSeparatei, (arg, *value))]
        if kind == "blend_func":
            return [(GL.glBlendFuncSeparatei, (arg, *value))]
        if kind == "color_mask":
            return [(GL.glColorMaski, (arg, *value))]
    elif slot == "depth_func":
        return [(GL.glDepthFunc, (value,))]
    elif slot == "depth_mask":
        return [(GL.glDepthMask, (GL.GL_TRUE if value else GL.GL_FALSE,))]
    elif slot == "blend_color":
        return [(GL.glBlendColor, value)]
    elif slot == "cull_face":
        return [(GL.glCullFace, (value,))]
    elif slot == "polygon_offset":
        return [(GL.glPolygonOffset, value)]
    elif slot == "polygon_mode":
        return [(GL.glPolygonMode, (GL.GL_FRONT_AND_BACK, value))]
    elif slot == "front_face":
        return [(GL.glFrontFace, (value,))]
    elif slot == "depth_range":
        return [(GL.glDepthRange, value)]
    raise KeyError(f"unknown GL state slot {slot!r}")


class StateVector:
    """The slot values one pass (or one clear, one blit) depends on.  ``id`` names the values:
    vectors of equal values share it, so the process-wide transition table (keyed on state and
    vector ids) holds one entry per distinct transition however many pipelines are built (a
    fresh id per vector made it grow with every pipeline, about 40 KiB each, until its limit)."""

    __slots__ = ("id", "items", "label")
    _ids: dict = {}                  # items -> id

    def __init__(self, items: Sequence[tuple[Any, Any]], label: str = ""):
        self.items = tuple(sorted(((_INDEX[s], v) for s, v in items), key=lambda kv: kv[0]))
        self.label = label
        try:
            self.id = StateVector._ids.setdefault(self.items, len(StateVector._ids))
        except TypeError:            # an unhashable value: a vector of its own
            self.id = -1 - len(StateVector._ids)
            StateVector._ids[object()] = self.id

    def as_dict(self) -> dict:
        return {SLOTS[k]: v for k, v in self.items}

    def __repr__(self) -> str:
        return f"StateVector({self.label or self.id}, {len(self.items)} slots)"


def slot_vector(items: dict, label: str = "") -> StateVector:
    """A vector of the given ``{slot: value}`` only (clears and blits)."""
    return StateVector(list(items.items()), label)


_COMPARE = {f.value: e for f, e in (
    (ir.CompareFunc.NEVER, GL.GL_NEVER), (ir.CompareFunc.LESS, GL.GL_LESS),
    (ir.CompareFunc.EQUAL, GL.GL_EQUAL), (ir.CompareFunc.LEQUAL, GL.GL_LEQUAL),
    (ir.CompareFunc.GREATER, GL.GL_GREATER), (ir.CompareFunc.NOTEQUAL, GL.GL_NOTEQUAL),
    (ir.CompareFunc.GEQUAL, GL.GL_GEQUAL), (ir.CompareFunc.ALWAYS, GL.GL_ALWAYS))}

_CONSTANT_FACTORS = {ir.BlendFactor.CONSTANT_COLOR, ir.BlendFactor.ONE_MINUS_CONSTANT_COLOR,
                     ir.BlendFactor.CONSTANT_ALPHA, ir.BlendFactor.ONE_MINUS_CONSTANT_ALPHA}


def pass_vector(state: ir.PassState, writes: Sequence[str] = (), *,
                depth_format: Optional[F.Format] = None, label: str = "") -> StateVector:
    """Lower one pass's state to the slots it depends on (see the module docstring).

    The arguments are ``gl_state.apply_state``'s: setting this vector on top of *any* state
    renders exactly what ``apply_state`` followed by the same draw renders.
    """
    from pipegen.runtime.gl.enums import BLEND_FACTOR, BLEND_OP, COMPARE, CULL, STENCIL_OP
    items: list[tuple[Any, Any]] = list(RESET)
    depth = state.depth
    # A test that always passes and writes nothing is the same as no test (the stencil ops
    # see a passing depth test either way): such tests are switched off, their details unset.
    has_depth = depth_format is not None and depth.enabled
    has_stencil = (depth_format is not None and depth_format.has_stencil
                   and state.stencil.enabled)
    items.append((("enable", GL.GL_DEPTH_TEST), has_depth))
    if has_depth:
        items.append(("depth_func", COMPARE[depth.func.value]))
        items.append(("depth_mask", bool(depth.write)))
    items.append((("enable", GL.GL_DEPTH_CLAMP), bool(depth.clamp)))

    items.append((("enable", GL.GL_STENCIL_TEST), has_stencil))
    if has_stencil:
        faces = (state.stencil.front, state.stencil.back)
        items.append(("stencil_func", tuple((COMPARE[s.func.value], int(s.ref),
                                             int(s.read_mask) & 0xFF) for s in faces)))
        items.append(("stencil_op", tuple((STENCIL_OP[s.fail.value], STENCIL_OP[s.zfail.value],
                                           STENCIL_OP[s.zpass.value]) for s in faces)))
        items.append(("stencil_mask", tuple((int(s.write_mask) & 0xFF,) for s in faces)))

    constant = False
    if len(writes) > MAX_DRAW_BUFFERS:
        raise ValueError(f"{len(writes)} colour outputs; GL offers {MAX_DRAW_BUFFERS}")
    for i, name in enumerate(writes):
        b = state.blend_for(name)
        items.append((("blend", i), bool(b.enabled)))
        if b.enabled:
            rgb, alpha = b.rgb, b.alpha
            items.append((("blend_eq", i), (BLEND_OP[rgb.op.value], BLEND_OP[alpha.op.value])))
            items.append((("blend_func", i), (BLEND_FACTOR[rgb.src.value],
                                              BLEND_FACTOR[rgb.dst.value],
                                              BLEND_FACTOR[alpha.src.value],
                                              BLEND_FACTOR[alpha.dst.value])))
            constant |= bool({rgb.src, rgb.dst, alpha.src, alpha.dst} & _CONSTANT_FACTORS)
        items.append((("color_mask", i), tuple(bool(m) for m in b.write_mask)))
    if constant:
        items.append(("blend_color", tuple(float(c) for c in state.blend_constant)))

    culling = state.cull not in (ir.CullMode.NONE, ir.CullMode.AUTO)   # auto: per light run
    items.append((("enable", GL.GL_CULL_FACE), culling))
    if culling:
        items.append(("cull_face", CULL[state.cull.value]))
    offset = state.polygon_offset
    items.append((("enable", GL.GL_POLYGON_OFFSET_FILL), offset is not None))
    if offset is not None:
        items.append(("polygon_offset", (float(offset.factor), float(offset.units))))
    return StateVector(items, label)


# Clears through a framebuffer obey the depth / stencil write masks (gl_pipeline partial clears).
CLEAR_DEPTH = slot_vector({"depth_mask": True}, "clear depth")
CLEAR_STENCIL = slot_vector({"stencil_mask": ((0xFF,), (0xFF,))}, "clear stencil")


@dataclass(frozen=True)
class Transition:
    calls: tuple[tuple[Callable, tuple], ...]
    to: int                                  # the interned state afterwards


class TransitionTable:
    """Interned states (tuples of slot values, None = unknown) and the transitions between
    them: ``transition(state_id, vector)`` is computed on first use, looked up afterwards."""

    UNKNOWN = 0
    LIMIT = 100_000      # transitions kept (a frame's sequence needs a few hundred at most)

    def __init__(self):
        unknown = (None,) * len(SLOTS)
        self.states: list[tuple] = [unknown]
        self._ids: dict[tuple, int] = {unknown: 0}
        self.table: dict[tuple[int, int], Transition] = {}

    def _intern(self, state: tuple) -> int:
        k = self._ids.get(state)
        if k is None:
            k = self._ids[state] = len(self.states)
            self.states.append(state)
        return k

    def transition(self, state_id: int, vector: StateVector) -> Transition:
        key = (state_id, vector.id)
        t = self.table.get(key)
        if t is None:
            if len(self.table) >= self.LIMIT:     # never in a pass sequence; random use only
                self.table.clear()
            state = list(self.states[state_id])
            out = []
            for k, v in vector.items:
                if state[k] != v or state[k] is None:
                    out.extend(calls(SLOTS[k], v, state[k]))
                    state[k] = v
            t = self.table[key] = Transition(tuple(out), self._intern(tuple(state)))
        return t

    def __len__(self) -> int:
        return len(self.table)


class StateTracker:
    """What the GL context's state is, as far as the runtime set it (see the module doc)."""

    def __init__(self, table: Optional[TransitionTable] = None):
        self.table = table or TransitionTable()
        self.invalidate()

    def invalidate(self) -> None:
        """Forget everything: the next ``apply`` sets every slot of its vector, each binding is
        set again.  Call at the start of a frame and after anyone else touched the context."""
        self.state = TransitionTable.UNKNOWN
        self.fbo: Optional[int] = None
        self.view: Optional[tuple[int, int, int, int]] = None     # x, y, w, h
        self.scissor_rect: Any = ()        # () unknown, None off, (x, y, w, h) on
        self.units: dict[int, tuple[int, int]] = {}

    def apply(self, vector: StateVector) -> int:
        """Make the context satisfy ``vector``; returns the number of GL calls made."""
        t = self.table.transition(self.state, vector)
        for fn, args in t.calls:
            fn(*args)
        self.state = t.to
        return len(t.calls)

    def prime(self, vectors: Sequence[StateVector]) -> None:
        """Compute (without calling GL) the transitions of a sequence applied from unknown
        state: a frame's pass sequence, computed when a pipeline is built."""
        s = TransitionTable.UNKNOWN
        for v in vectors:
            s = self.table.transition(s, v).to

    # -- bindings ------------------------------------------------------------------------------
    def framebuffer(self, fbo: int) -> None:
        if self.fbo != fbo:
            GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fbo)
            self.fbo = fbo

    def viewport(self, w: int, h: int, x: int = 0, y: int = 0) -> None:
        """The viewport ``w`` x ``h`` at ``(x, y)`` (a shadow-map tile; else the origin)."""
        view = (int(x), int(y), int(w), int(h))
        if self.view != view:
            GL.glViewport(*view)
            self.view = view

    def scissor(self, rect) -> None:
        """``(x, y, w, h)`` in window pixels enables the scissor test there; None disables."""
        if rect is not None:
            rect = tuple(int(v) for v in rect)
            rect = (rect[0], rect[1], max(rect[2], 0), max(rect[3], 0))
        old = self.scissor_rect
        if rect == old:
            return
        if rect is None:
            GL.glDisable(GL.GL_SCISSOR_TEST)
        else:
            if old is None or old == ():
                GL.glEnable(GL.GL_SCISSOR_TEST)
            GL.glScissor(*rect)
        self.scissor_rect = rect

    def texture(self, unit: int, tex: int, sampler: int) -> None:
        """Bind texture ``tex`` and sampler object ``sampler`` to texture unit ``unit``."""
        old = self.units.get(unit)
        if old == (tex, sampler):
            return
        if old is None or old[0] != tex:
            GL.glBindTextureUnit(unit, tex)
        if old is None or old[1] != sampler:
            GL.glBindSampler(unit, sampler)
        self.units[unit] = (tex, sampler)


# One context per process (gl_context), so one tracker: every pipeline sets state through it.
TRACKER = StateTracker()
