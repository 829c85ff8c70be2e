"""The compiler: ``driver`` (a ``.pipe`` to a ``Compiled``: front end, passes, plans),
``specialise`` (a build for one scene), ``capabilities`` (what a technique renders, from its
IR), ``mismatches`` (where a technique and a scene disagree), ``emit_files`` (what
``pipegen compile`` writes), ``inputs`` (what the commands read).

``pipegen.compiler`` is public: ``compile_file``, ``compile_source`` and ``Compiled``.
"""

from __future__ import annotations

from pipegen.core.lazy import lazy_names


def _driver():
    from pipegen.compiler import driver
    return driver


# read from the driver on first use, so that importing one of the folder's modules
# (``compiler.inputs`` for the command line's argument types) does not load the compiler
__all__ = ["Compiled", "compile_file", "compile_source"]
__getattr__, __dir__ = lazy_names(globals(), dict.fromkeys(__all__, _driver))
