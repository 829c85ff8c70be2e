"""Lowering: ``ast.Module`` -> ``ir.Technique``.

This is where every user-facing check of a technique happens: includes, names, parameter
values, formats, the light schema, packings, the types of all shader code, and the structural
rules of passes (what a pass may read, write, attach, blend).  Anything wrong raises a
``PipegenError`` located at the token the user wrote.

Phases, in order (each may rely on the ones before):

1. collect  -- follow includes, sort declarations by kind, number the repeat groups
2. params   -- declared values, overrides from the caller, allowed sets
3. lights, targets, output
4. packings -- ``packing.build`` generates functions (parsed like user code) and constants
5. functions -- signatures first, then bodies (so order and mutual calls do not matter),
                then recursion and what each function needs transitively
6. passes   -- draw, attachments, fixed-function state, fragment body

The IR keeps technique parameters as ``Var(kind="param")`` in shader code (the specialise pass
folds them); everywhere else (sizes, clears, formats) their values are substituted here.
``ir.Param.default`` holds the value the technique is compiled with (an override if given).
Format-valued parameters have type ``ir.VOID`` and a ``str`` value: they are not shader values.
"""

from __future__ import annotations

import contextlib
import importlib
import os
from dataclasses import dataclass, field
from typing import Callable, Iterable, Optional, Union

from . import ast, ir, sources, syntax
from .builtins import (BUILTINS, LIGHT_FIELDS, LIGHT_INDEX, LIGHT_TYPES, STAGE_INPUTS,
                       TARGET_FUNCTIONS, TYPE_NAMES, VOLUME_LIGHT_FIELDS, Where, binary_type,
                       describe_overloads,
                       resolve_builtin, target_read_type, target_write_type, unary_type)
from .diagnostics import PipegenError, Span
from .formats import FORMATS, Format

Loader = Callable[[str], str]

_PARAM_TYPES = {"float": ir.FLOAT, "int": ir.INT, "uint": ir.UINT, "bool": ir.BOOL,
                "format": ir.VOID}
_MATERIALS = ("opaque", "translucent")
_SAMPLE_COUNTS = (1, 2, 4, 8)
_RESERVED = {"light": "the light being drawn (light.FIELD)",
             "lights": "the light table (lights[i].FIELD)"}


def lower(module: ast.Module, filename: str, params: Optional[dict] = None,
          loader: Optional[Loader] = None) -> ir.Technique:
    """Resolve, check and lower a parsed technique.

    ``params`` overrides parameter defaults (values or their source spelling, e.g. ``"0.5"``);
    ``loader(path) -> text`` reads included files (default: from disk).
    """
    return _Lowerer(filename, dict(params or {}), loader or _read_file).run(module)


def _read_file(path: str) -> str:
    return sources.read_source(path)


def _err(span: Optional[Span], message: str, hint: str) -> PipegenError:
    return PipegenError(span, message, hint)


def _did_you_mean(name: str, candidates: Iterable[str], fallback: str) -> str:
    import difflib
    close = difflib.get_close_matches(name, sorted(set(candidates)), n=1, cutoff=0.6)
    return f"did you mean '{close[0]}'?" if close else fallback


def _listing(names: Iterable[str]) -> str:
    names = sorted(names)
    return ", ".join(names) if names else "(none)"


# ---------------------------------------------------------------------------------------------
# Phase 1: collect declarations across includes
# ---------------------------------------------------------------------------------------------


@dataclass
class _PassItem:
    decl: ast.PassDecl
    group: Optional[int]          # repeat group from a `repeat per light { … }` block
    block_types: tuple = ()       # the block's light types (`repeat per light spot { … }`)


@dataclass
class _Decls:
    technique: Optional[ast.TechniqueDecl] = None
    params: list[ast.ParamDecl] = field(default_factory=list)
    lights: list[ast.LightsDecl] = field(default_factory=list)
    targets: list[ast.TargetDecl] = field(default_factory=list)
    outputs: list[ast.OutputDecl] = field(default_factory=list)
    packs: list[ast.PackDecl] = field(default_factory=list)
    functions: list[ast.FunctionDef] = field(default_factory=list)
    passes: list[_PassItem] = field(default_factory=list)
    named: list[tuple[ast.Name, str]] = field(default_factory=list)   # in source order


# What an included file may contribute (language.md: "functions, params, packs").
_INCLUDABLE = (ast.Include, ast.ParamDecl, ast.PackDecl, ast.FunctionDef)


class _Collector:
    def __init__(self, loader: Loader):
        self.loader = loader
        self.decls = _Decls()
        self.seen: set[str] = set()
        self.texts: dict[str, str] = {}     # found by _find, parsed by _include
        self.groups = 0

    def module(self, module: ast.Module, path: str, stack: tuple[str, ...] = ()) -> None:
        self.seen.add(os.path.normpath(path))
        included = bool(stack)
        for item in module.items:
            if included and not isinstance(item, _INCLUDABLE):
                raise _err(item.span, f"an included file may only declare params, packs and "
                           f"functions, not a {_item_kind(item)}",
                           "move it into the technique file that includes this one")
            self._item(item, path, stack)

    def _item(self, item: ast.Item, path: str, stack: tuple[str, ...]) -> None:
        d = self.decls
        if isinstance(item, ast.Include):
            self._include(item, path, stack)
        elif isinstance(item, ast.TechniqueDecl):
            if d.technique is not None:
                raise _err(item.span, "a file declares one technique",
                           f"'{d.technique.name.name}' is declared on line "
                           f"{d.technique.span.line}")
            d.technique = item
        elif isinstance(item, ast.RepeatBlock):
            if not item.passes:
                raise _err(item.span, "an empty `repeat per light` block",
                           "put the passes that run once per light inside it")
            group = self._new_group()
            types = tuple(item.light_types)
            d.passes.extend(_PassItem(p, group, types) for p in item.passes)
        elif isinstance(item, ast.PassDecl):
            # A pass with its own `repeat per light` is a repeat group of one.
            repeats = any(isinstance(s, ast.RepeatPerLight) for s in item.stmts)
            d.passes.append(_PassItem(item, self._new_group() if repeats else None))
        else:
            bucket = {ast.ParamDecl: d.params, ast.LightsDecl: d.lights,
                      ast.TargetDecl: d.targets, ast.OutputDecl: d.outputs,
                      ast.PackDecl: d.packs, ast.FunctionDef: d.functions}[type(item)]
            bucket.append(item)
            kind = _NAMED_KINDS.get(type(item))
            if kind is not None:
                d.named.append((item.name, kind))

    def _new_group(self) -> int:
        self.groups += 1
        return self.groups - 1

    def _include(self, inc: ast.Include, path: str, stack: tuple[str, ...]) -> None:
        if not inc.path.isprintable():
            raise _err(inc.span, "an include path cannot contain control characters",
                       'write the path of a .pipe file, e.g. include "common/lighting.pipe"')
        target = self._find(inc, path)
        if target in stack or target == os.path.normpath(path):
            raise _err(inc.span, f"'{inc.path}' includes itself (through "
                       f"{' -> '.join(os.path.basename(s) for s in stack + (path,))})",
                       "remove one of the includes of the cycle")
        if target in self.seen:
            return   # already spliced in: a file's declarations are included once
        text = self.texts.pop(target)
        self.module(syntax.parse(text, target), target, stack + (path,))

    def _find(self, inc: ast.Include, path: str) -> str:
        """The first of ``sources.include_candidates`` that exists (its text kept in
        ``self.texts``); a file that exists but cannot be read is an error, not skipped."""
        candidates = sources.include_candidates(inc.path, path)
        for target, _ in candidates:
            if target in self.seen:
                return target
            try:
                self.texts[target] = self.loader(target)
                return target
            except FileNotFoundError:
                continue
            except (OSError, UnicodeDecodeError) as e:
                raise _err(inc.span, f"cannot read included file '{inc.path}' ({target}): "
                           f"{getattr(e, 'strerror', None) or e}",
                           "include a .pipe file (a regular file of at most "
                           f"{sources.MAX_SOURCE_BYTES >> 20} MiB)") from None
        searched = "; ".join(f"{t} ({where})" for t, where in candidates)
        raise _err(inc.span, f"cannot read included file '{inc.path}': not found (searched "
                   f"{searched})",
                   "include paths are relative to the including file; the library shipped "
                   "with pipegen is included as common/NAME.pipe; more folders can be listed "
                   "in PIPEGEN_PATH")


_NAMED_KINDS = {ast.ParamDecl: "parameter", ast.TargetDecl: "target", ast.PackDecl: "packing",
                ast.FunctionDef: "function"}


def _item_kind(item: ast.Item) -> str:
    return {ast.TechniqueDecl: "technique", ast.LightsDecl: "light table",
            ast.TargetDecl: "target", ast.OutputDecl: "output", ast.PassDecl: "pass",
            ast.RepeatBlock: "repeat block"}.get(type(item), type(item).__name__)


# ---------------------------------------------------------------------------------------------
# Global names
# ---------------------------------------------------------------------------------------------


@dataclass
class _Global:
    kind: str                     # "parameter", "target", "packing", "function"
    span: Span


@dataclass
class _Signature:
    name: str
    params: list[tuple[str, ir.Type]]
    ret: ir.Type
    decl: ast.FunctionDef
    pack: Optional[str] = None    # the packing that generated it


@dataclass
class _Uses:
    """What a body needs from the pass that runs it (functions record, passes check)."""

    scene: list[tuple[str, Span]] = field(default_factory=list)     # scene-only inputs
    light: list[Span] = field(default_factory=list)                 # light.FIELD
    reads: dict[str, Span] = field(default_factory=dict)            # targets loaded/sampled
    calls: list[tuple[str, Span]] = field(default_factory=list)     # user functions called

    def merge(self, other: "_Uses") -> None:
        self.scene.extend(other.scene)
        self.light.extend(other.light)
        for t, s in other.reads.items():
            self.reads.setdefault(t, s)


