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
    source) as triple-quoted blocks.  ``ast.literal_eval(pyrepr(x)) == x``."""
    pad, inner = " " * indent, " " * (indent + 4)
    if isinstance(obj, str):
        return '"""\\\n' + obj + '"""' if _multiline_ok(obj) else repr(obj)
    if isinstance(obj, (dict, list, tuple)):
        flat = _flat(obj, width - indent)
        if flat is not None:
            return flat
        if isinstance(obj, dict):
            items = [f"{inner}{k!r}: {pyrepr(v, indent + 4, width)}," for k, v in obj.items()]
            return "{\n" + "\n".join(items) + f"\n{pad}}}"
        open_, close = ("[", "]") if isinstance(obj, list) else ("(", ")")
        items = [f"{inner}{pyrepr(v, indent + 4, width)}," for v in obj]
        return open_ + "\n" + "\n".join(items) + f"\n{pad}{close}"
    return repr(obj)


def _flat(obj, room: int):
    """``repr(obj)`` when it fits in ``room`` characters and holds no string that ``pyrepr``
    writes as a block, else None.  Built piece by piece for plain dicts, lists and tuples, so
    that a long container (the plan's shader sources) is given up as soon as it is too long
    instead of being repr'd whole at every level of ``pyrepr``'s descent."""
    kind = type(obj)
    if kind is dict or kind is list or kind is tuple:
        left = room - 1                       # the opening bracket
        parts = []
        for item in (obj.items() if kind is dict else obj):
            prefix = repr(item[0]) + ": " if kind is dict else ""
            left -= len(prefix) + (2 if parts else 0)        # the key, ", "
            value = _flat(item[1] if kind is dict else item, left) if left >= 0 else None
            if value is None:
                return None
            left -= len(value)
            parts.append(prefix + value)
        text = ", ".join(parts)
        if kind is dict:
            text = "{" + text + "}"
        elif kind is list:
            text = "[" + text + "]"
        else:
            text = "(" + text + (",)" if len(parts) == 1 else ")")
    elif isinstance(obj, (dict, list, tuple)):        # a subclass: its own repr
        if any(isinstance(v, str) and _multiline_ok(v) for v in _leaves(obj)):
            return None
        text = repr(obj)
    elif isinstance(obj, str) and (len(obj) > room or _multiline_ok(obj)):
        return None          # too long however written: no need to scan it (shader source)
    else:
        text = repr(obj)
    return text if len(text) <= room else None


def _leaves(obj):
    if isinstance(obj, dict):
        obj = obj.values()
    for v in obj:
        if isinstance(v, (dict, list, tuple)):
            yield from _leaves(v)
        else:
            yield v
