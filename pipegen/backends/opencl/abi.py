"""What the OpenCL programs and the CL runtime (``pipegen/runtime/cl``) agree on: tile and
sub-pixel sizes, the codes of the fixed-function enumerations (the prelude's ``PG_*`` macros),
the varying slots and flat inputs the vertex and raster kernels exchange through the runtime's
buffers, the order of the dynamic-state argument and the multisample positions.  Data and the
functions that lay it out, nothing that renders a program (``programs.py``)."""

from __future__ import annotations

import struct
from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.ir.builtins import FLAT_SCENE_INPUTS
from pipegen.ir.nodes import DrawKind
from pipegen.backends.plan import PassPlan

TILE = 16
SUBPIXEL = 256       # window coordinates snap to 1/256 pixel (GL_SUBPIXEL_BITS = 8)
# the set-up program's cull switch; "auto": per triangle, bit 2 of its flat input word says
# whether its light is drawn with its back faces (``cull auto``: the host decides per light,
# ``draws.light_runs``)
SETUP_CULL = {"none": 0, "back": 1, "front": 2, "auto": 3}

# ---- enumerations shared by the prelude and the state macros -------------------------------------

COMPARE = {"never": 0, "less": 1, "equal": 2, "lequal": 3, "greater": 4, "notequal": 5,
           "gequal": 6, "always": 7}
STENCIL_OP = {"keep": 0, "zero": 1, "replace": 2, "incr": 3, "decr": 4, "incr_wrap": 5,
              "decr_wrap": 6, "invert": 7}
BLEND_OP = {"add": 0, "sub": 1, "revsub": 2, "min": 3, "max": 4}
BLEND_FACTOR = {f.value: k for k, f in enumerate(ir.BlendFactor)}
CULL = {"none": 0, "back": 1, "front": 2}


def enum_defines() -> list[tuple[str, int]]:
    """The enumerations as the prelude's ``#define`` (name, value) rows."""
    out = [(f"PG_{k.upper()}", v) for k, v in COMPARE.items()]
    out += [(f"PG_SOP_{k.upper()}", v) for k, v in STENCIL_OP.items()]
    out += [(f"PG_BO_{k.upper()}", v) for k, v in BLEND_OP.items()]
    out += [(f"PG_BF_{k.upper()}", v) for k, v in BLEND_FACTOR.items()]
    return out


# ---- what the vertex kernel passes the raster kernel ---------------------------------------------

# scene varyings: input -> (OpenCL type, value in the vertex kernel; p = float4 position,
# n = float3 normal, vp = view-space position)
SCENE_VARYINGS = {
    "world_pos": ("float3", "p.xyz"),
    "view_pos": ("float3", "vp.xyz"),
    "normal": ("float3", "n"),
    "view_normal": ("float3", "pg_m3_mul_v3(pg_m3_from_m4(frame->view), n)"),
    "albedo": ("float3", "a_albedo[v].xyz"),
    "specular": ("float", "a_material[v].x"),
    "shininess": ("float", "a_material[v].y"),
    "alpha": ("float", "a_material[v].z"),
}
# the varyings passed flat (builtins.FLAT_SCENE_INPUTS: materials are per object): the provoking
# vertex's value; the others are perspective-corrected (llvmpipe: LP_INTERP_PERSPECTIVE)
FLAT_VARYINGS = FLAT_SCENE_INPUTS & frozenset(SCENE_VARYINGS)
# flat scene inputs -> component of the per-triangle ``tri_flat`` (x is the facing bit; w holds
# the light index in light draws and the stipple layer in scene draws)
SCENE_FLAT = {"object_id": "y", "normal_group": "z", "layer": "w"}


def varying_slots(pass_: PassPlan) -> list[dict]:
    """Varyings of a pass, in slot order (``scene_varying_slots``)."""
    if pass_.draw.kind is not DrawKind.SCENE:
        return []
    return scene_varying_slots(pass_.code.inputs if pass_.code is not None else ())


def scene_varying_slots(names) -> list[dict]:
    """The scene varyings among ``names``, in slot order (that of ``SCENE_VARYINGS``): name,
    OpenCL type, vertex-kernel value, ``flat`` (the provoking vertex's value) and, for the others,
    ``coef``: the index of the slot's perspective plane among the smooth slots
    (``Triangles.coef``)."""
    inputs = set(names)
    out = []
    smooth = 0
    for k, n in enumerate(n for n in SCENE_VARYINGS if n in inputs):
        t, v = SCENE_VARYINGS[n]
        flat = n in FLAT_VARYINGS
        out.append({"name": n, "type": t, "value": v, "slot": k, "flat": flat,
                    "coef": None if flat else smooth})
        smooth += not flat
    return out


# ---- the dynamic state ---------------------------------------------------------------------------


