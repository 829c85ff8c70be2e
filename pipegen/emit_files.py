"""What ``pipegen compile`` writes: per-pass shaders/kernels, the pipeline modules, the report.

Layout of the output folder:
    report.txt
    gl/<n>_<pass>.vert, gl/<n>_<pass>.frag, pipeline_gl.py
    cl/<n>_<pass>.cl, pipeline_cl.py
"""

from __future__ import annotations

from pathlib import Path


def write_outputs(compiled, out: Path, backends: tuple[str, ...]) -> None:
    if "gl" in backends:
        from .backends.glsl import gl_module_source
        plan = compiled.plan("gl")
        (out / "gl").mkdir()
        for i, p in enumerate(plan["passes"], 1):
            stem = out / "gl" / f"{i:02d}_{p['name']}"
            stem.with_suffix(".vert").write_text(p["vertex"])
            stem.with_suffix(".frag").write_text(p["fragment"])
        (out / "pipeline_gl.py").write_text(gl_module_source(plan))
    if "cl" in backends:
        from .backends.opencl import cl_module_source
        plan = compiled.plan("cl")
        (out / "cl").mkdir()
        for i, p in enumerate(plan["passes"], 1):
            (out / "cl" / f"{i:02d}_{p['name']}.cl").write_text(p["kernel"])
        (out / "pipeline_cl.py").write_text(cl_module_source(plan))
    (out / "report.txt").write_text(compiled.report())
