"""The GLSL 330 core backend: a ``CStyleLanguage`` dialect (data plus a few hooks) and
``emit_gl(tech) -> Plan`` with one vertex and one fragment shader per pass.

Conventions shared with the GL runtime are in docs/internals.md ("GLSL conventions").  Choices
made here that the runtime (and the OpenCL backend, which must agree) rely on:

- ``load(T)`` reads the texel at ``ivec2(gl_FragCoord.xy)``; explicit coordinates, and the
  pixel of a target whose size differs from the pass's render size, are clamped to the target
  (clamp to edge, like ``sample``).  Depth targets read ``.x``, the depth value in [0, 1].
- ``sample(T, uv)`` is ``texture(t_T, uv)``: the pass's ``"sampled"`` list names the targets the
  runtime must bind with linear filtering (all reads clamp to edge).  Multisampled targets are
  read through a resolved single-sample texture.
- Colour outputs are zero-initialised at the top of ``main()``: paths that do not write a
  target write zero, on both backends.
- ``round`` is round-half-to-even (``roundEven``), the defined rounding both backends have.
- Scene vertices: ``gl_Position = u_proj * (u_view * vec4(a_position, 1.0))``.  Only the
  varyings (and so attributes) the fragment shader uses are emitted; ``"attributes"`` in the
  pass dict lists the active ones (locations: position 0, normal 1, albedo 2, material 3, ids 4,
  layer 5; ``a_layer`` is the scene's ``Geometry.layer`` as a float, read as ``flat uint
  v_layer = uint(a_layer + 0.5)``).
- Light volumes: ``a_position`` (location 0) is the unit mesh of ``meshes.light_volume``,
  ``a_light`` (location 1, per instance) the light's table index, passed on as ``flat uint
  v_light``.  Sphere: centre + a_position * radius.  Cone: z scaled by radius, x/y by
  radius * tan(acos(cos_outer)), local -z rotated onto the direction (a rotation, so winding is
  kept).  Quad: the clip-space rectangle of the projected bounding box of the light's sphere,
  at the depth of its nearest point; full screen at the near plane when the box reaches
  in front of the near plane, or when the light's radius is <= 0 (directional lights).
  ``cull auto`` (sphere and cone only) is a host-side choice per light
  (``runtime.draws.light_runs``); the shaders do not see it.
- Full-screen draws: one triangle from ``gl_VertexID`` (3 vertices, no attributes) at the far
  plane (window depth 1.0), so ``depth greater`` selects covered pixels and ``equal`` the sky.
"""

from __future__ import annotations

from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.ir.light_layout import table_layout
from pipegen.ir.nodes import DrawKind, Type, Volume
from pipegen.backends import plan as planlib
from pipegen.backends.plan import GLPassCode, Plan
from pipegen.backends import templating
from pipegen.ir.builtins import FLAT_SCENE_INPUTS, PREVIOUS_FRAME_INPUTS, VOLUME_LIGHT_FIELDS
from pipegen.backends.cstyle import FLT_MIN, CStyleLanguage, texel_select

# GLSL keywords, reserved words and the builtin functions this backend emits: user identifiers
# with these names get a trailing "_" (a local named `texture` would hide texture()).
GLSL_RESERVED = frozenset("""
    attribute const uniform varying layout centroid flat smooth noperspective patch sample
    break continue do for while switch case default if else subroutine in out inout float
    double int void bool true false invariant discard return mat2 mat3 mat4 dmat2 dmat3 dmat4
    mat2x2 mat2x3 mat2x4 mat3x2 mat3x3 mat3x4 mat4x2 mat4x3 mat4x4 vec2 vec3 vec4 ivec2 ivec3
    ivec4 bvec2 bvec3 bvec4 dvec2 dvec3 dvec4 uint uvec2 uvec3 uvec4 lowp mediump highp
    precision sampler1D sampler2D sampler3D samplerCube sampler2DMS usampler2D isampler2D
    struct common partition active asm class union enum typedef template this resource goto
    inline noinline public static extern external interface long short half fixed unsigned
    superp input output hvec2 hvec3 hvec4 fvec2 fvec3 fvec4 filter sizeof cast namespace using
    main texture texelFetch textureSize uintBitsToFloat floatBitsToUint inversesqrt sqrt pow
    max min dot cross normalize length distance clamp mix step smoothstep exp exp2 log log2
    abs sign floor ceil round roundEven fract mod sin cos tan atan equal notEqual lessThan
    lessThanEqual greaterThan greaterThanEqual not any all packed buffer shared coherent
    volatile restrict readonly writeonly precise sample image1D image2D image3D imageCube
    samplerBuffer sampler2DRect sampler2DShadow isampler3D usampler3D atomic_uint
""".split())

