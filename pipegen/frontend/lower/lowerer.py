"""Lowering: ``ast.Module`` -> ``ir.Technique``.

This is where every user-facing check of a technique happens: includes, names, parameter
values, formats, the light schema, packings, the types of all shader code, and the structural
rules of passes (what a pass may read, write, attach, blend).  Anything wrong raises a
``PipegenError`` located at the token the user wrote.

Phases, in order (each may rely on the ones before):

1. collect  -- follow includes, sort declarations by kind, number the repeat groups
               (``lowering/collect.py``)
2. params   -- declared values, overrides from the caller, allowed sets (``lowering/params.py``)
3. lights, targets, output
4. packings -- ``packing.build`` generates functions (parsed like user code) and constants
5. functions -- signatures first, then bodies (so order and mutual calls do not matter),
                then recursion and what each function needs transitively (bodies:
                ``lowering/expressions.py`` and ``lowering/statements.py``)
6. passes   -- draw, attachments, fixed-function state, fragment body (``lowering/passes.py``);
               then the passes and targets whose `if COND` is false are dropped (every pass is
               checked first, present or not; ``lowering/conditions.py``)
7. expectations -- ``expect`` statements: names and scene files checked
                (``lowering/expectations.py``)

This module holds the entry point and the declarations (phases 2-5 and the order of all seven);
``lowering/names.py`` what the parts share (errors, signatures, contexts, reserved names).

The IR keeps technique parameters as ``Var(kind="param")`` in shader code (the specialise pass
folds them); everywhere else (sizes, clears, formats) their values are substituted here.
``ir.Param.default`` holds the value the technique is compiled with (an override if given).
Format-valued parameters have type ``ir.VOID`` and a ``str`` value: they are not shader values.
"""

from __future__ import annotations

import dataclasses
from typing import Optional, Union

from pipegen.frontend import ast, parse as syntax
from pipegen.ir import nodes as ir
from pipegen.core import sources
from pipegen.ir.builtins import LIGHT_FIELDS
from pipegen.core.diagnostics import Span
from pipegen.core.formats import FORMATS, Format
from pipegen.packing.base import SCHEMES as SCHEME_NAMES
from pipegen.frontend.lower.collect import Collector, Decls, PassItem
from pipegen.frontend.lower.combinations import check_shadow_volume_combinations
from pipegen.frontend.lower.conditions import holds, spelling
from pipegen.frontend.lower.expectations import lower_expectations
from pipegen.frontend.lower.materials import lower_material_table
from pipegen.frontend.lower.names import (
    SAMPLE_COUNTS, Loader, a_or_an, Context, did_you_mean, error, generated_by, Global, listing,
    param_type_name, reserved_meaning, shader_type, show_number, Signature, Uses)
from pipegen.frontend.lower.params import ParamBuilder
from pipegen.frontend.lower.passes import PassLowerer
from pipegen.frontend.lower.statements import BodyChecker


def lower(module: ast.Module, filename: str, params: Optional[dict] = None,
          loader: Optional[Loader] = None) -> ir.Technique:
    """Resolve, check and lower a parsed technique.

    ``params`` overrides parameter defaults (values or their source spelling, e.g. ``"0.5"``);
    ``loader(path) -> text`` reads included files (default: from disk).
    """
    return _Lowerer(filename, dict(params or {}), loader or _read_file).run(module)


def _read_file(path: str) -> str:
    return sources.read_source(path)


