"""Supervisor on the fake transport: readiness errors, death reports within 1 s, end of run."""

from __future__ import annotations

import os
import re
import signal
import sys
import threading
import time
from dataclasses import dataclass

import pytest
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import Control, Event, MocapFrame
from tlfleet.coordinator.launch.processes import Launcher, LaunchError
from tlfleet.coordinator.live.supervisor import Supervisor, SupervisorConfig, expected_tokens
from tlfleet.coordinator.record.recorder import Recorder, RecorderTap

SCENARIO = """
name = "sup"
fleet = "sup"
duration = 5.0
[[regions]]
name = "a1"
center = [-1.0, 0.0]
[[robots]]
id = 1
kind = "unicycle"
pose = [0.0, -1.0, 0.0]
ltl = "G F a1"
[[robots]]
id = 2
kind = "omni"
pose = [0.0, 1.0, 0.0]
stl = ["G[0,5] (dist(p2, p1) <= 2.5)"]
"""


@dataclass
class FakeChild:
    name: str
    returncode: int | None = None

    def log_tail(self, lines: int = 15) -> str:
        return f"  | last words of {self.name}"


@pytest.fixture
def fleet(tmp_path):
    path = tmp_path / "sup.toml"
    path.write_text(SCENARIO)
    scenario = load_scenario(path)
    net = FakeNetwork()
    coord = net.transport("coordinator")
    recorder = Recorder(tmp_path / "run", [1, 2])
    tap = RecorderTap(coord, scenario.fleet, recorder)
    children = {n: FakeChild(n) for n in ("router", "sim", "agent-1", "agent-2")}
    reports: list[str] = []
    sup = Supervisor(coord, scenario, tap, children, duration=5.0,
                     config=SupervisorConfig(ready_timeout=0.3, wall_timeout=10.0,
                                             poll_period=0.01, stop_grace=0.2),
                     report=reports.append)
    yield scenario, net, sup, children, reports
    sup.close()
    recorder.close()


def declare(net, scenario, names):
    transports = {}
    for name in names:
        t = net.transport(name)
        role, ident = ("sim", 0) if name == "sim" else ("agent", name.split("-")[1])
        t.declare_alive(keys.alive(scenario.fleet, role, ident))
        transports[name] = t
    return transports


def test_expected_tokens(fleet):
    scenario = fleet[0]
    assert expected_tokens(scenario) == {"tlfleet/sup/alive/sim/0": "sim",
                                         "tlfleet/sup/alive/agent/1": "agent-1",
                                         "tlfleet/sup/alive/agent/2": "agent-2"}


def test_wait_ready_names_who_did_not_come_up(fleet):
    scenario, net, sup, _children, _ = fleet
    declare(net, scenario, ["sim", "agent-1"])
    with pytest.raises(LaunchError, match=r"not up after 0.3 s .*: agent-2\n"
                                          r".*last words of agent-2"):
        sup.wait_ready()


def test_wait_ready_fails_early_when_a_child_exits(fleet):
    _scenario, _net, sup, children, _ = fleet
    children["agent-1"].returncode = 1
    with pytest.raises(LaunchError, match=r"agent-1 exited with code 1 .*\n.*last words"):
        sup.wait_ready()


def test_start_death_and_sim_done(fleet):
    scenario, net, sup, _children, reports = fleet
    peers = declare(net, scenario, ["sim", "agent-1", "agent-2"])
    controls = []
    peers["sim"].subscribe(keys.control(scenario.fleet),
                           lambda _k, p: controls.append(decode(Control, p).cmd))
    assert sup.wait_ready() < 0.3
    sup.start()
    assert controls == ["start"]
    sim = peers["sim"]
    killed_at = {}

    def script():
        for k in range(50):
            sim.publish(keys.mocap(scenario.fleet),
                        encode(MocapFrame(k / 10, k, ((1, 0.0, 0.0, 0.0), (2, 0.0, 1.0, 0.0)))))
            if k == 10:
                killed_at["wall"] = time.time()
                sup.children["agent-2"].returncode = -9  # the process is gone
                peers["agent-2"].kill()  # and its token with it
            time.sleep(0.005)
        sim.publish(keys.event(scenario.fleet, "sim", 0), encode(Event(4.9, "sim", "sim_done", {})))

    thread = threading.Thread(target=script)
    thread.start()
    outcome = sup.supervise()
    thread.join()
    assert outcome.reason == "sim_done"
    assert [d.process for d in outcome.deaths] == ["agent-2"]
    assert outcome.deaths[0].wall - killed_at["wall"] < 1.0
    assert outcome.deaths[0].how == "liveliness token lost"
    assert "agent-2 died (liveliness token lost)" in reports[0]
    assert "goes on without it" in reports[0]
    codes = sup.finish()
    assert controls == ["start", "stop"]
    assert codes == {"sim": None, "agent-1": None, "agent-2": -9}  # the other fakes never exit
    assert sup.tap.recorder.event_kinds["process_died"] == 1


