"""What a sweep writes into its output folder (``results.csv``, ``results.json``,
``table.txt``, ``pareto.png``, ``errors/``, ``images/``, ``index.html``), and ``load_result``
to read a folder back."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

from pipegen.tools.sweep.pareto import pareto_png
from pipegen.tools.sweep.report_html import report_page
from pipegen.tools.sweep.result import COLUMNS, EXTRA_COLUMNS, JSON_ONLY, NUMERIC, SweepResult


def csv_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS + EXTRA_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in rows:
        out = {}
        for k in COLUMNS + EXTRA_COLUMNS:
            v = r.get(k)
            if isinstance(v, bool):
                v = "true" if v else "false"
            elif isinstance(v, list):                   # ties: row numbers, space-separated
                v = " ".join(map(str, v))
            elif v is None or (isinstance(v, float) and math.isnan(v)):
                v = ""
            elif isinstance(v, float):
                v = repr(round(v, 6))
            out[k] = v
        w.writerow(out)
    return buf.getvalue()


def json_text(result: SweepResult) -> str:
    from pipegen.proof.accuracy import finite_or_none
    def plain(v):                    # JSON has no NaN or infinity: null
        if isinstance(v, float):
            return finite_or_none(v)
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        return v
    rows = [{k: plain(r.get(k)) for k in COLUMNS + EXTRA_COLUMNS + JSON_ONLY}
            for r in result.rows]
    meta = dict(scene=result.scene, width=result.width, height=result.height,
                lights=result.lights, backends=list(result.backends), renders=result.where,
                timing=result.timing, notes=result.notes, references=result.references,
                command=result.command, warnings=result.warnings,
                columns=COLUMNS + EXTRA_COLUMNS)
    return json.dumps(dict(meta, rows=rows), indent=1) + "\n"


def load_result(folder) -> SweepResult:
    """A ``SweepResult`` read back from ``DIR/results.json`` (rows and metadata; no error
    maps), e.g. to redraw ``pareto.png``."""
    data = json.loads((Path(folder) / "results.json").read_text())
    rows = [{k: (math.nan if v is None and k in NUMERIC else v) for k, v in r.items()}
            for r in data["rows"]]
    return SweepResult(rows, data["scene"], data["width"], data["height"], data["lights"],
                       tuple(data["backends"]), data["renders"], data["timing"], data["notes"],
                       references=data.get("references", {}), command=data.get("command", ""),
                       warnings=data.get("warnings", []))


def write_outputs(result: SweepResult, out, journal: str = "") -> Path:
    """results.csv, results.json, table.txt, pareto.png, errors/, images/ and index.html into
    ``out`` (a path or an ``outdir.OutputDir``), through a staging folder like every pipegen
    output; ``journal``: the text of ``rows.jsonl`` (``journal.py``), kept with them."""
    from pipegen.core.outdir import as_output_dir
    out = as_output_dir(out, "sweep")
    with out.staging() as tmp:
        (tmp / "results.csv").write_text(csv_text(result.rows))
        (tmp / "results.json").write_text(json_text(result))
        (tmp / "table.txt").write_text(result.summary())
        pareto_png(result, tmp / "pareto.png")
        (tmp / "errors").mkdir()
        for name, data in result.maps.items():
            (tmp / "errors" / name).write_bytes(data)
        (tmp / "images").mkdir()
        for name, data in result.images.items():
            (tmp / "images" / name).write_bytes(data)
        (tmp / "index.html").write_text(report_page(result), encoding="utf-8")
        if journal:
            from pipegen.tools.sweep.journal import JOURNAL
            (tmp / JOURNAL).write_text(journal)
    return out.path
