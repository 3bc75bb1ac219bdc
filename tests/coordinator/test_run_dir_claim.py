"""The run directory is safe (``rundir.claim_run_dir``): ``--out`` never overwrites a run, a
second run cannot write into a directory another run is writing, and every bad ``--out`` is a
one-line error before anything starts."""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
from pathlib import Path

import pytest
from tlfleet.cli.main import main
from tlfleet.coordinator.record.rundir import (
    CLAIMED_ENV,
    LOCK,
    RunDirectoryError,
    claim_run_dir,
)

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "scenario1.toml"


def test_a_new_or_empty_directory_is_claimed_and_released(tmp_path):
    (tmp_path / "empty").mkdir()
    for path in (tmp_path / "a" / "b", tmp_path / "empty"):  # created with its parents; empty
        lock = claim_run_dir(path)
        assert path.is_dir() and (path / LOCK).read_text() == str(os.getpid())
        lock.release()
        assert not (path / LOCK).exists()
        lock.release()  # idempotent


def test_a_directory_that_holds_a_run_is_never_overwritten(tmp_path):
    (tmp_path / "report.md").write_text("an earlier run's report")
    with pytest.raises(RunDirectoryError, match=r"holds 1 file\(s\) already \(report.md\)"):
        claim_run_dir(tmp_path)
    assert (tmp_path / "report.md").read_text() == "an earlier run's report"


def test_a_directory_another_run_writes_into_is_refused(tmp_path):
    lock = claim_run_dir(tmp_path / "run")
    try:
        # another process trying the same: flock is per open file, as a second run's would be
        code = subprocess.run([sys.executable, "-c", (
            "import sys; from tlfleet.coordinator.record.rundir import claim_run_dir\n"
            f"try: claim_run_dir({str(tmp_path / 'run')!r})\n"
            "except Exception as e: print(e); sys.exit(7)")],
            capture_output=True, text=True, timeout=60)
        assert code.returncode == 7 and f"another run is writing into it (pid {os.getpid()})" \
            in code.stdout, code
    finally:
        lock.release()


def test_a_crashed_runs_lock_alone_does_not_block_a_new_run(tmp_path):
    (tmp_path / LOCK).write_text("12345")  # the lock file of a run that was SIGKILLed early
    fd = os.open(tmp_path / LOCK, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)  # nobody holds it
    finally:
        os.close(fd)
    claim_run_dir(tmp_path).release()


def test_the_launcher_hands_its_claim_to_its_supervise(tmp_path):
    lock = claim_run_dir(tmp_path / "run")
    (tmp_path / "run" / "logs").mkdir()  # what the namespace-host launcher writes first
    try:
        inherited = claim_run_dir(tmp_path / "run", {CLAIMED_ENV: str(tmp_path / "run")})
        inherited.release()  # a no-op: the launcher's claim stays
        assert (tmp_path / "run" / LOCK).exists()
        with pytest.raises(RunDirectoryError):
            claim_run_dir(tmp_path / "run", {CLAIMED_ENV: str(tmp_path / "other")})
    finally:
        lock.release()


@pytest.mark.parametrize("bad", ["file", "unwritable", "existing run", "empty string"])
def test_every_bad_out_is_one_line_before_anything_starts(tmp_path, capsys, monkeypatch, bad):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.txt").write_text("the user's own file")
    out = {"file": str(tmp_path / "notes.txt"),
           "unwritable": "/proc/self/no-such-dir/run",  # not creatable, even by root
           "existing run": str(tmp_path),
           "empty string": ""}[bad]
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(["run", str(SCENARIO), "--out", out, "--no-rrd", "-q"])
    err = [line for line in capsys.readouterr().err.splitlines()
           if line.strip() and not line.startswith("tlfleet run: links are plain TCP")]
    assert code == 1 and len(err) == 1 and err[0].startswith("tlfleet run: "), err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert (tmp_path / "notes.txt").read_text() == "the user's own file"
