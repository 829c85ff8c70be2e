"""The OpenCL programs, assembled from the templates: the prelude every pass program starts with
(``prelude_source``), the program of one pass (``pass_program``: the fragment code the emitter
rendered, the pass's fixed-function state as ``S_*`` macros, the vertex and raster kernels of
``templates/cl_pass.cl.j2``), and the runtime's own programs: triangle set-up, binning and
multisample resolve."""

from __future__ import annotations

import functools
import textwrap
from typing import Optional

from pipegen.core import formats as F
from pipegen.core.float32 import f32
from pipegen.ir import access, nodes as ir
from pipegen.ir.builtins import PREVIOUS_FRAME_INPUTS, reads_nudges
from pipegen.ir.light_layout import schema_layout
from pipegen.backends import templating
from pipegen.backends.cstyle import FLT_MIN
from pipegen.backends.plan import REACH_WORDS, CLPassCode, PassPlan, Plan
from pipegen.backends.opencl import wide as cl_wide
from pipegen.backends.opencl.abi import (
    SAMPLE_POSITIONS, SCENE_FLAT, SETUP_CULL, SMALL_BOX, SUBPIXEL, TILE, enum_defines,
    inside_func, sample_positions, scene_varying_slots, state_values, varying_slots)
from pipegen.backends.opencl.dialect import OpenCLLanguage, dialect
from pipegen.backends.opencl.expansions import prelude_forms
from pipegen.backends.opencl.formats import (
    clamp_test, cl_format, cl_format64, pad_to_four, rcp_literal, read_expr, scaled16_conversions)

# ---- the prelude -----------------------------------------------------------------------------


@templating.template_filter
def c_comment(text: str, width: int = 95) -> str:
    """``text`` as a C block comment wrapped at ``width`` columns."""
    lines = textwrap.wrap(text + " */", width, initial_indent="/* ", subsequent_indent=" * ",
                          break_on_hyphens=False, break_long_words=False)
    return "\n".join(lines)


@functools.lru_cache(maxsize=None)
def prelude_source(tile: int = TILE, precision: str = "f32", previous: bool = False) -> str:
    """The prelude every pass program starts with (``templates/cl_prelude.cl.j2``); with
    ``precision="f64"`` followed by the float64 evaluation's building blocks; ``previous``:
    the frame structs end with the previous frame's camera (``prev_view``, ``prev_proj``).
    Rendered once per arguments (every pass program of a plan starts with the same one)."""
    return templating.render("cl_prelude.cl.j2", tile=tile, enums=enum_defines(),
                             scaled16=scaled16_conversions(), f64=precision == "f64",
                             previous=previous, order=prelude_forms())


# ---- per-pass program --------------------------------------------------------------------------


def _state_defines(pass_: PassPlan, dynamic: bool,
                   precision: str = "f32") -> list[tuple[str, str]]:
    lang = dialect(precision)()
    out = []
    for k, (name, kind, value) in enumerate(state_values(pass_)):
        if dynamic:
            out.append((name, f"as_float(pg_st[{k}])" if kind == "f" else f"(pg_st[{k}])"))
        else:
            out.append((name, lang.render_float(value) if kind == "f" else str(value)))
    names = {name for name, _ in out}
    for i, (name, value) in enumerate(out):
        if name + "_IN" in names:     # per triangle: the `inside` test or the pass's own
            out[i] = (name, f"(pg_inside ? {name}_IN : {value})")
    return out


# scene varyings in the float64 kernel: (type, value) over the parent triangle's attributes
# interpolated at the pixel with exact perspective-correct weights (``P``: position, ``N``:
# normal, double3) and its provoking vertex ``pv`` (flat values); a varying that is an affine
# function of an attribute (view-space position, view-space normal) is that function of the
# interpolated attribute -- the same value as interpolating it per vertex, without rounding
SCENE_VARYINGS64 = {
    "world_pos": ("double3", "P"),
    "view_pos": ("double3", "pg_dm4_mul_v4(frame64->view, (double4)(P, 1.0)).xyz"),
    "normal": ("double3", "N"),
    "view_normal": ("double3", "pg_dm3_mul_v3(pg_dm3_from_m4(frame64->view), N)"),
    "albedo": ("double3", "convert_double3(a_albedo[pv].xyz)"),
    "specular": ("double", "(double)a_material[pv].x"),
    "shininess": ("double", "(double)a_material[pv].y"),
    "alpha": ("double", "(double)a_material[pv].z"),
}