# stage input -> (GLSL expression, scene varying it needs)
INPUTS: dict[str, tuple[str, Optional[str]]] = {
    "frag_coord": ("gl_FragCoord", None), "camera_pos": ("u_camera_pos", None),
    "view": ("u_view", None), "proj": ("u_proj", None), "inv_view": ("u_inv_view", None),
    "inv_proj": ("u_inv_proj", None), "output_size": ("u_output_size", None),
    "prev_view": ("u_prev_view", None), "prev_proj": ("u_prev_proj", None),
    "num_lights": ("u_num_lights", None), "ambient": ("u_ambient", None),
    "sample_id": ("gl_SampleID", None), "sample_mask": ("uint(gl_SampleMaskIn[0])", None),
    "world_pos": ("v_world_pos", "v_world_pos"), "view_pos": ("v_view_pos", "v_view_pos"),
    "normal": ("v_normal", "v_normal"), "view_normal": ("v_view_normal", "v_view_normal"),
    "albedo": ("v_albedo", "v_albedo"), "specular": ("v_material.x", "v_material"),
    "shininess": ("v_material.y", "v_material"), "alpha": ("v_material.z", "v_material"),
    "object_id": ("v_ids.x", "v_ids"), "normal_group": ("v_ids.y", "v_ids"),
    "layer": ("v_layer", "v_layer"),
}

# scene varying -> (type, value in the vertex stage, attribute it reads)
SCENE_VARYINGS = {
    "v_world_pos": ("vec3", "a_position", "a_position"),
    "v_view_pos": ("vec3", "view_pos.xyz", "a_position"),
    "v_normal": ("vec3", "a_normal", "a_normal"),
    "v_view_normal": ("vec3", "mat3(u_view) * a_normal", "a_normal"),
    "v_albedo": ("vec3", "a_albedo", "a_albedo"),
    "v_material": ("vec3", "a_material", "a_material"),
    "v_ids": ("uvec2", "uvec2(a_ids + 0.5)", "a_ids"),
    # the stipple layer (0 opaque, 1..3 translucent): a small whole number, exact in a float
    "v_layer": ("uint", "uint(a_layer + 0.5)", "a_layer"),
}
# the varyings carrying the inputs both backends pass flat (builtins.FLAT_SCENE_INPUTS: a
# material value on a unorm tie must not round one way on llvmpipe and the other on CL)
FLAT_VARYINGS = frozenset(INPUTS[n][1] for n in FLAT_SCENE_INPUTS)
SCENE_ATTRIBUTES = [("a_position", "vec3"), ("a_normal", "vec3"), ("a_albedo", "vec3"),
                    ("a_material", "vec3"), ("a_ids", "vec2"), ("a_layer", "float")]

UNIFORMS = [("mat4", "u_view"), ("mat4", "u_proj"), ("mat4", "u_inv_view"),
            ("mat4", "u_inv_proj"), ("vec3", "u_camera_pos"), ("vec3", "u_ambient"),
            ("vec2", "u_output_size"), ("uint", "u_num_lights"), ("sampler2D", "u_lights")]


# packHalf2x16 / unpackHalf2x16 are GLSL 4.20; a 330 shader that calls them enables the
# extension (Mesa has it everywhere): only those shaders get the line
PACKING_BUILTINS = frozenset({"packHalf2x16", "unpackHalf2x16"})
PACKING_EXTENSION = "GL_ARB_shading_language_packing"
# gl_SampleID (GLSL 4.00): a 330 shader that reads sample_id enables the extension; its
# static use makes the fragment shader run once per covered sample
SAMPLE_SHADING_EXTENSION = "GL_ARB_sample_shading"
# the extension each per-sample input needs in a 330 shader; gl_SampleMaskIn has none that
# glslang accepts (GL_ARB_gpu_shader5 only "partially supported"): a shader reading sample_mask
# is GLSL 4.00, where it is core (llvmpipe: 4.50)
SAMPLE_EXTENSIONS = {"sample_id": SAMPLE_SHADING_EXTENSION}
GLSL_400_INPUTS = frozenset({"sample_mask"})


