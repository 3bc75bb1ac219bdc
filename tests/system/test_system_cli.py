"""``tlfleet run`` as a user runs it: a subprocess, its output, its exit code, Ctrl-C."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from process_helpers import processes_mentioning
from system_helpers import HERE, ROOT, leftover_in_groups
from tlfleet.coordinator.report.render import render_table
from tlfleet.coordinator.report.run_report import build_report

pytestmark = pytest.mark.system
TWO = HERE / "two_robots.toml"


def tlfleet_run(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tlfleet.cli", "run", str(TWO), *args],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_run_prints_the_summary_and_the_run_directory(tmp_path):
    proc = tlfleet_run("--lockstep", "--duration", "5", "--out", str(tmp_path / "run"))
    try:
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    run_dir = tmp_path / "run"
    assert out.startswith("report two_robots")
    # the printed table is the one the run directory's files give when the report is rebuilt
    assert render_table(build_report(run_dir)) in out
    assert f"report:  {run_dir / 'report.md'}" in out
    figures = sorted(run_dir.glob("*.png"))
    assert figures and all(f"figure:  {path}" in out for path in figures)
    assert f"rerun:   {run_dir / 'run.rrd'}" in out
    last = out.rstrip().splitlines()
    assert last[-3] == f"run directory: {run_dir}"
    tasks = json.loads((run_dir / "run.json").read_text())["tasks"]
    assert last[-2] == tasks["line"] and last[-2].startswith("tasks: ")
    assert last[-1].startswith("outcome: clean")
    assert (run_dir / "summary.txt").read_text().rstrip().splitlines()[-2:] == last[-2:]
    assert "\r[" not in err  # stderr is not a terminal: no progress bar
    assert (run_dir / "summary.txt").read_text().startswith("run two_robots")
    assert leftover_in_groups(tmp_path / "run") == []
    assert_rrd_matches_trajectory(tmp_path / "run")


def assert_rrd_matches_trajectory(run_dir) -> None:
    """run.rrd (written after the run) reads back with rerun's reader: robots over the
    trajectory's whole sim-time range."""
    from rerun.chunk import RrdReader

    times = [float(line.split(",", 1)[0])
             for line in (run_dir / "trajectory.csv").read_text().splitlines()[1:]]
    robots = [chunk for chunk in RrdReader(str(run_dir / "run.rrd")).stream().to_chunks()
              if chunk.entity_path == "/world/robots" and "sim_time" in chunk.timeline_names]
    ns = [v for c in robots for v in c.to_record_batch().column("sim_time").cast("int64")
          .to_pylist()]
    assert (min(ns), max(ns)) == (round(times[0] * 1e9), round(times[-1] * 1e9))


def test_ctrl_c_stops_every_process_and_exits_130(tmp_path):
    proc = tlfleet_run("--realtime", "--out", str(tmp_path / "run"))
    try:
        deadline = time.monotonic() + 60
        trajectory = tmp_path / "run" / "trajectory.csv"
        while not (trajectory.exists() and len(trajectory.read_text().splitlines()) > 50):
            assert time.monotonic() < deadline and proc.poll() is None, "the run never started"
            time.sleep(0.05)
        # tlfleet run itself, the sim and 2 agents (the router has no scenario path)
        assert len(processes_mentioning(str(TWO))) == 4
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130
    assert "run directory:" in out
    assert "outcome: interrupted" in out  # the run says it was interrupted
    assert "the run was interrupted at t = " in err
    assert leftover_in_groups(tmp_path / "run") == []