def state_values(pass_: PassPlan) -> list[tuple[str, str, object]]:
    """The pass state as (macro name, kind "i"/"f", value) rows, in the dynamic-state order."""
    st = pass_.state
    depth = st.depth
    has_depth = pass_.depth_target is not None
    enabled = has_depth and depth.enabled
    rows: list[tuple[str, str, object]] = [
        ("S_DEPTH_TEST", "i", int(enabled)),
        ("S_DEPTH_FUNC", "i", COMPARE[depth.func.value] if enabled else COMPARE["always"]),
        ("S_DEPTH_WRITE", "i", int(enabled and depth.write)),
    ]
    faces = [st.stencil.front, st.stencil.back]
    rows.append(("S_STENCIL", "i", int(st.stencil.enabled)))
    for tag, f in zip("FB", faces):
        rows += [(f"S_ST_FUNC_{tag}", "i", COMPARE[f.func.value]),
                 (f"S_ST_REF_{tag}", "i", min(max(int(f.ref), 0), 255)),
                 (f"S_ST_RMASK_{tag}", "i", int(f.read_mask) & 255),
                 (f"S_ST_WMASK_{tag}", "i", int(f.write_mask) & 255),
                 (f"S_ST_FAIL_{tag}", "i", STENCIL_OP[f.fail.value]),
                 (f"S_ST_ZFAIL_{tag}", "i", STENCIL_OP[f.zfail.value]),
                 (f"S_ST_ZPASS_{tag}", "i", STENCIL_OP[f.zpass.value])]
    rows += [(f"S_BCONST_{c}", "f", float(v)) for c, v in zip("RGBA", st.blend_constant)]
    for k, name in enumerate(pass_.writes):
        b = st.blend_for(name)
        mask = sum(1 << i for i, m in enumerate(b.write_mask) if m)
        rows += [(f"S_BLEND_{k}", "i", int(b.enabled)),
                 (f"S_RGB_OP_{k}", "i", BLEND_OP[b.rgb.op.value]),
                 (f"S_RGB_SRC_{k}", "i", BLEND_FACTOR[b.rgb.src.value]),
                 (f"S_RGB_DST_{k}", "i", BLEND_FACTOR[b.rgb.dst.value]),
                 (f"S_A_OP_{k}", "i", BLEND_OP[b.alpha.op.value]),
                 (f"S_A_SRC_{k}", "i", BLEND_FACTOR[b.alpha.src.value]),
                 (f"S_A_DST_{k}", "i", BLEND_FACTOR[b.alpha.dst.value]),
                 (f"S_WMASK_{k}", "i", mask)]
    inside = inside_func(pass_)
    if inside is not None:
        # `cull auto` + `depth … inside FUNC`: the test of the triangles of lights drawn with
        # their back faces (the runtime sets bit 1 of their tri_flat.x, `pg_inside`)
        on = has_depth and (inside is not ir.CompareFunc.ALWAYS or depth.write)
        rows += [("S_DEPTH_TEST_IN", "i", int(on)),
                 ("S_DEPTH_FUNC_IN", "i", COMPARE[inside.value] if on else COMPARE["always"]),
                 ("S_DEPTH_WRITE_IN", "i", int(on and depth.write))]
    return rows


def inside_func(pass_: PassPlan) -> Optional[ir.CompareFunc]:
    """The `inside FUNC` depth test of a `cull auto` pass (None when it has none)."""
    if not pass_.cull_auto or not pass_.depth_target:
        return None
    return pass_.state.depth.inside


def state_words(pass_: PassPlan) -> list[int]:
    """The dynamic-state argument (int32 words) matching ``state_values`` order."""
    out = []
    for _, kind, value in state_values(pass_):
        if kind == "f":
            out.append(struct.unpack("<i", struct.pack("<f", float(value)))[0])
        else:
            out.append(int(value))
    return out


# Multisample positions, GL window space (y up).  4: llvmpipe's (GL_SAMPLE_POSITION,
# measured), which are Direct3D's standard 4x pattern in sixteenths of a pixel read in GL's
# axes.  llvmpipe stops at 4 (GL_MAX_SAMPLES), so 2 and 8 cannot be measured here: they are
# Direct3D's standard 2x and 8x patterns read the same way, what GPUs with standard patterns
# report; GL renders at those counts agree with these only on such a GPU.
def _sixteenths(*offsets: tuple[int, int]) -> list[tuple[float, float]]:
    return [(0.5 + x / 16, 0.5 + y / 16) for x, y in offsets]


SAMPLE_POSITIONS = {1: [(0.5, 0.5)],
                    2: _sixteenths((4, 4), (-4, -4)),
                    4: [(0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875)],
                    8: _sixteenths((1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1),
                                   (3, 7), (7, -7))}


# the set-up tests each triangle whose bounding box holds at most this many pixels at every
# sample of the box, and drops it where it covers none: a small triangle between pixel centres
# draws nothing (at 160x90, 82% of many_lights' scene triangles in view and 23% of deferred's
# light-sphere triangles).  Larger boxes practically always cover one; testing them would cost
# more than it saves.  (runtime/cl/setup.py's covers_a_sample, cl_setup.cl.j2's setup_tri)
SMALL_BOX = 16


def sample_positions(samples: int) -> tuple[list[int], list[int]]:
    """Sample offsets within a pixel in 1/256 pixel (x list, y list)."""
    pos = SAMPLE_POSITIONS.get(samples)
    if pos is None:
        raise ValueError(f"{samples} samples per pixel: the OpenCL backend supports "
                         f"{', '.join(map(str, SAMPLE_POSITIONS))}")
    return [int(x * 256) for x, _ in pos], [int(y * 256) for _, y in pos]

