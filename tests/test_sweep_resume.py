"""Sweeps that survive being stopped (issue 29 item 1): rows committed as they finish,
``--resume`` equal to an uninterrupted run (timings aside), Ctrl-C and ``kill -9`` mid-sweep,
a Dask worker killed mid-sweep (pipegen/tools/sweep/journal.py)."""

from __future__ import annotations

import csv
import json
import os
import signal
import threading
import time
from pathlib import Path

import pytest

from interrupted import finish, start, wait_until

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUE = str(ROOT / "pipelines/forward.pipe")
SCENE = str(ROOT / "examples/scenes/small.toml")
# four variants (pcf_taps), one render process: slow enough to stop in the middle
# the axis named, not the declared ones: forward.pipe may declare more (pcf_pattern did)
ARGS = [TECHNIQUE, "--scene", SCENE, "--size", "32x18", "--frames", "0", "--jobs", "1",
        "-p", "pcf_taps=1,4,9,16", "--no-progress"]
TIMING = {"frame_ms", "cpu_ms", "frame_ms_q1", "frame_ms_q3", "ties", "pareto"}
ROWS = 8                        # 4 variants x 2 backends

pytestmark = [pytest.mark.gl, pytest.mark.cl]


def sweep(*args, **kw):
    return start("sweep", *args, **kw)


def journal_rows(folder: Path) -> int:
    try:
        return len((folder / "rows.jsonl").read_text().splitlines()) - 1
    except OSError:
        return 0


def wait_for_rows(proc, folder: Path, n: int = 1) -> None:
    wait_until(proc, lambda: journal_rows(folder) >= n, "row")


def csv_rows(folder: Path) -> list[dict]:
    with open(folder / "results.csv", newline="") as f:
        return [{k: v for k, v in r.items() if k not in TIMING} for r in csv.DictReader(f)]


def json_rows(folder: Path) -> list[dict]:
    rows = json.loads((folder / "results.json").read_text())["rows"]
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("whole") / "sweep"
    rc, _, err = finish(sweep(*ARGS, "-o", out))
    assert rc == 0, err
    return out


def test_kill_9_then_resume_equals_an_uninterrupted_sweep(uninterrupted, tmp_path):
    out = tmp_path / "sweep"
    proc = sweep(*ARGS, "-o", out)
    wait_for_rows(proc, out)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done = journal_rows(out)
    assert 1 <= done < 4, "killed too late to test anything"
    # valid after any row: the rows so far, parsed
    assert len(csv_rows(out)) == 2 * done and len(json_rows(out)) == 2 * done
    rc, _, err = finish(sweep(*ARGS, "-o", out, "--resume"))
    assert rc == 0, err
    assert csv_rows(out) == csv_rows(uninterrupted)
    assert json_rows(out) == json_rows(uninterrupted)
    for name in sorted(os.listdir(uninterrupted / "images")):
        assert (out / "images" / name).read_bytes() == \
            (uninterrupted / "images" / name).read_bytes()


def test_ctrl_c_exits_130_with_valid_partial_outputs_and_the_resume_command(tmp_path):
    out = tmp_path / "sweep"
    proc = sweep(*ARGS, "-o", out)
    wait_for_rows(proc, out)
    stopped = time.monotonic()
    proc.send_signal(signal.SIGINT)
    rc, _, err = finish(proc, timeout=30)
    # a hang guard, not a timing (the stop takes about a second here; a loaded CI machine is
    # slower): the interrupt must not wait for the remaining rows
    assert time.monotonic() - stopped < 20
    assert rc == 130, err
    assert "Traceback" not in err
    assert "--resume" in err and "interrupted:" in err and f"of {ROWS} rows done" in err
    rows = csv_rows(out)
    assert 2 <= len(rows) < ROWS and len(json_rows(out)) == len(rows)
    assert {r["backend"] for r in rows} == {"gl", "cl"}


def test_resume_refuses_other_options(tmp_path):
    out = tmp_path / "sweep"
    rc, _, err = finish(sweep(TECHNIQUE, "--scene", SCENE, "--size", "32x18", "--frames", "0",
                              "-p", "pcf_taps=1", "--no-progress", "-o", out))
    assert rc == 0, err
    rc, _, err = finish(sweep(TECHNIQUE, "--scene", SCENE, "--size", "32x20", "--frames", "0",
                              "-p", "pcf_taps=1", "--no-progress", "-o", out, "--resume"))
    assert rc == 1 and "Traceback" not in err
    assert "--resume" in err and "the size differs" in err


def test_a_dask_worker_killed_mid_sweep_loses_and_repeats_nothing(tmp_path):
    distributed = pytest.importorskip("distributed")
    from pipegen.core.outdir import OutputDir
    from pipegen.tools.sweep.journal import Journal
    from pipegen.tools.sweep.run import run_sweep
    from pipegen.tools.sweep.variants import parse_axes

    out = tmp_path / "sweep"
    killed = []
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:   # closed before the sweep's own client
            pids = client.run(os.getpid)

        def kill_a_busy_worker():
            deadline = time.monotonic() + 60
            while journal_rows(out) < 1 and time.monotonic() < deadline:
                time.sleep(0.05)
            # the scheduler runs in this process: which worker is rendering a job now
            busy = [a for a, ws in list(cluster.scheduler.workers.items())
                    if ws.processing and a in pids]
            if busy:
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(busy[0])

        killer = threading.Thread(target=kill_a_busy_worker)
        killer.start()
        result = run_sweep([TECHNIQUE], SCENE, (32, 18),
                           parse_axes(["pcf_taps=1,4,9,16", "shadow_tiles=1,2"]), frames=0,
                           scheduler=cluster.scheduler_address, progress=False,
                           journal=Journal(OutputDir(out, "sweep")))
        killer.join()
    assert killed, "no worker was busy when the first row was in: nothing was tested"
    keys = [(r["params"], r["backend"]) for r in result.rows]
    assert len(keys) == 16 and len(set(keys)) == 16
    assert journal_rows(out) == 8


def test_a_commit_cut_short_leaves_the_folder_owned(tmp_path):
    """``commit_files`` killed between its manifest and its move: the file still holds what it
    was replacing, and the folder is still pipegen's (no 'changed since' refusal)."""
    import hashlib
    from pipegen.core.outdir import MANIFEST, OutputDir, _write_manifest, read_manifest

    out = OutputDir(tmp_path / "o", "sweep")
    out.commit_files({"results.csv": b"a\n1\n"})
    out.release()
    old = hashlib.sha256(b"a\n1\n").hexdigest()
    new = hashlib.sha256(b"a\n1\n2\n").hexdigest()
    # the manifest as commit_files writes it before the move
    _write_manifest(tmp_path / "o", "sweep", {"results.csv": new}, {"results.csv": old})
    assert read_manifest(tmp_path / "o") == {"results.csv": old}
    again = OutputDir(tmp_path / "o", "sweep")           # checked: no refusal
    again.commit_files({"results.csv": b"a\n1\n2\n"})
    assert (tmp_path / "o" / "results.csv").read_bytes() == b"a\n1\n2\n"
    assert "pending" not in (tmp_path / "o" / MANIFEST).read_text()
    assert read_manifest(tmp_path / "o") == {"results.csv": new}
    # a file the user edited is still refused
    (tmp_path / "o" / "results.csv").write_text("mine\n")
    with pytest.raises(Exception, match="changed since"):
        OutputDir(tmp_path / "o", "sweep")