def prelude_file(precision: str = "f32", previous: bool = False) -> str:
    """The file name ``pipegen compile`` writes a prelude to (``prelude_source``'s arguments;
    the pass programs ``#include`` it, see ``CLPassCode.included``)."""
    return "prelude" + ("_previous_frame" if previous else "") + \
        ("" if precision == "f32" else f"_{precision}") + ".cl"


def pass_prelude(pass_: PassPlan, tile: int, precision: str) -> tuple[str, str]:
    """(file name, text) of the prelude the program of ``pass_`` starts with."""
    code = pass_.code if pass_.code is not None else CLPassCode("", None)
    previous = bool(set(code.inputs) & set(PREVIOUS_FRAME_INPUTS))
    return prelude_file(precision, previous), prelude_source(tile, precision, previous)


def pass_program(plan: Plan, pass_: PassPlan, dynamic: bool = False, tile: int = TILE,
                 row_fn: Optional[str] = None) -> str:
    """The complete OpenCL program of one pass (``dynamic``: state from a kernel argument),
    in the plan's precision (``plan.precision``: "f32", or "f64" for the float64 evaluation:
    the same program with double arithmetic and storage, docs/internals.md).  ``row_fn``:
    instead the unit a repeat group's fused kernel links (``group.py``): no kernels, the
    raster kernel's body a function of that name drawing one tile row (its tile an argument),
    every program-scope name static."""
    if not 1 <= int(tile) <= 64:       # pg_raster keeps a row's drawn pixels in a ulong mask
        raise ValueError(f"tile size {tile}: the raster kernel supports 1 to 64")
    precision = plan.precision
    f64 = precision == "f64"
    fmt_of = cl_format64 if f64 else cl_format
    code = pass_.code if pass_.code is not None else CLPassCode("", None)
    writes = []
    for k, name in enumerate(pass_.writes):
        f = fmt_of(plan.target(name).format.name)
        writes.append({**f, "k": k, "name": name, "format": f["name"],
                       "bpp": plan.target(name).format.bytes_per_pixel,
                       "clamp": clamp_test(f["name"], precision) if code.fragment else None})
    depth = None
    stencil_bits = 0
    if pass_.depth_target:
        fmt = plan.target(pass_.depth_target).format
        depth = fmt_of(fmt.name)
        stencil_bits = fmt.stencil_bits
    stencil = stencil_bits > 0
    reads = []
    for name in pass_.reads:
        f = fmt_of(plan.target(name).format.name)
        reads.append({**f, "name": name, "format": f["name"], "decoded": read_expr(f),
                      "integer": f["cls"] == "uint",
                      "linear": f["cls"] in ("unorm8", "unorm", "snorm", "half", "float", "f64"),
                      "sampled": name in code.sampled,
                      # load_sample: the target's sample planes are bound, not its resolve
                      "per_sample": name in pass_.sample_reads,
                      "samples": plan.target(name).samples})
    inputs = set(code.inputs)
    draw = pass_.draw
    layout = schema_layout(plan.lights.fields)
    volume = (draw.volume or ir.Volume.SPHERE).value
    # the previous frame's camera: in the frame struct of the programs that read it only
    # (the host's frame buffer always holds it, after the common fields)
    prelude = pass_prelude(pass_, tile, precision)[1]
    samples = plan.pass_samples(pass_)
    sx, sy = sample_positions(samples)
    varyings = varying_slots(pass_)
    # the wide fragment function (wide/: PG_W pixels per call), when the emitter made one
    wide = not f64 and cl_wide.has_wide(code.fragment)
    early_z = code.discard and not _writes_stencil(pass_, stencil_bits, dynamic)
    depth_store = dynamic or _writes_depth(pass_)
    # batches across triangles (cl_pass.cl.j2): wide passes, unless a fragment's late depth
    # write could be one a later triangle's early test must see; with varyings (each lane
    # interpolates its own triangle's, a batch's flat ones equal) not per sample
    xbatch = wide and cl_wide.CROSS_TRIANGLE and not (early_z and depth_store) and (
        not varyings or (cl_wide.CROSS_TRIANGLE_VARYINGS and "sample_id" not in inputs
                         and "sample_mask" not in inputs))
    if f64:
        for v in varyings:
            v["type64"], v["value64"] = SCENE_VARYINGS64[v["name"]]
    batch = batches_lights(plan, pass_, dynamic)
    reach = reaches_by_object(plan, pass_)
    # a run of lights drawn once per row (pg_once) blends each batch of pixels in registers
    # across the lights, PG_W lanes at a time: float targets, one sample, no discard
    once_wide = batch and xbatch and samples == 1 and not code.discard and all(
        w["cls"] in ("half", "float") for w in writes)
    # the discontinuity search's run-time nudges (proof/discontinuity.py): a buffer argument
    nudges = f64 and reads_nudges(inputs)
    return templating.render(
        "cl_pass.cl.j2",
        technique=plan.technique, pass_name=pass_.name, prelude=prelude,
        dynamic=dynamic, state=_state_defines(pass_, dynamic, precision),
        kind=draw.kind.value, volume=volume, fields=layout.places, light_rows=layout.rows,
        varyings=varyings,
        flats=[{"name": n, "component": c} for n, c in SCENE_FLAT.items() if n in inputs],
        writes=writes, depth=depth, stencil=stencil, reads=reads,
        fragment=code.fragment, discard=code.discard, early_z=early_z, depth_store=depth_store,
        stencil_load=stencil and (dynamic or pass_.state.stencil.enabled),
        stencil_store=_writes_stencil(pass_, stencil_bits, dynamic),
        flt_min=OpenCLLanguage().render_float(FLT_MIN),
        scissor=draw.scissor, samples=samples, sample_x=sx, sample_y=sy,
        inside=inside_func(pass_) is not None, f64=f64, real="double" if f64 else "float",
        wide=wide, xbatch=xbatch, wide_helpers=cl_wide.wide_helpers() if wide else "",
        wide_w=cl_wide.W, batch=batch, once_wide=once_wide, per_sample="sample_id" in inputs,
        reach=reach, reach_words=REACH_WORDS,
        mask_input="sample_mask" in inputs, nudges=nudges, row_fn=row_fn)


