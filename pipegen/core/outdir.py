"""Output folders: write into a folder without ever deleting or overwriting a file pipegen did
not write.  ``compile``, ``run`` and ``check`` (and ``Compiled.write``, ``save_pngs``) all go
through ``OutputDir``:

    out = OutputDir("out/forward", "run", force=False)   # checked now, before any work
    with out.staging() as tmp:                            # a temporary folder
        ...write files into tmp...                        # then moved into place on success

Rules:

- The folder may be absent (it is created), empty, or *owned*: it holds a manifest
  (``.pipegen-manifest.json``) listing the files pipegen wrote there, with their SHA-256.  A
  folder without a manifest is written into only when everything in it is pipegen's: sub-folders
  holding a manifest of their own (``build/check/<technique>`` inside ``build``, ``out/forward``
  inside ``out``) are other outputs.  Anything else makes it *foreign*: refused unless ``force``.
- Files no manifest lists (the user's notes, other outputs) are never removed, and never
  overwritten unless ``force`` is given and a new output has the same name; the same holds for
  a listed file whose content changed since pipegen wrote it.
- Everything is generated into a staging folder first (a hidden sibling when the folder does
  not exist yet, a hidden ``.pipegen-stage-*`` folder inside it when it does, so the final
  moves never cross a file system).  A failure while generating leaves the previous outputs
  exactly as they were.  On success each file is moved into place with ``os.replace`` (each
  output is at every moment either the old or the new file), files the previous manifest listed
  that this run no longer writes are removed, and the new manifest is written.  Nothing that no
  manifest lists is ever removed.
- The output path being a file, or a parent that cannot be created, is reported before any
  work as a ``PipegenError`` (exit status 1 on the command line).
- Long runs (``pipegen sweep``) also commit as they go (``commit_files``): each file is written
  beside its destination and moved in with ``os.replace``; the manifest first lists it with its
  new digest and, under ``"pending"``, the digest of the file it replaces, and is rewritten
  without ``pending`` once the move is done.  A process killed in between leaves a file whose
  content is one of the two: ``read_manifest`` takes either as pipegen's, so the folder stays
  owned and the next run (or ``--resume``) may write into it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator, Optional, Union

from pipegen.core.diagnostics import PipegenError
from pipegen.core.folder_lock import FolderLock

MANIFEST = ".pipegen-manifest.json"
STAGE_MARK = ".pipegen-stage-"     # staging folders and temporary manifests carry this
MAX_NAME_BYTES = 120               # longest file name pipegen writes (file systems allow 255)
_FOREIGN_SHOWN = 5


def safe_name(stem: str, suffix: str = "", limit: int = MAX_NAME_BYTES) -> str:
    """``stem + suffix``, or, when that is longer than ``limit`` bytes, the stem cut short and
    followed by ``-`` and 8 hex digits of its SHA-1: distinct stems keep distinct names, the
    same stem always gives the same name, and any legal pass or target name gives a file name
    every file system accepts."""
    name = stem + suffix
    if len(name.encode()) <= limit and "/" not in name and "\0" not in name:
        return name
    digest = hashlib.sha1(stem.encode()).hexdigest()[:8]
    keep = max(1, limit - len(suffix.encode()) - len(digest) - 1)
    cut = stem.replace("/", "_").replace("\0", "_").encode()[:keep].decode(errors="ignore")
    return f"{cut}-{digest}{suffix}"


class OutputDir:
    """A folder pipegen writes into; see the module docstring.  ``command`` (``"run"``,
    ``"compile"``, ``"check"``, ...) is recorded in the manifest."""

    def __init__(self, path: Union[str, os.PathLike], command: str = "pipegen",
                 force: bool = False):
        self.path = Path(path)
        self.command = command
        self.force = force
        self.lock: Optional[FolderLock] = None
        self.check()
        self.lock = FolderLock(self.path, command)   # one writer at a time (folder_lock.py)

    def release(self) -> None:
        """Let another process write into the folder (done once the outputs are in place)."""
        if self.lock is not None:
            self.lock.release()

    def __fspath__(self) -> str:
        return os.fspath(self.path)

    def __str__(self) -> str:
        return str(self.path)

    def __repr__(self) -> str:
        return f"OutputDir({str(self.path)!r}, {self.command!r}, force={self.force})"

    # -- checks, before any work -------------------------------------------------------------

    def check(self) -> None:
        """Raise ``PipegenError`` unless the folder can be written without losing anything."""
        p = self.path
        if p.is_symlink() and not p.exists():
            raise _error(f"output folder '{p}' is a broken symbolic link",
                         "remove the link or pass another folder with -o")
        if p.exists():
            if not p.is_dir():
                raise _error(f"output path '{p}' is a file, not a folder",
                             "pass a folder with -o (it is created if missing)")
            owned = read_manifest(p)
            foreign = [] if owned is not None else \
                foreign_entries(p, limit=_FOREIGN_SHOWN + 1)
            edited = [] if owned is None or self.force else edited_outputs(p, owned)
            if edited:
                raise _error(f"output folder '{p}': files pipegen wrote there were changed "
                             f"since ({', '.join(edited[:_FOREIGN_SHOWN])}"
                             f"{', ...' if len(edited) > _FOREIGN_SHOWN else ''}); a new run "
                             f"would overwrite them",
                             "move them away, pass another folder, or add --force (pipegen "
                             "then replaces only the files it writes again)")
            if foreign and not self.force:
                shown = ", ".join(foreign[:_FOREIGN_SHOWN]) + \
                    (", ..." if len(foreign) > _FOREIGN_SHOWN else "")
                raise _error(f"output folder '{p}' holds files pipegen did not write "
                             f"({shown})",
                             "pass an empty or new folder, or add --force to write into it "
                             "anyway (files pipegen did not write are never removed)")
            _probe(p)
            return
        ancestor = p.parent
        while not ancestor.exists() and ancestor != ancestor.parent:
            if ancestor.is_symlink():
                break
            ancestor = ancestor.parent
        if not ancestor.is_dir():
            raise _error(f"cannot create output folder '{p}': '{ancestor}' is not a folder",
                         "pass a folder with -o whose parents are folders")
        _probe(ancestor, creating=p)

    # -- writing -----------------------------------------------------------------------------

    @contextlib.contextmanager
    def staging(self) -> Iterator[Path]:
        """A temporary folder to write the outputs into; on leaving the block without an
        exception its files replace the previous outputs (``commit``), otherwise it is removed
        and the folder is left exactly as it was."""
        self.check()
        if self.lock is None or not self.lock.held:       # released by an earlier staging
            self.lock = FolderLock(self.path, self.command)
        if self.path.is_dir():
            stage = Path(tempfile.mkdtemp(prefix=STAGE_MARK, dir=self.path))
        else:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                stage = Path(tempfile.mkdtemp(prefix=f".{self.path.name}{STAGE_MARK}",
                                              dir=self.path.parent))
            except OSError as e:
                raise _error(f"cannot create output folder '{self.path}': "
                             f"{e.strerror or e}") from None
        try:
            yield stage
            self._commit(stage)
        finally:
            shutil.rmtree(stage, ignore_errors=True)
            self.release()

    def commit_files(self, files: dict[str, bytes]) -> None:
        """Write ``{relative path: content}`` into the folder now, each file atomically (the
        module docstring), adding them to the manifest; files not named are left alone.  For
        outputs that grow while a long run goes on (a sweep's rows as they finish)."""
        if self.lock is None or not self.lock.held:
            self.lock = FolderLock(self.path, self.command)
        out = self.path
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise _error(f"cannot create output folder '{out}': {e.strerror or e}") from None
        owned = read_manifest(out) or {}
        new = {rel: hashlib.sha256(data).hexdigest() for rel, data in files.items()}
        for rel in new:
            assert _is_relative(rel) and rel != MANIFEST, rel
            dest = out / rel
            if (dest.exists() or dest.is_symlink()) and not self.force and \
                    owned.get(rel) != _sha256(dest):
                raise _error(f"output folder '{out}': pipegen would overwrite a file it did not "
                             f"write ({rel})", "move it away, pass another folder, or add --force")
        pending = {rel: owned[rel] for rel in new if rel in owned and owned[rel] != new[rel]}
        _write_manifest(out, self.command, {**owned, **new}, pending)
        for rel, data in files.items():
            dest = out / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=STAGE_MARK, dir=dest.parent)
            try:
                with os.fdopen(fd, "wb") as f:
                    f.write(data)
                    f.flush()
                    os.fsync(f.fileno())
                os.replace(tmp, dest)
            except BaseException:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
                raise
        _write_manifest(out, self.command, {**owned, **new})

    def _commit(self, stage: Path) -> None:
        files = sorted(f.relative_to(stage).as_posix() for f in stage.rglob("*")
                       if f.is_file() or f.is_symlink())
        assert MANIFEST not in files, "outputs may not be called " + MANIFEST
        new = {rel: _sha256(stage / rel) for rel in files}
        if not self.path.exists() and not self.path.is_symlink():
            _write_manifest(stage, self.command, new)
            try:
                os.rename(stage, self.path)
                return
            except OSError:
                if not self.path.is_dir():
                    raise
                os.unlink(stage / MANIFEST)   # it appeared meanwhile: write into it
        self._move_into(stage, new)

    def _move_into(self, stage: Path, new: dict[str, str]) -> None:
        out = self.path
        old = read_manifest(out) or {}
        blocked, foreign, unchanged = [], [], set()
        for rel in new:
            dest = out / rel
            parent = dest.parent
            while parent != out:
                if parent.is_symlink() or (parent.exists() and not parent.is_dir()):
                    blocked.append(rel)
                parent = parent.parent
            if dest.is_dir() and not dest.is_symlink():
                blocked.append(rel)
            elif dest.exists() or dest.is_symlink():
                digest = _sha256(dest)
                if old.get(rel) != digest:
                    foreign.append(rel)
                elif digest == new[rel] and not dest.is_symlink():
                    unchanged.add(rel)      # pipegen's, and already what it would write
        if blocked:
            raise _error(f"cannot write into '{out}': a folder or file is in the way of "
                         f"{', '.join(sorted(set(blocked))[:_FOREIGN_SHOWN])}",
                         "pass an empty or new folder with -o")
        if foreign and not self.force:
            raise _error(f"output folder '{out}': pipegen would overwrite files it did not "
                         f"write ({', '.join(foreign[:_FOREIGN_SHOWN])})",
                         "move them away, pass another folder, or add --force")
        # Claim the union first: if this is interrupted, every file that may now be pipegen's
        # is listed, so the next run may replace or remove it.
        _write_manifest(out, self.command, {**old, **new})
        for rel in new:
            if rel in unchanged:      # left as it is: its content, and its mtime for make & co.
                continue
            dest = out / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(stage / rel, dest)
        for rel, digest in old.items():
            if rel in new:
                continue
            dest = out / rel
            if dest.is_file() and not dest.is_symlink() and _sha256(dest) == digest:
                dest.unlink()
                _prune_empty(dest.parent, out)
        _write_manifest(out, self.command, new)


