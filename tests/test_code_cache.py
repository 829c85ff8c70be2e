"""``core/code_cache``: record ``__init__`` code compiled once and kept in the user's cache
folder.  A fresh interpreter per case (the cache is read once a process and written at its
exit); ``PIPEGEN_CACHE_DIR`` points at a folder of the test's own."""

from __future__ import annotations

import json
import marshal
import os
import subprocess
import sys
from importlib.util import MAGIC_NUMBER

import pytest

RUN = """
import json, sys
import pipegen.core.code_cache as cc
calls = []
real = compile
def counting(*a, **k):
    calls.append(a[0])
    return real(*a, **k)
cc.compile = counting            # the module's own name for the builtin
from pipegen.core.records import record

@record
class Probe:
    a: int
    b: str = "x"

p = Probe(3)
q = Probe(4, b="y")
print(json.dumps({"compiled": len(calls), "a": p.a, "b": p.b, "qb": q.b, "eq": Probe(3) == p}))
"""


def _run(cache_dir) -> dict:
    env = {**os.environ, "PIPEGEN_CACHE_DIR": str(cache_dir)}
    proc = subprocess.run([sys.executable, "-c", RUN], capture_output=True, text=True, env=env,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _cache_file(folder) -> str:
    return os.path.join(folder, "code", f"code-{MAGIC_NUMBER.hex()}.marshal")


def test_compiled_once_then_read_from_the_cache(tmp_path):
    first = _run(tmp_path)
    assert first["compiled"] == 1                  # Probe's __init__, compiled from its text
    assert (first["a"], first["b"], first["qb"], first["eq"]) == (3, "x", "y", True)
    with open(_cache_file(tmp_path), "rb") as f:
        kept = marshal.load(f)
    assert any(text.startswith("def __init__(self, a, b=_d_b):") for text in kept)
    second = _run(tmp_path)
    assert second["compiled"] == 0                 # the same text: the kept code
    assert second == {**first, "compiled": 0}


def test_a_file_others_could_write_or_of_the_wrong_shape_is_not_used(tmp_path):
    _run(tmp_path)
    path = _cache_file(tmp_path)
    os.chmod(path, 0o666)                          # group- and world-writable: never read
    assert _run(tmp_path)["compiled"] == 1
    os.chmod(path, 0o600)
    with open(path, "wb") as f:
        marshal.dump({"def __init__(self, a, b=_d_b):": 42}, f)     # not code
    assert _run(tmp_path)["compiled"] == 1


def test_no_cache_folder_compiles_every_time(tmp_path):
    env_dir = ""                                   # PIPEGEN_CACHE_DIR empty: no cache
    assert _run(env_dir)["compiled"] == 1
    assert _run(env_dir)["compiled"] == 1
    assert not os.path.exists(_cache_file(tmp_path))
