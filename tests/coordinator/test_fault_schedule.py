"""The fault scheduler on fake clocks, and the process actuator on real processes."""

from __future__ import annotations

import os
import signal
import sys
import time

import pytest
from tlfleet.agent.model.faults import FaultSpecError, parse_fault
from tlfleet.agent.scenario import load_scenario
from tlfleet.coordinator.faults.plan import run_faults
from tlfleet.coordinator.faults.schedule import FaultError, FaultScheduler, ProcessActuator
from tlfleet.coordinator.launch.processes import Launcher


class FakeActuator:
    def __init__(self):
        self.calls: list[tuple[str, str]] = []

    def check(self, fault):
        if fault.target == "agent-9":
            raise FaultError("no agent-9")

    def start(self, fault):
        self.calls.append(("start", fault.spec))
        if fault.target == "agent-2" and fault.kind == "kill":
            raise OSError("boom")
        return {"pid": 42}

    def end(self, fault):
        self.calls.append(("end", fault.spec))
        return {}


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def make(*specs):
    clock, events, said = Clock(), [], []
    actuator = FakeActuator()
    schedule = FaultScheduler([parse_fault(s) for s in specs], actuator, events.append,
                              said.append, clock=clock, wall=lambda: 1000.0 + clock.now)
    return schedule, actuator, clock, events, said


def test_faults_start_at_their_sim_time_and_end_after_their_wall_duration():
    schedule, actuator, clock, events, said = make("freeze:robot1@2+3", "kill:robot3@1")
    schedule.poll(0.5)
    assert actuator.calls == [] and events == []
    schedule.poll(1.0)
    assert actuator.calls == [("start", "kill:agent-3@1")]
    assert [e.kind for e in events] == ["fault_start", "fault_end"]  # a kill is over once done
    schedule.poll(2.02)
    assert actuator.calls[-1] == ("start", "freeze:agent-1@2+3")
    start = events[-1]
    assert (start.kind, start.t, start.source) == ("fault_start", 2.02, "coordinator")
    assert start.data["spec"] == "freeze:robot1@2+3" and start.data["wall"] == 1100.0
    assert start.data["pid"] == 42
    clock.now += 2.9
    schedule.poll(2.02)  # lockstep: sim time may stand still, the fault lasts wall time
    assert actuator.calls[-1][0] == "start"
    clock.now += 0.1
    schedule.poll(2.5)
    assert actuator.calls[-1] == ("end", "freeze:agent-1@2+3")
    end = events[-1]
    assert (end.kind, end.t) == ("fault_end", 2.5)
    assert end.data["lasted"] == pytest.approx(3.0) and end.data["start_t"] == 2.02
    assert end.data["wall"] == pytest.approx(1103.0)
    assert len(said) == 3
    findings = schedule.findings()
    assert findings == ["fault kill:robot3@1 injected at t = 1.00 s, ended at t = 1.00 s after "
                        "0.00 s wall",
                        "fault freeze:robot1@2+3 injected at t = 2.02 s, ended at t = 2.50 s "
                        "after 3.00 s wall"]


def test_close_ends_active_faults_and_reports_those_that_never_started():
    schedule, actuator, _clock, events, _said = make("cut:robot1@1+10", "cut:robot2@50+1")
    schedule.poll(1.0)
    schedule.close()
    assert actuator.calls == [("start", "cut:agent-1@1+10"), ("end", "cut:agent-1@1+10")]
    assert events[-2].kind == "fault_end" and events[-2].data["early"] is True
    skipped = events[-1]  # recorded, so the report's fault table lists it with its reason
    assert skipped.kind == "fault_skipped" and skipped.data["spec"] == "cut:robot2@50+1"
    reason = "the run ended at t = 1.00 s, before the fault's time t = 50 s"
    assert skipped.data["reason"] == reason
    assert schedule.findings()[1] == f"fault cut:robot2@50+1 skipped: {reason}"
    schedule.close()  # idempotent
    assert len(actuator.calls) == 2


