"""The emitted GLSL, OpenCL C and reports of every shipped technique are byte-identical to the
recorded text (tests/golden/emitted.sha256): refactoring the compiler, plan or backends must not
change what runs.  An intended change regenerates the file (tests/golden/make_emitted_sha256.py)."""

from pathlib import Path

from golden.make_emitted_sha256 import GOLDEN, emitted_hashes


def test_emitted_text_is_unchanged():
    recorded = dict(line.split()[::-1] for line in GOLDEN.read_text().splitlines())
    now = emitted_hashes()
    assert sorted(now) == sorted(recorded), "the set of emitted files changed"
    changed = sorted(name for name in now if now[name] != recorded[name])
    assert not changed, f"emitted text changed: {changed}"
