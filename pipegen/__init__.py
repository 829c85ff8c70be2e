"""pipegen: compile real-time rendering techniques (``.pipe``) to GLSL + moderngl and OpenCL C +
PoCL pipelines, run them, and check one against the other.

    import pipegen

    compiled = pipegen.compile_file("pipelines/forward.pipe")
    scene = pipegen.load_scene("examples/scenes/small.toml")     # or pipegen.default_scene()
    targets = compiled.pipeline("gl").render(scene)
    pipegen.save_pngs(compiled, scene, targets, "out/forward")   # one PNG per target

Names are imported on first use, so ``import pipegen`` (and compiling) never imports moderngl or
pyopencl; only ``Compiled.pipeline`` does.
"""

from __future__ import annotations

import importlib

from pipegen.core.defaults import DEFAULT_SIZE, version as _version  # noqa: F401 (re-exported)

_LAZY = {
    "compile_file": "pipegen.compiler.driver",
    "compile_source": "pipegen.compiler.driver",
    "Compiled": "pipegen.compiler.driver",
    "load_scene": "pipegen.scene",
    "parse_scene": "pipegen.scene",
    "default_scene": "pipegen.scene",
    "Scene": "pipegen.scene",
    "save_pngs": "pipegen.views.outputs",
    "write_render": "pipegen.views.outputs",
    "OutputDir": "pipegen.core.outdir",
    "PipegenError": "pipegen.core.diagnostics",
}

__all__ = sorted([*_LAZY, "DEFAULT_SIZE", "__version__"])


def __getattr__(name: str):
    if name == "__version__":
        version = _version()
        globals()["__version__"] = version
        return version
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'pipegen' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
