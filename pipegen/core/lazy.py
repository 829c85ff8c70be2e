"""Names a package gives from its modules, imported on first use: the package facade
(``import pipegen``), ``pipegen.compiler`` and ``pipegen.scene`` show their public names without
loading the modules that define them until one is read (PEP 562), so ``import pipegen`` and a
module of those folders stay cheap.  Each name comes with the function that imports its module
(a plain import statement, not a string: the layer rule allows string imports only to the
backend registry)."""

from __future__ import annotations

from types import ModuleType
from typing import Callable


def lazy_names(namespace: dict, loaders: dict[str, Callable[[], ModuleType]]):
    """``(__getattr__, __dir__)`` for the module whose globals are ``namespace``: reading a name
    of ``loaders`` calls its loader, takes the name from the module it returns and keeps it in
    ``namespace`` (read once)."""
    def __getattr__(name: str):
        load = loaders.get(name)
        if load is None:
            raise AttributeError(f"module {namespace['__name__']!r} has no attribute {name!r}")
        value = getattr(load(), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(loaders))

    return __getattr__, __dir__
