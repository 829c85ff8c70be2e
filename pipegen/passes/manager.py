"""The pass manager: the one caller of compiler passes (NIR's ``NIR_PASS``, Halide's lowering
list).

A pipeline is data, a tuple of steps run in order:

- ``Pass(name, run)``: a ``run(tech) -> tech`` from ``pipegen/passes`` under the name the
  compiler reports it by (``Compiled.phases_run``, ``--dump-after``).  A plain
  ``(name, run)`` pair is a pass too;
- ``Fixpoint(name, steps, cap)``: its passes repeated, in order, until a round leaves the IR as
  it found it; more than ``cap`` rounds is a compiler bug (``InternalError`` naming the group).

``run_pipeline`` runs one, optionally verifying the IR after every pass and showing it to a
caller (progress, the IR after chosen passes).  Passes never call passes: what one pass needs
done before or after it is a step of the pipeline (``pipelines.py``).
"""

from __future__ import annotations

from typing import Callable, Iterator, NamedTuple, Optional, Union

from pipegen.core.records import record
from pipegen.ir import nodes as ir
from pipegen.ir.verify import verify

PassFn = Callable[[ir.Technique], ir.Technique]


class Pass(NamedTuple):
    name: str
    run: PassFn


@record(frozen=True)
class Fixpoint:
    name: str
    steps: tuple[Pass, ...]
    cap: int = 8                # rounds; the passes here settle in two or three


Step = Union[Pass, Fixpoint, tuple]
Pipeline = tuple[Step, ...]
ALL = "all"                     # ``dump_after``: after every pass


class InternalError(AssertionError):
    """A compiler bug found by the pass manager (an assertion, like the IR verifier's)."""


@record(frozen=True)
class Watch:
    """What a caller sees of a pipeline run: ``progress(name)`` before each pass runs;
    ``dump(name, tech)`` after each pass named in ``dump_after`` (a set of names, or ``ALL``)."""
    progress: Optional[Callable[[str], None]] = None
    dump_after: Union[frozenset, str] = frozenset()
    dump: Optional[Callable[[str, ir.Technique], None]] = None


def pass_names(pipeline: Pipeline) -> list[str]:
    """The names of the pipeline's passes, each once, in the order they first run."""
    return list(dict.fromkeys(p.name for p in _passes(pipeline)))


def _passes(steps) -> Iterator[Pass]:
    for step in steps:
        if isinstance(step, Fixpoint):
            yield from _passes(step.steps)
        else:
            yield Pass(*step)


def run_pipeline(pipeline: Pipeline, tech: ir.Technique, verify_each: bool = False,
                 progress: Optional[Callable[[str], None]] = None,
                 dump_after: Union[frozenset, set, str] = frozenset(),
                 dump: Optional[Callable[[str, ir.Technique], None]] = None,
                 ) -> tuple[ir.Technique, list[str]]:
    """Run ``pipeline`` on ``tech``: the resulting technique and the names of the passes run,
    in order (a fixpoint group's once per round).  ``verify_each``: the IR verifier after every
    pass, its failure re-raised naming the pass."""
    run = _Run(verify_each, progress, dump_after, dump)
    return run.steps(pipeline, tech), run.ran


class _Run:
    def __init__(self, verify_each, progress, dump_after, dump):
        self.verify_each, self.progress = verify_each, progress
        self.dump = dump if dump_after else None
        self.dump_after = dump_after
        self.ran: list[str] = []

    def steps(self, steps, tech: ir.Technique) -> ir.Technique:
        for step in steps:
            if isinstance(step, Fixpoint):
                tech = self.fixpoint(step, tech)
            else:
                tech = self.one(Pass(*step), tech)
        return tech

    def fixpoint(self, group: Fixpoint, tech: ir.Technique) -> ir.Technique:
        for _ in range(group.cap):
            before = tech
            tech = self.steps(group.steps, tech)
            if tech is before or tech == before:
                return tech
        raise InternalError(f"pass group `{group.name}` did not settle in {group.cap} rounds "
                            f"({', '.join(p.name for p in _passes(group.steps))})")

    def one(self, p: Pass, tech: ir.Technique) -> ir.Technique:
        if self.progress is not None:
            self.progress(p.name)
        tech = p.run(tech)
        self.ran.append(p.name)
        if self.verify_each:
            try:
                verify(tech)
            except AssertionError as e:
                raise InternalError(f"after pass `{p.name}`: {e}") from e
        if self.dump is not None and (self.dump_after == ALL or p.name in self.dump_after):
            self.dump(p.name, tech)
        return tech