class _Lowerer:
    def __init__(self, filename: str, overrides: dict, loader: Loader):
        self.filename = filename
        self.overrides = overrides
        self.loader = loader
        self.globals: dict[str, _Global] = {}
        self.params: dict[str, ir.Param] = {}
        self.targets: dict[str, ir.Target] = {}
        self.lights = ir.LightTable((), 0)
        self.packs: dict[str, ast.PackDecl] = {}
        self.pack_specs: dict[str, object] = {}
        self.pack_options: dict[str, dict] = {}
        self.signatures: dict[str, _Signature] = {}
        self.bodies: dict[str, tuple[ir.Stmt, ...]] = {}
        self.uses: dict[str, _Uses] = {}          # per function, transitive after phase 5

    def run(self, module: ast.Module) -> ir.Technique:
        collector = _Collector(self.loader)
        collector.module(module, self.filename)
        d = collector.decls
        tech = self._technique_line(module, d)
        for name, kind in d.named:   # all at once, so a clash is reported where it is later
            self._declare(name, kind)
        params = self._params(d.params)
        self._lights(d.lights)
        targets = self._targets(d.targets)
        output = self._output(d.outputs, tech)
        self._packings(d.packs)
        self._functions(d.functions)
        passes = self._passes(d.passes)
        return ir.Technique(
            name=tech.name.name, title=tech.title, params=params, targets=targets,
            lights=self.lights, packings=self._ir_packings(),
            functions=self._ir_functions(user=True), passes=passes, output=output,
            source=self.filename)

    def _declare(self, name: ast.Name, kind: str) -> None:
        """Enter a top-level name; parameters, targets, packings and functions share one
        namespace because shader code refers to all of them by bare name."""
        n = name.name
        if n in self.globals:
            prev = self.globals[n]
            raise _err(name.span, f"duplicate name '{n}': already declared as {_a(prev.kind)}",
                       f"the first declaration is at {prev.span.file}:{prev.span.line}; "
                       f"rename one of them")
        reserved = _reserved_meaning(n)
        if reserved:
            raise _err(name.span, f"'{n}' is reserved: it is {reserved}",
                       f"choose another name for this {kind}")
        self.globals[n] = _Global(kind, name.span)

    # -- technique line ------------------------------------------------------------------------
    def _technique_line(self, module: ast.Module, d: _Decls) -> ast.TechniqueDecl:
        first = module.items[0] if module.items else None
        if d.technique is None or first is not d.technique:
            span = first.span if first is not None else module.span
            raise _err(span, "a technique file starts with `technique NAME \"title\"`",
                       "add e.g. `technique forward \"Single-pass forward\"` as its first line")
        return d.technique

    # -- parameters ----------------------------------------------------------------------------
    def _params(self, decls: list[ast.ParamDecl]) -> tuple[ir.Param, ...]:
        for decl in decls:
            self.params[decl.name.name] = _ParamBuilder(decl).build()
        for name, value in self.overrides.items():
            if name not in self.params:
                raise _err(None, f"unknown parameter '{name}'",
                           f"{self.filename} declares: {_listing(self.params)}")
            p = self.params[name]
            decl = next(d for d in decls if d.name.name == name)
            self.params[name] = _ParamBuilder(decl).override(p, value)
        return tuple(self.params.values())

    # -- values in declarations ----------------------------------------------------------------
    def number(self, e: ast.Expr, what: str, integer: bool = False) -> Union[int, float]:
        """A numeric value in a declaration: a literal, a parameter, or ``PACK.constant``."""
        if isinstance(e, ast.Number):
            if integer and e.kind == "float":
                raise _err(e.span, f"{what} must be an integer, not {_show_number(e)}",
                           f"write {int(e.value)}")
            return e.value
        if isinstance(e, ast.Name) and e.name in self.params:
            p = self.params[e.name]
            ok = (ir.INT, ir.UINT) if integer else (ir.INT, ir.UINT, ir.FLOAT)
            if p.type not in ok:
                raise _err(e.span, f"{what} must be {'an integer' if integer else 'a number'}, "
                           f"but parameter '{e.name}' is {_a(_param_type_name(p))}",
                           "use a literal or a parameter of a numeric type")
            return p.default
        if isinstance(e, ast.Field) and isinstance(e.base, ast.Name) \
                and e.base.name in self.pack_specs:
            const = self.pack_constant(e.base, e.name)
            if not const.type.is_scalar or const.type == ir.BOOL:
                raise _err(e.span, f"{what} must be a number, not {_a(const.type)}",
                           "use a numeric constant")
            if integer and const.type.scalar is not ir.Scalar.INT \
                    and const.type.scalar is not ir.Scalar.UINT:
                raise _err(e.span, f"{what} must be an integer, not {_a(const.type)}",
                           "use an integer constant")
            return const.value
        if isinstance(e, ast.Name):
            raise _err(e.span, f"unknown parameter '{e.name}' in {what}",
                       _did_you_mean(e.name, self.params, "declare it with `param NAME = VALUE`"))
        raise _err(e.span, f"{what} must be a number", "write a number or a parameter name")

    def integer(self, e: ast.Expr, what: str, lo: int, hi: Optional[int] = None) -> int:
        value = int(self.number(e, what, integer=True))
        if value < lo or (hi is not None and value > hi):
            bound = f"between {lo} and {hi}" if hi is not None else f"at least {lo}"
            raise _err(e.span, f"{what} must be {bound}, not {value}", f"use a value {bound}")
        return value

    # -- light table ---------------------------------------------------------------------------
    def _lights(self, decls: list[ast.LightsDecl]) -> None:
        if not decls:
            return
        if len(decls) > 1:
            raise _err(decls[1].span, "the light table is declared twice",
                       f"the first `lights[…]` is on line {decls[0].span.line}")
        decl = decls[0]
        capacity = self.integer(decl.capacity, "the light capacity", 1)
        fields: list[ir.LightAttr] = []
        for f in decl.fields:
            name = f.name.name
            if name not in LIGHT_FIELDS:
                raise _err(f.name.span, f"lights have no field '{name}'",
                           _did_you_mean(name, LIGHT_FIELDS,
                                         f"light fields: {_listing(LIGHT_FIELDS)}"))
            if any(a.name == name for a in fields):
                raise _err(f.name.span, f"light field '{name}' is declared twice",
                           "list each field once")
            want = LIGHT_FIELDS[name]
            if ir.parse_type(f.type.name) != want:
                raise _err(f.type.span, f"light field '{name}' has type {want}, "
                           f"not {f.type.name}", f"write `{name}: {want}`")
            fields.append(ir.LightAttr(name, want))
        self.lights = ir.LightTable(tuple(fields), capacity, decl.span)

    # -- targets -------------------------------------------------------------------------------
    def _targets(self, decls: list[ast.TargetDecl]) -> tuple[ir.Target, ...]:
        for decl in decls:
            self.targets[decl.name.name] = self._target(decl)
        return tuple(self.targets.values())

    def _target(self, decl: ast.TargetDecl) -> ir.Target:
        fmt = self._format(decl.format)
        size, samples, clear = ir.Size(), 1, None
        seen: dict[type, ast.Node] = {}
        for opt in decl.options:
            kind = ast.SizeRel if isinstance(opt, ast.SizeAbs) else type(opt)
            if kind in seen:
                raise _err(opt.span, f"target '{decl.name.name}' has two "
                           f"`{_option_word(opt)}` options", "keep one")
            seen[kind] = opt
            if isinstance(opt, ast.SizeAbs):
                size = ir.Size(width=self.integer(opt.width, "a target width", 1),
                               height=self.integer(opt.height, "a target height", 1))
            elif isinstance(opt, ast.SizeRel):
                size = ir.Size(scale=self._scale(opt))
            elif isinstance(opt, ast.Samples):
                samples = self._samples(opt)
            else:
                clear = self.clear(opt, decl.name.name, fmt)
        return ir.Target(decl.name.name, fmt, size, samples,
                         _complete_clear(clear, fmt), decl.span)

    def _format(self, name: ast.Name) -> Format:
        n = name.name
        if n in self.params:
            p = self.params[n]
            if p.type != ir.VOID:
                raise _err(name.span, f"parameter '{n}' is {_a(_param_type_name(p))}, "
                           f"not a format", "declare it like `param fmt = rgba16f`")
            return FORMATS[p.default]
        if n not in FORMATS:
            raise _err(name.span, f"unknown format '{n}'",
                       _did_you_mean(n, FORMATS, f"formats: {' '.join(FORMATS)}"))
        return FORMATS[n]

    def _scale(self, opt: ast.SizeRel) -> float:
        if opt.scale is None:
            return 1.0
        scale = float(self.number(opt.scale, "a size scale"))
        if not 0.0 < scale <= 16.0:
            raise _err(opt.scale.span, f"size scale {scale:g} is out of range",
                       "scale the output size by a factor in (0, 16]")
        return scale

    def _samples(self, opt: ast.Samples) -> int:
        n = self.integer(opt.value, "the sample count", 1)
        if n not in _SAMPLE_COUNTS:
            raise _err(opt.value.span, f"{n} samples per pixel is not supported",
                       f"use one of {', '.join(map(str, _SAMPLE_COUNTS))}")
        return n

    def clear(self, spec: ast.ClearSpec, target: str, fmt: Format) -> ir.Clear:
        """A clear as written (parts not mentioned stay None)."""
        if spec.color is not None or spec.all is not None:
            if not fmt.is_color:
                raise _err(spec.span, f"depth target '{target}' is cleared with "
                           f"`clear depth D` (not a colour)",
                           "write e.g. `clear depth 1.0 stencil 0`" if fmt.has_stencil
                           else "write e.g. `clear depth 1.0`")
            return ir.Clear(color=self._clear_color(spec, target, fmt))
        if not fmt.has_depth:
            raise _err(spec.span, f"colour target '{target}' ({fmt.name}) has no depth or "
                       f"stencil to clear", "clear a colour target with `clear (r, g, b, a)`")
        depth = None
        if spec.depth is not None:
            depth = float(self.number(spec.depth, "a depth clear value"))
            if not 0.0 <= depth <= 1.0:
                raise _err(spec.depth.span, f"depth clear value {depth:g} is outside [0, 1]",
                           "depth is cleared to a value in [0, 1], usually 1.0")
        stencil = None
        if spec.stencil is not None:
            if not fmt.has_stencil:
                raise _err(spec.stencil.span, f"target '{target}' ({fmt.name}) has no "
                           f"stencil bits", "use a d24s8 target for stencil")
            stencil = self.integer(spec.stencil, "a stencil clear value", 0, 255)
        return ir.Clear(depth=depth, stencil=stencil)

    def _clear_color(self, spec: ast.ClearSpec, target: str,
                     fmt: Format) -> tuple[float, float, float, float]:
        if spec.all is not None:
            items = [spec.all] * 4
        else:
            items = list(spec.color.items)
            if len(items) not in (fmt.channels, 4):
                raise _err(spec.color.span, f"target '{target}' ({fmt.name}) has "
                           f"{fmt.channels} channel(s), but the clear colour has {len(items)}",
                           f"give {fmt.channels} or 4 values, or one value for all channels")
        values = [float(self.number(e, "a clear colour component")) for e in items]
        if fmt.is_integer:
            for e, v in zip(items, values):
                if v != int(v) or v < 0:
                    raise _err(e.span, f"integer target '{target}' is cleared to whole "
                               f"numbers, not {v:g}", "use values like 0 or 255")
        return tuple(values + [0.0] * (4 - len(values)))

    # -- output --------------------------------------------------------------------------------
    def _output(self, decls: list[ast.OutputDecl], tech: ast.TechniqueDecl) -> str:
        if len(decls) > 1:
            raise _err(decls[1].span, "the output target is declared twice",
                       f"the first `output` is on line {decls[0].span.line}")
        if not decls:
            if "color" in self.targets and self.targets["color"].format.is_color:
                return "color"
            raise _err(tech.span, "the technique has no output target",
                       "declare `output NAME` or a colour target named color")
        name = decls[0].name
        t = self.targets.get(name.name)
        if t is None:
            raise _err(name.span, f"output target '{name.name}' is not declared",
                       _did_you_mean(name.name, self.targets, "declare it with `target`"))
        if not t.format.is_color:
            raise _err(name.span, f"output target '{name.name}' is a depth target",
                       "the output is a colour target")
        return name.name

    # -- packings ------------------------------------------------------------------------------
    def _packings(self, decls: list[ast.PackDecl]) -> None:
        if not decls:
            return
        packing = importlib.import_module("pipegen.packing")
        for decl in decls:
            self._packing(decl, packing)

    def _packing(self, decl: ast.PackDecl, packing) -> None:
        name, scheme = decl.name.name, decl.scheme.name
        schemes = getattr(packing, "SCHEMES", None)
        if schemes is not None and scheme not in schemes:
            raise _err(decl.scheme.span, f"unknown packing scheme '{scheme}'",
                       _did_you_mean(scheme, schemes, f"schemes: {_listing(schemes)}"))
        options = self._pack_options(decl.options)
        target_format = None
        if "target" in options:
            target_format = self.targets[options["target"]].format
        spec = packing.build(name, scheme, options, target_format, decl.scheme.span)
        self.packs[name] = decl
        self.pack_specs[name] = spec
        self.pack_options[name] = options
        with _generated_by(decl):
            module = syntax.parse(spec.functions_source, f"<{scheme} packing '{name}'>")
            for item in module.items:
                assert isinstance(item, ast.FunctionDef), f"packing {scheme} generated {item}"
                assert item.name.name.startswith(name + "_"), item.name.name
                self._signature(item, pack=decl)

    def _pack_options(self, options: list[ast.Option]) -> dict:
        out: dict = {}
        for opt in options:
            key = opt.key.name
            if key in out:
                raise _err(opt.key.span, f"option '{key}' is given twice", "keep one")
            out[key] = self._pack_option(key, opt.value)
        return out

    def _pack_option(self, key: str, value):
        if isinstance(value, ast.Record):
            return self._pack_options(value.options)
        if isinstance(value, str):
            return value
        if key == "target":
            if not isinstance(value, ast.Name) or value.name not in self.targets:
                shown = value.name if isinstance(value, ast.Name) else "this"
                raise _err(value.span, f"unknown target '{shown}'",
                           _did_you_mean(shown, self.targets, "declare it with `target`"))
            return value.name
        if isinstance(value, ast.Bool):
            return value.value
        if isinstance(value, ast.Name) and value.name not in self.params:
            return value.name     # a scheme-specific word
        if isinstance(value, ast.Name) and self.params[value.name].type == ir.VOID:
            return self.params[value.name].default
        return self.number(value, "a packing option")

    def pack_constant(self, pack: ast.Name, const: ast.Name) -> ir.Const:
        spec = self.pack_specs[pack.name]
        if const.name not in spec.constants:
            raise _err(const.span, f"packing '{pack.name}' has no constant '{const.name}'",
                       f"its constants: {_listing(spec.constants)}")
        t, value = spec.constants[const.name]
        return ir.Const(t, value)

    def _ir_packings(self) -> tuple[ir.Packing, ...]:
        out = []
        for name, decl in self.packs.items():
            spec = self.pack_specs[name]
            functions = tuple(self._ir_function(s) for s in self._ordered_signatures()
                              if s.pack == name)
            constants = tuple((k, ir.Const(t, v)) for k, (t, v) in spec.constants.items())
            out.append(ir.Packing(name, decl.scheme.name, _freeze(self.pack_options[name]),
                                  functions, constants, spec.capacity, spec.error,
                                  tuple(spec.notes or ()), decl.span))
        return tuple(out)

    # -- functions -----------------------------------------------------------------------------
    def _functions(self, decls: list[ast.FunctionDef]) -> None:
        for decl in decls:
            self._signature(decl)
        for sig in list(self.signatures.values()):
            checker = _BodyChecker(self, _Context.for_function(sig))
            with _generated_by(self.packs[sig.pack] if sig.pack is not None else None):
                self.bodies[sig.name] = checker.function_body(sig)
            self.uses[sig.name] = checker.uses
        self._close_uses()

    def _signature(self, decl: ast.FunctionDef, pack: Optional[ast.PackDecl] = None) -> None:
        if pack is not None:   # user functions were entered with the other top-level names
            self._declare_generated(decl.name.name, pack)
        ret = _shader_type(decl.ret, allow_void=True)
        params: list[tuple[str, ir.Type]] = []
        for p in decl.params:
            if any(n == p.name.name for n, _ in params):
                raise _err(p.name.span, f"parameter '{p.name.name}' is declared twice",
                           "rename one of them")
            params.append((p.name.name, _shader_type(p.type)))
        self.signatures[decl.name.name] = _Signature(
            decl.name.name, params, ret, decl, pack.name.name if pack is not None else None)

    def _declare_generated(self, name: str, pack: ast.PackDecl) -> None:
        if name in self.globals:
            raise _err(pack.name.span, f"packing '{pack.name.name}' defines function "
                       f"'{name}', which is already declared as {_a(self.globals[name].kind)}",
                       "rename the packing or the other declaration")
        self.globals[name] = _Global("function", pack.span)

    def _close_uses(self) -> None:
        """Make every function's ``_Uses`` transitive and reject recursion (GLSL has none)."""
        done: set[str] = set()

        def visit(name: str, path: tuple[str, ...]) -> None:
            if name in done:
                return
            for callee, span in self.uses[name].calls:
                if callee in path or callee == name:
                    cycle = " -> ".join(path + (name, callee))
                    raise _err(span, f"recursive call of '{callee}' ({cycle})",
                               "shader code cannot recurse; rewrite it as a bounded loop")
                visit(callee, path + (name,))
                self.uses[name].merge(self.uses[callee])
            done.add(name)

        for name in self.signatures:
            visit(name, ())

    def _ordered_signatures(self) -> list[_Signature]:
        """Callees before callers, so backends can emit functions without prototypes."""
        order: list[_Signature] = []
        placed: set[str] = set()

        def place(name: str) -> None:
            if name in placed:
                return
            placed.add(name)
            for callee, _ in self.uses[name].calls:
                place(callee)
            order.append(self.signatures[name])

        for name in self.signatures:
            place(name)
        return order

    def _ir_function(self, sig: _Signature) -> ir.Function:
        return ir.Function(sig.name, tuple(sig.params), sig.ret, self.bodies[sig.name],
                           sig.decl.span)

    def _ir_functions(self, user: bool) -> tuple[ir.Function, ...]:
        return tuple(self._ir_function(s) for s in self._ordered_signatures()
                     if (s.pack is None) == user)

    # -- passes --------------------------------------------------------------------------------
    def _passes(self, items: list[_PassItem]) -> tuple[ir.Pass, ...]:
        names: dict[str, Span] = {}
        out = []
        for item in items:
            name = item.decl.name
            if name.name in names:
                raise _err(name.span, f"duplicate pass name '{name.name}'",
                           f"the first pass '{name.name}' is on line {names[name.name].line}")
            names[name.name] = name.span
            out.append(_PassLowerer(self, item).lower())
        return tuple(out)


