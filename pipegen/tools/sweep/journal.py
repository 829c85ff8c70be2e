"""A sweep that survives being stopped (issue 29): each variant's rows are committed into the
output folder as its render job finishes, and ``--resume`` picks up from them.

``rows.jsonl`` (the journal): a first line with the sweep's identity (``sweep_identity``: the
technique files and their SHA-256, the variants, backends, scene and its SHA-256, size,
reference, build), then one line per rendered variant: its rows (the phase 1 columns: no frame
times, no command) and the names of its error map and image files.  After each variant the
journal, ``results.csv``, ``results.json`` (the rows so far, frame times empty) and the
variant's ``errors/`` and ``images/`` files are written with ``OutputDir.commit_files``: each
file is replaced atomically and listed in the manifest, so the folder is valid after any row
and a ``kill -9`` loses only the variants being rendered.

``--resume`` reads the journal back, refuses (a ``PipegenError`` naming what differs) when the
sweep's identity is not the journal's, and renders only the variants it lacks.  Frame times
are phase 2: a resumed sweep times every variant again, in one process, so that all its
figures come from the same conditions (timings of an earlier process are never mixed in).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

from pipegen.core.journal import (absolute as _absolute, check_identity, file_sha256,
                                  interrupts_deferred, read_back, read_journal)

__all__ = ["JOURNAL", "Journal", "SweepInterrupted", "file_sha256", "interrupts_deferred",
           "sweep_identity", "variant_key"]

JOURNAL = "rows.jsonl"
FORMAT = 1


class SweepInterrupted(Exception):
    """Ctrl-C during a sweep: ``rows`` of ``total`` rows are rendered and committed;
    ``timing``: it came during phase 2 (every row rendered, none timed)."""

    def __init__(self, rows: int, total: int, timing: bool):
        super().__init__(f"interrupted: {rows} of {total} rows done")
        self.rows, self.total, self.timing = rows, total, timing


def sweep_identity(variants: list, spec: dict, size: tuple, backends, reference: Optional[str],
                   reference_samples: int, general: bool, f64: bool) -> dict:
    """What makes a sweep's rows the same rows: a resumed sweep must match the journal's."""
    files = sorted({_absolute(v.file) for v in variants})
    return dict(format=FORMAT,
                files={f: file_sha256(f) for f in files},
                variants=[[_absolute(v.file), v.params_text] for v in variants],
                backends=list(backends),
                scene=spec.get("key"), scene_sha256=spec["path"] and file_sha256(spec["path"]),
                size=list(size), reference=reference, reference_samples=reference_samples,
                general=bool(general), f64=bool(f64))


def variant_key(v) -> str:
    return json.dumps([_absolute(v.file), v.params_text])


class Journal:
    """The journal of one sweep in ``out`` (an ``OutputDir``).  ``command``: the sweep's
    command line (written into the partial results.json)."""

    def __init__(self, out, resume: bool = False, command: str = ""):
        self.out = out
        self.resume = resume
        self.command = command
        self.lines: list[str] = []

    def start(self, identity: dict) -> dict:
        """Begin the journal; returns ``{variant_key: (rows, maps, images)}`` of the variants
        already rendered (none unless resuming)."""
        done: dict = {}
        self.lines = [json.dumps(dict(sweep=identity))]
        path = Path(self.out.path) / JOURNAL
        if not self.resume or not path.is_file():
            return done
        before, lines, entries = read_journal(path, "sweep", "sweep")
        check_identity(identity, before, self.out.path, WHAT, "sweep",
                       hint="give the same files, options and scene as the partial run (its "
                            "command is in results.json), or run without --resume to start "
                            "again")
        for line, entry in zip(lines, entries):
            names = entry["names"]
            done[json.dumps(entry["variant"])] = (
                entry["rows"], self._read_back("errors", names), self._read_back("images", names))
            self.lines.append(line)
        return done

    def _read_back(self, folder: str, names: list) -> dict:
        return {name: read_back(self.out.path, f"{folder}/{name}", "sweep",
                                "a rendered variant") for name in names}

    def record(self, v, rows: list, maps: dict, images: dict, results: dict) -> None:
        """Commit a rendered variant: its journal line, its error maps and images, and
        ``results`` ({file name: text}: results.csv and results.json with the rows so far).
        Ctrl-C waits until the commit is done (the folder then holds the variant or not).
        ``commit_files`` writes in order, the journal last."""
        self.lines.append(json.dumps(dict(variant=json.loads(variant_key(v)), rows=rows,
                                          names=sorted(maps))))
        files = {f"errors/{n}": data for n, data in maps.items()}
        files.update({f"images/{n}": data for n, data in images.items()})
        files.update({name: text.encode() for name, text in results.items()})
        files[JOURNAL] = self.text().encode()   # last: a row in the journal is in every file
        with interrupts_deferred():
            self.out.commit_files(files)

    def text(self) -> str:
        """The journal as the final outputs write it."""
        return "\n".join(self.lines) + "\n"


WHAT = {"files": "the technique files (or their contents)", "variants": "the variants (-p)",
        "scene": "the scene", "scene_sha256": "the scene file's content",
        "size": "the size", "reference_samples": "--reference-samples",
        "general": "--general", "f64": "the f64 evaluation",
        "backends": "the backends", "reference": "--reference"}
