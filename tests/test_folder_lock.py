"""Two writers, one folder (issue 29 item 4): the second pipegen asking for a folder that
another is writing gets a clear error at once, before any work, naming the holder; once the
first is done the folder is free; one process may claim its own folder twice."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path


from pipegen.core.folder_lock import lock_path
from pipegen.core.outdir import OutputDir, read_manifest

ROOT = Path(__file__).resolve().parents[1]
FORWARD = str(ROOT / "pipelines/forward.pipe")
HOLD = """
import sys, time
from pipegen.core.outdir import OutputDir
out = OutputDir(sys.argv[1], "run")
with out.staging() as tmp:
    (tmp / "from_holder.txt").write_text("holder")
    print("holding", flush=True)
    sys.stdin.readline()            # until the test says so
"""


def test_a_second_writer_is_refused_at_once_and_the_folder_never_mixes(tmp_path):
    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "holding"
        t0 = time.monotonic()
        r = subprocess.run([sys.executable, "-m", "pipegen", "run",
                            str(ROOT / "pipelines/forward.pipe"), "--size", "32x18",
                            "-o", str(out)], capture_output=True, text=True, timeout=120)
        assert r.returncode == 1 and "Traceback" not in r.stderr
        assert (f"error: output folder '{out}' is being written by another pipegen "
                f"(pid {holder.pid}, pipegen run)") in r.stderr
        assert "hint: wait for it to finish, or pass another folder with -o" in r.stderr
        assert "rendering" not in r.stderr                   # refused before any work
        assert time.monotonic() - t0 < 60
    finally:
        holder.communicate("go\n", timeout=60)
    assert holder.returncode == 0
    assert sorted(read_manifest(out)) == ["from_holder.txt"]       # the holder's alone
    r = subprocess.run([sys.executable, "-m", "pipegen", "run", FORWARD,
                        "--size", "32x18", "-o", str(out), "--force"], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr                            # free again
    assert "color.png" in read_manifest(out)


def test_one_process_may_claim_its_folder_twice_and_releases_it_with_the_last(tmp_path):
    out = tmp_path / "out"
    first = OutputDir(out, "check")
    second = OutputDir(out, "check")        # a helper's as_output_dir on the same path
    with second.staging() as tmp:
        (tmp / "a.txt").write_text("a")
    assert first.lock.held                  # still claimed by the first
    probe = subprocess.run([sys.executable, "-c",
                            "import sys; from pipegen.core.outdir import OutputDir; "
                            "OutputDir(sys.argv[1], 'run', force=True)", str(out)],
                           capture_output=True, text=True, timeout=60)
    assert probe.returncode == 1 and "is being written by another pipegen" in probe.stderr
    first.release()
    probe = subprocess.run(probe.args, capture_output=True, text=True, timeout=60)
    assert probe.returncode == 0, probe.stderr


def test_the_lock_lives_outside_the_users_folders(tmp_path):
    out = tmp_path / "new" / "out"
    o = OutputDir(out, "run")
    assert not out.exists() and not out.parent.exists()          # nothing created early
    assert tmp_path not in lock_path(out).parents
    assert lock_path(out) == lock_path(tmp_path / "new" / "." / "out")
    o.release()
