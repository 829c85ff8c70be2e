"""Backend-neutral queries about shader code: what a pass body or function body calls, reads,
samples, writes and whether it may discard, and which functions a pass reaches.  Used by the
emitters (``backends/plan.py`` re-exports them), the scene features and capabilities (``compiler/capabilities.py``) and the
compiler passes; kept out of ``backends/`` so that the compiler core does not depend on it.
"""

from __future__ import annotations

from typing import Any, Iterator

from pipegen.core.records import record
from pipegen.ir import nodes as ir, walk as irwalk


# ---- per-pass code queries -------------------------------------------------------------------
#
# Each statement list (a pass body, a function body) is walked once: ``code_facts`` remembers
# what the queries below need, keyed by the identity of the (immutable) tuple, which the memo
# holds so that the identity stays its own.  Emission asks several queries of the same bodies
# for each backend; the walks were most of its time.


@record(frozen=True)
class CodeFacts:
    """What one statement list holds (nested statements included, called functions not)."""
    calls: tuple[str, ...]          # user functions called (not builtins), first call first
    call_list: tuple[str, ...]      # every call of a user function, in order (repeats kept)
    loads: int                      # how many ``load``/``sample`` expressions
    inputs: frozenset[str]          # stage inputs read (``light`` for the drawn light's fields)
    sampled: frozenset[str]         # targets sampled bilinearly (``ir.Sample``)
    outputs: frozenset[str]         # targets written (``ir.Output``)
    discard: bool                   # holds a ``discard``
    reads: frozenset[str]           # targets read (``load``, ``sample``, ``size``)
    sample_reads: frozenset[str] = frozenset()   # targets read per sample (``load_sample``)
    resolved_reads: frozenset[str] = frozenset()  # targets read otherwise (their resolve)


# The cache holds its statement tuples (so that an id is not reused while cached), and through
# them the IR and source text of the techniques compiled lately: its bound is what a long-lived
# process keeps.  A compile walks a few hundred distinct bodies; 4096 kept about ten techniques'
# IR alive (issue 29's soak: RSS rising by ~100 KiB a compile until the bound was reached).
_FACTS: dict[int, tuple[Any, CodeFacts]] = {}
_FACTS_MAX = 1024


def code_facts(stmts) -> CodeFacts:
    """The ``CodeFacts`` of a statement list, walked once per tuple (a list is walked each
    time: it may change)."""
    hit = _FACTS.get(id(stmts))
    if hit is not None and hit[0] is stmts:
        return hit[1]
    calls: list[str] = []
    inputs, sampled, reads, per_sample, resolved = set(), set(), set(), set(), set()
    loads = 0
    for e in irwalk.exprs_of(stmts):
        t = type(e)
        if t is ir.Call:
            if not e.builtin:
                calls.append(e.name)
        elif t is ir.Var:
            if e.kind == "input":
                inputs.add(e.name)
        elif t is ir.LightField:
            if e.index is None:
                inputs.add("light")
        elif t is ir.Sample:
            sampled.add(e.target)
            reads.add(e.target)
            resolved.add(e.target)
            loads += 1
        elif t is ir.Load:
            reads.add(e.target)
            (resolved if e.sample is None else per_sample).add(e.target)
            loads += 1
        elif t is ir.TargetSize:
            reads.add(e.target)
    outputs, discard = set(), False
    for s in irwalk.walk_stmts(stmts):
        if isinstance(s, ir.Output):
            outputs.add(s.target)
        elif isinstance(s, ir.Discard):
            discard = True
    facts = CodeFacts(tuple(dict.fromkeys(calls)), tuple(calls), loads, frozenset(inputs),
                      frozenset(sampled), frozenset(outputs), discard, frozenset(reads),
                      frozenset(per_sample), frozenset(resolved))
    if isinstance(stmts, tuple):
        if len(_FACTS) >= _FACTS_MAX:
            _FACTS.clear()
        _FACTS[id(stmts)] = (stmts, facts)
    return facts


def pass_functions(tech: ir.Technique, body: tuple[ir.Stmt, ...]) -> list[ir.Function]:
    """The functions ``body`` reaches, callees before callers (so no prototypes are needed)."""
    by_name = {f.name: f for f in tech.all_functions()}
    order: list[ir.Function] = []
    seen: set[str] = set()

    def visit(stmts) -> None:
        for name in code_facts(stmts).calls:
            if name not in seen and name in by_name:
                seen.add(name)
                visit(by_name[name].body)
                order.append(by_name[name])

    visit(body)
    return order


def code_exprs(body, functions) -> Iterator[ir.Expr]:
    """Every expression of a pass's body and of the functions it uses."""
    yield from irwalk.walk_exprs(body)
    for f in functions:
        yield from irwalk.walk_exprs(f.body)


def stage_inputs(body, functions) -> set[str]:
    """Names of the stage inputs (``Var(kind="input")``) the code reads; ``light.index`` and
    ``light.FIELD`` of the drawn light count as the input ``light``."""
    out = set(code_facts(body).inputs)
    for f in functions:
        out |= code_facts(f.body).inputs
    return out


def sampled_targets(body, functions) -> set[str]:
    out = set(code_facts(body).sampled)
    for f in functions:
        out |= code_facts(f.body).sampled
    return out


def sample_read_targets(body, functions) -> set[str]:
    """The targets the code reads per sample (``load_sample``): the runtimes bind their
    samples, not their resolve."""
    out = set(code_facts(body).sample_reads)
    for f in functions:
        out |= code_facts(f.body).sample_reads
    return out


def resolved_read_targets(body, functions) -> set[str]:
    """The targets the code reads through ``load``/``sample`` (a multisampled one: its
    resolve)."""
    out = set(code_facts(body).resolved_reads)
    for f in functions:
        out |= code_facts(f.body).resolved_reads
    return out


def shades_per_sample(body, functions) -> bool:
    """Whether the code reads ``sample_id``: its pass runs once per covered sample (GL:
    a static use of gl_SampleID forces per-sample shading)."""
    return "sample_id" in stage_inputs(body, functions)


def may_discard(body, functions) -> bool:
    """Whether the code (the body or a function it uses) holds a ``discard``."""
    return code_facts(body).discard or any(code_facts(f.body).discard for f in functions)