def test_end_at_duration_and_on_stop_event(fleet):
    scenario, net, sup, _children, _ = fleet
    peers = declare(net, scenario, ["sim", "agent-1", "agent-2"])
    sup.wait_ready()
    sup.start()
    peers["sim"].publish(keys.mocap(scenario.fleet),
                         encode(MocapFrame(5.0, 500, ((1, 0.0, 0.0, 0.0), (2, 0.0, 1.0, 0.0)))))
    assert sup.supervise().reason == "duration"
    stop = threading.Event()
    stop.set()
    sup.tap.recorder.last_t = 0.0
    assert sup.supervise(stop).reason == "interrupted"


def test_sim_death_ends_the_run(fleet):
    scenario, net, sup, children, reports = fleet
    declare(net, scenario, ["sim", "agent-1", "agent-2"])
    sup.wait_ready()
    sup.start()
    children["sim"].returncode = -9
    outcome = sup.supervise()
    assert outcome.reason == "sim_died"
    assert "sim died (exited with code -9)" in reports[0] and "cannot go on" in reports[0]


def test_a_killed_child_process_is_reported_within_one_second(fleet, tmp_path):
    scenario, net, sup, _children, _reports = fleet
    declare(net, scenario, ["sim", "agent-1", "agent-2"])
    with Launcher(tmp_path / "logs") as launcher:
        real = launcher.start("agent-1", [sys.executable, "-c",
                                          "import time; print('up', flush=True); "
                                          "time.sleep(600)"])
        sup.children["agent-1"] = real
        sup.wait_ready()
        sup.start()
        killed = {}

        def kill():
            killed["wall"] = time.time()
            os.kill(real.pid, signal.SIGKILL)

        timer = threading.Timer(0.2, kill)
        timer.start()
        stop = threading.Event()
        threading.Timer(1.5, stop.set).start()
        outcome = sup.supervise(stop)
        timer.join()
    assert outcome.reason == "interrupted"  # the run went on until stopped
    (death,) = outcome.deaths
    assert death.process == "agent-1" and death.returncode == -signal.SIGKILL
    assert death.wall - killed["wall"] < 1.0


def test_the_sim_ending_by_itself_after_sim_done_is_not_a_death(fleet):
    scenario, net, sup, children, reports = fleet
    peers = declare(net, scenario, ["sim", "agent-1", "agent-2"])
    sup.wait_ready()
    sup.start()
    # the process exit and the token loss are seen before the sim_done event is drained
    children["sim"].returncode = 0
    peers["sim"].kill()
    sup.check()
    peers["agent-1"].publish(keys.event(scenario.fleet, "sim", 0),
                             encode(Event(5.0, "sim", "sim_done", {})))
    outcome = sup.supervise()
    assert outcome.reason == "sim_done" and outcome.deaths == [] and reports == []


def test_the_last_frame_counts_when_it_arrives_while_sim_done_is_read(fleet):
    """The sim publishes its last frame, then sim_done; they come through separate channels,
    so a drain may read the frames' channel just before both arrive and find sim_done alone.
    The outcome's t_end is still the last frame's (seen once as t_end 2.99 of 3.0 in CI)."""
    scenario, net, sup, children, _ = fleet
    peers = declare(net, scenario, ["sim", "agent-1", "agent-2"])
    sup.wait_ready()
    sup.start()
    sim = peers["sim"]
    poses = ((1, 0.0, 0.0, 0.0), (2, 0.0, 1.0, 0.0))
    for k in range(49):
        sim.publish(keys.mocap(scenario.fleet), encode(MocapFrame(k / 10, k, poses)))
    sup.check()
    assert sup.sim_time == pytest.approx(4.8)
    (events,) = [c for what, c in sup.tap._channels if what == "event"]
    recv = events.recv

    def recv_then_last_frame(timeout):
        item = recv(timeout)
        if item is not None:  # the last frame lands behind the drain's read of the frames
            sim.publish(keys.mocap(scenario.fleet), encode(MocapFrame(4.9, 49, poses)))
        return item

    events.recv = recv_then_last_frame
    children["sim"].returncode = 0  # the simulator has ended: its sim_done is plausible
    sim.publish(keys.event(scenario.fleet, "sim", 0), encode(Event(4.9, "sim", "sim_done", {})))
    outcome = sup.supervise()
    assert outcome.reason == "sim_done"
    assert outcome.t_end == pytest.approx(4.9)


