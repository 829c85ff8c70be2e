"""The generated OpenCL builds without a word (issue 24, "quiet by default"): every program a
shipped technique's CL pipeline builds to render a scene, in float32 and in the float64
evaluation, has an empty build log, so no run prints clang's "N warnings generated" or
pyopencl's ``CompilerWarning``.

Two subprocesses per technique: the first renders a scene and records the source and options
of every program built (with the run's shared PoCL cache: the suite builds these programs
anyway); the second builds each of them again with PoCL's kernel cache off and prints the
logs.  A cached program is not compiled again and says nothing, which would make the test pass
without building anything; the clang warnings come from the build (``clBuildProgram``), not
from the kernels PoCL compiles when they are first queued, so nothing is rendered there.

"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest


pytestmark = pytest.mark.cl

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUES = sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe"))

RECORD = """
import json, sys
import pyopencl as cl
from pipegen.compiler.driver import compile_file
from pipegen.scene import default_scene

build = cl.Program.build
programs = []
def recorded(self, options=(), *args, **kwargs):
    programs.append({"source": self.get_info(cl.program_info.SOURCE), "options": list(options)})
    return build(self, options, *args, **kwargs)
cl.Program.build = recorded
compile_ = cl.Program.compile
def compiled_unit(self, options=(), *args, **kwargs):    # a repeat group's linked units
    programs.append({"source": self.get_info(cl.program_info.SOURCE), "options": list(options),
                     "unit": True})
    return compile_(self, options, *args, **kwargs)
cl.Program.compile = compiled_unit

compiled = compile_file(sys.argv[1])
scene = default_scene().with_size(24, 16)
for precision in sys.argv[2].split(","):
    compiled.pipeline("cl", (24, 16), precision=precision).render(scene)
json.dump(programs, open(sys.argv[3], "w"))
"""

BUILD = """
import json, sys, warnings
import pyopencl as cl
from pipegen.runtime.cl.context import get_context

ctx, _ = get_context()
logs = []
for p in json.load(open(sys.argv[1])):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # the log is read below, whole
        program = cl.Program(ctx, p["source"])
        program = (program.compile if p.get("unit") else program.build)(options=p["options"])
    for device in program.get_info(cl.program_info.DEVICES):
        log = program.get_build_info(device, cl.program_build_info.LOG).strip()
        if log:
            logs.append(log)
print(len(json.load(open(sys.argv[1]))), "programs")
print("\\n---\\n".join(logs))
"""


# The float64 evaluation's programs come from the same emitter with the precision switched:
# CI builds them for the two techniques that reach the most of it (deferred_calver: volumes,
# quads, tables, shadows, the wide path; inferred: MSAA, low-resolution targets, packings);
# --exhaustive builds them for all (CI's 10-minute budget: 5-10 s of PoCL compiles each).
F64_IN_CI = {"deferred_calver", "inferred"}
# float32 in CI: those two, lidr_transparent (per-sample MSAA shading, front-face volumes,
# translucency), forward (the shadow atlas and PCF, a table loop) and deferred (a repeat
# group fused into one launch: its passes' units, compiled and linked); the others, whose
# programs are built from the same templates and emitter paths, with --exhaustive.
F32_IN_CI = F64_IN_CI | {"lidr_transparent", "forward", "deferred"}
CASES = [pytest.param(name, "f32,f64" if name in F64_IN_CI else "f32", id=name,
                      marks=() if name in F32_IN_CI else (pytest.mark.exhaustive,))
         for name in TECHNIQUES] + [
         pytest.param(name, "f64", id=f"{name}-f64", marks=pytest.mark.exhaustive)
         for name in TECHNIQUES if name not in F64_IN_CI]


@pytest.mark.parametrize("name,precisions", CASES)
def test_every_program_of_a_shipped_technique_builds_with_an_empty_log(name, precisions,
                                                                       tmp_path):
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    listing = tmp_path / "programs.json"
    proc = subprocess.run([sys.executable, "-c", RECORD, str(ROOT / "pipelines" / f"{name}.pipe"),
                           precisions, str(listing)], capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    if name == "deferred" and "f32" in precisions:  # its light volumes' group: units compiled
        assert '"unit": true' in listing.read_text()   # to be linked (float32 only: f64 fuses none)
    env.update(POCL_CACHE_DIR=str(tmp_path / "pocl"), POCL_KERNEL_CACHE="0")
    proc = subprocess.run([sys.executable, "-c", BUILD, str(listing)], capture_output=True,
                          text=True, env=env, cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    count, _, logs = proc.stdout.partition("\n")
    # never nothing built: two pass programs at least, the runtime's binning, and in float32
    # its set-up too (the float64 evaluation sets triangles up on the host)
    assert int(count.split()[0]) >= (4 if "f32" in precisions else 3), proc.stdout
    assert logs.strip() == "", f"build logs of {name}:\n{logs[:3000]}"
    assert "warning" not in proc.stderr.lower(), proc.stderr[-3000:]
