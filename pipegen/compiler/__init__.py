"""The compiler: ``driver`` (a ``.pipe`` to a ``Compiled``: front end, passes, plans),
``specialise`` (a build for one scene), ``features`` (what a scene calls for, what a technique
renders, where the two disagree), ``emit_files`` (what ``pipegen compile`` writes),
``inputs`` (what the commands read).

``pipegen.compiler`` is public: ``compile_file``, ``compile_source`` and ``Compiled``.
"""

from pipegen.compiler.driver import (  # noqa: F401 (the public compiler API)
    Compiled, compile_file, compile_source)
