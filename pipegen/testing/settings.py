"""What a test run asks of ``pipegen.testing``, set by the pytest plugin (or by hand).

Plain module attributes, no imports: the plugin sets them from its command-line options before
any test runs, and ``pipegen.testing``'s functions read them when they compare.

- ``update_goldens``: ``assert_matches_golden`` writes (or rewrites) the goldens it is given
  instead of comparing (``pytest --pipegen-update-goldens``; also the environment variable
  ``PIPEGEN_UPDATE_GOLDENS=1``).  Never on in a normal run: a missing golden fails with the
  command that creates it.
- ``keep_images``: every comparison keeps its pictures (expected, actual, difference, ꟻLIP
  map) in its ``records.Comparison`` for the HTML report (``--pipegen-report=DIR``); off, only
  a failing comparison's error image is written.
- ``artifacts_dir``: where error images go (a folder per test when the plugin runs; else a
  ``pipegen-testing`` folder in the system's temporary folder).
- ``current_test``: the running test's id (pytest's node id), named in records and messages.
- ``general``: render the general build instead of the variant compiled for each scene (the
  default, as ``pipegen run``), wherever a function is not told (``general=``): ``pytest
  --pipegen-general``, or the environment variable ``PIPEGEN_GENERAL=1``.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Optional

update_goldens: bool = os.environ.get("PIPEGEN_UPDATE_GOLDENS", "") not in ("", "0")
keep_images: bool = False
artifacts_dir: Optional[Path] = None
current_test: str = ""
general: bool = os.environ.get("PIPEGEN_GENERAL", "") not in ("", "0")


def artifacts() -> Path:
    """The folder error images are written to (made on first use)."""
    path = artifacts_dir or Path(tempfile.gettempdir()) / "pipegen-testing"
    path.mkdir(parents=True, exist_ok=True)
    return path
