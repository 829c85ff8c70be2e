"""What ``pipegen compile`` writes: per-pass shaders/kernels, the pipeline modules, the report.

Layout of the output folder:
    report.txt
    gl/<n>_<pass>.vert, gl/<n>_<pass>.frag, pipeline_gl.py
    cl/<n>_<pass>.cl, cl/prelude*.cl (what the pass programs ``#include``), pipeline_cl.py
    .pipegen-manifest.json (written by ``outdir.OutputDir``: what pipegen wrote there)
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from pipegen.backends import registry
from pipegen.core.outdir import safe_name


def write_outputs(compiled, out: Path, backends: tuple[str, ...],
                  output_size: Optional[tuple[int, int]] = None) -> None:
    """Write into the (staging) folder ``out``; the report states target memory at
    ``output_size`` (default: ``Compiled.report``'s).  A pass name too long for a file name is
    shortened with a hash (``outdir.safe_name``)."""
    for name in backends:
        backend = registry.get(name)
        plan = compiled.plan(name)
        (out / name).mkdir()
        for file, text in backend.plan_files(plan).items():
            (out / name / file).write_text(text)
        for i, p in enumerate(plan.passes, 1):
            for file, text in backend.pass_files(safe_name(f"{i:02d}_{p.name}"), p).items():
                (out / name / file).write_text(text)
        (out / backend.module_name).write_text(backend.module_source(plan))
    report = compiled.report(output_size) if output_size else compiled.report()
    (out / "report.txt").write_text(report)