class GLSLLanguage(CStyleLanguage):
    """GLSL 330 core.  The IR's type spellings are GLSL's, so ``type_names`` stays empty."""

    builtin_map = {"round": "roundEven"}
    vector_ops = {"<": "lessThan", "<=": "lessThanEqual", ">": "greaterThan",
                  ">=": "greaterThanEqual", "==": "equal", "!=": "notEqual", "!": "not"}
    inf_literal = "uintBitsToFloat(0x7F800000u)"
    nan_literal = "uintBitsToFloat(0x7FC00000u)"
    reserved = GLSL_RESERVED

    def __init__(self, tech: Optional[ir.Technique] = None, pass_: Optional[ir.Pass] = None):
        super().__init__()
        self.tech, self.pass_ = tech, pass_
        self.light_layout = table_layout(tech.lights) if tech else None
        lights = pass_ is not None and pass_.draw.kind is DrawKind.LIGHTS
        self.current_light = "v_light" if lights else "u_light"
        self.unclamped: set[str] = set()   # targets whose load(T) needs no clamp
        self.extensions: list[str] = []    # #extension lines the shader needs (packHalf2x16)
        self.version = 330                 # #version: 400 where a 4.00 input is read
        if tech and pass_:
            size = _render_size(tech, pass_)
            self.unclamped = {r for r in pass_.reads if tech.target(r).size == size}

    def function_key(self) -> tuple:
        # a function's GLSL names the light being drawn and clamps loads by the pass's size
        return (self.current_light, frozenset(self.unclamped))

    def fresh(self) -> "GLSLLanguage":
        return type(self)(self.tech, self.pass_)

    def absorb(self, other: "GLSLLanguage") -> None:
        super().absorb(other)
        self.extensions += [e for e in other.extensions if e not in self.extensions]
        self.version = max(self.version, other.version)

    def render_builtin(self, name: str, args: list[str], types: list[Type], ret: Type) -> str:
        if name in PACKING_BUILTINS and PACKING_EXTENSION not in self.extensions:
            self.extensions.append(PACKING_EXTENSION)
        return super().render_builtin(name, args, types, ret)

    def render_input(self, name: str, t: Type) -> str:
        if name == "light_index":
            return self.current_light
        extension = SAMPLE_EXTENSIONS.get(name)     # gl_SampleID: GLSL 4.00
        if extension and extension not in self.extensions:
            self.extensions.append(extension)
        if name in GLSL_400_INPUTS:
            self.version = 400
        assert name in INPUTS, f"unknown stage input '{name}'"
        return INPUTS[name][0]

    def render_param(self, name: str, t: Type) -> str:
        default = next(p.default for p in self.tech.params if p.name == name)
        return self.literal(default, t)

    def render_current_light(self) -> str:
        return self.current_light

    def render_light_row(self, index: str, row: int) -> str:
        return f"texelFetch(u_lights, ivec2({row}, {index}), 0)"

    def render_load(self, target: str, coord: Optional[str], t: Type) -> str:
        if coord is None:
            coord = "ivec2(gl_FragCoord.xy)"
            if target in self.unclamped:
                return f"texelFetch(t_{target}, {coord}, 0){texel_select(t)}"
        coord = f"clamp({coord}, ivec2(0), textureSize(t_{target}, 0) - 1)"
        return f"texelFetch(t_{target}, {coord}, 0){texel_select(t)}"

    def render_load_sample(self, target: str, coord: Optional[str], sample: str,
                           t: Type) -> str:
        # t_T is a sampler2DMS here (the pass's "sample_reads"); textureSize takes no lod
        if coord is None:
            coord = "ivec2(gl_FragCoord.xy)"
            if target not in self.unclamped:
                coord = f"clamp({coord}, ivec2(0), textureSize(t_{target}) - 1)"
        else:
            coord = f"clamp({coord}, ivec2(0), textureSize(t_{target}) - 1)"
        # an index past the samples reads 0 on llvmpipe (GL leaves it undefined): clamped,
        # as the OpenCL runtime clamps it
        last = self.tech.target(target).samples - 1
        return f"texelFetch(t_{target}, {coord}, clamp({sample}, 0, {last})){texel_select(t)}"

    def render_sample(self, target: str, uv: str, t: Type) -> str:
        return f"texture(t_{target}, {uv}){texel_select(t)}"

    def render_target_size(self, target: str) -> str:
        return f"textureSize(t_{target}, 0)"

    def render_output(self, target: str, value: str) -> str:
        return f"o_{target} = {value};"


def _render_size(tech: ir.Technique, p: ir.Pass) -> Optional[ir.Size]:
    attached = list(p.writes) + ([p.depth_target] if p.depth_target else [])
    return tech.target(attached[0]).size if attached else None


# ---- emission -----------------------------------------------------------------------------------


def emit_gl(tech: ir.Technique) -> Plan:
    """The plan of ``tech`` with GLSL (``GLPassCode``: vertex and fragment shader) per pass."""
    rendered: dict = {}
    parts = [emit_pass(tech, p, rendered) for p in tech.passes]
    return planlib.technique_plan(
        tech, "gl", [GLPassCode(d["vertex"], d["fragment"], tuple(d["attributes"])) for d in parts],
        [tuple(d["sampled"]) for d in parts])


