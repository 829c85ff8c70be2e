"""What every part of lowering shares: errors and their wording, the top-level names
(``Global``), function signatures and what bodies use (``Signature``, ``Uses``), where a body
runs (``Context``) and its locals (``Local``), reserved names and shader types."""

from __future__ import annotations

import contextlib
from dataclasses import field
from typing import Callable, Iterable, Optional, Protocol, Union

from pipegen.core.records import record
from pipegen.frontend import ast
from pipegen.ir import nodes as ir
from pipegen.ir.builtins import BUILTINS, STAGE_INPUTS, TARGET_FUNCTIONS, TYPE_NAMES
from pipegen.core.diagnostics import PipegenError, Span
from pipegen.core.formats import Format

Loader = Callable[[str], str]

PARAM_TYPES = {"float": ir.FLOAT, "int": ir.INT, "uint": ir.UINT, "bool": ir.BOOL,
                "format": ir.VOID}
MATERIALS = ("opaque", "translucent")
SAMPLE_COUNTS = (1, 2, 4, 8)
RESERVED = {"light": "the light being drawn (light.FIELD)",
             "lights": "the light table (lights[i].FIELD)"}


def error(span: Optional[Span], message: str, hint: str) -> PipegenError:
    return PipegenError(span, message, hint)


def did_you_mean(name: str, candidates: Iterable[str], fallback: str) -> str:
    import difflib
    close = difflib.get_close_matches(name, sorted(set(candidates)), n=1, cutoff=0.6)
    return f"did you mean '{close[0]}'?" if close else fallback


def listing(names: Iterable[str]) -> str:
    names = sorted(names)
    return ", ".join(names) if names else "(none)"


@record
class Global:
    kind: str                     # "parameter", "target", "packing", "function"
    span: Span


@record
class Signature:
    name: str
    params: list[tuple[str, ir.Type]]
    ret: ir.Type
    decl: ast.FunctionDef
    pack: Optional[str] = None    # the packing that generated it


@record
class Uses:
    """What a body needs from the pass that runs it (functions record, passes check)."""

    scene: list[tuple[str, Span]] = field(default_factory=list)     # scene-only inputs
    light: list[Span] = field(default_factory=list)                 # light.FIELD
    reads: dict[str, Span] = field(default_factory=dict)            # targets loaded/sampled
    calls: list[tuple[str, Span]] = field(default_factory=list)     # user functions called
    sample_id: list[Span] = field(default_factory=list)             # `sample_id` read
    sample_reads: dict[str, Span] = field(default_factory=dict)     # load_sample(T, …)
    resolved_reads: dict[str, Span] = field(default_factory=dict)   # load/sample(T, …)

    def merge(self, other: "Uses") -> None:
        self.scene.extend(other.scene)
        self.light.extend(other.light)
        self.sample_id.extend(other.sample_id)
        for mine, theirs in ((self.reads, other.reads), (self.sample_reads, other.sample_reads),
                             (self.resolved_reads, other.resolved_reads)):
            for t, s in theirs.items():
                mine.setdefault(t, s)


@contextlib.contextmanager
def generated_by(pack: Optional[ast.PackDecl]):
    """Errors in the code a packing generates are reported at the ``pack`` declaration: the
    user cannot see or edit that code (a name of theirs may clash with one of its locals)."""
    try:
        yield
    except PipegenError as e:
        if pack is None or (e.span is not None and not e.span.file.startswith("<")):
            raise
        raise error(pack.span, f"the code packing '{pack.name.name}' generates does not compile "
                    f"in this technique: {e.message}",
                    "a name declared here may clash with one the generated functions use; "
                    "rename it") from None


def reserved_meaning(name: str) -> Optional[str]:
    if name in STAGE_INPUTS:
        return "a stage input"
    if name in RESERVED:
        return RESERVED[name]
    if name in TYPE_NAMES:
        return "a type"
    if name in BUILTINS or name in TARGET_FUNCTIONS:
        return "a builtin function"
    if name in ("true", "false"):
        return "a boolean literal"
    return None


def a_or_an(thing) -> str:
    """'a float', 'an int', 'an ivec2', 'a uint': the article for a type name in a message."""
    text = str(thing)
    return ("an " if text[:1] in "aeio" else "a ") + text


def A_or_An(thing) -> str:
    return a_or_an(thing).capitalize()


def show_number(n: ast.Number) -> str:
    return n.span.source_line[n.span.column - 1:n.span.end_column - 1] or str(n.value)


def param_type_name(p: ir.Param) -> str:
    return "format" if p.type == ir.VOID else str(p.type)


def shader_type(name: ast.Name, allow_void: bool = False) -> ir.Type:
    t = ir.parse_type(name.name)
    if t is None:
        raise error(name.span, f"unknown type '{name.name}'",
                    did_you_mean(name.name, TYPE_NAMES,
                                 "types: float int uint bool vec2-4 ivec2-4 uvec2-4 bvec2-4 "
                                 "mat3 mat4"))
    if t.is_void and not allow_void:
        raise error(name.span, "a value cannot have type void", "use a value type like float")
    return t


@record
class Context:
    """Where a body runs.  A pass body checks its needs on the spot; a function body records
    them (``Uses``) and every pass that calls it checks them at the call."""

    pass_name: Optional[str] = None
    draw: Optional[ir.DrawKind] = None
    repeat: bool = False
    writes: tuple[str, ...] = ()
    reads: tuple[str, ...] = ()
    ret: ir.Type = ir.VOID
    function: Optional[str] = None
    samples: int = 1              # samples per pixel of the pass's attachments

    @staticmethod
    def for_function(sig: Signature) -> "Context":
        return Context(ret=sig.ret, function=sig.name)

    @property
    def in_pass(self) -> bool:
        return self.pass_name is not None

    @property
    def has_light(self) -> bool:
        return self.draw is ir.DrawKind.LIGHTS or self.repeat

    def describe(self) -> str:
        if self.draw is ir.DrawKind.SCENE:
            kind = "a scene pass"
        elif self.draw is ir.DrawKind.LIGHTS:
            kind = "a light pass"
        else:
            kind = "a full-screen pass"
        return f"pass '{self.pass_name}' ({kind})"


@record
class Local:
    type: ir.Type
    span: Span
    loop_var: bool = False


class Lowering(Protocol):
    """What the checkers of a technique's parts (``expressions``, ``passes``) read from the
    lowerer that runs them (``lower._Lowerer``): the declarations lowered so far and its readers
    of numbers, clears and packing constants in declarations.  A protocol, so that the parts
    need not import the lowerer, which imports them."""

    globals: dict[str, Global]
    params: dict[str, ir.Param]
    targets: dict[str, ir.Target]
    lights: ir.LightTable
    materials: Optional[ir.MaterialTable]
    packs: dict[str, ast.PackDecl]
    pack_specs: dict[str, object]
    pack_options: dict[str, dict]
    pack_schemes: dict[str, str]
    signatures: dict[str, Signature]
    uses: dict[str, Uses]

    def number(self, e: ast.Expr, what: str, integer: bool = False) -> Union[int, float]: ...

    def integer(self, e: ast.Expr, what: str, lo: int, hi: Optional[int] = None) -> int: ...

    def clear(self, spec: ast.ClearSpec, target: str, fmt: Format) -> ir.Clear: ...

    def pack_constant(self, pack: ast.Name, const: ast.Name) -> ir.Const: ...