def test_a_failing_fault_is_recorded_and_reported_and_the_run_goes_on():
    schedule, actuator, _clock, events, said = make("kill:robot2@1", "kill:robot1@1")
    schedule.poll(1.0)
    assert [c[1] for c in actuator.calls] == ["kill:agent-2@1", "kill:agent-1@1"]
    assert events[0].data["error"] == "boom"
    assert "FAILED: boom" in said[0]
    assert "(boom)" in schedule.findings()[0]


def test_a_fault_the_actuator_cannot_do_is_rejected_before_the_run():
    with pytest.raises(FaultError, match="no agent-9"):
        make("kill:robot9@1")


def test_process_faults_reject_link_cuts_with_the_reason():
    with pytest.raises(FaultError, match="cut drops links, which needs namespace hosts"):
        ProcessActuator.check_all([parse_fault("cut:robot3@20+3")])
    with pytest.raises(FaultError, match="partition drops links"):
        ProcessActuator.check_all([parse_fault("partition:host1,robot2@20+3")])
    ProcessActuator.check_all([parse_fault("freeze:robot3@20+3"), parse_fault("kill:sim@1"),
                               parse_fault("kill:router@1"), parse_fault("restart:robot1@1"),
                               parse_fault("restart:router@1")])  # its own router: restartable
    with pytest.raises(FaultError, match="use kill:sim"):
        ProcessActuator.check_all([parse_fault("restart:sim@1")])


def test_run_faults_merges_the_scenario_and_the_cli_and_checks_both(scenarios_dir):
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    extra = (parse_fault("kill:robot2@5"),)
    assert run_faults(scenario, extra) == extra
    with pytest.raises(FaultSpecError, match="no robot 9"):
        run_faults(scenario, (parse_fault("kill:robot9@5"),))
    with pytest.raises(FaultSpecError, match="not before the end of the run \\(10 s\\)"):
        run_faults(scenario, (*extra, parse_fault("kill:robot1@20")), duration=10.0)


SLEEPER = [sys.executable, "-c", "import time; print('up', flush=True); time.sleep(60)"]


def state(pid: int) -> str:
    with open(f"/proc/{pid}/stat") as handle:
        return handle.read().rsplit(")", 1)[1].split()[0]


def wait_for_ups(log, count: int) -> None:
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        if log.is_file() and log.read_text().count("up") >= count:
            return
        time.sleep(0.01)
    raise AssertionError(f"{log} never said 'up' {count} times")


def test_the_process_actuator_freezes_kills_and_restarts_a_child(tmp_path):
    log = tmp_path / "logs" / "agent-1.log"
    with Launcher(tmp_path / "logs") as launcher:
        first = launcher.start("agent-1", SLEEPER)
        wait_for_ups(log, 1)
        children = {"agent-1": first}
        actuator = ProcessActuator(launcher, children)
        freeze = parse_fault("freeze:robot1@0+1")
        assert actuator.start(freeze) == {"pid": first.pid}
        deadline = time.monotonic() + 5
        while state(first.pid) != "T" and time.monotonic() < deadline:
            time.sleep(0.01)
        assert state(first.pid) == "T"
        actuator.end(freeze)
        while state(first.pid) == "T" and time.monotonic() < deadline:
            time.sleep(0.01)
        assert state(first.pid) != "T"
        done = actuator.start(parse_fault("restart:robot1@0"))
        assert first.returncode == -signal.SIGKILL
        second = children["agent-1"]
        assert done == {"pid": first.pid, "new_pid": second.pid} and second.pid != first.pid
        assert second.argv == first.argv and second.returncode is None
        assert [c.name for c in launcher.children] == ["agent-1"]
        wait_for_ups(log, 2)  # the restarted child writes on in the same log
        actuator.start(parse_fault("kill:robot1@0"))
        assert second.returncode == -signal.SIGKILL
        with pytest.raises(FaultError, match="no child process 'agent-7'"):
            actuator.start(parse_fault("kill:robot7@0"))
    assert log.read_text().count("up") == 2
    with pytest.raises(ProcessLookupError):
        os.killpg(second.pid, 0)