def as_output_dir(out: Union[str, os.PathLike, OutputDir], command: str,
                  force: bool = False) -> OutputDir:
    return out if isinstance(out, OutputDir) else OutputDir(out, command, force)


def read_manifest(folder: Path) -> Optional[dict[str, str]]:
    """``{relative path: sha256}`` of the files pipegen wrote into ``folder``; None when it has
    no (readable) manifest."""
    try:
        data = json.loads((Path(folder) / MANIFEST).read_text())
        files = data["files"]
        if isinstance(files, dict) and all(isinstance(k, str) and isinstance(v, str)
                                           for k, v in files.items()):
            owned = {k: v for k, v in files.items() if _is_relative(k)}
            # a commit_files cut short: the file is still the one it was replacing
            for rel, before in (data.get("pending") or {}).items():
                if rel in owned and isinstance(before, str) and \
                        _sha256(Path(folder) / rel) == before:
                    owned[rel] = before
            return owned
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return None


def edited_outputs(folder: Path, owned: dict[str, str]) -> list[str]:
    """The files the manifest lists whose content is no longer what pipegen wrote (sorted)."""
    return sorted(rel for rel, digest in owned.items()
                  if (Path(folder) / rel).is_file() and _sha256(Path(folder) / rel) != digest)


def foreign_entries(folder: Path, limit: Optional[int] = None) -> list[str]:
    """Paths (relative, sorted) in ``folder`` that pipegen did not write: not the manifest,
    not a file it lists with the recorded content, not inside a sub-folder that is another
    pipegen output (holds a manifest), not a staging folder.  Stops after ``limit``."""
    folder = Path(folder)
    owned = read_manifest(folder) or {}
    found: list[str] = []

    def walk(d: Path, prefix: str) -> None:
        try:
            entries = sorted(os.scandir(d), key=lambda e: e.name)
        except OSError:
            found.append(prefix or ".")
            return
        for e in entries:
            if limit is not None and len(found) >= limit:
                return
            rel = prefix + e.name
            if (not prefix and e.name == MANIFEST) or STAGE_MARK in e.name:
                continue
            if e.is_dir(follow_symlinks=False):
                if not (Path(e.path) / MANIFEST).is_file():
                    walk(Path(e.path), rel + "/")
            elif rel not in owned or e.is_symlink() or _sha256(Path(e.path)) != owned[rel]:
                found.append(rel)

    walk(folder, "")
    return found