@contextlib.contextmanager
def _generated_by(pack: Optional[ast.PackDecl]):
    """Errors in the code a packing generates are reported at the ``pack`` declaration: the
    user cannot see or edit that code (a name of theirs may clash with one of its locals)."""
    try:
        yield
    except PipegenError as e:
        if pack is None or (e.span is not None and not e.span.file.startswith("<")):
            raise
        raise _err(pack.span, f"the code packing '{pack.name.name}' generates does not compile "
                   f"in this technique: {e.message}",
                   "a name declared here may clash with one the generated functions use; "
                   "rename it") from None


def _reserved_meaning(name: str) -> Optional[str]:
    if name in STAGE_INPUTS:
        return "a stage input"
    if name in _RESERVED:
        return _RESERVED[name]
    if name in TYPE_NAMES:
        return "a type"
    if name in BUILTINS or name in TARGET_FUNCTIONS:
        return "a builtin function"
    if name in ("true", "false"):
        return "a boolean literal"
    return None


def _option_word(opt: ast.Node) -> str:
    return {ast.SizeAbs: "size", ast.SizeRel: "size", ast.Samples: "samples"}.get(
        type(opt), "clear")


def _complete_clear(clear: Optional[ir.Clear], fmt: Format) -> ir.Clear:
    """A target's clear with every part its format has filled in (zero when not given)."""
    clear = clear or ir.Clear()
    if fmt.is_color:
        return ir.Clear(color=clear.color or (0.0, 0.0, 0.0, 0.0))
    stencil = (clear.stencil or 0) if fmt.has_stencil else None
    return ir.Clear(depth=clear.depth if clear.depth is not None else 0.0, stencil=stencil)


def _freeze(options: dict) -> tuple:
    return tuple((k, _freeze(v) if isinstance(v, dict) else v) for k, v in options.items())


def _a(thing) -> str:
    """'a float', 'an int', 'an ivec2', 'a uint': the article for a type name in a message."""
    text = str(thing)
    return ("an " if text[:1] in "aeio" else "a ") + text


def _A(thing) -> str:
    return _a(thing).capitalize()


def _show_number(n: ast.Number) -> str:
    return n.span.source_line[n.span.column - 1:n.span.end_column - 1] or str(n.value)


def _param_type_name(p: ir.Param) -> str:
    return "format" if p.type == ir.VOID else str(p.type)


def _shader_type(name: ast.Name, allow_void: bool = False) -> ir.Type:
    t = ir.parse_type(name.name)
    if t is None:
        raise _err(name.span, f"unknown type '{name.name}'",
                   _did_you_mean(name.name, TYPE_NAMES,
                                 "types: float int uint bool vec2-4 ivec2-4 uvec2-4 bvec2-4 "
                                 "mat3 mat4"))
    if t.is_void and not allow_void:
        raise _err(name.span, "a value cannot have type void", "use a value type like float")
    return t


# ---------------------------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------------------------


