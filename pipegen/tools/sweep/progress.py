"""Progress bars on stderr (tqdm), for the render jobs and the timing process."""

from __future__ import annotations

import sys


def progress_bar(total: int, desc: str, enabled: bool = True):
    try:
        from tqdm import tqdm
    except ImportError:                         # pragma: no cover - tqdm is a dependency
        class _Null:
            def update(self, n=1): pass
            def close(self): pass
            def set_postfix_str(self, s): pass
        return _Null()
    return tqdm(total=total, desc=desc, unit="job" if desc != "timing" else "frame",
                disable=not enabled, file=sys.stderr, dynamic_ncols=True, leave=True)

