"""Faults in a docker compose fleet: ``docker network disconnect`` /
``connect`` of robot 3's container and ``docker pause`` / ``unpause`` of robot 1's give the
outcomes the namespace-host cut (test_system_link_faults.py) and the process freeze
(test_system_fault_injection.py) give; ``docker kill`` + ``docker start`` of robot 2's container
gives those of the loopback restart (a death that comes back, the robot driven again).

One compose run of Scenario 1, **realtime** (in lockstep the fleet's sim time stands still while
a robot is cut or frozen, so the watchdog, the stale mocap and the catching up would not show),
60 s of sim time, with the knobs of the namespace-host test (lease 500 ms on every service,
watchdog 0.15 s, LTL robots at 10 Hz: ``test_system_link_faults.fast_watchdog``). The faults are
scheduled by the coordinator in its container and run on the host by ``tlfleet compose-faults``,
which ``docker/compose-run.sh`` starts (:mod:`tlfleet.coordinator.faults.handoff`).

Root, docker.io, docker-compose and mmdebstrap as the compose test needs (``need_docker``); the
image is the one that test builds (cached; rebuilt only when the sources changed). Bounded: the
script in 900 s; whatever it leaves when it is stopped (containers, network, a dockerd it started)
is removed in ``finally``.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys

import numpy as np
import pytest
import test_system_link_faults as link_faults
from needs import need_docker
from system_helpers import ROOT, SCENARIOS, events, load_trajectory, robot_robot_contacts
from tlfleet.agent.model.faults import parse_fault
from tlfleet.coordinator.compose import ComposeConfig, write_compose

pytestmark = [pytest.mark.system, pytest.mark.needs_system, pytest.mark.slow]
CUT, FREEZE, RESTART = "cut:robot3@20+3", "freeze:robot1@35+3", "restart:robot2@42"


WORK = os.environ.get("TLFLEET_DOCKER_WORK", "/tmp/tlfleet-docker")


def daemon_answers(env=None) -> bool:
    return subprocess.run(["docker", "version"], capture_output=True, env=env).returncode == 0


def private_daemon() -> dict[str, str]:
    """The environment that reaches the dockerd compose-run.sh starts (dockerd-start.sh)."""
    return dict(os.environ, DOCKER_HOST=f"unix://{WORK}/docker.sock")


def compose_command() -> list[str]:
    return ["docker", "compose"] if subprocess.run(
        ["docker", "compose", "version"], capture_output=True).returncode == 0 \
        else ["docker-compose"]


def listed(what: list[str], project: str, env=None) -> list[str]:
    done = subprocess.run(["docker", *what, "--filter", f"label=com.docker.compose.project="
                           f"{project}"], capture_output=True, text=True, timeout=60, env=env)
    return done.stdout.split()


def by_kind(run_dir, kind, source=None):
    return [e for e in events(run_dir) if e["kind"] == kind
            and (source is None or e["source"] == source)]


def about(run_dir, kind, process):
    return [e for e in by_kind(run_dir, kind) if e["data"].get("process") == process]


def test_scenario1_in_compose_a_cut_a_pause_and_a_restart_as_on_namespace_hosts(tmp_path):
    need_docker()
    had_daemon = daemon_answers()
    scenario = link_faults.fast_watchdog(SCENARIOS / "scenario1.toml",
                                         tmp_path / "scenario1.toml")
    file = write_compose(ComposeConfig(scenario, tmp_path / "compose.faults.yaml",
                                       mode="realtime", duration=60.0,
                                       lease_ms=link_faults.LEASE_MS,
                                       faults=tuple(map(parse_fault, (CUT, FREEZE, RESTART)))))
    run_dir = tmp_path / "run"
    script = subprocess.Popen(["bash", str(ROOT / "docker" / "compose-run.sh"), str(file),
                               str(run_dir)], cwd=ROOT, env=dict(os.environ, PYTHON=sys.executable),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              start_new_session=True)
    project = f"tlfleet-faults-{script.pid}"  # compose-run.sh: tlfleet-<name>-$$
    try:
        out, err = script.communicate(timeout=900)
    finally:
        if script.poll() is None:  # stopped by the timeout: its clean-up first, then ours
            os.killpg(script.pid, signal.SIGTERM)
            try:
                script.communicate(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(script.pid, signal.SIGKILL)
                script.communicate()
        env = None if had_daemon else private_daemon()
        if daemon_answers(env) and listed(["ps", "-aq"], project, env):
            subprocess.run([*compose_command(), "-p", project, "-f", str(file), "down",
                            "--timeout", "5"], capture_output=True, timeout=120, env=env)
        if not had_daemon and daemon_answers(env):  # only one dockerd-start.sh started
            subprocess.run(["bash", str(ROOT / "docker" / "dockerd-stop.sh"), WORK], timeout=60)
    assert script.returncode == 4, out[-3000:] + err[-3000:]  # degraded: the faults
    # every container and the network are gone; a dockerd the script started is gone again
    assert daemon_answers() == had_daemon
    assert had_daemon or not daemon_answers(private_daemon())
    if had_daemon:
        assert listed(["ps", "-aq"], project) == [] and listed(["network", "ls", "-q"],
                                                               project) == []
    executor = json.loads((run_dir / "logs" / "faults" / "executor.json").read_text())
    with pytest.raises(ProcessLookupError):
        os.kill(executor["pid"], 0)  # the host's executor ended with the script
    assert "5 request(s) handled" in (run_dir / "logs" / "compose-faults.log").read_text()
    for process, (stopped, lost, back) in check_outcomes(run_dir).items():
        if math.isnan(stopped):
            print(f"compose {process} restarted: process_died after {lost:.3f} s; "
                  f"process_recovered {back:.2f} s (sim) after the fault")
        else:
            print(f"compose {process}: stopped {stopped:.3f} s after its last command; "
                  f"link_lost after {lost:.3f} s; link_restored {back:.3f} s after the restore")


def check_outcomes(run_dir) -> dict[str, tuple[float, float, float]]:
    """What the namespace-host cut and the freeze tests assert, on the compose run's directory
    → {process: (stopped after its last command [s sim], link_lost after the fault [s wall],
    link_restored after the restore [s wall])}; for the restarted agent (nan, process_died after
    the fault [s wall], process_recovered after the fault [s sim])."""
    from tlfleet.coordinator.record import rundir

    files = rundir.read_run(run_dir, strict=True)  # every file is there and parses
    assert files.trajectory is not None and files.trajectory.t[-1] == pytest.approx(60.0)
    info = json.loads((run_dir / "run.json").read_text())
    assert info["reason"] in ("sim_done", "duration")
    assert [f["spec"] for f in info["faults"]] == [CUT, FREEZE, RESTART]
    starts, ends = by_kind(run_dir, "fault_start"), by_kind(run_dir, "fault_end")
    assert [e["data"]["spec"] for e in starts] == [CUT, FREEZE, RESTART] == \
        [e["data"]["spec"] for e in ends]
    t, states = load_trajectory(run_dir)
    figures = {}
    # the restart: robot 2's container killed and started again; its agent is a death that
    # comes back (a recovery), gets Control(start) again and drives its robot again
    (died,), (recovered,) = by_kind(run_dir, "process_died"), by_kind(run_dir,
                                                                      "process_recovered")
    assert died["data"]["process"] == "agent-2" == recovered["data"]["process"]
    how = [part.split()[:2] for part in starts[2]["data"]["how"].split("; ")]
    assert how == [["docker", "kill"], ["docker", "wait"]]
    assert starts[2]["data"]["then"].startswith("docker start ")  # after the ack
    assert 42.0 <= starts[2]["t"] < 42.3 and died["t"] >= starts[2]["t"] - 0.1
    after = t > recovered["t"] + 1.0
    assert after.sum() > 100
    assert np.ptp(states[2][after, 0]) + np.ptp(states[2][after, 1]) > 0.05
    logs = (run_dir / "logs" / "agent-2.log").read_text()
    assert logs.count("waiting for start") == 2  # one container, two processes
    figures["agent-2"] = (math.nan, died["data"]["wall"] - starts[2]["data"]["wall"],
                          recovered["t"] - starts[2]["t"])
    pairs = zip(starts[:2], ends[:2], strict=True)
    for (start, end), robot, at in zip(pairs, (3, 1), (20.0, 35.0), strict=True):
        process = f"agent-{robot}"
        assert at <= start["t"] < at + 0.3 and 3.0 <= end["data"]["lasted"] < 3.5
        assert start["data"]["how"].startswith(("docker network disconnect", "docker pause"))
        # the simulator's watchdog stops the robot within 0.2 s of its last command
        (stop,) = [e for e in by_kind(run_dir, "watchdog_stop") if e["data"]["robot"] == robot
                   and start["t"] - 0.2 < e["t"] < end["t"]]
        assert stop["t"] - stop["data"]["last_command_t"] <= 0.2
        held = (t > stop["t"] + 0.3) & (t < end["t"])
        assert held.sum() > 100
        assert np.ptp(states[robot][held, 0]) < 0.02 and np.ptp(states[robot][held, 1]) < 0.02
        after = t > end["t"] + 1.5
        assert np.ptp(states[robot][after, 0]) + np.ptp(states[robot][after, 1]) > 0.05
        # the coordinator: link_lost within 1 s (a paused container's session misses its
        # keep-alives: the router drops its link after the lease, as for a cut), link_restored
        # after the restore; the agent silent, then back
        (lost,), (restored,) = about(run_dir, "link_lost", process), \
            about(run_dir, "link_restored", process)
        assert 0.0 < lost["data"]["wall"] - start["data"]["wall"] < 1.0
        assert restored["data"]["wall"] > end["data"]["wall"]
        figures[process] = (stop["t"] - stop["data"]["last_command_t"],
                            lost["data"]["wall"] - start["data"]["wall"],
                            restored["data"]["wall"] - end["data"]["wall"])
        kinds = [(e["kind"], e["data"].get("robot")) for e in events(run_dir)
                 if e["kind"] in ("agent_silent", "agent_back")]
        silent = kinds.index(("agent_silent", robot))  # in the order recorded: an event's t
        assert ("agent_back", robot) in kinds[silent:]  # is the agent's newest frame time
        assert [e["data"]["robot"] for e in by_kind(run_dir, "agent_silent")
                if start["t"] <= e["t"] <= end["t"] + 1.0] == [robot]
        # the agent catches up with the newest frame (no burst of stale commands): the
        # simulator ignored at most one command, computed on the newest frame the agent had
        # when it resumed — at the latest the last one sent to it before the router dropped its
        # link (a paused agent's socket keeps taking frames until then: seen 35.6 for a pause at
        # 35.0 with the link lost at 35.65)
        resumed = by_kind(run_dir, "resumed", f"agent/{robot}")
        assert resumed and resumed[0]["t"] >= start["t"] and resumed[0]["data"]["gap"] >= 2.5
        late = [e for e in by_kind(run_dir, "stale_command", "sim") if e["data"]["robot"] == robot
                and start["t"] <= e["t"] <= end["t"] + 2.0]
        assert len(late) <= 1 and all(e["data"]["command_t"] <= lost["t"] for e in late)
    stats = {e["source"]: e["data"] for e in by_kind(run_dir, "agent_stats")}
    assert stats["agent/3"]["stale_episodes"] >= 1 and stats["agent/3"]["stale_commands"] >= 1
    for robot in (4, 5):  # the others never lost their frames
        assert stats[f"agent/{robot}"]["stale_episodes"] == 0
    # no contact; robot 3 completes its later sub-task F[57,58]
    assert robot_robot_contacts(run_dir) == []
    report = json.loads((run_dir / "report.json").read_text())
    assert report["verdicts"]["subtasks"]["3"][1]["verdict"] == "satisfied"
    rows = report["faults"]
    assert [r["spec"] for r in rows] == [CUT, FREEZE, RESTART]
    for row, kind in zip(rows, ("link_lost", "link_lost", "process_died"), strict=True):
        assert row["detection"]["kind"] == kind and row["detection"]["after_wall"] < 1.0
        assert row["min_clearance"] > 0
    text = (run_dir / "report.md").read_text()
    assert CUT in text and FREEZE in text and RESTART in text
    return figures
