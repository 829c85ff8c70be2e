"""What ``pipegen compile`` writes: per-pass shaders/kernels, the pipeline modules, the report.

Layout of the output folder:
    report.txt
    gl/<n>_<pass>.vert, gl/<n>_<pass>.frag, pipeline_gl.py
    cl/<n>_<pass>.cl, pipeline_cl.py
    .pipegen-manifest.json (written by ``outdir.OutputDir``: what pipegen wrote there)
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from .outdir import safe_name


def write_outputs(compiled, out: Path, backends: tuple[str, ...],
                  output_size: Optional[tuple[int, int]] = None) -> None:
    """Write into the (staging) folder ``out``; the report states target memory at
    ``output_size`` (default: ``Compiled.report``'s).  A pass name too long for a file name is
    shortened with a hash (``outdir.safe_name``)."""
    if "gl" in backends:
        from .backends.glsl import gl_module_source
        plan = compiled.plan("gl")
        (out / "gl").mkdir()
        for i, p in enumerate(plan["passes"], 1):
            stem = out / "gl" / safe_name(f"{i:02d}_{p['name']}")
            stem.with_suffix(".vert").write_text(p["vertex"])
            stem.with_suffix(".frag").write_text(p["fragment"])
        (out / "pipeline_gl.py").write_text(gl_module_source(plan))
    if "cl" in backends:
        from .backends.opencl import cl_module_source
        plan = compiled.plan("cl")
        (out / "cl").mkdir()
        for i, p in enumerate(plan["passes"], 1):
            (out / "cl" / safe_name(f"{i:02d}_{p['name']}", ".cl")).write_text(p["kernel"])
        (out / "pipeline_cl.py").write_text(cl_module_source(plan))
    report = compiled.report(output_size) if output_size else compiled.report()
    (out / "report.txt").write_text(report)