def reaches_by_object(plan: Plan, pass_: PassPlan) -> bool:
    """Whether the raster kernel of ``pass_`` skips, per light, the triangles of objects the
    light does not reach (``draw scene… within light radius``: its ``pg_reach`` argument, a
    ``draws.reach_table``).  The float64 evaluation draws every object for every light: it
    is the reference that shows a pass whose output does not vanish beyond the radius."""
    return pass_.draw.within and plan.precision == "f32"


def batches_lights(plan: Plan, pass_: PassPlan, dynamic: bool = False) -> bool:
    """Whether the raster kernel of ``pass_`` draws a run of lights in one launch (its
    ``pg_batch``, ``pg_nbatch`` arguments; 0 lights: ``repeat_light`` alone).  One launch
    gives what a launch per light gives where nothing but the light differs between the
    draws and no draw changes what the next one tests: the pass is alone in its ``repeat per
    light`` group (else the group's passes alternate), draws the scene (the same triangles for
    every light), clears nothing, writes no depth or stencil, with one sample, in float32 and
    baked state, reading varyings.  (A cross-triangle batch, ``xbatch``, runs its own loop
    inside the light loop.)  Multi-pass forward's light passes: 255 launches a frame become
    one."""
    if dynamic or plan.precision != "f32" or pass_.repeat_group is None:
        return False
    if sum(q.repeat_group == pass_.repeat_group for q in plan.passes) != 1:
        return False
    if pass_.draw.kind is not ir.DrawKind.SCENE or pass_.draw.shadow or pass_.clears:
        return False
    stencil_bits = plan.target(pass_.depth_target).format.stencil_bits \
        if pass_.depth_target else 0
    if plan.pass_samples(pass_) != 1 or _writes_depth(pass_) \
            or _writes_stencil(pass_, stencil_bits, False):
        return False
    # scene draws read varyings (a pass without them is left to its own kernel)
    code = pass_.code
    return code is not None and bool(code.fragment) and bool(varying_slots(pass_))


def _writes_depth(pass_: PassPlan) -> bool:
    """Whether a pass (its baked state) may write its depth attachment: the raster kernel
    stores the depth it keeps per row only then."""
    rows = {name: value for name, _, value in state_values(pass_)}
    return bool(rows.get("S_DEPTH_WRITE") or rows.get("S_DEPTH_WRITE_IN"))


