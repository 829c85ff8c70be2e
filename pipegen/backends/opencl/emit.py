"""The OpenCL backend's driver: ``emit_cl(tech) -> Plan`` (the registry's emitter), with one
OpenCL program per pass (``programs.pass_program``), and ``emit_fragment``, the fragment
function of a pass rendered from the IR through the dialect (``dialect.OpenCLLanguage``) and,
where the wide path applies, its 8-pixel form (``wide``).  The backend as a whole: the package
docstring (``pipegen/backends/opencl/__init__.py``)."""

from __future__ import annotations

from dataclasses import replace
from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.ir.builtins import VOLUME_LIGHT_FIELDS
from pipegen.ir.nodes import DrawKind
from pipegen.passes import lower_mix_constant
from pipegen.backends import plan as planlib
from pipegen.backends.plan import CLPassCode, Plan
from pipegen.backends.opencl import wide as cl_wide
from pipegen.backends.opencl.abi import SCENE_FLAT, SCENE_VARYINGS, TILE
from pipegen.backends.opencl.dialect import OpenCLLanguage, dialect
from pipegen.backends.opencl.programs import pass_prelude, pass_program


def emit_cl(tech: ir.Technique, precision: str = "f32") -> Plan:
    """The plan of ``tech`` with one OpenCL program (``CLPassCode.kernel``) per pass;
    ``precision="f64"``: the float64 evaluation of the technique (``plan.precision``)."""
    lang = dialect(precision)
    if precision == "f32":
        tech = lower_mix_constant.run(tech)     # llvmpipe's split of mix(x, y, constant)
    rendered: dict = {}
    wide_rendered: dict = {}
    frags = [emit_fragment(tech, p, lang, rendered=rendered, wide_rendered=wide_rendered)
             for p in tech.passes]
    codes = [CLPassCode("", f["fragment"], tuple(f["inputs"]), f["discard"], tuple(f["sampled"]))
             for f in frags]
    sampled = [tuple(r for r in p.reads if r in f["sampled"]) for p, f in zip(tech.passes, frags)]
    plan = planlib.technique_plan(tech, "cl", codes, sampled)
    if precision != "f32":
        plan = replace(plan, precision=precision)
    return replace(plan, passes=tuple(
        replace(p, code=replace(p.code, kernel=pass_program(plan, p),
                                prelude=pass_prelude(p, TILE, plan.precision)))
        for p in plan.passes))


def emit_fragment(tech: ir.Technique, p: ir.Pass,
                  language: type[OpenCLLanguage] = OpenCLLanguage, wide: bool = True,
                  rendered: Optional[dict] = None,
                  wide_rendered: Optional[dict] = None) -> dict:
    """The fragment function of a pass (OpenCL C) and what it reads (``language``: the
    dialect, ``OpenCLLanguage64`` for the float64 evaluation; ``rendered``: user functions
    already rendered for other passes of ``tech``, see ``CStyleLanguage.functions_once``
    (a function's OpenCL text does not depend on the pass: the dialect reads only
    technique-wide facts, ``in_body`` is off); ``wide_rendered``:
    their wide specialisations, ``wide_fragment``'s ``shared``)."""
    lang = language(tech, p)
    functions = planlib.pass_functions(tech, p.body)
    inputs = planlib.stage_inputs(p.body, functions)
    kind = p.draw.kind
    scene_only = sorted(n for n in inputs if n in SCENE_VARYINGS or n in SCENE_FLAT)
    # the front end rejects these programs: here they are invariants
    assert not scene_only or kind is DrawKind.SCENE, (p.name, scene_only)
    assert not (inputs & {"light", "light_index"}) or kind is DrawKind.LIGHTS \
        or p.repeat_per_light, p.name
    if kind is DrawKind.LIGHTS:
        names = {f.name for f in tech.lights.fields}
        assert all(f in names for f in
                   VOLUME_LIGHT_FIELDS[(p.draw.volume or ir.Volume.SPHERE).value]), p.name
    sampled = sorted(planlib.sampled_targets(p.body, functions))
    discard = planlib.may_discard(p.body, functions)
    if not p.body:
        return {"fragment": None, "inputs": sorted(inputs), "discard": False, "sampled": sampled}
    code = lang.functions_once(functions, {} if rendered is None else rendered)
    lang.in_body = True
    body = lang.stmts(p.body, 1)
    lang.in_body = False
    if lang.helpers:
        code = [lang.helper_source()] + code
    if lang.raw_helpers:
        code = ["\n\n".join(lang.raw_helpers.values())] + code
    main = "\n".join(["static inline bool pg_fragment(const pg_in *in, pg_out *out) {", *body,
                      "    return true;", "}"])
    text = "\n\n".join(code + [main]) + "\n"
    if language is OpenCLLanguage and wide:
        # the same code for PG_W pixels at once (explicit SIMD over pixels), where it can
        wtext = cl_wide.wide_fragment(tech, p, OpenCLLanguage(tech, p), wide_rendered)
        if wtext is not None:
            text += "\n" + wtext
    return {"fragment": text, "inputs": sorted(inputs), "discard": discard, "sampled": sampled}
