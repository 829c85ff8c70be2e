"""The compiler: ``driver`` (a ``.pipe`` to a ``Compiled``: front end, passes, plans),
``specialise`` (a build for one scene), ``capabilities`` (what a technique renders, from its
IR), ``mismatches`` (where a technique and a scene disagree), ``emit_files`` (what
``pipegen compile`` writes), ``inputs`` (what the commands read).

``pipegen.compiler`` is public: ``compile_file``, ``compile_source`` and ``Compiled``.
"""

from __future__ import annotations

__all__ = ["Compiled", "compile_file", "compile_source"]


def __getattr__(name: str):
    # read from the driver on first use, so that importing one of the folder's modules
    # (``compiler.inputs`` for the command line's argument types) does not load the compiler
    if name not in __all__:
        raise AttributeError(f"module 'pipegen.compiler' has no attribute {name!r}")
    from pipegen.compiler import driver
    value = getattr(driver, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