class _Lowerer:
    def __init__(self, filename: str, overrides: dict, loader: Loader):
        self.filename = filename
        self.overrides = overrides
        self.loader = loader
        self.globals: dict[str, Global] = {}
        self.params: dict[str, ir.Param] = {}
        self.targets: dict[str, ir.Target] = {}
        self.lights = ir.LightTable((), 0)
        self.materials: Optional[ir.MaterialTable] = None
        self.packs: dict[str, ast.PackDecl] = {}
        self.pack_specs: dict[str, object] = {}
        self.pack_options: dict[str, dict] = {}
        self.pack_schemes: dict[str, str] = {}     # the scheme (a parameter may choose it)
        self.signatures: dict[str, Signature] = {}
        self.bodies: dict[str, tuple[ir.Stmt, ...]] = {}
        self.uses: dict[str, Uses] = {}          # per function, transitive after phase 5

    def run(self, module: ast.Module) -> ir.Technique:
        collector = Collector(self.loader)
        collector.module(module, self.filename)
        d = collector.decls
        tech = self._technique_line(module, d)
        for name, kind in d.named:   # all at once, so a clash is reported where it is later
            self._declare(name, kind)
        params = self._params(d.params)
        self._lights(d.lights)
        self.materials = lower_material_table(d.materials, self.lights)
        targets = self._targets(d.targets)
        output = self._output(d.outputs, tech)
        self._packings(d.packs)
        self._functions(d.functions)
        passes = self._passes(d.passes)
        targets = self._present_targets(d.targets, targets, passes, output)
        return ir.Technique(
            name=tech.name.name, title=tech.title, params=params, targets=targets,
            lights=self.lights, packings=self._ir_packings(),
            functions=self._ir_functions(user=True), passes=passes, output=output,
            source=self.filename, materials=self.materials,
            expectations=lower_expectations(d.expects, (t.name for t in targets)))

    def _declare(self, name: ast.Name, kind: str) -> None:
        """Enter a top-level name; parameters, targets, packings and functions share one
        namespace because shader code refers to all of them by bare name."""
        n = name.name
        if n in self.globals:
            prev = self.globals[n]
            raise error(name.span,
                        f"duplicate name '{n}': already declared as {a_or_an(prev.kind)}",
                        f"the first declaration is at {prev.span.file}:{prev.span.line}; "
                        f"rename one of them")
        reserved = reserved_meaning(n)
        if reserved:
            raise error(name.span, f"'{n}' is reserved: it is {reserved}",
                        f"choose another name for this {kind}")
        self.globals[n] = Global(kind, name.span)

    # -- technique line ------------------------------------------------------------------------
    def _technique_line(self, module: ast.Module, d: Decls) -> ast.TechniqueDecl:
        first = module.items[0] if module.items else None
        if d.technique is None or first is not d.technique:
            span = first.span if first is not None else module.span
            raise error(span, "a technique file starts with `technique NAME \"title\"`",
                        "add e.g. `technique forward \"Single-pass forward\"` as its first line")
        return d.technique

    # -- parameters ----------------------------------------------------------------------------
    def _params(self, decls: list[ast.ParamDecl]) -> tuple[ir.Param, ...]:
        for decl in decls:
            self.params[decl.name.name] = ParamBuilder(decl).build()
        for name, value in self.overrides.items():
            if name not in self.params:
                raise error(None, f"unknown parameter '{name}'",
                            f"{self.filename} declares: {listing(self.params)}")
            p = self.params[name]
            decl = next(d for d in decls if d.name.name == name)
            self.params[name] = ParamBuilder(decl).override(p, value)
        return tuple(self.params.values())

    # -- values in declarations ----------------------------------------------------------------
    def number(self, e: ast.Expr, what: str, integer: bool = False) -> Union[int, float]:
        """A numeric value in a declaration: a literal, a parameter, or ``PACK.constant``."""
        if isinstance(e, ast.Number):
            if integer and e.kind == "float":
                raise error(e.span, f"{what} must be an integer, not {show_number(e)}",
                            f"write {int(e.value)}")
            return e.value
        if isinstance(e, ast.Name) and e.name in self.params:
            p = self.params[e.name]
            ok = (ir.INT, ir.UINT) if integer else (ir.INT, ir.UINT, ir.FLOAT)
            if p.type not in ok:
                raise error(e.span, f"{what} must be {'an integer' if integer else 'a number'}, "
                            f"but parameter '{e.name}' is {a_or_an(param_type_name(p))}",
                            "use a literal or a parameter of a numeric type")
            return p.default
        if isinstance(e, ast.Field) and isinstance(e.base, ast.Name) \
                and e.base.name in self.pack_specs:
            const = self.pack_constant(e.base, e.name)
            if not const.type.is_scalar or const.type == ir.BOOL:
                raise error(e.span, f"{what} must be a number, not {a_or_an(const.type)}",
                            "use a numeric constant")
            if integer and const.type.scalar is not ir.Scalar.INT \
                    and const.type.scalar is not ir.Scalar.UINT:
                raise error(e.span, f"{what} must be an integer, not {a_or_an(const.type)}",
                            "use an integer constant")
            return const.value
        if isinstance(e, ast.Name):
            raise error(e.span, f"unknown parameter '{e.name}' in {what}",
                        did_you_mean(e.name, self.params, "declare it with `param NAME = VALUE`"))
        raise error(e.span, f"{what} must be a number", "write a number or a parameter name")

    def integer(self, e: ast.Expr, what: str, lo: int, hi: Optional[int] = None) -> int:
        value = int(self.number(e, what, integer=True))
        if value < lo or (hi is not None and value > hi):
            bound = f"between {lo} and {hi}" if hi is not None else f"at least {lo}"
            raise error(e.span, f"{what} must be {bound}, not {value}", f"use a value {bound}")
        return value

    # -- light table ---------------------------------------------------------------------------
    def _lights(self, decls: list[ast.LightsDecl]) -> None:
        if not decls:
            return
        if len(decls) > 1:
            raise error(decls[1].span, "the light table is declared twice",
                        f"the first `lights[…]` is on line {decls[0].span.line}")
        decl = decls[0]
        capacity = self.integer(decl.capacity, "the light capacity", 1)
        fields: list[ir.LightAttr] = []
        for f in decl.fields:
            name = f.name.name
            if name not in LIGHT_FIELDS:
                raise error(f.name.span, f"lights have no field '{name}'",
                            did_you_mean(name, LIGHT_FIELDS,
                                         f"light fields: {listing(LIGHT_FIELDS)}"))
            if any(a.name == name for a in fields):
                raise error(f.name.span, f"light field '{name}' is declared twice",
                            "list each field once")
            want = LIGHT_FIELDS[name]
            if ir.parse_type(f.type.name) != want:
                raise error(f.type.span, f"light field '{name}' has type {want}, "
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
                raise error(opt.span, f"target '{decl.name.name}' has two "
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
                raise error(name.span, f"parameter '{n}' is {a_or_an(param_type_name(p))}, "
                            f"not a format", "declare it like `param fmt = rgba16f`")
            if p.default not in FORMATS:
                what = "the packing scheme" if p.default in SCHEME_NAMES else "the word"
                raise error(name.span, f"parameter '{n}' holds {what} "
                                      f"'{p.default}', not a format",
                            "declare a format parameter like `param fmt = rgba16f`")
            return FORMATS[p.default]
        if n not in FORMATS:
            raise error(name.span, f"unknown format '{n}'",
                        did_you_mean(n, FORMATS, f"formats: {' '.join(FORMATS)}"))
        return FORMATS[n]

    def _scale(self, opt: ast.SizeRel) -> float:
        if opt.scale is None:
            return 1.0
        scale = float(self.number(opt.scale, "a size scale"))
        if not 0.0 < scale <= 16.0:
            raise error(opt.scale.span, f"size scale {scale:g} is out of range",
                        "scale the output size by a factor in (0, 16]")
        return scale

    def _samples(self, opt: ast.Samples) -> int:
        n = self.integer(opt.value, "the sample count", 1)
        if n not in SAMPLE_COUNTS:
            raise error(opt.value.span, f"{n} samples per pixel is not supported",
                        f"use one of {', '.join(map(str, SAMPLE_COUNTS))}")
        return n

    def clear(self, spec: ast.ClearSpec, target: str, fmt: Format) -> ir.Clear:
        """A clear as written (parts not mentioned stay None)."""
        if spec.color is not None or spec.all is not None:
            if not fmt.is_color:
                raise error(spec.span, f"depth target '{target}' is cleared with "
                            f"`clear depth D` (not a colour)",
                            "write e.g. `clear depth 1.0 stencil 0`" if fmt.has_stencil
                            else "write e.g. `clear depth 1.0`")
            return ir.Clear(color=self._clear_color(spec, target, fmt))
        if not fmt.has_depth:
            raise error(spec.span, f"colour target '{target}' ({fmt.name}) has no depth or "
                        f"stencil to clear", "clear a colour target with `clear (r, g, b, a)`")
        depth = None
        if spec.depth is not None:
            depth = float(self.number(spec.depth, "a depth clear value"))
            if not 0.0 <= depth <= 1.0:
                raise error(spec.depth.span, f"depth clear value {depth:g} is outside [0, 1]",
                            "depth is cleared to a value in [0, 1], usually 1.0")
        stencil = None
        if spec.stencil is not None:
            if not fmt.has_stencil:
                raise error(spec.stencil.span, f"target '{target}' ({fmt.name}) has no "
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
                raise error(spec.color.span, f"target '{target}' ({fmt.name}) has "
                            f"{fmt.channels} channel(s), but the clear colour has {len(items)}",
                            f"give {fmt.channels} or 4 values, or one value for all channels")
        values = [float(self.number(e, "a clear colour component")) for e in items]
        if fmt.is_integer:
            for e, v in zip(items, values):
                if v != int(v) or v < 0:
                    raise error(e.span, f"integer target '{target}' is cleared to whole "
                                f"numbers, not {v:g}", "use values like 0 or 255")
        return tuple(values + [0.0] * (4 - len(values)))

    # -- output --------------------------------------------------------------------------------
    def _output(self, decls: list[ast.OutputDecl], tech: ast.TechniqueDecl) -> str:
        if len(decls) > 1:
            raise error(decls[1].span, "the output target is declared twice",
                        f"the first `output` is on line {decls[0].span.line}")
        if not decls:
            if "color" in self.targets and self.targets["color"].format.is_color:
                return "color"
            raise error(tech.span, "the technique has no output target",
                        "declare `output NAME` or a colour target named color")
        name = decls[0].name
        t = self.targets.get(name.name)
        if t is None:
            raise error(name.span, f"output target '{name.name}' is not declared",
                        did_you_mean(name.name, self.targets, "declare it with `target`"))
        if not t.format.is_color:
            raise error(name.span, f"output target '{name.name}' is a depth target",
                        "the output is a colour target")
        return name.name

    # -- packings ------------------------------------------------------------------------------
    def _packings(self, decls: list[ast.PackDecl]) -> None:
        if not decls:
            return
        # imported per call: the front end's tests stand a stub in for the schemes
        from pipegen.packing.schemes import SCHEMES, build
        for decl in decls:
            self._packing(decl, SCHEMES, build)

    def _packing(self, decl: ast.PackDecl, schemes, build) -> None:
        name, scheme = decl.name.name, decl.scheme.name
        if scheme in self.params:      # `pack nrm = encoding(…)`: the scheme a parameter holds
            p = self.params[scheme]
            if p.type != ir.VOID:
                raise error(decl.scheme.span, f"parameter '{scheme}' is "
                            f"{a_or_an(param_type_name(p))}, not a packing scheme",
                            "declare it like `param encoding = octahedral in {kircher, "
                            "octahedral}`")
            scheme = str(p.default)
        if scheme not in schemes:
            raise error(decl.scheme.span, f"unknown packing scheme '{scheme}'",
                        did_you_mean(scheme, schemes, f"schemes: {listing(schemes)}"))
        options = self._pack_options(decl.options)
        target_format = None
        if "target" in options:
            target_format = self.targets[options["target"]].format
        spec = build(name, scheme, options, target_format, decl.scheme.span)
        self.packs[name] = decl
        self.pack_schemes[name] = scheme
        self.pack_specs[name] = spec
        self.pack_options[name] = options
        with generated_by(decl):
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
                raise error(opt.key.span, f"option '{key}' is given twice", "keep one")
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
                raise error(value.span, f"unknown target '{shown}'",
                            did_you_mean(shown, self.targets, "declare it with `target`"))
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
            raise error(const.span, f"packing '{pack.name}' has no constant '{const.name}'",
                        f"its constants: {listing(spec.constants)}")
        t, value = spec.constants[const.name]
        return ir.Const(t, value)

    def _ir_packings(self) -> tuple[ir.Packing, ...]:
        out = []
        for name, decl in self.packs.items():
            spec = self.pack_specs[name]
            functions = tuple(self._ir_function(s) for s in self._ordered_signatures()
                              if s.pack == name)
            constants = tuple((k, ir.Const(t, v)) for k, (t, v) in spec.constants.items())
            out.append(ir.Packing(name, self.pack_schemes[name], _freeze(self.pack_options[name]),
                                  functions, constants, spec.capacity, spec.error,
                                  tuple(spec.notes or ()), decl.span))
        return tuple(out)

    # -- functions -----------------------------------------------------------------------------
    def _functions(self, decls: list[ast.FunctionDef]) -> None:
        for decl in decls:
            self._signature(decl)
        for sig in list(self.signatures.values()):
            checker = BodyChecker(self, Context.for_function(sig))
            with generated_by(self.packs[sig.pack] if sig.pack is not None else None):
                self.bodies[sig.name] = checker.function_body(sig)
            self.uses[sig.name] = checker.uses
        self._close_uses()

    def _signature(self, decl: ast.FunctionDef, pack: Optional[ast.PackDecl] = None) -> None:
        if pack is not None:   # user functions were entered with the other top-level names
            self._declare_generated(decl.name.name, pack)
        ret = shader_type(decl.ret, allow_void=True)
        params: list[tuple[str, ir.Type]] = []
        for p in decl.params:
            if any(n == p.name.name for n, _ in params):
                raise error(p.name.span, f"parameter '{p.name.name}' is declared twice",
                            "rename one of them")
            params.append((p.name.name, shader_type(p.type)))
        self.signatures[decl.name.name] = Signature(
            decl.name.name, params, ret, decl, pack.name.name if pack is not None else None)

    def _declare_generated(self, name: str, pack: ast.PackDecl) -> None:
        if name in self.globals:
            raise error(pack.name.span, f"packing '{pack.name.name}' defines function "
                        f"'{name}', which is already declared as "
                        f"{a_or_an(self.globals[name].kind)}",
                        "rename the packing or the other declaration")
        self.globals[name] = Global("function", pack.span)

    def _close_uses(self) -> None:
        """Make every function's ``Uses`` transitive and reject recursion (GLSL has none)."""
        done: set[str] = set()

        def visit(name: str, path: tuple[str, ...]) -> None:
            if name in done:
                return
            for callee, span in self.uses[name].calls:
                if callee in path or callee == name:
                    cycle = " -> ".join(path + (name, callee))
                    raise error(span, f"recursive call of '{callee}' ({cycle})",
                                "shader code cannot recurse; rewrite it as a bounded loop")
                visit(callee, path + (name,))
                self.uses[name].merge(self.uses[callee])
            done.add(name)

        for name in self.signatures:
            visit(name, ())

    def _ordered_signatures(self) -> list[Signature]:
        """Callees before callers, so backends can emit functions without prototypes."""
        order: list[Signature] = []
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

    def _ir_function(self, sig: Signature) -> ir.Function:
        return ir.Function(sig.name, tuple(sig.params), sig.ret, self.bodies[sig.name],
                           sig.decl.span)

    def _ir_functions(self, user: bool) -> tuple[ir.Function, ...]:
        return tuple(self._ir_function(s) for s in self._ordered_signatures()
                     if (s.pack is None) == user)

    # -- passes --------------------------------------------------------------------------------
    def _passes(self, items: list[PassItem]) -> tuple[ir.Pass, ...]:
        names: dict[str, Span] = {}
        out, present = [], []
        for item in items:
            name = item.decl.name
            if name.name in names:
                raise error(name.span, f"duplicate pass name '{name.name}'",
                            f"the first pass '{name.name}' is on line {names[name.name].line}")
            names[name.name] = name.span
            lowered = PassLowerer(self, item).lower()   # checked whether present or not
            if all([holds(c, self.params) for c in item.conditions]):
                out.append(lowered)
                present.append(item)
        check_shadow_volume_combinations(out, present)
        return _renumber_groups(out)

    def _present_targets(self, decls: list[ast.TargetDecl], targets: tuple[ir.Target, ...],
                         passes: tuple[ir.Pass, ...], output: str) -> tuple[ir.Target, ...]:
        """The targets whose condition holds (all of them without conditions); a pass, a
        packing or the output using one whose condition does not is an error."""
        absent = {d.name.name: d.condition for d in decls
                  if d.condition is not None and not holds(d.condition, self.params)}
        if not absent:
            return targets
        why = lambda t: (f"target '{t}', which is present only if {spelling(absent[t])} "
                         f"(false here)")
        if output in absent:
            raise error(absent[output].span, f"the output is {why(output)}",
                        "the output target cannot have a condition")
        for p in passes:
            used = set(p.reads) | set(p.writes) | {p.depth_target} | {t for t, _ in p.clears}
            for t in sorted(used & absent.keys()):
                raise error(p.span, f"pass '{p.name}' uses {why(t)}",
                            "give the pass a condition that implies the target's")
        for name, options in self.pack_options.items():
            if options.get("target") in absent:
                raise error(self.packs[name].span, f"packing '{name}' is for "
                            f"{why(options['target'])}", "drop the target's condition")
        return tuple(t for t in targets if t.name not in absent)


def _renumber_groups(passes: list[ir.Pass]) -> tuple[ir.Pass, ...]:
    """Repeat groups numbered 0, 1, … in pass order again once absent passes are gone."""
    numbers: dict[int, int] = {}
    out = []
    for p in passes:
        if p.repeat_group is not None:
            group = numbers.setdefault(p.repeat_group, len(numbers))
            if group != p.repeat_group:
                p = dataclasses.replace(p, repeat_group=group)
        out.append(p)
    return tuple(out)


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
