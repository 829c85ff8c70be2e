"""``record``: ``dataclasses.dataclass`` for the many small node classes of the IR and the
syntax tree, cheaper to define.

Python 3.11's ``dataclass`` writes ``__init__``, ``__eq__``, ``__hash__``, ``__repr__`` and, for
frozen classes, ``__setattr__`` and ``__delattr__`` as source text for every class and compiles
each with ``exec``: for the ~100 classes of ``ir/nodes.py`` and ``frontend/ast.py`` that was about a sixth of
every ``pipegen compile`` (callgrind: 1309 M instructions in all; defining the two modules 160 M
of them).  A ``record`` is a dataclass for which ``dataclass`` only collects the fields (the
``fields``, ``replace``, ``__match_args__`` and pickling machinery work as for any dataclass)
and that shares one implementation of the rest:

- equality, hashing and ``repr`` by an ``operator.attrgetter`` of the fields made once per
  class, so they run at C speed as the generated methods did;
- the frozen guard: one ``__setattr__``/``__delattr__`` raising ``FrozenInstanceError``;
- ``__init__`` is compiled the first time the class is instantiated (most classes never are in
  one compile: the syntax trees come unpickled from the cache, without ``__init__``), and the
  compiled code is kept in the user's cache folder for the next process (``code_cache``).

Same semantics as ``dataclass(eq=True)`` with the features the IR uses (defaults,
``default_factory``, ``kw_only``, ``compare=False``, ``repr=False``, ``__post_init__``): equal
when of the same class and the compared fields are equal; frozen records hash those fields,
mutable ones are unhashable; the same ``repr`` text (the specialisation cache keys on it).
Python 3.13 compiles a dataclass's methods in one ``exec``; this module can go when pipegen
requires it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import MISSING, FrozenInstanceError, dataclass, fields
from operator import attrgetter

from pipegen.core.code_cache import compiled


def record(cls=None, /, *, frozen: bool = False):
    """Class decorator: ``@record`` or ``@record(frozen=True)``, as ``@dataclass``."""
    def wrap(c):
        doc = c.__dict__.get("__doc__")
        # without a docstring dataclass would build one from inspect.signature (slow)
        c.__doc__ = doc or "-"
        c = dataclass(c, init=False, eq=False, repr=False)
        names = [f.name for f in fields(c)]
        c._record_fields = tuple(names)
        _check_order(c)
        if not doc:
            c.__doc__ = f"{c.__name__}({', '.join(names)})"
        compared = [f.name for f in fields(c) if f.compare]
        # one field: the value itself; none: every instance of the class is equal
        c._record_key = attrgetter(*compared) if compared else attrgetter("__class__")
        c._record_shown = tuple(f.name for f in fields(c) if f.repr)
        # methods the class body defines are kept, as dataclass keeps them
        own = {k: v for k, v in c.__dict__.items() if k in _METHODS}
        if own.get("__hash__", 0) is None and "__eq__" in own:
            del own["__hash__"]      # Python's implicit None for a class defining __eq__
        c.__init__ = _first_init
        c.__eq__ = _eq
        c.__repr__ = _repr
        if frozen:
            c.__hash__ = _hash
            c.__setattr__ = _frozen
            c.__delattr__ = _frozen
        else:
            c.__hash__ = None
        for k, v in own.items():
            setattr(c, k, v)
        return c
    return wrap if cls is None else wrap(cls)


_METHODS = ("__init__", "__eq__", "__hash__", "__repr__")


def replace(obj, /, **changes):
    """``dataclasses.replace(obj, **changes)`` for records, a few times cheaper: the copy is
    made without ``__init__`` (a record's only sets its fields, each to the value given) and
    holds the fields alone, as ``replace`` would leave it.  A class with ``__post_init__``,
    and anything not a record, goes through ``dataclasses.replace``.  (The lowerer gives some
    550 expressions of a compile their span this way.)"""
    cls = obj.__class__
    names = cls.__dict__.get("_record_fields")
    if names is None or hasattr(cls, "__post_init__"):
        return dataclasses.replace(obj, **changes)
    unknown = [k for k in changes if k not in names]
    if unknown:
        raise TypeError(f"{cls.__qualname__}.__init__() got an unexpected keyword argument "
                        f"{unknown[0]!r}")
    new = object.__new__(cls)
    fresh, old = new.__dict__, obj.__dict__
    for name in names:
        fresh[name] = old[name]
    fresh.update(changes)
    return new


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


def _frozen(self, name, *value):
    raise FrozenInstanceError(f"cannot assign to field {name!r}")


def _first_init(self, *args, **kwargs):
    """Compile the class's ``__init__``, install it and run it."""
    cls = type(self)
    init = cls.__init__ = _make_init(cls)
    init(self, *args, **kwargs)


def _check_order(cls) -> None:
    """What dataclass checks when it writes ``__init__``, checked at definition all the same."""
    seen_default = None
    for f in fields(cls):
        if not f.init:
            raise TypeError(f"record {cls.__qualname__}: init=False fields are not supported")
        if f.kw_only:
            continue
        if f.default is not MISSING or f.default_factory is not MISSING:
            seen_default = f.name
        elif seen_default:
            raise TypeError(f"non-default argument {f.name!r} follows default argument "
                            f"{seen_default!r} in {cls.__qualname__}")


_FACTORY = object()      # "no argument given" for a field with a default_factory


def _make_init(cls):
    """``__init__`` as dataclass writes it: parameters in field order (``kw_only`` ones after
    a ``*``), defaults, factories, attributes set with ``object.__setattr__`` (frozen or not),
    then ``__post_init__``."""
    env = {"_set": object.__setattr__, "_FACTORY": _FACTORY}
    positional, keyword, body = [], [], []
    for f in fields(cls):
        if f.default is not MISSING:
            env[f"_d_{f.name}"] = f.default
            param, value = f"{f.name}=_d_{f.name}", f.name
        elif f.default_factory is not MISSING:
            env[f"_f_{f.name}"] = f.default_factory
            param = f"{f.name}=_FACTORY"
            value = f"_f_{f.name}() if {f.name} is _FACTORY else {f.name}"
        else:
            param, value = f.name, f.name
        (keyword if f.kw_only else positional).append(param)
        body.append(f"    _set(self, {f.name!r}, {value})")
    if hasattr(cls, "__post_init__"):
        body.append("    self.__post_init__()")
    params = ", ".join(["self"] + positional + (["*"] + keyword if keyword else []))
    # compiled once per text and interpreter, then kept (code_cache): compiling ~70 of these
    # was 2-3 % of a fresh ``pipegen compile``
    exec(compiled(f"def __init__({params}):\n" + ("\n".join(body) or "    pass")), env)
    init = env["__init__"]
    init.__qualname__ = f"{cls.__qualname__}.__init__"
    return init