def _writes_stencil(pass_: PassPlan, stencil_bits: int, dynamic: bool) -> bool:
    """Whether a pass may write its stencil attachment.  A pass whose fragment function may
    discard tests depth and stencil before shading and writes depth after it (llvmpipe's
    EARLY_DEPTH_TEST | LATE_DEPTH_WRITE, lp_state_fs.c) unless it writes stencil: a stencil op
    runs on the test's outcome, which a later discard must undo.  Dynamic-state programs
    (tests) take any state, so any stencil attachment counts."""
    if not stencil_bits:
        return False
    if dynamic:
        return True
    return access.state_writes_stencil(pass_.state, stencil_bits)


# ---- runtime programs: triangle set-up, binning and multisample resolve ---------------------


def setup_program(cull: str, depth_clamp: bool, samples: Optional[int], has_flat: bool,
                  has_scissor: bool, w_plane: bool, with_zq: bool, smooth: tuple,
                  slots: int) -> str:
    """The device set-up program (``cl_setup.cl.j2``: ``pg_setup``, ``pg_clip_setup``) for one
    combination of the set-up's switches (``runtime/cl/setup_device.py``)."""
    lo, hi = (SUBPIXEL // 2, SUBPIXEL // 2) if samples == 1 else (SUBPIXEL - 1, 1)
    # a small triangle covering none of its box's samples is dropped (abi.SMALL_BOX):
    # where the pass's sample positions are known
    sx, sy = sample_positions(samples) if samples in SAMPLE_POSITIONS else ([], [])
    return templating.render(
        "cl_setup.cl.j2", cull=SETUP_CULL[cull], depth_clamp=int(depth_clamp), box_lo=lo,
        box_hi=hi, has_flat=int(has_flat), has_scissor=int(has_scissor), w_plane=int(w_plane),
        with_zq=int(with_zq), smooth=list(smooth), slots=int(slots), sample_x=sx,
        sample_y=sy, small_box=SMALL_BOX)


@functools.lru_cache(maxsize=None)
def scene_vertex_program(names: tuple[str, ...]) -> str:
    """A program of one scene vertex kernel (``pg_vertex``, float32) computing the varyings
    ``names``: the union of those of the passes that share a set-up
    (``runtime/cl/geometry.py``), where each pass's own vertex kernel would compute the clip
    positions again and their varyings be gathered into one buffer by copies.  The same
    kernel text as a pass program's (``cl_vertex.cl.j2``), its varyings in the union's slots
    (the prelude's tile size is the default one: the vertex stage does not use it)."""
    return templating.render(
        "cl_scene_vertex.cl.j2", prelude=prelude_source(), kind="scene", names=list(names),
        varyings=scene_varying_slots(names), f64=False,
        flt_min=OpenCLLanguage().render_float(FLT_MIN))


def bin_program() -> str:
    """The device binning program (``cl_bin.cl.j2``: ``pg_bin_count``, ``pg_bin_starts``,
    ``pg_bin_write``; ``runtime/cl/bin.py``)."""
    return templating.render("cl_bin.cl.j2", subpixel=SUBPIXEL)


def resolve_program(format_name: str, samples: int) -> Optional[str]:
    """The device multisample resolve (``cl_resolve.cl.j2``, ``pg_resolve``) of a target
    format, or None for the formats it does not take (float32, snorm, integer: the runtime
    resolves those in numpy)."""
    fmt = F.get(format_name)
    f = cl_format(format_name)
    if not (f["cls"] in ("unorm8", "unorm", "half")
            or (fmt.kind is F.Kind.DEPTH_STENCIL and fmt.bits[0] == 24)):
        return None
    top = rcp_literal(1.0)
    if f["cls"] in ("unorm8", "unorm"):
        tops = pad_to_four([float((1 << b) - 1) for b in fmt.bits], len(fmt.bits))
        top = "(float4)(" + ", ".join(rcp_literal(v) for v in tops) + ")"
    return templating.render(
        "cl_resolve.cl.j2", prelude=prelude_source(TILE, "f32", False), f=f,
        stencil=fmt.kind is F.Kind.DEPTH_STENCIL, samples=samples,
        inv_samples=rcp_literal(float(f32(1.0 / samples))), top=top,
        d24_rcp=rcp_literal(float(f32(1.0 / 16777215.0))))