class _ParamBuilder:
    """Types, default, allowed set and override of one ``param`` declaration."""

    def __init__(self, decl: ast.ParamDecl):
        self.decl = decl

    def build(self) -> ir.Param:
        d = self.decl
        t = self._type()
        default = self._coerce(d.value, t)
        allowed = tuple(self._coerce(v, t) for v in d.allowed or ())
        if allowed and default not in allowed:
            raise _err(d.value.span, f"the default of '{d.name.name}' ({_show(default)}) is "
                       f"not one of its allowed values", f"allowed: {_show_all(allowed)}")
        return ir.Param(d.name.name, t, default, allowed, d.span)

    def _type(self) -> ir.Type:
        d = self.decl
        if d.type is not None:
            if d.type.name not in _PARAM_TYPES:
                raise _err(d.type.span, f"a parameter cannot have type '{d.type.name}'",
                           f"parameter types: {', '.join(_PARAM_TYPES)}")
            return _PARAM_TYPES[d.type.name]
        v = d.value
        if isinstance(v, ast.Number):
            return _PARAM_TYPES[v.kind]
        if isinstance(v, ast.Bool):
            return ir.BOOL
        if isinstance(v, ast.Name):
            return ir.VOID
        raise _err(v.span, "a parameter's value is a number, true/false or a format name",
                   "e.g. `param scale = 0.5` or `param fmt = rgba16f`")

    def _coerce(self, v: ast.Expr, t: ir.Type):
        value = v.value if isinstance(v, (ast.Number, ast.Bool)) else \
            v.name if isinstance(v, ast.Name) else None
        kind = v.kind if isinstance(v, ast.Number) else \
            "bool" if isinstance(v, ast.Bool) else "name" if isinstance(v, ast.Name) else "?"
        result = _convert_param_value(value, kind, t)
        if result is None:
            raise _err(v.span, f"parameter '{self.decl.name.name}' is "
                       f"{_a(_type_word(t))}; {_show_literal(v)} is not", _param_hint(t))
        return result

    def override(self, p: ir.Param, value) -> ir.Param:
        kind, raw = _classify_override(value)
        converted = _convert_param_value(raw, kind, p.type)
        if converted is None:
            raise _err(self.decl.name.span, f"parameter '{p.name}' is {_a(_type_word(p.type))}; "
                       f"the value {value!r} given for it is not", _param_hint(p.type))
        if p.allowed and converted not in p.allowed:
            raise _err(self.decl.name.span, f"{_show(converted)} is not an allowed value of "
                       f"parameter '{p.name}'", f"allowed: {_show_all(p.allowed)}")
        return ir.Param(p.name, p.type, converted, p.allowed, p.span)


def _convert_param_value(value, kind: str, t: ir.Type):
    """A literal of ``kind`` ("float", "int", "uint", "bool", "name") as a value of parameter
    type ``t``; None when it does not fit.  Integer literals serve float and (when not
    negative) uint parameters; names serve format parameters."""
    if t == ir.FLOAT and kind in ("float", "int", "uint"):
        return float(value)
    if t == ir.INT and kind == "int":
        return int(value)
    if t == ir.UINT and kind in ("uint", "int") and value >= 0:
        return int(value)
    if t == ir.BOOL and kind == "bool":
        return bool(value)
    if t == ir.VOID and kind == "name" and value in FORMATS:
        return value
    return None


def _classify_override(value) -> tuple[str, object]:
    """A caller's override (a Python value, or its spelling from a command line)."""
    if isinstance(value, bool):
        return "bool", value
    if isinstance(value, int):
        return "int", value
    if isinstance(value, float):
        return "float", value
    text = str(value).strip()
    if text in ("true", "false"):
        return "bool", text == "true"
    try:
        if text.lower().endswith("u"):
            return "uint", int(text[:-1], 0)
        return "int", int(text, 0)
    except ValueError:
        pass
    try:
        return "float", float(text)
    except ValueError:
        return "name", text


def _type_word(t: ir.Type) -> str:
    return "format" if t == ir.VOID else str(t)


def _param_hint(t: ir.Type) -> str:
    return {ir.FLOAT: "write a number like 0.5", ir.INT: "write an integer like 3",
            ir.UINT: "write a non-negative integer like 3u", ir.BOOL: "write true or false"}.get(
        t, f"write a format name: {' '.join(FORMATS)}")


