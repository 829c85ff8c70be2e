"""Lowering the ``expect`` statements: names checked (the target exists, the backends, the
statistic, the count), the scene file found, into ``ir.Expectation``s.  They are evaluated
only by ``pipegen test`` and the pytest plugin (``testing/expectations.py``), never emitted."""

from __future__ import annotations

import os
from typing import Iterable, Optional

from pipegen.frontend import ast
from pipegen.frontend.lower.names import did_you_mean, error, listing
from pipegen.ir import nodes as ir

E = ir.Expectation
_INTEGER_STATISTICS = ("discontinuities", "over")


def lower_expectations(decls: list[ast.Expect],
                       targets: Iterable[str]) -> tuple[ir.Expectation, ...]:
    names = set(targets)
    return tuple(_lower(d, names) for d in decls)


def _lower(d: ast.Expect, targets: set[str]) -> ir.Expectation:
    subject = d.subject.name
    if d.check == "count":
        _count_subject(d.subject, targets)
    else:
        _target_subject(d.subject, targets)
    against = _against(d)
    statistic = None
    if d.statistic is not None:
        statistic = d.statistic.name
        if statistic not in E.STATISTICS:
            raise error(d.statistic.span, f"unknown statistic '{statistic}'",
                        did_you_mean(statistic, E.STATISTICS,
                                     f"statistics: {', '.join(E.STATISTICS)}"))
    value = None
    if d.value is not None:
        value = d.value.value
        integer = d.check == "count" or statistic in _INTEGER_STATISTICS
        if integer and d.value.kind == "float":
            what = f"'{subject}'" if d.check == "count" else f"'{statistic}'"
            raise error(d.value.span, f"{what} counts, so its bound is a whole number, "
                        f"not {d.value.value}", f"write e.g. {int(d.value.value)}")
    size = None
    if d.size is not None:
        size = (int(d.size.width.value), int(d.size.height.value))
        if min(size) < 1:
            raise error(d.size.span, f"a size is at least 1x1, not {size[0]}x{size[1]}",
                        "each side is at least 1, e.g. `at 96x64`")
    return ir.Expectation(subject, d.check, against, statistic,
                          d.op.value if d.op is not None else None, value,
                          _scene(d.scene), size, d.text, span=d.span)


def _target_subject(name: ast.Name, targets: set[str]) -> None:
    if name.name in targets:
        return
    if name.name in E.COUNTS:
        raise error(name.span, f"'{name.name}' is a count, not a target",
                    f"compare it with a number: `expect {name.name} == 0`")
    raise error(name.span, f"unknown target '{name.name}'",
                did_you_mean(name.name, targets, f"the targets: {listing(targets)}"))


def _count_subject(name: ast.Name, targets: set[str]) -> None:
    if name.name in E.COUNTS:
        return
    if name.name in targets:
        raise error(name.span, f"'{name.name}' is a target: a target is compared, not counted",
                    f"write `expect {name.name} agrees gl cl`, `expect {name.name} vs f64` or "
                    f"`expect {name.name} vs f64 p99 <= 2`")
    raise error(name.span, f"unknown count '{name.name}'",
                did_you_mean(name.name, E.COUNTS, f"counts: {', '.join(E.COUNTS)}"))


def _against(d: ast.Expect) -> tuple[str, ...]:
    if d.check == "count":
        return ()
    if d.check == "vs":
        ref = d.against[0]
        if ref.name not in E.REFERENCES:
            hint = (f"`vs` compares with the float64 evaluation: `vs f64`; to compare backends "
                    f"write `expect {d.subject.name} agrees gl cl`"
                    if ref.name in E.BACKENDS else
                    did_you_mean(ref.name, E.REFERENCES, "write `vs f64`"))
            raise error(ref.span, f"unknown reference '{ref.name}'", hint)
        return (ref.name,)
    seen: list[str] = []
    for b in d.against:
        if b.name not in E.BACKENDS:
            raise error(b.span, f"unknown backend '{b.name}'",
                        did_you_mean(b.name, E.BACKENDS,
                                     f"backends: {', '.join(E.BACKENDS)}"
                                     + ("; the float64 evaluation is compared with "
                                        f"`expect {d.subject.name} vs f64`"
                                        if b.name in E.REFERENCES else "")))
        if b.name in seen:
            raise error(b.span, f"backend '{b.name}' is named twice",
                        "name each backend once: `agrees gl cl`")
        seen.append(b.name)
    if len(seen) < 2:
        raise error(d.against[0].span, "a backend agrees with another one: name two",
                    f"write `expect {d.subject.name} agrees {' '.join(E.BACKENDS)}`")
    return tuple(seen)


def _scene(scene: Optional[ast.Word]) -> Optional[str]:
    """The scene file, found relative to the technique's folder (an absolute path as it is)."""
    if scene is None:
        return None
    if not scene.value or not scene.value.isprintable():
        raise error(scene.span, "a scene path is the name of a file",
                    'write e.g. `on "scenes/hard.toml"` (relative to this .pipe file)')
    base = os.path.dirname(scene.span.file) if scene.span.file != "<string>" else ""
    path = os.path.abspath(os.path.join(base, os.path.expanduser(scene.value)))
    if not os.path.isfile(path):
        raise error(scene.span, f"scene file '{scene.value}' not found ({path})",
                    "a scene path is relative to the .pipe file's folder: a scene .toml, "
                    ".gltf, .glb or .obj")
    return path
