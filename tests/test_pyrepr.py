"""templating.pyrepr builds each container's one-line form once, piece by piece, and gives it up
as soon as it is too long (compile time, issues 8 and 26); the text it writes is the same as
when it repr'd every container whole, kept below as the reference, on random plain data and on
real plans."""

from __future__ import annotations

import ast
import collections
import random

import pytest

from pipegen.backends.templating import _leaves, _multiline_ok, pyrepr

Pair = collections.namedtuple("Pair", "a b")


def reference(obj, indent: int = 0, width: int = 100) -> str:
    """pyrepr as it was: repr of the whole container at every level."""
    pad, inner = " " * indent, " " * (indent + 4)
    if isinstance(obj, str):
        return '"""\\\n' + obj + '"""' if _multiline_ok(obj) else repr(obj)
    if isinstance(obj, (dict, list, tuple)):
        flat = repr(obj)
        if len(flat) + indent <= width and not any(
                isinstance(v, str) and _multiline_ok(v) for v in _leaves(obj)):
            return flat
        if isinstance(obj, dict):
            items = [f"{inner}{k!r}: {reference(v, indent + 4, width)}," for k, v in obj.items()]
            return "{\n" + "\n".join(items) + f"\n{pad}}}"
        open_, close = ("[", "]") if isinstance(obj, list) else ("(", ")")
        items = [f"{inner}{reference(v, indent + 4, width)}," for v in obj]
        return open_ + "\n" + "\n".join(items) + f"\n{pad}{close}"
    return repr(obj)


def random_data(rng: random.Random, depth: int = 0):
    roll = rng.random()
    if depth > 3 or roll < 0.45:
        return rng.choice([
            lambda: rng.randint(-10 ** rng.randint(0, 12), 10 ** rng.randint(0, 12)),
            lambda: rng.uniform(-1e6, 1e6), lambda: rng.choice([True, False, None]),
            lambda: "x" * rng.randint(0, 30), lambda: "line\n" * rng.randint(1, 3),
            lambda: 'ends with a quote"\n', lambda: "tab\there\n", lambda: "back\\slash\n",
            lambda: rng.choice(["", "a", "é", "'quoted'"]),
        ])()
    n = rng.choice([0, 1, 1, 2, 3, 5, 8])
    kind = rng.choice(["dict", "list", "tuple", "pair"])
    if kind == "dict":
        return {rng.choice(["k", "name", "a_long_key_name", 3, (1, 2)]) if i == 0 else f"k{i}":
                random_data(rng, depth + 1) for i in range(n)}
    if kind == "pair":
        return Pair(random_data(rng, depth + 1), random_data(rng, depth + 1))
    items = [random_data(rng, depth + 1) for _ in range(n)]
    return items if kind == "list" else tuple(items)


def test_pyrepr_writes_what_it_wrote_before_on_random_data():
    rng = random.Random(8)
    for i in range(3000):
        obj = random_data(rng)
        for indent, width in ((0, 100), (4, 100), (8, 40), (0, 12), (30, 20)):
            assert pyrepr(obj, indent, width) == reference(obj, indent, width), (i, obj)


@pytest.mark.parametrize("technique", ["deferred_calver", "inferred", "lidr_bitplanes"])
def test_pyrepr_writes_what_it_wrote_before_on_plans(technique):
    from pathlib import Path
    from pipegen.compiler.driver import compile_file
    root = Path(__file__).resolve().parents[1]
    compiled = compile_file(root / "pipelines" / f"{technique}.pipe")
    for backend in ("gl", "cl"):
        data = compiled.plan(backend).to_dict()       # what the pipeline modules hold
        text = pyrepr(data)
        assert text == reference(data)
        assert ast.literal_eval(text) == data
