"""Facts the whole package shares, at the bottom of its layers (every module may import them;
``pipegen/__init__.py`` re-exports them): the default output size and the version."""

from __future__ import annotations

import functools

#: Output size (width, height) when nothing else says: the built-in scene is rendered at it and
#: ``pipegen compile``/``info`` and ``Compiled.report`` state target memory at it.  A scene file
#: keeps the size it declares; ``--size`` overrides both.
DEFAULT_SIZE = (1280, 720)


@functools.cache
def version() -> str:
    """pipegen's version: its installed metadata's, else ``0.1.0+unknown``."""
    found = _version_from_metadata_folder()
    if found:
        return found
    try:
        from importlib.metadata import PackageNotFoundError, version as metadata_version
        return metadata_version("pipegen")
    except (ImportError, PackageNotFoundError):
        return "0.1.0+unknown"


def _version_from_metadata_folder() -> str | None:
    """The version in the first ``pipegen-*.dist-info`` (or ``pipegen*.egg-info``) folder on
    ``sys.path``, the distribution ``importlib.metadata.version`` finds, read without importing
    importlib.metadata: its import costs ~15 ms, and every ``pipegen compile`` writes the
    version into the output folder's manifest.  None when not found (then importlib.metadata
    decides)."""
    import os
    import sys
    for entry in sys.path:
        folder = entry or "."
        try:
            names = os.listdir(folder)
        except OSError:
            continue
        meta = [n for n in names if n.lower().startswith("pipegen-") and n.lower().endswith(
            ".dist-info")]
        meta += [n for n in names if n.lower().startswith(("pipegen-", "pipegen.")) and
                 n.lower().endswith(".egg-info")]
        for name in meta:
            inner = "METADATA" if name.lower().endswith(".dist-info") else "PKG-INFO"
            try:
                with open(os.path.join(folder, name, inner), encoding="utf-8") as f:
                    for line in f:
                        if line.startswith("Version:"):
                            return line[len("Version:"):].strip() or None
                        if not line.strip():
                            break          # the headers end at the first blank line
            except OSError:
                continue
    return None
