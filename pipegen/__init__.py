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

#: Output size (width, height) when nothing else says: the built-in scene is rendered at it and
#: ``pipegen compile``/``info`` and ``Compiled.report`` state target memory at it.  A scene file
#: keeps the size it declares; ``--size`` overrides both.
DEFAULT_SIZE = (1280, 720)

_LAZY = {
    "compile_file": "pipegen.compiler",
    "compile_source": "pipegen.compiler",
    "Compiled": "pipegen.compiler",
    "load_scene": "pipegen.scene",
    "parse_scene": "pipegen.scene",
    "default_scene": "pipegen.scene",
    "Scene": "pipegen.scene",
    "save_pngs": "pipegen.outputs",
    "write_render": "pipegen.outputs",
    "OutputDir": "pipegen.outdir",
    "PipegenError": "pipegen.diagnostics",
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


def _version() -> str:
    found = _version_from_metadata_folder()
    if found:
        return found
    try:
        from importlib.metadata import PackageNotFoundError, version
        return version("pipegen")
    except (ImportError, PackageNotFoundError):
        return "0.1.0+unknown"


def _version_from_metadata_folder() -> str | None:
    """The version in the first ``pipegen-*.dist-info`` (or ``pipegen*.egg-info``) folder on
    ``sys.path``, the distribution ``importlib.metadata.version`` finds, read without importing
    importlib.metadata: its import costs ~15 ms, and every ``pipegen compile`` writes the
    version into the output folder's manifest.  None when not found (then importlib.metadata
    decides)."""
    import os
    import sys
    for entry in sys.path:
        folder = entry or "."
        try:
            names = os.listdir(folder)
        except OSError:
            continue
        meta = [n for n in names if n.lower().startswith("pipegen-") and n.lower().endswith(
            ".dist-info")]
        meta += [n for n in names if n.lower().startswith(("pipegen-", "pipegen.")) and
                 n.lower().endswith(".egg-info")]
        for name in meta:
            inner = "METADATA" if name.lower().endswith(".dist-info") else "PKG-INFO"
            try:
                with open(os.path.join(folder, name, inner), encoding="utf-8") as f:
                    for line in f:
                        if line.startswith("Version:"):
                            return line[len("Version:"):].strip() or None
                        if not line.strip():
                            break          # the headers end at the first blank line
            except OSError:
                continue
    return None
