"""jinja2 for whole files (glad's generator is the model): the templates ship inside the wheel as
the ``pipegen.templates`` package (the top-level ``templates/`` folder), are read from it
(``package_files.package_text``: its folder, or ``importlib.resources`` inside a zip), and render
with ``StrictUndefined``, ``trim_blocks`` and ``lstrip_blocks``.  Filters are plain Python
functions registered with ``@template_filter``.

Python renders expressions (``cstyle.py``); templates only lay out files.
"""

from __future__ import annotations

import functools
from typing import Callable, Optional

import jinja2

FILTERS: dict[str, Callable] = {}


def template_filter(fn: Callable) -> Callable:
    """Register ``fn`` as a template filter under its own name."""
    FILTERS[fn.__name__] = fn
    environment.cache_clear()
    return fn


def _load(name: str):
    if "/" in name or "\\" in name or name.startswith("."):
        return None
    from pipegen.core.package_files import package_text
    return package_text("pipegen.templates", name)


def _bytecode_cache() -> Optional[jinja2.BytecodeCache]:
    """Compiled templates kept in the user's pipegen cache folder (``package_files.cache_dir``):
    compiling every template from source costs a fresh process ~150 ms.  Used only when the
    folder is the user's own and writable by no one else (the cache holds code); otherwise,
    or when it cannot be created, templates are compiled each time."""
    import os
    from pipegen.core.package_files import cache_dir, owned_privately
    base = cache_dir()
    if base is None:
        return None
    folder = os.path.join(base, "templates")
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        if not (owned_privately(os.stat(base)) and owned_privately(os.stat(folder))):
            return None
    except OSError:
        return None
    return jinja2.FileSystemBytecodeCache(folder)


@functools.cache
def environment() -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.FunctionLoader(_load), undefined=jinja2.StrictUndefined,
                             trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                             autoescape=False, bytecode_cache=_bytecode_cache())
    env.filters.update(FILTERS)
    return env


def render(template: str, **context) -> str:
    return environment().get_template(template).render(**context)


# ---- filters -------------------------------------------------------------------------------------


def _multiline_ok(s: str) -> bool:
    return ("\n" in s and "\\" not in s and '"""' not in s and not s.endswith('"')
            and s.replace("\n", "").isprintable())   # every character printable or a newline


@template_filter
def pyrepr(obj, indent: int = 0, width: int = 100) -> str:
    """A readable Python literal for plain data (dicts, lists, tuples, str, numbers, bool, None):
    short containers on one line, long ones one item per line, multi-line strings (shader
    source) as triple-quoted blocks.  ``ast.literal_eval(pyrepr(x)) == x``.

    A container goes on one line when its ``repr`` fits in what is left of ``width`` after
    its indent and holds no string written as a block.  Each container's one-line text is
    worked out once (``_OneLine``), however deep it sits: the plan a pipeline module holds
    has some 1,500 of them."""
    return _layout(obj, indent, width, _OneLine(width))


def _layout(obj, indent: int, width: int, one_line: "_OneLine") -> str:
    if isinstance(obj, str):
        return '"""\\\n' + obj + '"""' if _multiline_ok(obj) else repr(obj)
    if isinstance(obj, (dict, list, tuple)):
        flat = one_line(obj)
        if flat is not None and len(flat) <= width - indent:
            return flat
        pad, inner = " " * indent, " " * (indent + 4)
        if isinstance(obj, dict):
            items = [f"{inner}{k!r}: {_layout(v, indent + 4, width, one_line)},"
                     for k, v in obj.items()]
            return "{\n" + "\n".join(items) + f"\n{pad}}}"
        open_, close = ("[", "]") if isinstance(obj, list) else ("(", ")")
        items = [f"{inner}{_layout(v, indent + 4, width, one_line)}," for v in obj]
        return open_ + "\n" + "\n".join(items) + f"\n{pad}{close}"
    return repr(obj)


class _OneLine:
    """``repr(obj)`` as one line, or None where that is longer than ``width`` (no indent
    leaves it room) or holds a string ``pyrepr`` writes as a block; kept per container (by
    ``id``: the containers live as long as the ``pyrepr`` call).  Built piece by piece for
    plain dicts, lists and tuples and given up as soon as it is too long, so that a long
    container (the plan's shader sources) costs no more than its first ``width`` characters."""

    def __init__(self, width: int):
        self.width = width
        self.known: dict[int, Optional[str]] = {}

    def __call__(self, obj) -> Optional[str]:
        kind = type(obj)
        if kind is dict or kind is list or kind is tuple:
            key = id(obj)
            if key in self.known:
                return self.known[key]
            text = self.known[key] = self._container(obj, kind)
            return text
        if isinstance(obj, (dict, list, tuple)):        # a subclass: its own repr
            if any(isinstance(v, str) and _multiline_ok(v) for v in _leaves(obj)):
                return None
            text = repr(obj)
        elif isinstance(obj, str) and (len(obj) > self.width or _multiline_ok(obj)):
            return None          # too long however written: no need to scan it (shader source)
        else:
            text = repr(obj)
        return text if len(text) <= self.width else None

    def _container(self, obj, kind) -> Optional[str]:
        left = self.width - 2                 # the brackets
        parts = []
        for item in (obj.items() if kind is dict else obj):
            if kind is dict:
                value = self(item[1])
                part = None if value is None else repr(item[0]) + ": " + value
            else:
                part = self(item)
            if part is None:
                return None
            left -= len(part) + (2 if parts else 0)      # the item, ", "
            if left < 0:
                return None
            parts.append(part)
        text = ", ".join(parts)
        if kind is dict:
            return "{" + text + "}"
        if kind is list:
            return "[" + text + "]"
        if len(parts) == 1:
            return "(" + text + ",)" if left >= 1 else None
        return "(" + text + ")"


def _leaves(obj):
    if isinstance(obj, dict):
        obj = obj.values()
    for v in obj:
        if isinstance(v, (dict, list, tuple)):
            yield from _leaves(v)
        else:
            yield v
