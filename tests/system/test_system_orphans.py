"""Nothing outlives its run (``tlfleet.bus.lifeline``): a SIGKILL of ``tlfleet run`` takes every
process of the run with it (PR_SET_PDEATHSIG), and processes started by someone else end once
their coordinator's liveliness token has been gone ``--orphan-after`` seconds."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from by_hand import start_by_hand, wait_until
from process_helpers import free_port, kill_group, processes_mentioning
from system_helpers import HERE, SCENARIOS
from tlfleet.coordinator.launch.processes import Launcher

pytestmark = pytest.mark.system
LEFT_AFTER = 5.0  # [s] wall: the bound for "no process of the run left"


def unique_scenario(tmp_path: Path, source: Path) -> tuple[Path, str]:
    """A copy of ``source`` whose name (and so fleet, on the router's command line) and path
    carry a marker no other process on the machine has."""
    marker = f"orphan{os.getpid()}x{time.monotonic_ns() % 10**6}"
    text = source.read_text().replace(f'name = "{source.stem}"', f'name = "{marker}"', 1)
    assert marker in text
    path = tmp_path / f"{marker}.toml"
    path.write_text(text)
    return path, marker


def rows(path: Path) -> int:
    try:
        return max(0, len(path.read_text().splitlines()) - 1)
    except OSError:
        return 0


def test_sigkill_of_tlfleet_run_leaves_no_process_of_the_run(tmp_path):
    scenario, marker = unique_scenario(tmp_path, SCENARIOS / "scenario1.toml")
    run_dir = tmp_path / "run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "tlfleet.cli", "run", str(scenario), "--lockstep", "--max-speed",
         "1", "--duration", "60", "--out", str(run_dir), "--no-report", "--no-rrd"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        assert wait_until(lambda: rows(run_dir / "trajectory.csv") > 20, 120.0), \
            proc.stderr.read().decode() if proc.poll() is not None else "no rows after 120 s"
        children = processes_mentioning(marker)
        assert len([p for p in children if p.pid != proc.pid]) >= 7  # router, sim, 5 agents
        os.kill(proc.pid, signal.SIGKILL)
        killed = time.monotonic()
        gone = wait_until(lambda: not processes_mentioning(marker), LEFT_AFTER, period=0.1)
        left = [(p.pid, " ".join(p.cmdline())[:120]) for p in processes_mentioning(marker)]
        assert gone, f"{len(left)} process(es) of the run left after {LEFT_AFTER} s: {left}"
        print(f"every process of the run gone {time.monotonic() - killed:.2f} s after the kill")
    finally:
        kill_group(proc)
        for leftover in processes_mentioning(marker):
            leftover.kill()


def test_processes_started_by_hand_exit_when_their_coordinator_is_gone(tmp_path):
    """A fleet started by hand (not children of the coordinator): SIGKILL of ``tlfleet
    supervise`` mid-run, and the sim and the agents exit about ``--orphan-after`` later; the
    router, which outlives runs by design, stays until Ctrl-C."""
    scenario, marker = unique_scenario(tmp_path, HERE / "two_robots.toml")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    orphan_after = 1.0
    launcher = Launcher(tmp_path / "logs")
    supervise = None
    try:
        start_by_hand(launcher, scenario, endpoint,
                      sim_args=("--max-speed", "1", "--orphan-after", str(orphan_after)),
                      agent_args=("--orphan-after", str(orphan_after)))
        supervise = subprocess.Popen(
            [sys.executable, "-m", "tlfleet.cli", "supervise", str(scenario), "--connect",
             endpoint, "--out", str(tmp_path / "run"), "--no-report", "--no-rrd"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        assert wait_until(lambda: rows(tmp_path / "run" / "trajectory.csv") > 20, 90.0)
        os.kill(supervise.pid, signal.SIGKILL)
        fleet = [c for c in launcher.children if c.name != "router"]
        assert wait_until(lambda: all(c.returncode is not None for c in fleet),
                          orphan_after + LEFT_AFTER), \
            {c.name: c.returncode for c in fleet}
        assert {c.name: c.returncode for c in fleet} == {c.name: 0 for c in fleet}
        for child in fleet:
            assert "coordinator's liveliness token has been gone" in child.log_path.read_text()
        router = next(c for c in launcher.children if c.name == "router")
        assert router.returncode is None
    finally:
        if supervise is not None:
            kill_group(supervise)
        launcher.stop_all(1.0)
        for leftover in processes_mentioning(marker):
            leftover.kill()