def _started(net, scenario, sup):
    """The three tokens declared, the fleet ready and started; the peers by name."""
    peers = declare(net, scenario, ["sim", "agent-1", "agent-2"])
    sup.wait_ready()
    sup.start()
    return peers


def _blip(net, scenario, sup, peers, *, exit_code=None):
    """The sim's token goes (its transport killed) and comes back 0.1 s later from a new one,
    as when the coordinator's own session lapses and reconnects; ``exit_code``: the process
    is seen to exit meanwhile. Returns the supervision's outcome once sim_done arrives."""
    frame = MocapFrame(1.0, 100, ((1, 0.0, 0.0, 0.0), (2, 0.0, 1.0, 0.0)))
    peers["sim"].publish(keys.mocap(scenario.fleet), encode(frame))
    sup.check()
    peers["sim"].kill()
    sup.check()
    time.sleep(0.1)
    if exit_code is not None:
        sup.children["sim"].returncode = exit_code
    back = declare(net, scenario, ["sim"])["sim"]
    stop = threading.Event()

    def finish() -> None:  # as the simulator does: sim_done, then it exits
        back.publish(keys.event(scenario.fleet, "sim", 0), encode(Event(5.0, "sim", "sim_done",
                                                                         {})))
        back.kill()

    done = threading.Timer(sup.config.end_grace + 0.3, finish)
    done.start()
    threading.Timer(3.0, stop.set).start()  # bound: the run ends by itself well before
    try:
        return sup.supervise(stop)
    finally:
        done.cancel()
        stop.set()


def test_the_sims_token_gone_and_back_within_the_grace_is_a_blip_not_a_death(fleet):
    """CI rehearsal on a starved machine: the coordinator lost every token at once (a 500 ms
    lease lapsed), they came back 40 ms later, and the sim was declared dead ``end_grace``
    later anyway, ending the run. A token back while the process runs lifts the suspicion."""
    scenario, net, sup, _children, reports = fleet
    outcome = _blip(net, scenario, sup, _started(net, scenario, sup))
    assert outcome.reason == "sim_done" and outcome.deaths == [], reports
    (line,) = [r for r in reports if "blip" in r]
    # how long it was away depends on the machine's load (0.1 s asleep, then the checks)
    assert re.match(r"sim's liveliness token went at t = 1.00 s and came back 0\.\d+ s later",
                    line), line
    assert sup.tap.recorder.event_kinds["token_blip"] == 1
    assert sup.tap.recorder.event_kinds["process_died"] == 0


def test_the_sims_token_back_after_its_process_exited_is_still_a_death(fleet):
    scenario, net, sup, _children, reports = fleet
    outcome = _blip(net, scenario, sup, _started(net, scenario, sup), exit_code=-9)
    assert outcome.reason == "sim_died", reports
    assert [d.process for d in outcome.deaths] == ["sim"]
    assert sup.tap.recorder.event_kinds["token_blip"] == 0


def _checks_for(sup, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        sup.check()
        time.sleep(0.01)


@pytest.mark.parametrize("away", [0.1, None])
def test_without_a_handle_an_agents_token_back_within_the_grace_is_a_blip(fleet, away):
    """A compose run's coordinator lost every token at once and had them back 0.05 s later:
    each agent was a death and a recovery. Back within ``end_grace``: a blip; gone for good:
    a death once the grace is over. No handle on any process, as under ``tlfleet supervise``
    (by hand, compose): the tokens are all there is to go by."""
    scenario, net, sup, _children, reports = fleet
    sup.children.clear()
    peers = _started(net, scenario, sup)
    peers["agent-1"].kill()
    sup.check()
    if away is not None:
        time.sleep(away)
        declare(net, scenario, ["agent-1"])
    _checks_for(sup, sup.config.end_grace + 0.3)
    kinds = sup.tap.recorder.event_kinds
    if away is not None:
        assert (kinds["token_blip"], kinds["process_died"]) == (1, 0), reports
        assert any(r.startswith("agent-1's liveliness token went") for r in reports), reports
    else:
        assert (kinds["token_blip"], kinds["process_died"]) == (0, 1), reports
        assert list(sup.deaths) == ["agent-1"]
