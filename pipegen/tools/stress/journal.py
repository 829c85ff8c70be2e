"""A stress run that survives being stopped (issue 29): each case is committed into the output
folder as it finishes, and ``--resume`` picks up from there (``pipegen/core/journal.py``).

``cases.jsonl`` (the journal): a first line with the run's identity (``stress_identity``: the
technique file and its SHA-256, the parameters, the base scene and its SHA-256, size, cases,
``--random``/``--seed``, reference, ``--general``), then one line per case rendered: its
``CaseRecord`` (the table row, the notes, the row against the reference, which build rendered
it, the SHA-256 of its scene, the files it wrote).  With each case the journal, ``table.txt``
(the table so far) and the case's worst-pixel PNGs and scene (a failing case) are written with
``OutputDir.commit_files``, so the folder is valid after any case and a ``kill -9`` loses only
the case in flight.

``--resume`` refuses a run whose identity is not the journal's and reuses each case the
journal holds whose scene is the same (``random`` scenes too: hypothesis, seeded, draws them
again in the same order, so the search replays up to where it stopped).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import pickle
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

from pipegen.core.diagnostics import PipegenError
from pipegen.core.journal import (absolute, check_identity, file_sha256, interrupts_deferred,
                                  read_back, read_journal)

JOURNAL = "cases.jsonl"
TABLE = "table.txt"
FORMAT = 1

WHAT = {"file": "the technique file", "file_sha256": "the technique file's content",
        "params": "the parameters (-p)", "scene": "the base scene (--scene)",
        "scene_sha256": "the base scene file's content", "size": "the size",
        "cases": "the cases", "random": "--random", "seed": "--seed",
        "reference": "--reference", "reference_samples": "--reference-samples",
        "general": "--general", "format": "the journal format"}


@dataclass
class CaseRecord:
    """What the outputs need of a case (``report.row``, ``report.notes``, ``reference_row``,
    the reference's notes on its scene), kept in the journal; ``build``: the facts of the
    variant that rendered it; ``scene_sha256``: of its scene (a resumed case must have the
    same scene); ``files``: the outputs it wrote (a failing case's PNGs and scene)."""
    case: str
    status: str
    row: list
    notes: list
    ref_row: Optional[list]
    ref_notes: list
    build: str
    scene_sha256: str
    files: list

    @property
    def failed(self) -> bool:
        return self.status == "FAIL"


def stress_identity(file, params: list, scene, size: tuple, cases: list, random: int,
                    seed: int, reference: Optional[str], reference_samples: int,
                    general: bool) -> dict:
    """What makes a stress run's cases the same cases: a resumed run must match the
    journal's."""
    return dict(format=FORMAT, file=absolute(file), file_sha256=file_sha256(file),
                params=list(params), scene=scene and absolute(scene),
                scene_sha256=scene and file_sha256(scene), size=list(size), cases=list(cases),
                random=random, seed=seed, reference=reference,
                reference_samples=reference_samples, general=bool(general))


def scene_sha256(scene) -> str:
    """A digest of a scene's content: the pickle of its fields (the same in every process for
    the same scene; not of the objects themselves, which rendering may give caches)."""
    return hashlib.sha256(pickle.dumps(dataclasses.astuple(scene))).hexdigest()


class StressJournal:
    """The journal of one stress run in ``out`` (an ``OutputDir``)."""

    def __init__(self, out, resume: bool = False):
        self.out = out
        self.resume = resume
        self.lines: list[str] = []
        self.records: dict[str, CaseRecord] = {}     # case name -> the latest record

    def start(self, identity: dict) -> dict:
        """Begin the journal; returns ``{case: CaseRecord}`` of the cases already rendered
        (none unless resuming)."""
        self.lines = [json.dumps(dict(stress=identity))]
        path = Path(self.out.path) / JOURNAL
        if not self.resume or not path.is_file():
            return {}
        before, lines, entries = read_journal(path, "stress", "stress run")
        check_identity(identity, before, self.out.path, WHAT, "stress run",
                       hint="give the same technique, options and scene as the partial run, "
                            "or run without --resume to start again")
        fields = {f.name for f in dataclasses.fields(CaseRecord)}
        for line, entry in zip(lines, entries):
            if set(entry) != fields:
                raise PipegenError(
                    None, f"--resume: '{path}' has a line pipegen cannot read",
                    hint="run the stress run again without --resume")
            self.records[entry["case"]] = CaseRecord(**entry)
            self.lines.append(line)
        return dict(self.records)

    def record(self, rec: CaseRecord, files: dict, table_text: str) -> None:
        """Commit a case: its journal line, its ``files`` ({name: bytes}) and ``table.txt``
        (``table_text``).  Ctrl-C waits until the commit is done; the journal is written
        last, so a case in the journal is in every file."""
        self.records[rec.case] = rec
        self.lines.append(json.dumps(dataclasses.asdict(rec)))
        files = dict(files)
        files[TABLE] = table_text.encode()
        files[JOURNAL] = self.text().encode()
        with interrupts_deferred():
            self.out.commit_files(files)

    def files_of(self, rec: CaseRecord) -> dict:
        """The files a committed case wrote, read back from the folder."""
        return {name: read_back(self.out.path, name, "stress run", f"case {rec.case}")
                for name in rec.files}

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


class JournaledRunner:
    """A ``Stress`` runner whose ``run_case`` returns a ``CaseRecord``: the journal's when it
    holds the case with the same scene, else the case rendered and committed.
    ``report_text(records)``: ``table.txt`` for the records so far."""

    def __init__(self, runner, journal: StressJournal, done: dict, reference,
                 report_text: Callable[[list], str]):
        self.runner, self.journal, self.done = runner, journal, done
        self.reference, self.report_text = reference, report_text

    def run_case(self, case) -> CaseRecord:
        digest = scene_sha256(case.scene)
        old = self.done.get(case.name)
        if old is not None and old.scene_sha256 == digest:
            return old
        from pipegen.tools.stress import report
        res = self.runner.run_case(case)
        files = case_files(res)
        ref_row = ref_notes = None
        if self.reference is not None:
            ref_row = list(report.reference_row(res))
            ref_notes = sorted(self.reference.notes(res.scene)) if res.scene is not None \
                else []
        rec = CaseRecord(res.case, res.status, list(report.row(res)), report.notes([res]),
                         ref_row, ref_notes or [], self.runner.build_key(case.scene), digest,
                         sorted(files))
        records = list({**self.journal.records, rec.case: rec}.values())
        self.journal.record(rec, files, self.report_text(records))
        return rec


def case_files(res) -> dict:
    """A failing case's outputs, {name: bytes}: the worst-pixel PNG of each target over its
    bound and (a named case) its scene as TOML with its OBJ files."""
    if not res.failed:
        return {}
    from pipegen.core.outdir import safe_name
    from pipegen.tools.stress.cases import scene_toml
    from pipegen.tools.stress.report import worst_pixels_png
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for t in res.targets:
            if not t.passed and res.images:
                worst_pixels_png(res, t, tmp / safe_name(f"{res.case}_{t.backend}_{t.key}",
                                                         ".png"))
        if not res.case.startswith("random"):
            scene_toml(res.scene, tmp, safe_name(res.case, ""))
        return {f.name: f.read_bytes() for f in sorted(tmp.iterdir()) if f.is_file()}
