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

from pipegen.core.defaults import DEFAULT_SIZE  # noqa: F401 (re-exported)
from pipegen.core.lazy import lazy_names


def _compiler():
    from pipegen.compiler import driver
    return driver


def _scene():
    import pipegen.scene
    return pipegen.scene


def _outputs():
    from pipegen.views import outputs
    return outputs


def _outdir():
    from pipegen.core import outdir
    return outdir


def _diagnostics():
    from pipegen.core import diagnostics
    return diagnostics


def _version():
    # looked up only when asked for: it reads the installed distribution's metadata
    from types import SimpleNamespace
    from pipegen.core.defaults import version
    return SimpleNamespace(__version__=version())


_LOADERS = {
    **dict.fromkeys(("compile_file", "compile_source", "Compiled"), _compiler),
    **dict.fromkeys(("load_scene", "parse_scene", "default_scene", "Scene"), _scene),
    **dict.fromkeys(("save_pngs", "write_render"), _outputs),
    "OutputDir": _outdir,
    "PipegenError": _diagnostics,
    "__version__": _version,
}

__all__ = sorted([*_LOADERS, "DEFAULT_SIZE"])

__getattr__, __dir__ = lazy_names(globals(), _LOADERS)