def _show(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _show_all(values: Iterable) -> str:
    return "{" + ", ".join(_show(v) for v in values) + "}"


def _show_literal(v: ast.Expr) -> str:
    s = v.span
    if s.line == s.end_line and s.end_column > s.column:
        return f"'{s.source_line[s.column - 1:s.end_column - 1]}'"
    return "this value"


# ---------------------------------------------------------------------------------------------
# Shader code: names, types and the IR
# ---------------------------------------------------------------------------------------------


@dataclass
class _Context:
    """Where a body runs.  A pass body checks its needs on the spot; a function body records
    them (``_Uses``) and every pass that calls it checks them at the call."""

    pass_name: Optional[str] = None
    draw: Optional[ir.DrawKind] = None
    repeat: bool = False
    writes: tuple[str, ...] = ()
    reads: tuple[str, ...] = ()
    ret: ir.Type = ir.VOID
    function: Optional[str] = None

    @staticmethod
    def for_function(sig: _Signature) -> "_Context":
        return _Context(ret=sig.ret, function=sig.name)

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


@dataclass
class _Local:
    type: ir.Type
    span: Span
    loop_var: bool = False


class _BodyChecker:
    """Type checks one function or fragment body and builds its IR."""

    def __init__(self, low: _Lowerer, ctx: _Context):
        self.low = low
        self.ctx = ctx
        self.scopes: list[dict[str, _Local]] = [{}]
        self.loops = 0
        self.uses = _Uses()
        self.outputs: set[str] = set()       # targets this body writes

    # -- bodies ---------------------------------------------------------------------------------
    def function_body(self, sig: _Signature) -> tuple[ir.Stmt, ...]:
        for (name, t), p in zip(sig.params, sig.decl.params):
            self._declare_local(p.name, t)
        body = self.block(sig.decl.body, new_scope=False)
        if not sig.ret.is_void and not _always_returns(sig.decl.body):
            raise _err(sig.decl.name.span, f"function '{sig.name}' can reach its end without "
                       f"returning {_a(sig.ret)}", "end every path with `return VALUE;`")
        return body

    def block(self, stmts: list[ast.Stmt], new_scope: bool = True) -> tuple[ir.Stmt, ...]:
        if new_scope:
            self.scopes.append({})
        try:
            return tuple(self.stmt(s) for s in stmts)
        finally:
            if new_scope:
                self.scopes.pop()

    # -- statements -------------------------------------------------------------------------------
    def stmt(self, s: ast.Stmt) -> ir.Stmt:
        method = getattr(self, "_stmt_" + type(s).__name__)
        return method(s)

    def _stmt_VarDecl(self, s: ast.VarDecl) -> ir.Stmt:
        t = _shader_type(s.type)
        init = None
        if s.init is not None:
            init = self.expr(s.init)
            if init.type != t:
                raise _err(s.init.span, f"cannot initialise {t} '{s.name.name}' with "
                           f"{_a(init.type)}", _conversion_hint(init.type, t))
        self._declare_local(s.name, t)
        return ir.Declare(s.name.name, t, init)

    def _stmt_Assign(self, s: ast.Assign) -> ir.Stmt:
        if isinstance(s.target, ast.Name) and s.target.name in self.low.targets:
            return self._output(s)
        target = self._lvalue(s.target)
        value = self.expr(s.value)
        if s.op == "=":
            ok = value.type == target.type
        else:
            ok = binary_type(s.op[0], target.type, value.type) == target.type
        if not ok:
            what = "assign" if s.op == "=" else f"apply '{s.op}' with"
            raise _err(s.value.span, f"cannot {what} {_a(value.type)} to {_a(target.type)}",
                       _conversion_hint(value.type, target.type))
        return ir.Assign(target, s.op, value)

    def _stmt_ExprStmt(self, s: ast.ExprStmt) -> ir.Stmt:
        if not isinstance(s.expr, (ast.Call, ast.MethodCall)):
            raise _err(s.span, "this statement has no effect",
                       "a statement is a declaration, an assignment or a call")
        value = self.expr(s.expr, allow_void=True)
        if not isinstance(value, ir.Call):   # a constructor, conversion or load()/sample()
            raise _err(s.span, "this statement has no effect",
                       "use the value: assign it to a variable or a target")
        return ir.ExprStmt(value)

    def _stmt_If(self, s: ast.If) -> ir.Stmt:
        cond = self._condition(s.cond, "an if condition")
        then = self.block(s.then)
        other = self.block(s.other) if s.other is not None else ()
        return ir.If(cond, then, other)

    def _stmt_For(self, s: ast.For) -> ir.Stmt:
        t = _shader_type(s.var_type)
        if t not in (ir.INT, ir.UINT):
            raise _err(s.var_type.span, f"a loop counter is an int or a uint, not {t}",
                       "write `for (int i = 0; i < N; i++)`")
        start = self.expr(s.start)
        if start.type != t:
            raise _err(s.start.span, f"loop counter '{s.var.name}' is {_a(t)}, but it starts at "
                       f"{_a(start.type)}", _conversion_hint(start.type, t))
        bound = self._loop_bound(s, t)
        if s.step_var.name != s.var.name or not (isinstance(s.step, ast.Number)
                                                 and s.step.value == 1):
            raise _err(s.step_var.span, f"a loop steps its counter by one: "
                       f"`{s.var.name}++`", "loops are bounded: for (i = A; i < B; i++)")
        self.scopes.append({})
        self._declare_local(s.var, t, loop_var=True)
        self.loops += 1
        try:
            body = self.block(s.body)
        finally:
            self.loops -= 1
            self.scopes.pop()
        return ir.For(s.var.name, t, start, bound, body)

    def _loop_bound(self, s: ast.For, t: ir.Type) -> ir.Expr:
        c = s.cond
        if not (isinstance(c, ast.BinaryOp) and c.op == "<" and isinstance(c.left, ast.Name)
                and c.left.name == s.var.name):
            raise _err(c.span, f"a loop condition has the form `{s.var.name} < BOUND`",
                       "loops are bounded: for (int i = A; i < B; i++)")
        bound = self.expr(c.right)
        if bound.type != t:
            raise _err(c.right.span, f"loop counter '{s.var.name}' is {_a(t)}, but its bound is "
                       f"{_a(bound.type)}", _conversion_hint(bound.type, t))
        if not _is_static(bound):
            raise _err(c.right.span, "the loop bound is not a constant or a parameter",
                       "loop to a constant bound and break early, e.g. "
                       "`if (uint(i) >= num_lights) break;`")
        return bound

    def _stmt_Break(self, s: ast.Break) -> ir.Stmt:
        self._in_loop(s, "break")
        return ir.Break()

    def _stmt_Continue(self, s: ast.Continue) -> ir.Stmt:
        self._in_loop(s, "continue")
        return ir.Continue()

    def _in_loop(self, s: ast.Node, word: str) -> None:
        if not self.loops:
            raise _err(s.span, f"`{word}` outside a loop", "use it inside a for loop")

    def _stmt_Return(self, s: ast.Return) -> ir.Stmt:
        want = self.ctx.ret
        if s.value is None:
            if not want.is_void:
                raise _err(s.span, f"function '{self.ctx.function}' returns {_a(want)}",
                           f"write `return VALUE;` with {_a(want)} value")
            return ir.Return(None)
        if self.ctx.in_pass:
            raise _err(s.value.span, "a fragment body returns no value",
                       "write `return;` to end the fragment, or `discard;` to drop it")
        value = self.expr(s.value)
        if want.is_void or value.type != want:
            raise _err(s.value.span, f"function '{self.ctx.function}' returns "
                       f"{'nothing' if want.is_void else _a(want)}, not {_a(value.type)}",
                       _conversion_hint(value.type, want) if not want.is_void
                       else "write `return;`")
        return ir.Return(value)

    def _stmt_Discard(self, s: ast.Discard) -> ir.Stmt:
        return ir.Discard()

    def _condition(self, e: ast.Expr, what: str) -> ir.Expr:
        cond = self.expr(e)
        if cond.type != ir.BOOL:
            raise _err(e.span, f"{what} must be a bool, not {_a(cond.type)}",
                       "compare explicitly, e.g. `x != 0u` or `v > 0.0`")
        return cond

    # -- assignments and outputs ------------------------------------------------------------------
    def _lvalue(self, e: ast.Expr) -> ir.Expr:
        root = e
        while isinstance(root, (ast.Field, ast.Subscript)):
            root = root.base
        if not isinstance(root, ast.Name):
            raise _err(e.span, "this expression cannot be assigned to",
                       "assign to a local variable, one of its components or an element")
        local = self._lookup_local(root.name)
        if local is None:
            what = self._describe_global(root.name)
            raise _err(root.span, f"cannot assign to {what}",
                       "only local variables and function parameters can be assigned")
        if local.loop_var:
            raise _err(root.span, f"cannot assign to loop counter '{root.name}'",
                       "loops are bounded; use a separate variable")
        target = self.expr(e)
        if isinstance(target, ir.Swizzle) and len(set(target.components)) != \
                len(target.components):
            raise _err(e.span, "a swizzle written to cannot repeat a component",
                       "write each component once, e.g. v.xy = …")
        return target

    def _describe_global(self, name: str) -> str:
        low = self.low
        if name in low.params:
            return f"parameter '{name}' (parameters are constant)"
        if name in STAGE_INPUTS:
            return f"stage input '{name}' (inputs are read-only)"
        if name in _RESERVED:
            return f"'{name}' ({_RESERVED[name]}, read-only)"
        if name in low.globals:
            return f"{low.globals[name].kind} '{name}'"
        return f"unknown name '{name}'"

    def _output(self, s: ast.Assign) -> ir.Stmt:
        name = s.target.name
        t = self.low.targets[name]
        ctx = self.ctx
        if not ctx.in_pass:
            raise _err(s.target.span, f"function '{ctx.function}' writes target '{name}'",
                       "targets are written in fragment bodies; return the value instead")
        if not t.format.is_color:
            raise _err(s.target.span, f"'{name}' is a depth target and cannot be written as "
                       f"a colour", f"depth is written by the depth test: "
                       f"`depth {name} less write`")
        if name not in ctx.writes:
            raise _err(s.target.span, f"{ctx.describe()} writes target '{name}' but does not "
                       f"declare it", f"add `writes {name}` to the pass")
        if s.op != "=":
            raise _err(s.target.span, f"target '{name}' can only be assigned with '='",
                       "targets are write-only: compute the value in a local first")
        value = self.expr(s.value)
        self.outputs.add(name)
        return ir.Output(name, _widen_output(value, t, s.value.span), s.span)

    def _declare_local(self, name: ast.Name, t: ir.Type, loop_var: bool = False) -> None:
        n = name.name
        prev = self._lookup_local(n)
        if prev is not None:
            raise _err(name.span, f"'{n}' is already declared (line {prev.span.line})",
                       "rename this variable; names are not shadowed")
        clash = _reserved_meaning(n) or (_a(self.low.globals[n].kind)
                                         if n in self.low.globals else None)
        if clash:
            raise _err(name.span, f"'{n}' is already {clash}",
                       f"rename this variable (e.g. '{n}_')")
        self.scopes[-1][n] = _Local(t, name.span, loop_var)

    def _lookup_local(self, name: str) -> Optional[_Local]:
        for scope in reversed(self.scopes):
            if name in scope:
                return scope[name]
        return None

    # -- expressions ------------------------------------------------------------------------------
    def expr(self, e: ast.Expr, allow_void: bool = False) -> ir.Expr:
        method = getattr(self, "_expr_" + type(e).__name__)
        result = method(e)
        if result.type.is_void and not allow_void:
            raise _err(e.span, "this call returns no value", "use it as a statement")
        return result

    def _expr_Number(self, e: ast.Number) -> ir.Expr:
        t = {"float": ir.FLOAT, "int": ir.INT, "uint": ir.UINT}[e.kind]
        return ir.Const(t, e.value)

    def _expr_Bool(self, e: ast.Bool) -> ir.Expr:
        return ir.Const(ir.BOOL, e.value)

    def _expr_Name(self, e: ast.Name) -> ir.Expr:
        n = e.name
        local = self._lookup_local(n)
        if local is not None:
            return ir.Var(n, local.type, "local")
        low = self.low
        if n in low.params:
            p = low.params[n]
            if p.type == ir.VOID:
                raise _err(e.span, f"parameter '{n}' is a format, not a value",
                           "format parameters are used in target declarations")
            return ir.Var(n, p.type, "param")
        if n in STAGE_INPUTS:
            return self._stage_input(e)
        if n in low.targets:
            raise _err(e.span, f"target '{n}' is not a value",
                       f"read it with load({n}) or sample({n}, uv); write it with `{n} = …;`")
        if n == "light":
            raise _err(e.span, "`light` is read by field", "e.g. light.position, light.index")
        if n == "lights":
            raise _err(e.span, "`lights` is read by index and field", "e.g. lights[i].position")
        if n in low.pack_specs:
            raise _err(e.span, f"packing '{n}' is not a value",
                       f"call its functions ({n}.fn(…)) or read its constants ({n}.name)")
        if n in low.signatures or n in BUILTINS:
            raise _err(e.span, f"function '{n}' is not a value", f"call it: {n}(…)")
        raise _err(e.span, f"unknown name '{n}'", _did_you_mean(n, self._visible_names(),
                                                                "declare it before use"))

    def _visible_names(self) -> list[str]:
        names = [n for scope in self.scopes for n in scope]
        names += [n for n, p in self.low.params.items() if p.type != ir.VOID]
        names += list(STAGE_INPUTS)
        return names

    def _stage_input(self, e: ast.Name) -> ir.Expr:
        inp = STAGE_INPUTS[e.name]
        if inp.where is Where.SCENE:
            if self.ctx.in_pass and self.ctx.draw is not ir.DrawKind.SCENE:
                raise _err(e.span, f"'{e.name}' exists only in scene draws, and "
                           f"{self.ctx.describe()} does not draw the scene",
                           "store it in a target in a scene pass and load() it here")
            self.uses.scene.append((e.name, e.span))
        return ir.Var(e.name, inp.type, "input")

    def _expr_UnaryOp(self, e: ast.UnaryOp) -> ir.Expr:
        if e.op == "-" and isinstance(e.operand, ast.Number):
            # A negative literal is a literal (matters for folding and for -2147483648).
            t = self._expr_Number(e.operand).type
            value = -e.operand.value
            return ir.Const(t, value & 0xFFFFFFFF if t == ir.UINT else value)
        operand = self.expr(e.operand)
        t = unary_type(e.op, operand.type)
        if t is None:
            raise _err(e.span, f"operator '{e.op}' does not apply to {_a(operand.type)}",
                       {"!": "'!' negates a bool", "~": "'~' inverts an int or uint"}.get(
                           e.op, "'-' negates a number or vector"))
        return operand if e.op == "+" else ir.Unary(e.op, operand, t)

    def _expr_BinaryOp(self, e: ast.BinaryOp) -> ir.Expr:
        left, right = self.expr(e.left), self.expr(e.right)
        t = binary_type(e.op, left.type, right.type)
        if t is None:
            raise _err(e.span, f"operator '{e.op}' cannot combine {_a(left.type)} and "
                       f"{_a(right.type)}", _operator_hint(e.op, left.type, right.type))
        return ir.Binary(e.op, left, right, t)

    def _expr_Conditional(self, e: ast.Conditional) -> ir.Expr:
        cond = self._condition(e.cond, "a ?: condition")
        then, other = self.expr(e.then), self.expr(e.other)
        if then.type != other.type:
            raise _err(e.span, f"the branches of ?: differ: {then.type} and {other.type}",
                       _conversion_hint(other.type, then.type))
        return ir.Ternary(cond, then, other, then.type)

    def _expr_Subscript(self, e: ast.Subscript) -> ir.Expr:
        if isinstance(e.base, ast.Name) and e.base.name == "lights" \
                and self._lookup_local("lights") is None:
            raise _err(e.span, "a light is read by field",
                       "e.g. lights[i].position; the schema lists the fields")
        base = self.expr(e.base)
        if not (base.type.is_vector or base.type.is_matrix):
            raise _err(e.base.span, f"{_A(base.type)} cannot be indexed",
                       "index a vector (v[i]) or a matrix column (m[i])")
        index = self._index_value(e.index)
        n = base.type.mat or base.type.size
        if isinstance(index, ir.Const) and not 0 <= index.value < n:
            raise _err(e.index.span, f"index {index.value} is out of range for {_a(base.type)}",
                       f"valid indices are 0 to {n - 1}")
        return ir.Index(base, index, base.type.element)

    def _index_value(self, e: ast.Expr) -> ir.Expr:
        index = self.expr(e)
        if index.type not in (ir.INT, ir.UINT):
            raise _err(e.span, f"an index is an int or a uint, not {_a(index.type)}",
                       _conversion_hint(index.type, ir.INT))
        return index

    def _expr_Field(self, e: ast.Field) -> ir.Expr:
        base = e.base
        if isinstance(base, ast.Name) and self._lookup_local(base.name) is None:
            if base.name == "light":
                return self._light_field(None, e)
            if base.name in self.low.pack_specs:
                return self.low.pack_constant(base, e.name)
        if isinstance(base, ast.Subscript) and isinstance(base.base, ast.Name) \
                and base.base.name == "lights" and self._lookup_local("lights") is None:
            return self._light_field(self._index_value(base.index), e)
        value = self.expr(base)
        return self._swizzle(value, e)

    def _light_field(self, index: Optional[ir.Expr], e: ast.Field) -> ir.Expr:
        name = e.name.name
        if index is None:
            if self.ctx.in_pass and not self.ctx.has_light:
                raise _err(e.base.span, f"`light` is only bound in light draws and repeat-per-"
                           f"light passes, and {self.ctx.describe()} is neither",
                           "index the light table instead: lights[i].FIELD, or add "
                           "`repeat per light` to the pass")
            self.uses.light.append(e.base.span)
            if name == LIGHT_INDEX:
                return ir.LightField(None, LIGHT_INDEX, ir.UINT)
        t = self.low.lights.field_type(name)
        if t is None:
            schema = [f.name for f in self.low.lights.fields]
            if name in LIGHT_FIELDS:
                hint = f"add `{name}: {LIGHT_FIELDS[name]}` to the `lights[…] {{ … }}` schema"
            else:
                hint = _did_you_mean(name, schema + ([LIGHT_INDEX] if index is None else []),
                                     f"the schema declares: {_listing(schema)}")
            raise _err(e.name.span, f"lights have no field '{name}'", hint)
        return ir.LightField(index, name, t)

    def _swizzle(self, value: ir.Expr, e: ast.Field) -> ir.Expr:
        name = e.name.name
        if not value.type.is_vector:
            raise _err(e.name.span, f"{_A(value.type)} has no field '{name}'",
                       "swizzles (.x, .rgb, …) apply to vectors")
        for sets in ("xyzw", "rgba", "stpq"):
            if all(c in sets for c in name):
                comps = "".join("xyzw"[sets.index(c)] for c in name)
                break
        else:
            raise _err(e.name.span, f"'{name}' is not a swizzle",
                       "use components from one of xyzw, rgba, stpq")
        if len(comps) > 4:
            raise _err(e.name.span, f"a swizzle has at most 4 components, not {len(comps)}",
                       "shorten it")
        too_far = [c for c in comps if "xyzw".index(c) >= value.type.size]
        if too_far:
            bad = name[comps.index(too_far[0])]
            raise _err(e.name.span, f"{_A(value.type)} has no component '{bad}'",
                       f"{_A(value.type)} has {value.type.size} components")
        if comps == "xyzw"[:value.type.size]:
            return value       # .xyz of a vec3 is the vector itself
        t = value.type.element if len(comps) == 1 else value.type.with_size(len(comps))
        return ir.Swizzle(value, comps, t)

    # -- calls ------------------------------------------------------------------------------------
    def _expr_Call(self, e: ast.Call) -> ir.Expr:
        name = e.func.name
        if self._lookup_local(name) is not None:
            raise _err(e.func.span, f"'{name}' is a variable, not a function",
                       "rename the variable or the function")
        if name in TYPE_NAMES:
            return self._construct(e)
        if name in TARGET_FUNCTIONS:
            return self._target_call(e)
        if name in self.low.signatures:
            return self._user_call(name, e.func.span, e.args, e.span)
        if name in BUILTINS:
            return self._builtin_call(e)
        raise _err(e.func.span, f"unknown function '{name}'",
                   _did_you_mean(name, list(BUILTINS) + list(self.low.signatures)
                                 + list(TARGET_FUNCTIONS),
                                 "builtins: " + " ".join(sorted(BUILTINS))))

    def _expr_MethodCall(self, e: ast.MethodCall) -> ir.Expr:
        obj = e.obj
        if not (isinstance(obj, ast.Name) and obj.name in self.low.pack_specs):
            shown = obj.name if isinstance(obj, ast.Name) else "this value"
            raise _err(obj.span, f"'{shown}' is not a packing, so it has no functions",
                       "only packings have functions: PACK.fn(…)")
        fn = f"{obj.name}_{e.method.name}"
        sig = self.low.signatures.get(fn)
        if sig is None or sig.pack != obj.name:
            own = [s.name[len(obj.name) + 1:] for s in self.low.signatures.values()
                   if s.pack == obj.name]
            raise _err(e.method.span, f"packing '{obj.name}' has no function "
                       f"'{e.method.name}'", _did_you_mean(e.method.name, own,
                                                           f"its functions: {_listing(own)}"))
        return self._user_call(fn, e.method.span, e.args, e.span,
                               shown=f"{obj.name}.{e.method.name}")

    def _user_call(self, name: str, name_span: Span, args: list[ast.Expr], span: Span,
                   shown: Optional[str] = None) -> ir.Expr:
        sig = self.low.signatures[name]
        shown = shown or name
        values = [self.expr(a) for a in args]
        if len(values) != len(sig.params):
            raise _err(name_span, f"'{shown}' takes {len(sig.params)} argument(s), "
                       f"not {len(values)}", f"{shown}({_params_text(sig.params)})")
        for (pname, pt), value, arg in zip(sig.params, values, args):
            if value.type != pt:
                raise _err(arg.span, f"argument '{pname}' of '{shown}' is {_a(pt)}, not "
                           f"{_a(value.type)}", _conversion_hint(value.type, pt))
        self._note_call(name, name_span)
        return ir.Call(name, tuple(values), sig.ret, builtin=False)

    def _note_call(self, name: str, span: Span) -> None:
        """Record a call; in a pass, check now what the callee needs (it is transitive)."""
        self.uses.calls.append((name, span))
        if not self.ctx.in_pass:
            return
        needs = self.low.uses[name]
        ctx = self.ctx
        if needs.scene and ctx.draw is not ir.DrawKind.SCENE:
            input_name, where = needs.scene[0]
            raise _err(span, f"'{name}' reads scene input '{input_name}' (line {where.line}), "
                       f"which {ctx.describe()} does not have",
                       "pass the value in as an argument, or call it from a scene pass")
        if needs.light and not ctx.has_light:
            raise _err(span, f"'{name}' reads `light` (line {needs.light[0].line}), which is "
                       f"not bound in {ctx.describe()}",
                       "call it from a light draw or a `repeat per light` pass")
        for target, where in needs.reads.items():
            if target not in ctx.reads:
                raise _err(span, f"'{name}' reads target '{target}' (line {where.line}), "
                           f"which pass '{ctx.pass_name}' does not declare",
                           f"add `reads {target}` to the pass")

    def _builtin_call(self, e: ast.Call) -> ir.Expr:
        name = e.func.name
        args = tuple(self.expr(a) for a in e.args)
        t = resolve_builtin(name, [a.type for a in args])
        if t is None:
            types = ", ".join(str(a.type) for a in args)
            raise _err(e.func.span, f"no version of '{name}' takes ({types})",
                       f"there are {describe_overloads(name)}; genType is float or vec2-4, "
                       f"genIType/genUType int/uint or ivec/uvec; no implicit conversions: "
                       f"write 1.0, not 1")
        return ir.Call(name, args, t, builtin=True)

    def _target_call(self, e: ast.Call) -> ir.Expr:
        name = e.func.name
        arity = {"load": (1, 2), "sample": (2,), "size": (1,)}[name]
        if len(e.args) not in arity or not isinstance(e.args[0], ast.Name):
            raise _err(e.span, f"'{name}' is called as {TARGET_FUNCTIONS[name].split(':')[0]}",
                       "its first argument is the name of a target")
        target = self._read_target(e.args[0])
        fmt = self.low.targets[target].format
        if name == "size":
            return ir.TargetSize(target, ir.IVEC2)
        if name == "load":
            coord = self._typed_arg(e.args[1], ir.IVEC2, "a load coordinate") \
                if len(e.args) == 2 else None
            return ir.Load(target, coord, target_read_type(fmt))
        if fmt.is_integer:
            raise _err(e.span, f"integer target '{target}' cannot be sampled",
                       f"read texels with load({target}) or load({target}, ivec2(…))")
        uv = self._typed_arg(e.args[1], ir.VEC2, "a sample coordinate")
        return ir.Sample(target, uv, target_read_type(fmt))

    def _typed_arg(self, e: ast.Expr, t: ir.Type, what: str) -> ir.Expr:
        value = self.expr(e)
        if value.type != t:
            raise _err(e.span, f"{what} is {_a(t)}, not {_a(value.type)}",
                       _conversion_hint(value.type, t))
        return value

    def _read_target(self, name: ast.Name) -> str:
        n = name.name
        if n not in self.low.targets:
            raise _err(name.span, f"unknown target '{n}'",
                       _did_you_mean(n, self.low.targets, "declare it with `target`"))
        ctx = self.ctx
        if ctx.in_pass and n not in ctx.reads:
            raise _err(name.span, f"{ctx.describe()} reads target '{n}' but does not "
                       f"declare it", f"add `reads {n}` to the pass")
        self.uses.reads.setdefault(n, name.span)
        return n

    # -- constructors -----------------------------------------------------------------------------
    def _construct(self, e: ast.Call) -> ir.Expr:
        t = _shader_type(e.func)
        args = [self.expr(a) for a in e.args]
        if not args:
            raise _err(e.span, f"{t}() needs arguments", f"e.g. {t}(0)")
        if any(a.type.is_matrix for a in args) and not t.is_matrix:
            raise _err(e.span, f"{_A(t)} cannot be built from a matrix",
                       "index the matrix (m[i]) for a column")
        if t.is_scalar:
            return self._construct_scalar(t, args, e)
        if t.is_matrix:
            return self._construct_matrix(t, args, e)
        return self._construct_vector(t, args, e)

    def _construct_scalar(self, t: ir.Type, args: list[ir.Expr], e: ast.Call) -> ir.Expr:
        if len(args) != 1 or not args[0].type.is_scalar:
            raise _err(e.span, f"{t}(…) converts one scalar",
                       "take a component first, e.g. float(v.x)")
        return _convert(args[0], t.scalar)

    def _construct_vector(self, t: ir.Type, args: list[ir.Expr], e: ast.Call) -> ir.Expr:
        if len(args) == 1:
            a = args[0]
            if a.type.is_scalar:
                return ir.Construct(t, (_convert(a, t.scalar),))
            if a.type.size < t.size:
                raise _err(e.span, f"{t}(…) needs {t.size} components; {_a(a.type)} has "
                           f"{a.type.size}", f"add the missing ones, e.g. {t}(v, 1.0)"
                           if t.scalar is ir.Scalar.FLOAT else "add the missing components")
            if a.type.size > t.size:     # vec3(v4): keep the leading components
                a = ir.Swizzle(a, "xyzw"[:t.size], a.type.with_size(t.size))
            return _convert(a, t.scalar)
        count = sum(a.type.size for a in args)
        if count != t.size:
            raise _err(e.span, f"{t}(…) needs {t.size} components, but the arguments have "
                       f"{count}", "use a swizzle to pass fewer components, e.g. v.xy")
        return ir.Construct(t, tuple(_convert(a, t.scalar) for a in args))

    def _construct_matrix(self, t: ir.Type, args: list[ir.Expr], e: ast.Call) -> ir.Expr:
        n = t.mat
        column = ir.Type(ir.Scalar.FLOAT, n)
        if len(args) == 1 and args[0].type == t:
            return args[0]
        if len(args) == 1 and (args[0].type == ir.FLOAT or args[0].type.is_matrix):
            return ir.Construct(t, (args[0],))
        if len(args) == n and all(a.type == column for a in args):
            return ir.Construct(t, tuple(args))
        if len(args) == n * n and all(a.type == ir.FLOAT for a in args):
            cols = tuple(ir.Construct(column, tuple(args[i * n:(i + 1) * n]))
                         for i in range(n))
            return ir.Construct(t, cols)
        raise _err(e.span, f"{t}(…) takes a float (diagonal), a matrix, {n} vec{n} columns "
                   f"or {n * n} floats", "no implicit conversions: write 1.0, not 1")


def _convert(value: ir.Expr, scalar: ir.Scalar) -> ir.Expr:
    """``value`` with its components converted to ``scalar`` (literals folded)."""
    t = value.type
    if t.scalar is scalar:
        return value
    target = ir.Type(scalar, t.size)
    if isinstance(value, ir.Const) and t.is_scalar:
        return ir.Const(target, _convert_literal(value.value, scalar))
    return ir.Construct(target, (value,))


def _convert_literal(v, scalar: ir.Scalar):
    if scalar is ir.Scalar.FLOAT:
        return float(v)
    if scalar is ir.Scalar.BOOL:
        return bool(v)
    if scalar is ir.Scalar.UINT and not isinstance(v, float):
        return int(v) & 0xFFFFFFFF       # uint(-1) wraps, as in GLSL
    return int(v)                        # float -> int truncates toward zero


def _widen_output(value: ir.Expr, target: ir.Target, span: Span) -> ir.Expr:
    """A colour write's value as the target's write type (vec4 / uvec4), padded with zeros."""
    fmt = target.format
    want = target_write_type(fmt)
    t = value.type
    if t.scalar is not want.scalar or t.is_matrix or t.size < fmt.channels:
        options = [str(ir.Type(want.scalar, n)) for n in range(fmt.channels, 5)]
        accepted = ", ".join(options[:-1]) + " or " + options[-1] if len(options) > 1 \
            else options[0]
        if t.scalar is not want.scalar and not t.is_matrix:
            hint = _conversion_hint(t, ir.Type(want.scalar, t.size))
        else:
            hint = f"the value needs at least {fmt.channels} components"
        raise _err(span, f"target '{target.name}' ({fmt.name}) takes {_a(accepted)}, "
                   f"not {_a(t)}", hint)
    if t.size == 4:
        return value
    zero = ir.Const(want.element, 0.0 if want.scalar is ir.Scalar.FLOAT else 0)
    return ir.Construct(want, (value,) + (zero,) * (4 - t.size))


def _is_static(e: ir.Expr) -> bool:
    """Known at compile time: literals, parameters, packing constants and arithmetic on them."""
    if isinstance(e, ir.Const):
        return True
    if isinstance(e, ir.Var):
        return e.kind == "param"
    if isinstance(e, ir.Unary):
        return _is_static(e.operand)
    if isinstance(e, ir.Binary):
        return _is_static(e.left) and _is_static(e.right)
    if isinstance(e, ir.Construct):
        return all(_is_static(a) for a in e.args)
    if isinstance(e, ir.Ternary):
        return _is_static(e.cond) and _is_static(e.then) and _is_static(e.other)
    return False


def _always_returns(stmts: list[ast.Stmt]) -> bool:
    if not stmts:
        return False
    last = stmts[-1]
    if isinstance(last, (ast.Return, ast.Discard)):
        return True
    if isinstance(last, ast.If) and last.other is not None:
        return _always_returns(last.then) and _always_returns(last.other)
    return False


def _params_text(params: list[tuple[str, ir.Type]]) -> str:
    return ", ".join(f"{t} {n}" for n, t in params)


def _conversion_hint(have: ir.Type, want: ir.Type) -> str:
    if have.is_void or want.is_void:
        return "check the value's type"
    if have.scalar is not want.scalar and have.size == want.size and not have.is_matrix:
        return f"no implicit conversions: write {want}(…) to convert"
    if have.is_vector and want.is_scalar:
        return "take one component with a swizzle, e.g. .x"
    if have.is_vector and want.is_vector and have.size > want.size:
        return f"keep the leading components with a swizzle, e.g. .{'xyzw'[:want.size]}"
    if want.is_vector and have.size < want.size:
        if want.scalar is ir.Scalar.FLOAT:
            return f"build the {want}, e.g. {want}(value, 1.0)" if have.size > 1 \
                else f"build the {want} with {want}(value)"
        return f"build it with {want}(…)"
    return f"the expected type is {want}"


def _operator_hint(op: str, a: ir.Type, b: ir.Type) -> str:
    if a.scalar is not b.scalar and {a.scalar, b.scalar} <= {ir.Scalar.FLOAT, ir.Scalar.INT,
                                                             ir.Scalar.UINT}:
        return "no implicit conversions between int, uint and float: write float(i), 1.0, 2u"
    if a.is_vector and b.is_vector and a.size != b.size:
        return "the vectors have different sizes; use a swizzle (.xyz) or a constructor"
    if op in ("&&", "||") or op == "!":
        return "logical operators take bools"
    if op in ("&", "|", "^", "<<", ">>", "%"):
        return f"'{op}' applies to int and uint values"
    if op in ("<", "<=", ">", ">="):
        return "comparisons take two scalars of the same type"
    return f"'{op}' needs operands of matching types"


# ---------------------------------------------------------------------------------------------
# Passes
# ---------------------------------------------------------------------------------------------

_SINGLE = (ast.Draw, ast.Writes, ast.Reads, ast.Depth, ast.BlendConstant, ast.Cull, ast.Offset,
           ast.Fragment, ast.RepeatPerLight)
_STMT_WORD = {ast.Draw: "draw", ast.Writes: "writes", ast.Reads: "reads", ast.Depth: "depth",
              ast.BlendConstant: "blend constant", ast.Cull: "cull", ast.Offset: "offset",
              ast.Fragment: "fragment", ast.RepeatPerLight: "repeat per light"}


class _PassLowerer:
    def __init__(self, low: _Lowerer, item: _PassItem):
        self.low = low
        self.decl = item.decl
        self.name = item.decl.name.name
        self.item = item
        self.group = item.group
        self.single: dict[type, ast.Node] = {}
        for s in self.decl.stmts:
            if isinstance(s, _SINGLE):
                if type(s) in self.single:
                    raise _err(s.span, f"pass '{self.name}' has two `{_STMT_WORD[type(s)]}` "
                               f"statements", "merge them into one")
                self.single[type(s)] = s

    def _all(self, kind: type) -> list:
        return [s for s in self.decl.stmts if isinstance(s, kind)]

    def lower(self) -> ir.Pass:
        draw = self._draw()
        writes = self._writes()
        reads = self._reads(writes)
        depth_target, depth = self._depth(reads)
        stencil = self._stencil(depth_target)
        blend = self._blend(writes)
        ctx = _Context(self.name, draw.kind, self.group is not None, writes, reads)
        body = self._fragment(ctx, writes)
        state = ir.PassState(depth, stencil, blend, self._blend_constant(), self._cull(),
                             self._offset())
        return ir.Pass(self.name, draw, state, writes, reads, depth_target, body, self.group,
                       self._clears(), self.decl.span, self._repeat_types())

    # -- draw --------------------------------------------------------------------------------
    def _draw(self) -> ir.Draw:
        d = self.single.get(ast.Draw)
        if d is None:
            raise _err(self.decl.name.span, f"pass '{self.name}' draws nothing",
                       "add `draw scene`, `draw lights as sphere` or `draw fullscreen`")
        if d.kind == "scene":
            material = ()
            if d.material is not None:
                if d.material.name not in _MATERIALS:
                    raise _err(d.material.span, f"unknown material '{d.material.name}'",
                               f"scene draws filter by {' or '.join(_MATERIALS)}")
                material = (d.material.name,)
            return ir.Draw(ir.DrawKind.SCENE, material=material)
        if d.kind == "fullscreen":
            return ir.Draw(ir.DrawKind.FULLSCREEN)
        types: list[str] = []
        for w in d.light_types:
            if w.value in types:
                raise _err(w.span, f"light type '{w.value}' is listed twice", "list it once")
            types.append(w.value)
        missing = [f for f in VOLUME_LIGHT_FIELDS[d.volume.value]
                   if self.low.lights.field_type(f) is None]
        if missing:
            raise _err(d.volume.span, f"{d.volume.value} light volumes need the light "
                       f"field(s) {', '.join(missing)}, which the lights schema lacks",
                       "add them to `lights[N] { … }`")
        return ir.Draw(ir.DrawKind.LIGHTS, volume=ir.Volume(d.volume.value),
                       light_types=tuple(t for t in LIGHT_TYPES if t in types),
                       light_set=self._light_set(d), scissor=d.scissor)

    def _light_set(self, d: ast.Draw) -> Optional[tuple[str, int]]:
        if d.light_set is None:
            return None
        pack, index = d.light_set
        decl = self.low.packs.get(pack.name)
        if decl is None:
            raise _err(pack.span, f"unknown packing '{pack.name}'",
                       _did_you_mean(pack.name, self.low.packs,
                                     "declare it with `pack NAME = channel_slots(…)`"))
        if decl.scheme.name != "channel_slots":
            raise _err(pack.span, f"packing '{pack.name}' is a {decl.scheme.name} packing; "
                       f"light sets come from channel_slots", "use a channel_slots packing")
        slots = self.low.pack_options[pack.name].get("slots", 4)
        k = self.low.integer(index, "a light set index", 0, int(slots) - 1)
        return pack.name, k

    # -- attachments ---------------------------------------------------------------------------
    def _target(self, name: ast.Name) -> ir.Target:
        t = self.low.targets.get(name.name)
        if t is None:
            raise _err(name.span, f"unknown target '{name.name}'",
                       _did_you_mean(name.name, self.low.targets, "declare it with `target`"))
        return t

    def _writes(self) -> tuple[str, ...]:
        stmt = self.single.get(ast.Writes)
        names = self._unique_targets(stmt, "writes")
        for n in (stmt.targets if stmt else ()):
            t = self._target(n)
            if not t.format.is_color:
                raise _err(n.span, f"'{n.name}' is a depth target and cannot be written as a "
                           f"colour", f"attach it with `depth {n.name} …`")
        return names

    def _reads(self, writes: tuple[str, ...]) -> tuple[str, ...]:
        stmt = self.single.get(ast.Reads)
        names = self._unique_targets(stmt, "reads")
        for n in (stmt.targets if stmt else ()):
            self._target(n)
            if n.name in writes:
                raise _err(n.span, f"pass '{self.name}' both writes and reads target "
                           f"'{n.name}'", "a pass cannot read a target it renders to; "
                           "write a copy in an earlier pass and read that")
        return names

    def _unique_targets(self, stmt, word: str) -> tuple[str, ...]:
        if stmt is None:
            return ()
        seen: list[str] = []
        for n in stmt.targets:
            if n.name in seen:
                raise _err(n.span, f"'{n.name}' is listed twice in `{word}`", "list it once")
            seen.append(n.name)
        return tuple(seen)

    def _depth(self, reads: tuple[str, ...]) -> tuple[Optional[str], ir.DepthState]:
        d = self.single.get(ast.Depth)
        if d is None:
            return None, ir.DepthState()
        t = self._target(d.target)
        if not t.format.has_depth:
            raise _err(d.target.span, f"'{t.name}' ({t.format.name}) is not a depth target",
                       "attach a d24s8 or d32f target")
        if d.func is None:
            return t.name, ir.DepthState()
        flags = [f.value for f in d.flags]
        for f in set(flags):
            if flags.count(f) > 1:
                raise _err(d.span, f"`{f}` is given twice", "give it once")
        if "write" in flags and "nowrite" in flags:
            raise _err(d.span, "depth is both `write` and `nowrite`", "choose one")
        write = "nowrite" not in flags
        if write and t.name in reads:
            raise _err(d.span, f"pass '{self.name}' writes depth to '{t.name}' while reading "
                       f"it", f"test without writing: `depth {t.name} {d.func.value} nowrite`")
        inside = None
        if d.inside is not None:
            cull = self.single.get(ast.Cull)
            if cull is None or cull.mode.value != "auto":
                raise _err(d.inside.span, "`inside FUNC` is the depth test of the lights that "
                           "`cull auto` draws with their back faces, but pass "
                           f"'{self.name}' does not `cull auto`",
                           "add `cull auto` or drop `inside`")
            inside = ir.CompareFunc(d.inside.value)
        return t.name, ir.DepthState(ir.CompareFunc(d.func.value), write, "clamp" in flags,
                                     inside)

    # -- stencil -------------------------------------------------------------------------------
    def _stencil(self, depth_target: Optional[str]) -> ir.StencilState:
        stmts = self._all(ast.Stencil)
        if not stmts:
            return ir.StencilState()
        self._require_stencil(stmts[0], depth_target)
        faces: dict[str, ir.StencilFace] = {}
        for s in stmts:
            face = self._stencil_face(s)
            names = (s.face.value,) if s.face is not None else ("front", "back")
            for n in names:
                if n in faces:
                    raise _err(s.span, f"the {n} stencil face is set twice",
                               "give each face one `stencil` statement")
                faces[n] = face
        return ir.StencilState(faces.get("front", ir.StencilFace()),
                               faces.get("back", ir.StencilFace()))

    def _require_stencil(self, s: ast.Stencil, depth_target: Optional[str]) -> None:
        hint = ("attach a d24s8 target with `depth T …` (or `depth T off` to use only its "
                "stencil)")
        if depth_target is None:
            raise _err(s.span, f"stencil state without a stencil target: pass '{self.name}' "
                       f"attaches no depth/stencil target", hint)
        fmt = self.low.targets[depth_target].format
        if not fmt.has_stencil:
            raise _err(s.span, f"stencil state without a stencil target: '{depth_target}' "
                       f"({fmt.name}) has no stencil bits", hint)

    def _stencil_face(self, s: ast.Stencil) -> ir.StencilFace:
        values: dict[str, object] = {}
        for item in s.items:
            if item.key in values:
                raise _err(item.span, f"`{item.key}` is given twice in this stencil block",
                           "give it once")
            if item.key == "func":
                values["func"] = ir.CompareFunc(item.value.value)
            elif item.key in ("fail", "zfail", "pass"):
                values[item.key] = ir.StencilOp(item.value.value)
            else:
                values[item.key] = self.low.integer(item.value, f"the stencil {item.key} "
                                                     f"value", 0, 255)
        return ir.StencilFace(
            func=values.get("func", ir.CompareFunc.ALWAYS), ref=values.get("ref", 0),
            read_mask=values.get("read", 0xFF), write_mask=values.get("write", 0xFF),
            fail=values.get("fail", ir.StencilOp.KEEP),
            zfail=values.get("zfail", ir.StencilOp.KEEP),
            zpass=values.get("pass", ir.StencilOp.KEEP))

    # -- blending ------------------------------------------------------------------------------
    def _blend(self, writes: tuple[str, ...]) -> tuple[tuple[str, ir.TargetBlend], ...]:
        """One entry per written target, in attachment order."""
        blends: dict[str, ir.TargetBlend] = {}
        masks: dict[str, tuple[bool, bool, bool, bool]] = {}
        for b in self._all(ast.Blend):
            t = self._written(b.target, writes, "blend")
            if t.name in blends:
                raise _err(b.target.span, f"target '{t.name}' is blended twice",
                           "give each target one `blend` statement")
            if b.rgb is not None and not t.format.blendable:
                raise _err(b.span, f"blend on an integer target: '{t.name}' ({t.format.name}) "
                           f"cannot be blended", "blend unorm or float targets; integer "
                           "targets are only overwritten")
            blends[t.name] = self._target_blend(b)
        for m in self._all(ast.Mask):
            t = self._written(m.target, writes, "mask")
            if t.name in masks:
                raise _err(m.target.span, f"target '{t.name}' is masked twice",
                           "give each target one `mask` statement")
            masks[t.name] = _write_mask(m, t)
        out = []
        for name in writes:
            b = blends.get(name, ir.TargetBlend())
            out.append((name, ir.TargetBlend(b.enabled, b.rgb, b.alpha,
                                             masks.get(name, b.write_mask))))
        return tuple(out)

    def _written(self, name: ast.Name, writes: tuple[str, ...], word: str) -> ir.Target:
        t = self._target(name)
        if name.name not in writes:
            raise _err(name.span, f"`{word}` for target '{name.name}', which pass '{self.name}' "
                       f"does not write", f"add `writes {name.name}` or remove the `{word}`")
        return t

    def _target_blend(self, b: ast.Blend) -> ir.TargetBlend:
        if b.rgb is None:
            return ir.TargetBlend(enabled=False)
        return ir.TargetBlend(True, _equation(b.rgb), _equation(b.alpha))

    def _blend_constant(self) -> tuple[float, float, float, float]:
        s = self.single.get(ast.BlendConstant)
        if s is None:
            return (0.0, 0.0, 0.0, 0.0)
        items = s.value.items if isinstance(s.value, ast.TupleLit) else [s.value] * 4
        if len(items) != 4:
            raise _err(s.value.span, f"the blend constant has 4 components, not {len(items)}",
                       "write `blend constant (r, g, b, a)` or one value for all four")
        return tuple(float(self.low.number(e, "a blend constant component")) for e in items)

    def _repeat_types(self) -> tuple[str, ...]:
        """``repeat per light TYPE …`` (on the pass or on its block): the light types the
        repeat group runs this pass for; () for every light."""
        stmt = self.single.get(ast.RepeatPerLight)
        own = list(stmt.light_types) if stmt is not None else []
        block = list(self.item.block_types)
        if own and block:
            raise _err(own[0].span, f"pass '{self.name}' is in a `repeat per light "
                       f"{' '.join(w.value for w in block)} {{ … }}` block and names light "
                       f"types again", "give the light types once, on the block or the pass")
        words = own or block
        types: list[str] = []
        for w in words:
            if w.value in types:
                raise _err(w.span, f"light type '{w.value}' is listed twice", "list it once")
            types.append(w.value)
        return tuple(t for t in LIGHT_TYPES if t in types)

    # -- other state ---------------------------------------------------------------------------
    def _cull(self) -> ir.CullMode:
        s = self.single.get(ast.Cull)
        if s is None:
            return ir.CullMode.NONE
        mode = ir.CullMode(s.mode.value)
        if mode is ir.CullMode.AUTO:
            d = self.single.get(ast.Draw)
            volume = d.volume.value if d is not None and d.volume is not None else None
            if d is None or d.kind != "lights" or volume not in ("sphere", "cone"):
                what = ("nothing" if d is None else "a screen quad" if volume == "quad" else
                        "scene geometry" if d.kind == "scene" else "a full-screen triangle")
                raise _err(s.span, f"`cull auto` chooses the faces of light volumes, but pass "
                           f"'{self.name}' draws {what}",
                           "use it with `draw lights as sphere` or `draw lights as cone`; "
                           "otherwise write `cull back`, `cull front` or `cull none`")
        return mode

    def _offset(self) -> Optional[ir.PolygonOffset]:
        s = self.single.get(ast.Offset)
        if s is None:
            return None
        return ir.PolygonOffset(float(self.low.number(s.factor, "the offset factor")),
                                float(self.low.number(s.units, "the offset units")))

    def _clears(self) -> tuple[tuple[str, ir.Clear], ...]:
        out: dict[str, ir.Clear] = {}
        for c in self._all(ast.PassClear):
            t = self._target(c.target)
            if t.name in out:
                raise _err(c.target.span, f"target '{t.name}' is cleared twice in pass "
                           f"'{self.name}'", "merge the clears")
            out[t.name] = self.low.clear(c.clear, t.name, t.format)
        return tuple(out.items())

    # -- fragment ------------------------------------------------------------------------------
    def _fragment(self, ctx: _Context, writes: tuple[str, ...]) -> tuple[ir.Stmt, ...]:
        frag = self.single.get(ast.Fragment)
        if frag is None:
            if writes:
                raise _err(self.single[ast.Writes].span, f"pass '{self.name}' writes "
                           f"{', '.join(writes)} but has no fragment body",
                           "add `fragment { … }` that assigns the targets, or drop `writes`")
            return ()
        checker = _BodyChecker(self.low, ctx)
        body = checker.block(frag.body)
        missing = [w for w in writes if w not in checker.outputs]
        if missing:
            raise _err(self.single[ast.Writes].span, f"pass '{self.name}' declares `writes "
                       f"{missing[0]}` but its fragment body never writes it",
                       f"assign it: `{missing[0]} = …;`, or drop it from `writes`")
        return body


def _equation(eq: ast.BlendEq) -> ir.BlendEquation:
    op = ir.BlendOp(eq.op.value)
    if op in (ir.BlendOp.MIN, ir.BlendOp.MAX):
        if eq.src is not None:
            raise _err(eq.src.span, f"`{op.value}` blending ignores factors",
                       f"write just `{op.value}`")
        return ir.BlendEquation(op)
    if eq.src is None:
        raise _err(eq.span, f"`{op.value}` blending needs factors",
                   f"e.g. `{op.value}(one, one)` or `{op.value}(src_alpha, one_minus_src_alpha)`")
    return ir.BlendEquation(op, ir.BlendFactor(eq.src.value), ir.BlendFactor(eq.dst.value))


def _write_mask(m: ast.Mask, t: ir.Target) -> tuple[bool, bool, bool, bool]:
    text = m.channels.name
    if text == "none":
        return (False, False, False, False)
    channels = "rgba"[:t.format.channels]
    if not all(c in "rgba" for c in text) or len(set(text)) != len(text):
        raise _err(m.channels.span, f"'{text}' is not a channel mask",
                   "list channels from r, g, b, a once each (e.g. `rg`), or write `none`")
    for c in text:
        if c not in channels:
            raise _err(m.channels.span, f"target '{t.name}' ({t.format.name}) has no "
                       f"{c} channel", f"its channels are {channels}")
    return tuple(c in text for c in "rgba")
