"""Regenerate ``emitted.sha256``: the SHA-256 of every shader, kernel and report that
``pipegen compile`` writes for the shipped techniques.  Run it only when a change to the emitted
text is intended, and say why in the commit:  python tests/golden/make_emitted_sha256.py
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).with_name("emitted.sha256")


def emitted_hashes() -> dict[str, str]:
    """``{"TECHNIQUE/relative/path": sha256}`` for the shaders, kernels and report of every
    shipped technique (the generated pipeline modules are left out: they hold the plan, whose
    spelling may change without changing what runs)."""
    sys.path.insert(0, str(ROOT))
    from pipegen.compiler.driver import compile_file

    out: dict[str, str] = {}
    here = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        # compiled by their path relative to the repository, which shaders and reports quote:
        # the hashes must not depend on where the repository is cloned
        os.chdir(ROOT)
        try:
            for pipe in sorted(Path("pipelines").glob("*.pipe")):
                folder = Path(tmp) / pipe.stem
                compile_file(pipe).write(folder)
        finally:
            os.chdir(here)
        for pipe in sorted((ROOT / "pipelines").glob("*.pipe")):
            folder = Path(tmp) / pipe.stem
            for f in sorted(folder.rglob("*")):
                if f.is_file() and f.suffix in (".vert", ".frag", ".cl", ".txt"):
                    rel = f"{pipe.stem}/{f.relative_to(folder).as_posix()}"
                    out[rel] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


if __name__ == "__main__":
    GOLDEN.write_text("".join(f"{h}  {name}\n" for name, h in emitted_hashes().items()))
    print(f"wrote {GOLDEN}")
