"""``records.record`` behaves as ``dataclass(eq=True)`` where the IR and the syntax tree rely on
it: equality (same class, compared fields only), hashing of frozen records, unhashable mutable
ones, and the same ``repr`` text (the specialisation cache keys on it)."""

from dataclasses import dataclass, field, replace
from typing import Optional

import pytest

from pipegen.core import records
from pipegen.core.records import record


@record(frozen=True)
class Frozen:
    a: int
    b: tuple = ()
    span: Optional[str] = field(default=None, compare=False)


@dataclass(frozen=True)
class FrozenDC:
    a: int
    b: tuple = ()
    span: Optional[str] = field(default=None, compare=False)


@record
class Mutable:
    x: int
    span: str = field(default="", repr=False, compare=False)


@record(frozen=True)
class Empty:
    pass


@record(frozen=True)
class One:
    v: float


def test_equality_ignores_uncompared_fields_and_other_classes():
    assert Frozen(1, (2,), "here") == Frozen(1, (2,), "there")
    assert Frozen(1) != Frozen(2)
    assert Frozen(1) != FrozenDC(1)          # another class, even with the same fields
    assert (Frozen(1) == 1) is False
    assert Empty() == Empty() and One(1.5) == One(1.5) and One(1.5) != One(2.5)


def test_frozen_records_hash_their_compared_fields_and_mutable_ones_are_unhashable():
    assert hash(Frozen(1, (2,), "a")) == hash(Frozen(1, (2,), "b"))
    assert len({Frozen(1), Frozen(1, (), "x"), Frozen(2)}) == 2
    assert len({Empty(), Empty()}) == 1
    with pytest.raises(TypeError):
        hash(Mutable(1))
    with pytest.raises(Exception):           # dataclasses.FrozenInstanceError
        Frozen(1).a = 2


def test_repr_is_dataclass_repr():
    assert repr(Frozen(1, (2,), "s")) == repr(FrozenDC(1, (2,), "s")).replace("FrozenDC", "Frozen")
    assert repr(Mutable(3, "hidden")) == "Mutable(x=3)"
    assert repr(Empty()) == "Empty()"


def test_dataclass_tools_still_work():
    assert replace(Frozen(1, (2,)), a=5) == Frozen(5, (2,))
    assert Frozen.__doc__ == "Frozen(a, b, span)"


def test_records_replace_is_dataclasses_replace():
    old = Frozen(1, (2,), "here")
    object.__setattr__(old, "_memo", "worked out for old")     # not a field: not copied
    new = records.replace(old, span="there")
    assert type(new) is Frozen and new is not old
    assert (new.a, new.b, new.span) == (1, (2,), "there") and not hasattr(new, "_memo")
    assert vars(new) == vars(replace(Frozen(1, (2,), "here"), span="there"))
    assert records.replace(old) == old and records.replace(Mutable(2), x=3) == Mutable(3)
    with pytest.raises(TypeError, match="unexpected keyword argument 'c'"):
        records.replace(old, c=1)
    with pytest.raises(Exception):                            # still frozen
        new.a = 2
    # __post_init__ runs as for dataclasses.replace, and plain dataclasses go through it
    assert records.replace(WithFactory([5]), label="z").items == [5, 1, 2]
    assert records.replace(FrozenDC(1), a=2) == FrozenDC(2)


@record
class WithFactory:
    items: list = field(default_factory=list)
    label: str = "x"
    span: str = field(default="", kw_only=True, compare=False)

    def __post_init__(self):
        self.items.append(len(self.items))


def test_init_as_dataclass_writes_it():
    a, b = WithFactory(), WithFactory()
    assert a.items == [0] and a.items is not b.items          # a new list each time
    assert WithFactory([5], "y", span="s") == WithFactory([5], "y")
    assert WithFactory([5], "y").items == [5, 1]               # __post_init__ ran
    with pytest.raises(TypeError):
        WithFactory([], "y", "positional span")                # kw_only
    with pytest.raises(TypeError):
        Frozen()                                               # a required field missing


def test_field_order_is_checked_at_definition():
    with pytest.raises(TypeError, match="non-default argument 'b'"):
        @record
        class Bad:
            a: int = 0
            b: int


@record(frozen=True)
class OwnMethods:
    file: str
    line: int

    def __eq__(self, other):
        return isinstance(other, OwnMethods) and self.line == other.line

    def __repr__(self):
        return f"at {self.line}"


def test_methods_the_class_defines_are_kept():
    assert OwnMethods("a", 1) == OwnMethods("b", 1)
    assert repr(OwnMethods("a", 1)) == "at 1"
    assert hash(OwnMethods("a", 1)) == hash(("a", 1))          # the record's hash
