"""The backends, in one place: each one's emitter, the files it writes per pass, the template of
its generated pipeline module and its runtime class.  ``compile``, ``emit``, ``run`` and
``check`` iterate ``BACKENDS``; adding a backend is one entry here (plus its emitter, template
and runtime).

Emitters and runtimes are named as ``"module:attribute"`` and imported on first use, so the
compiler core never imports moderngl or pyopencl (``pipegen compile`` works on any machine).
"""

from __future__ import annotations

import importlib
from typing import Callable, Optional

from pipegen.core.records import record
from pipegen.backends.plan import CLPassCode, GLPassCode, PassPlan, Plan, cl_preludes


def _gl_files(stem: str, p: PassPlan) -> dict[str, str]:
    assert isinstance(p.code, GLPassCode)
    return {f"{stem}.vert": p.code.vertex, f"{stem}.frag": p.code.fragment or ""}


def _cl_files(stem: str, p: PassPlan) -> dict[str, str]:
    assert isinstance(p.code, CLPassCode)
    return {f"{stem}.cl": p.code.included}


def _no_files(plan: Plan) -> dict[str, str]:
    return {}


@record(frozen=True)
class Backend:
    name: str                     # as the command line and ``Compiled.plan`` spell it
    title: str                    # as reports and tables print it
    description: str              # one line for ``--help``
    emitter: str                  # "module:function", ``(ir.Technique) -> Plan``
    runtime: str                  # "module:class", ``(plan, size) -> pipeline``
    module_template: str          # the generated pipeline module (templates/)
    pass_files: Callable[[str, PassPlan], dict[str, str]]   # per pass: {file name: text}
    # per plan, beside the pass files: {file name: text} (the CL preludes the passes include)
    plan_files: Callable[[Plan], dict[str, str]] = _no_files
    # the arithmetic precisions its emitter and runtime offer: "f32" (what the backend runs),
    # "f64" (the float64 evaluation of the technique, docs/internals.md)
    precisions: tuple[str, ...] = ("f32",)
    # "module:function" -> one line naming the device it renders on (renderer, how chosen)
    device: str = ""
    # "module:function" -> the device's short name ("llvmpipe", "NVIDIA H200", "PoCL")
    device_name: str = ""
    # the device the tolerance model's limits hold for (a part of its short name)
    calibrated: str = ""

    def describe_device(self) -> str:
        return _resolve(self.device)() if self.device else self.title

    def off_model(self) -> Optional[str]:
        """The device's short name where it is not the one the tolerance model's limits were
        measured on (``calibrated``: llvmpipe for GL, PoCL for CL; docs/tolerances.md, "On a
        GPU"), else None.  Opens the backend's context."""
        name = self._device_name()
        if name is None or not self.calibrated:
            return None
        return None if self.calibrated.lower() in name.lower() else name

    def label(self) -> str:
        """The title with the device this process renders on ("GL (NVIDIA H200)" where the
        GL context is on a GPU): what tables and verdicts print, so that a figure measured
        on one device is never credited to another.  Opens the backend's context."""
        name = self._device_name()
        return self.title if name is None else f"{self.title.partition(' (')[0]} ({name})"

    def _device_name(self) -> Optional[str]:
        """The device's short name, None where there is none or its context does not open (a
        label is no place to fail: rendering reports a missing device)."""
        if not self.device_name:
            return None
        try:
            return _resolve(self.device_name)()
        except Exception:
            return None

    @property
    def module_name(self) -> str:
        return self.module_template.removesuffix(".j2")

    def emit(self, tech, precision: str = "f32"):
        if precision == "f32":
            return _resolve(self.emitter)(tech)
        self.check_precision(precision)
        return _resolve(self.emitter)(tech, precision=precision)

    def check_precision(self, precision: str) -> None:
        """A ``PipegenError`` when this backend cannot evaluate at ``precision``."""
        if precision not in self.precisions:
            from pipegen.core.diagnostics import PipegenError
            others = [b.name for b in BACKENDS.values() if precision in b.precisions]
            raise PipegenError(None, f"the {self.name} backend has no precision {precision!r} "
                                     f"(it offers {', '.join(self.precisions)})",
                               hint=(f"use --backend {others[0]} for the {precision} evaluation"
                                     if others else "use precision \"f32\""))

    def runtime_class(self):
        return _resolve(self.runtime)

    def module_source(self, plan: Plan) -> str:
        """Source of the generated pipeline module holding ``plan`` as a literal."""
        from pipegen.backends import templating

        def safe(s: str) -> str:
            return s.replace("\\", "/").replace('"""', "'''")
        return templating.render(self.module_template, plan=plan.to_dict(),
                                 title=safe(plan.title), source=safe(plan.source or "<string>"))


def _resolve(path: str):
    module, _, attr = path.partition(":")
    return getattr(importlib.import_module(module), attr)


BACKENDS: dict[str, Backend] = {b.name: b for b in (
    Backend("gl", "GL (llvmpipe)", "moderngl on the system's OpenGL (Mesa llvmpipe without a GPU)",
            "pipegen.backends.glsl:emit_gl",
            "pipegen.runtime.gl.pipeline:GLPipeline", "pipeline_gl.py.j2", _gl_files,
            device="pipegen.runtime.gl.context:describe",
            device_name="pipegen.runtime.gl.context:short_name", calibrated="llvmpipe"),
    Backend("cl", "CL (PoCL)", "the OpenCL software reference on PoCL's CPU device",
            "pipegen.backends.opencl.emit:emit_cl",
            "pipegen.runtime.cl.pipeline:CLPipeline", "pipeline_cl.py.j2", _cl_files,
            plan_files=cl_preludes, precisions=("f32", "f64"),
            device="pipegen.runtime.cl.context:describe",
            device_name="pipegen.runtime.cl.context:short_name", calibrated="PoCL"),
)}


def get(name: str) -> Backend:
    try:
        return BACKENDS[name]
    except KeyError:
        raise ValueError(f"unknown backend {name!r} (expected one of: "
                         f"{', '.join(BACKENDS)})") from None