# -- helpers -----------------------------------------------------------------------------------


def _error(message: str, hint: str = "") -> PipegenError:
    return PipegenError(None, message, hint=hint)


def _probe(folder: Path, creating: Optional[Path] = None) -> None:
    """Prove that a folder can be created in ``folder`` (without leaving anything)."""
    try:
        os.rmdir(tempfile.mkdtemp(prefix=STAGE_MARK, dir=folder))
    except OSError as e:
        what = f"create output folder '{creating}'" if creating else f"write into '{folder}'"
        raise _error(f"cannot {what}: {e.strerror or e} ('{folder}')",
                     "pass a folder you can write to with -o") from None


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return ""
    return h.hexdigest()


def _write_manifest(folder: Path, command: str, files: dict[str, str],
                    pending: Optional[dict[str, str]] = None) -> None:
    from pipegen.core.defaults import version
    data = {"written_by": f"pipegen {version()}", "command": command,
            "note": "files pipegen wrote here; it replaces or removes only these",
            "files": dict(sorted(files.items()))}
    if pending:                     # commit_files: the digests of the files being replaced
        data["pending"] = dict(sorted(pending.items()))
    fd, tmp = tempfile.mkstemp(prefix=STAGE_MARK, dir=folder)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(data, f, indent=1)
            f.write("\n")
        os.replace(tmp, folder / MANIFEST)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _prune_empty(d: Path, top: Path) -> None:
    while d != top and top in d.parents:
        try:
            d.rmdir()
        except OSError:
            return
        d = d.parent


def _is_relative(rel: str) -> bool:
    parts = rel.split("/")
    return bool(rel) and not rel.startswith("/") and ".." not in parts and "" not in parts
