"""Compilation as a readable sequence of named phases (Granite's ``RenderGraph::bake()``).

    parse → lower → validate → specialise → fold → prune → emit

and, compiled for a scene (``compile_file(..., scene=)``, ``specialise.py``), the scene phases
after ``prune``: assume_scene → spec_light_types → spec_shadows → fold → dead_code →
unread_reads → prune → cull_empty_draws → cull_unread.

Each phase after ``lower`` is a ``run(ir) -> ir`` from ``pipegen.passes``, run by the pass
manager (``passes/manager.py``) from the pipelines as data (``passes/pipelines.py``); with
``verify_each=True`` (the tests' setting) the IR verifier runs after every phase, and a
``manager.Watch`` sees each pass run and the IR after the ones it names
(``pipegen compile --dump-after``).  Nothing here
imports moderngl or pyopencl: ``pipegen compile`` works on any machine; ``Compiled.pipeline``
imports a runtime only when asked to render.
"""

from __future__ import annotations

import os
from dataclasses import field
from pathlib import Path
from typing import TYPE_CHECKING, Optional

from pipegen.core.records import record
from pipegen.ir import nodes as ir, verify
from pipegen.frontend.lower import lowerer as lower
from pipegen.frontend import parse as syntax
from pipegen.core.diagnostics import PipegenError
from pipegen.backends import registry
from pipegen.backends.plan import Plan

if TYPE_CHECKING:
    from pipegen.compiler.specialise import Specialisation
from pipegen.passes import pipelines
from pipegen.passes.manager import Watch, run_pipeline

PHASES = pipelines.GENERAL      # read when a compile runs: a test may put another in its place


@record
class Compiled:
    """A compiled technique: the optimised IR plus everything emitted from it (lazily)."""

    technique: ir.Technique
    params: dict
    phases_run: list[str] = field(default_factory=list)
    specialisation: Optional["Specialisation"] = None    # set when compiled for a scene
    _plans: dict = field(default_factory=dict, repr=False)
    # output size -> report text: `pipegen compile` writes report.txt and prints it
    _reports: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def name(self) -> str:
        return self.technique.name

    def plan(self, backend: str) -> Plan:
        """The typed plan for ``backend`` (a name in ``backends.registry.BACKENDS``)."""
        if backend not in self._plans:
            self._plans[backend] = registry.get(backend).emit(self.technique)
        return self._plans[backend]

    def pipeline(self, backend: str = "gl", size: Optional[tuple[int, int]] = None,
                 precision: str = "f32"):
        """A runnable pipeline: ``.render(scene) -> {target: numpy array}``.

        ``precision="f64"`` (CL): the float64 evaluation of the technique, whose ``render``
        gives ``{target: float64 values}`` (unquantised; docs/internals.md); a backend without
        it raises a ``PipegenError``."""
        b = registry.get(backend)
        if precision == "f32":
            return b.runtime_class()(self.plan(backend), size)
        b.check_precision(precision)
        key = (backend, precision)
        if key not in self._plans:
            self._plans[key] = b.emit(self.technique, precision)
        return b.runtime_class()(self._plans[key], size)

    def report(self, output_size: tuple[int, int] = (1280, 720)) -> str:
        key = tuple(output_size)
        if key not in self._reports:
            from pipegen.views.report import render_report
            self._reports[key] = render_report(self, output_size)
        return self._reports[key]

    def warnings(self) -> list[str]:
        """What compiling found suspicious in the technique itself, each located in its
        source (``file:line:col: warning: ...``, the line, a caret, a hint): passes whose
        image depends on the order of the objects they draw (``blend_order.py``)."""
        from pipegen.compiler.blend_order import HINT, describe, order_dependent_blends
        from pipegen.core.diagnostics import warning_text
        return [warning_text(p.span, describe(p, target, what), HINT)
                for p, target, what in order_dependent_blends(self.technique)]

    def mismatches(self, scene) -> list:
        """What this technique will not render of ``scene`` (``features.Mismatch`` list:
        light types it cannot draw, translucent objects, light-index capacity)."""
        from pipegen.compiler.mismatches import mismatches
        return mismatches(self.technique, scene)

    def specialise(self, scene, verify_each: bool = False) -> "Compiled":
        """This technique compiled for what ``scene`` calls for (``specialise.py``); the
        light table is shrunk only by ``compile_file(..., scene=)``, which can recompile."""
        from pipegen.compiler.specialise import specialise
        return specialise(self, scene, verify_each=verify_each)

    def write(self, out_dir, backends: tuple[str, ...] = ("gl", "cl"),
              output_size: Optional[tuple[int, int]] = None, force: bool = False) -> Path:
        """Write shaders, pipeline modules and the report (targets sized for ``output_size``,
        default ``pipegen.DEFAULT_SIZE``) into ``out_dir`` (a path or an ``outdir.OutputDir``).
        Everything is generated into a staging folder first, so a failure leaves the previous
        outputs untouched; only files pipegen wrote there before are replaced or removed, and a
        folder holding other files is refused unless ``force`` (``outdir.py``)."""
        from pipegen.compiler.emit_files import write_outputs
        from pipegen.core.outdir import as_output_dir
        out = as_output_dir(out_dir, "compile", force)
        with out.staging() as tmp:
            write_outputs(self, tmp, backends, output_size)
        return out.path


