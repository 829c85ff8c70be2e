"""``record``: ``dataclasses.dataclass`` for the many small node classes of the IR and the
syntax tree, cheaper to define.

Python 3.11's ``dataclass`` writes ``__eq__``, ``__hash__`` and ``__repr__`` as source text for
every class and compiles each with ``exec``; for the ~100 classes of ``ir.py`` and ``ast.py``
that was 15 ms of every ``pipegen compile`` (measured: defining both modules 38 -> 23 ms),
about a twentieth of the whole command.  A ``record`` class is a dataclass without those three
generated methods (``dataclass`` still writes ``__init__`` and, when frozen, the attribute
guards) that shares one implementation of each instead, driven by an ``operator.attrgetter``
of its fields made once per class, so comparing and hashing run at C speed as before.

Same semantics as ``dataclass(eq=True)``: equal when of the same class and the fields that
take part in comparison (``compare=True``) are equal; frozen records hash those fields,
mutable ones are unhashable; the same ``repr`` text (``ClassName(field=value, ...)`` of the
``repr=True`` fields; the specialisation cache keys on it).  Python 3.13 compiles a
dataclass's methods in one ``exec``; this module can go when pipegen requires it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from operator import attrgetter


def record(cls=None, /, *, frozen: bool = False):
    """Class decorator: ``@record`` or ``@record(frozen=True)``, as ``@dataclass``."""
    def wrap(c):
        if not c.__dict__.get("__doc__"):
            # dataclass would build the docstring from inspect.signature (slow); the same
            # text from the fields after the class is made
            c.__doc__ = "-"
            c = dataclass(c, eq=False, repr=False, frozen=frozen)
            c.__doc__ = f"{c.__name__}({', '.join(f.name for f in fields(c))})"
        else:
            c = dataclass(c, eq=False, repr=False, frozen=frozen)
        compared = [f.name for f in fields(c) if f.compare]
        # one field: the value itself; none: every instance of the class is equal
        c._record_key = attrgetter(*compared) if compared else attrgetter("__class__")
        c._record_shown = tuple(f.name for f in fields(c) if f.repr)
        c.__eq__ = _eq
        c.__hash__ = _hash if frozen else None
        c.__repr__ = _repr
        return c
    return wrap if cls is None else wrap(cls)


def _eq(self, other):
    if other.__class__ is self.__class__:
        key = self._record_key
        return key(self) == key(other)
    return NotImplemented


def _hash(self):
    return hash(self._record_key(self))


def _repr(self):
    shown = ", ".join(f"{name}={getattr(self, name)!r}" for name in self._record_shown)
    return f"{self.__class__.__qualname__}({shown})"
