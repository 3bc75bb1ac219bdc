"""System tests of faults: a killed agent, malformed payloads on every key.

The fleet runs in realtime in a background thread (``run_fleet`` installs no signal handler);
the test finds the children by command line and disturbs them from the main thread.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import msgpack
import numpy as np
import pytest
from process_helpers import processes_mentioning
from system_helpers import (
    HERE,
    events,
    leftover_in_groups,
    load_trajectory,
    run,
)
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Event
from tlfleet.bus.transport import TransportConfig
from tlfleet.bus.zenoh.transport import open_transport

pytestmark = pytest.mark.system
TWO = HERE / "two_robots.toml"


class Background:
    """``run(...)`` in a thread; ``result`` / ``error`` afterwards."""

    def __init__(self, **kwargs):
        self.result = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._main, kwargs=kwargs, daemon=True)
        self.thread.start()

    def _main(self, **kwargs):
        try:
            self.result = run(**kwargs)
        except BaseException as exc:
            self.error = exc

    def join(self, timeout: float = 120.0):
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "the run did not end"
        if self.error is not None:
            raise self.error
        return self.result


def wait_until_started(run_dir: Path, t_min: float, timeout: float = 60.0) -> None:
    """Wait until the recorded trajectory reaches sim time ``t_min`` [s]."""
    deadline = time.monotonic() + timeout
    path = run_dir / "trajectory.csv"
    while time.monotonic() < deadline:
        if path.exists():
            lines = path.read_text().splitlines()
            if len(lines) > 1 and lines[-1].count(",") and float(lines[-1].split(",")[0]) >= t_min:
                return
        time.sleep(0.05)
    raise AssertionError(f"the run never reached t = {t_min} s")


def agent_process(robot: int):
    for proc in processes_mentioning(str(TWO.resolve())):
        cmd = proc.cmdline()
        if "agent" in cmd and "--robot" in cmd and cmd[cmd.index("--robot") + 1] == str(robot):
            return proc
    raise AssertionError(f"no agent process for robot {robot}")


def test_killed_agent_is_reported_the_robot_stopped_the_others_finish(tmp_path):
    run_dir = tmp_path / "run"
    bg = Background(scenario=TWO, out=run_dir, mode="realtime", duration=8.0)
    wait_until_started(run_dir, 2.5)
    killed_wall = time.time()
    os.kill(agent_process(2).pid, signal.SIGKILL)
    result = bg.join()
    assert result.outcome.reason in ("sim_done", "duration") and not result.clean
    (death,) = result.outcome.deaths
    assert death.process == "agent-2" and death.wall - killed_wall < 1.0
    recorded = [e for e in events(run_dir) if e["kind"] == "process_died"]
    assert [e["data"]["process"] for e in recorded] == ["agent-2"]
    stops = [e for e in events(run_dir) if e["kind"] == "watchdog_stop"]
    assert [e["data"]["robot"] for e in stops] == [2]
    watchdog = load_scenario(TWO).sim.watchdog
    t, s = load_trajectory(run_dir)
    assert t[-1] == pytest.approx(8.0)
    after = t >= death.t + watchdog + 0.5  # watchdog, then the deceleration
    assert after.sum() > 100
    assert np.ptp(s[2][after, 0]) < 1e-3 and np.ptp(s[2][after, 1]) < 1e-3
    assert np.ptp(s[1][after, 0]) + np.ptp(s[1][after, 1]) > 0.1  # robot 1 goes on
    assert result.exit_codes["agent-1"] == 0 and result.exit_codes["sim"] == 0
    assert result.exit_codes["agent-2"] == -signal.SIGKILL
    assert "process deaths: 1" in result.summary_text
    assert leftover_in_groups(run_dir) == []


GARBAGE = [
    b"",
    b"\xc1",
    b"not msgpack at all",
    msgpack.packb([1, 2, 3]),
    msgpack.packb({"v": 99, "k": "MocapFrame"}),
    msgpack.packb({"v": 1, "k": "MocapFrame", "t": "soon", "seq": -1, "poses": [[1]]}),
    msgpack.packb({"v": 1, "k": "Command", "robot": 1, "t": 0.0, "seq": 0, "u": ["x"]}),
    encode(Event(0.0, "intruder", "hello", {})),  # a valid message of the wrong kind
]


def test_malformed_payloads_on_every_key_crash_nothing_and_are_counted(tmp_path):
    run_dir = tmp_path / "run"
    scenario = load_scenario(TWO)
    fleet = scenario.fleet
    bg = Background(scenario=TWO, out=run_dir, mode="realtime", duration=6.0)
    wait_until_started(run_dir, 1.0)
    endpoint = json.loads((run_dir / "run.json").read_text())["endpoint"]
    intruder = open_transport(TransportConfig(mode="client", connect=(endpoint,)))
    targets = [keys.mocap(fleet), keys.clock(fleet), keys.control(fleet),
               keys.event(fleet, "sim", 0)]
    for robot in (1, 2):
        targets += [keys.cmd(fleet, robot), keys.status(fleet, robot)]
    try:
        for _ in range(3):
            for key in targets:
                for payload in GARBAGE:
                    if payload == GARBAGE[-1] and key == keys.event(fleet, "sim", 0):
                        continue  # a valid Event on the event key is not malformed
                    intruder.publish(key, payload)
            for payload in GARBAGE:
                intruder.query(keys.collab_from(fleet, 2, 1), payload, timeout=0.5)
            time.sleep(0.3)
    finally:
        intruder.close()
    result = bg.join()
    assert result.outcome.deaths == [] and result.clean, result.summary_text
    malformed = result.summary.deadlines.malformed_by_source
    assert malformed.get("sim", 0) >= 3 * 2 * len(GARBAGE) - 3  # on cmd keys (≈ all of them)
    assert malformed.get("agent/2", 0) > 0 and malformed.get("agent/1", 0) > 0
    assert any(k.startswith("coordinator") for k in malformed)
    assert result.summary.deadlines.malformed == sum(malformed.values())
    assert "malformed messages:" in result.summary_text
    assert leftover_in_groups(run_dir) == []


@pytest.mark.parametrize("paused", [1.5, 12.0], ids=["short-pause", "past-the-exit-grace"])
def test_a_forged_sim_done_during_a_pause_never_reads_clean(tmp_path, paused):
    """The issue's attack on an unsecured lockstep fleet: an agent withholds its command (here:
    SIGSTOP), the frames pause, and any local process publishes a ``sim_done`` claiming to be
    the simulator's. It used to end the run at once, ``clean``. Now the run waits for the
    simulator to end: after a short pause the frames go on and the forgery is flagged; after a
    pause longer than the supervisor's ``sim_exit_grace`` the run does end, and the verdict,
    which compares the end with the duration, says it failed."""
    run_dir = tmp_path / "run"
    bg = Background(scenario=TWO, out=run_dir, mode="lockstep", duration=20.0,
                    tick_timeout=paused + 10.0, sim_args=("--max-speed", "2"), rrd=False,
                    report=False, lease_ms=30_000)  # the paused agent's link outlives the pause
    wait_until_started(run_dir, 3.0)
    agent = agent_process(1)
    endpoint = json.loads((run_dir / "run.json").read_text())["endpoint"]
    forger = open_transport(TransportConfig(mode="client", connect=(endpoint,)))
    try:
        agent.send_signal(signal.SIGSTOP)
        time.sleep(0.7)  # the fleet waits for robot 1's command: no frame for 0.5 s and more
        fleet = load_scenario(TWO).fleet
        # no tick count: one that the frames recorded contradict is flagged at once
        forger.publish(keys.event(fleet, "sim", 0), encode(Event(20.0, "sim", "sim_done", {})))
        time.sleep(paused - 0.7)
    finally:
        agent.send_signal(signal.SIGCONT)
        forger.close()
    result = bg.join(180.0)
    assert result.verdict.label != "clean", result.verdict.line
    end = result.verdict.end
    assert end is not None and f"of {end.duration:g} s" in result.verdict.line
    info = json.loads((run_dir / "run.json").read_text())
    assert info["outcome"]["end"] == {"t": result.outcome.t_end, "duration": 20.0,
                                      "reason": result.outcome.reason}
    if paused < 10.0:  # the frames went on: the forgery is flagged, the run reaches its end
        assert result.outcome.t_end == pytest.approx(20.0)
        assert any(e["kind"] == "flagged_event" and e["data"].get("claimed_kind") == "sim_done"
                   for e in events(run_dir))
        assert result.verdict.label == "degraded"
    else:
        assert result.outcome.t_end < 10.0 and result.verdict.label == "failed"
        assert any("before its duration" in r for r in result.verdict.reasons)
