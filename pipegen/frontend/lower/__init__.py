"""Lowering: the checked syntax tree to the IR.  ``lowerer`` drives it; ``collect`` gathers
the declarations, ``names`` holds the shared context and messages, ``params``, ``passes``,
``statements`` and ``expressions`` check and lower their parts."""
