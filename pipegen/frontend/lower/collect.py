"""Phase 1 of lowering: follow includes (``sources.include_candidates``), sort the
declarations of the technique and its included files by kind, number the repeat groups."""

from __future__ import annotations

import os
from dataclasses import field
from typing import Optional

from pipegen.core.records import record
from pipegen.frontend import ast, parse as syntax
from pipegen.core import sources
from pipegen.frontend.lower.names import Loader, error

@record
class PassItem:
    decl: ast.PassDecl
    group: Optional[int]          # repeat group from a `repeat per light { … }` block
    block_types: tuple = ()       # the block's light types (`repeat per light spot { … }`)
    conditions: tuple = ()        # `if COND` of its block and its own: present where all hold


@record
class Decls:
    technique: Optional[ast.TechniqueDecl] = None
    params: list[ast.ParamDecl] = field(default_factory=list)
    lights: list[ast.LightsDecl] = field(default_factory=list)
    materials: list[ast.MaterialDecl] = field(default_factory=list)
    targets: list[ast.TargetDecl] = field(default_factory=list)
    outputs: list[ast.OutputDecl] = field(default_factory=list)
    packs: list[ast.PackDecl] = field(default_factory=list)
    functions: list[ast.FunctionDef] = field(default_factory=list)
    passes: list[PassItem] = field(default_factory=list)
    expects: list[ast.Expect] = field(default_factory=list)
    named: list[tuple[ast.Name, str]] = field(default_factory=list)   # in source order


# What an included file may contribute (language.md: "functions, params, packs").
_INCLUDABLE = (ast.Include, ast.ParamDecl, ast.PackDecl, ast.FunctionDef)


class Collector:
    def __init__(self, loader: Loader):
        self.loader = loader
        self.decls = Decls()
        self.seen: set[str] = set()
        self.texts: dict[str, str] = {}     # found by _find, parsed by _include
        self.groups = 0

    def module(self, module: ast.Module, path: str, stack: tuple[str, ...] = ()) -> None:
        self.seen.add(os.path.normpath(path))
        included = bool(stack)
        for item in module.items:
            if included and not isinstance(item, _INCLUDABLE):
                raise error(item.span, f"an included file may only declare params, packs and "
                            f"functions, not a {_item_kind(item)}",
                            "move it into the technique file that includes this one")
            self._item(item, path, stack)

    def _item(self, item: ast.Item, path: str, stack: tuple[str, ...]) -> None:
        d = self.decls
        if isinstance(item, ast.Include):
            self._include(item, path, stack)
        elif isinstance(item, ast.TechniqueDecl):
            if d.technique is not None:
                raise error(item.span, "a file declares one technique",
                            f"'{d.technique.name.name}' is declared on line "
                            f"{d.technique.span.line}")
            d.technique = item
        elif isinstance(item, ast.RepeatBlock):
            if not item.passes:
                raise error(item.span, "an empty `repeat per light` block",
                            "put the passes that run once per light inside it")
            group = self._new_group()
            types = tuple(item.light_types)
            block = (item.condition,) if item.condition is not None else ()
            d.passes.extend(PassItem(p, group, types, block + _own_condition(p))
                            for p in item.passes)
        elif isinstance(item, ast.PassDecl):
            # A pass with its own `repeat per light` is a repeat group of one.
            repeats = any(isinstance(s, ast.RepeatPerLight) for s in item.stmts)
            d.passes.append(PassItem(item, self._new_group() if repeats else None,
                                     conditions=_own_condition(item)))
        else:
            bucket = {ast.ParamDecl: d.params, ast.LightsDecl: d.lights, ast.MaterialDecl: d.materials,
                      ast.TargetDecl: d.targets, ast.OutputDecl: d.outputs,
                      ast.PackDecl: d.packs, ast.FunctionDef: d.functions,
                      ast.Expect: d.expects}[type(item)]
            bucket.append(item)
            kind = _NAMED_KINDS.get(type(item))
            if kind is not None:
                d.named.append((item.name, kind))

    def _new_group(self) -> int:
        self.groups += 1
        return self.groups - 1

    def _include(self, inc: ast.Include, path: str, stack: tuple[str, ...]) -> None:
        if not inc.path.isprintable():
            raise error(inc.span, "an include path cannot contain control characters",
                        'write the path of a .pipe file, e.g. include "common/lighting.pipe"')
        target = self._find(inc, path)
        if target in stack or target == os.path.normpath(path):
            raise error(inc.span, f"'{inc.path}' includes itself (through "
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
                raise error(inc.span, f"cannot read included file '{inc.path}' ({target}): "
                            f"{getattr(e, 'strerror', None) or e}",
                            "include a .pipe file (a regular file of at most "
                            f"{sources.MAX_SOURCE_BYTES >> 20} MiB)") from None
        searched = "; ".join(f"{t} ({where})" for t, where in candidates)
        raise error(inc.span, f"cannot read included file '{inc.path}': not found (searched "
                    f"{searched})",
                    "include paths are relative to the including file; the library shipped "
                    "with pipegen is included as common/NAME.pipe; more folders can be listed "
                    "in PIPEGEN_PATH")


def _own_condition(p: ast.PassDecl) -> tuple:
    return (p.condition,) if p.condition is not None else ()


_NAMED_KINDS = {ast.ParamDecl: "parameter", ast.TargetDecl: "target", ast.PackDecl: "packing",
                ast.FunctionDef: "function"}


def _item_kind(item: ast.Item) -> str:
    return {ast.TechniqueDecl: "technique", ast.LightsDecl: "light table",
            ast.TargetDecl: "target", ast.OutputDecl: "output", ast.PassDecl: "pass",
            ast.RepeatBlock: "repeat block", ast.Expect: "test expectation"}.get(
                type(item), type(item).__name__)