def emit_pass(tech: ir.Technique, p: ir.Pass, rendered: Optional[dict] = None) -> dict:
    """A pass's shaders and what they read (``rendered``: user functions already rendered
    for other passes of ``tech``, see ``CStyleLanguage.functions_once``)."""
    lang = GLSLLanguage(tech, p)
    functions = planlib.pass_functions(tech, p.body)
    inputs = planlib.stage_inputs(p.body, functions)
    kind = p.draw.kind
    scene_varyings = sorted({INPUTS[n][1] for n in inputs if n in INPUTS and INPUTS[n][1]},
                            key=list(SCENE_VARYINGS).index)
    # the front end (frontend/lower/) rejects scene inputs outside scene draws and `light` outside light passes
    assert not scene_varyings or kind is DrawKind.SCENE, (p.name, scene_varyings)
    uses_light = bool(inputs & {"light", "light_index"})
    assert not uses_light or kind is DrawKind.LIGHTS or p.repeat_per_light, p.name

    sample_reads = planlib.sample_read_targets(p.body, functions)
    written = planlib.code_facts(p.body).outputs
    assert written <= set(p.writes), f"pass {p.name} writes {written - set(p.writes)} undeclared"
    code = lang.functions_once(functions, {} if rendered is None else rendered)
    body = lang.stmts(p.body, 1)
    code = ([lang.helper_source()] if lang.helpers else []) + code

    if kind is DrawKind.SCENE:
        varyings = [_varying(n, SCENE_VARYINGS[n][0], n in FLAT_VARYINGS, SCENE_VARYINGS[n][1])
                    for n in scene_varyings]
        used = {"a_position"} | {SCENE_VARYINGS[n][2] for n in scene_varyings}
        attributes = [{"name": a, "type": t, "location": k}
                      for k, (a, t) in enumerate(SCENE_ATTRIBUTES) if a in used]
    elif kind is DrawKind.LIGHTS:
        varyings = [_varying("v_light", "uint", True, "uint(i)")] if uses_light else []
        attributes = [{"name": "a_position", "type": "vec3", "location": 0},
                      {"name": "a_light", "type": "float", "location": 1}]
    else:
        varyings, attributes = [], []

    common = {"technique": tech.name, "pass_name": p.name, "draw": p.draw.describe(),
              "source": tech.source, "uniforms": _uniforms(p, inputs)}
    fragment = templating.render(
        "gl_fragment.glsl.j2", **common, stage="fragment", varyings=varyings,
        samplers=[_sampler(tech, r, r in sample_reads) for r in p.reads],
        outputs=[_output(tech.target(w)) for w in p.writes], functions=code, body=body,
        extensions=lang.extensions, glsl_version=lang.version)
    sampled = planlib.sampled_targets(p.body, functions)
    return {"vertex": emit_vertex(tech, p, common, varyings, attributes), "fragment": fragment,
            "sampled": [r for r in p.reads if r in sampled],
            "attributes": [a["name"] for a in attributes]}


def emit_vertex(tech: ir.Technique, p: ir.Pass, common: dict, varyings: list,
                attributes: list) -> str:
    kind = p.draw.kind
    if kind is DrawKind.LIGHTS:
        volume = p.draw.volume or Volume.SPHERE
        fields = table_layout(tech.lights).places
        assert all(f in fields for f in VOLUME_LIGHT_FIELDS[volume.value]), p.name   # frontend/lower/
        return templating.render("gl_vertex_lights.glsl.j2", **common, stage="vertex",
                                 varyings=varyings, attributes=attributes, volume=volume.value,
                                 fields=fields, flt_min=GLSLLanguage().render_float(FLT_MIN))
    name = "gl_vertex_scene.glsl.j2" if kind is DrawKind.SCENE else "gl_vertex_fullscreen.glsl.j2"
    return templating.render(name, **common, stage="vertex", varyings=varyings,
                             attributes=attributes)


def _varying(name: str, type_: str, flat: bool, value: str) -> dict:
    return {"name": name, "type": type_, "flat": flat, "value": value}


def _sampler(tech: ir.Technique, read: str, per_sample: bool) -> dict:
    """The sampler uniform of a read target: its samples (``load_sample``) or one texel per
    pixel (a multisampled target's resolve)."""
    kind = "usampler2D" if tech.target(read).format.is_integer else "sampler2D"
    return {"name": read, "type": kind + ("MS" if per_sample else "")}


def _output(t: ir.Target) -> dict:
    integer = t.format.is_integer
    return {"name": t.name, "type": "uvec4" if integer else "vec4",
            "zero": "uvec4(0u)" if integer else "vec4(0.0)"}


def _uniforms(p: ir.Pass, inputs: frozenset = frozenset()) -> list[dict]:
    extra = [("uint", "u_light")] if p.repeat_per_light else []
    # the previous frame's camera: declared only where read (other shaders stay as they were)
    extra += [("mat4", INPUTS[n][0]) for n in PREVIOUS_FRAME_INPUTS if n in inputs]
    return [{"type": t, "name": n} for t, n in UNIFORMS + extra]