def compile_source(text: str, filename: str = "<string>", params: Optional[dict] = None,
                   verify_each: bool = False, watch: Optional[Watch] = None) -> Compiled:
    module = syntax.parse(text, filename)
    tech = lower.lower(module, filename, params=params)
    return _run_phases(tech, params or {}, verify_each, watch or _UNWATCHED)


def compile_file(path: str | os.PathLike, params: Optional[dict] = None,
                 verify_each: bool = False, scene=None, watch: Optional[Watch] = None) -> Compiled:
    """Compile a ``.pipe`` file; with ``scene``, specialised for what the scene calls for
    (``specialise.py``: cuts with reasons, guards, a cached variant per scene-feature key).
    ``watch``: what to show of the passes as they run (``manager.Watch``)."""
    from pipegen.core.sources import MAX_SOURCE_BYTES, read_source
    p = Path(path)
    try:
        text = read_source(str(p))     # bad UTF-8: a PipegenError at the byte
    except FileNotFoundError:
        raise PipegenError(None, f"no such file: {p}",
                           hint="pass the path of a .pipe file, e.g. pipelines/forward.pipe") \
            from None
    except OSError as e:
        raise PipegenError(None, f"cannot read {p}: {e.strerror or e}",
                           hint=f"pass a .pipe file (a regular file of at most "
                                f"{MAX_SOURCE_BYTES >> 20} MiB)") from None
    compiled = compile_source(text, str(p), params, verify_each, watch)
    if scene is None:
        return compiled
    from pipegen.compiler.specialise import specialise
    return specialise(compiled, scene, verify_each=verify_each, watch=watch,
                      recompile=lambda ps: compile_source(text, str(p), ps, verify_each, watch))


def for_scene(compiled: Compiled, scene, general: bool = False,
              path: Optional[str | os.PathLike] = None) -> Compiled:
    """What ``run``, ``check``, ``sweep``, ``stress``, ``tune`` and ``pipegen.testing`` render
    of ``scene``: the variant compiled for it (``specialise.py``; cached per process by
    technique, parameters and facts), or with ``general`` (``--general``) ``compiled`` itself.
    ``path``: the ``.pipe`` file ``compiled`` came from, when known, so that the light table
    shrinks as ``compile_file(path, scene=)`` shrinks it (without it the table keeps its size).
    A technique already specialised is returned as it is: its guards refuse a scene that
    breaks its facts."""
    if general or compiled.specialisation is not None:
        return compiled
    from pipegen.compiler.specialise import specialise
    recompile = None if path is None else (lambda ps: compile_file(path, ps))
    return specialise(compiled, scene, recompile=recompile)


GENERAL_HELP = ("render the general build, compiled for every scene, instead of the variant "
                "compiled for this scene's features (default: the variant: passes, targets "
                "and branches the scene does not call for are cut; docs/specialise.md)")
SPECIALISE_HELP = "the default: render the variant compiled for the scene (kept for " \
                  "compatibility; --general renders the general build)"


_UNWATCHED = Watch()


def _run_phases(tech: ir.Technique, params: dict, verify_each: bool, watch: Watch) -> Compiled:
    verify.verify(tech)
    tech, ran = run_pipeline(PHASES, tech, verify_each, watch.progress, watch.dump_after,
                             watch.dump)
    return Compiled(tech, dict(params), ["lower", "validate", *ran])
