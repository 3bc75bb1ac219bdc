"""The bridge process without ROS: :class:`BridgeProcess` on the in-memory transport with a
recording link in place of rclpy. Commands go to the robot on arrival (before the loop's next
tick), pass the simulator's checks first, and frames carry the newest poses on the simulator's
keys."""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path

import pytest
from ros_harness import lab_toml
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.scenario.lab import load_lab
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import Command, Control, Event, MocapFrame
from tlfleet.sim.hardware.process import BridgeProcess, HardwareError
from tlfleet.sim.hardware.world import HardwareWorld
from tlfleet.sim.process import SimConfig

FLEET_FILE = Path(__file__).resolve().parent / "four_robots.toml"


class Link:
    def __init__(self):
        self.sent: list[tuple[float, int, tuple[float, float, float]]] = []
        self.lock = threading.Lock()

    def send(self, robot, twist):
        with self.lock:
            self.sent.append((time.monotonic(), robot, twist))


@pytest.fixture
def bridge(tmp_path):
    scenario = load_scenario(FLEET_FILE)
    lab_path = tmp_path / "lab.toml"
    lab_path.write_text(lab_toml([(r.id, r.kind) for r in scenario.robots], 3))
    link = Link()
    world = HardwareWorld(scenario, load_lab(lab_path), link)
    for r in scenario.robots:
        world.on_pose(r.id, *r.pose)
    net = FakeNetwork()
    process = BridgeProcess(net.transport("hw"), scenario,
                            SimConfig.for_scenario(scenario, mode="realtime", duration=2.0),
                            world)
    frames: list[MocapFrame] = []
    events: list[Event] = []
    probe = net.transport("probe")
    probe.subscribe(keys.mocap(scenario.fleet), lambda k, p: frames.append(decode(MocapFrame, p)))
    probe.subscribe(keys.all_events(scenario.fleet), lambda k, p: events.append(decode(Event, p)))
    thread = threading.Thread(target=process.run, daemon=True)
    thread.start()
    yield scenario, process, world, link, probe, frames, events
    process.stop_event.set()
    thread.join(5)


def wait(predicate, timeout=5.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return False


def command(probe, fleet, robot, frame, u):
    probe.publish(keys.cmd(fleet, robot), encode(Command(robot, frame.t, frame.seq, u)))


def test_commands_go_out_on_arrival_after_the_simulators_checks(bridge):
    scenario, _process, world, link, probe, frames, events = bridge
    fleet = scenario.fleet
    assert wait(lambda: frames)
    command(probe, fleet, 3, frames[-1], (0.1, 0.0, 0.0))  # before the start: nothing
    assert link.sent == [] and world.safety.dropped["before_start"] == 1
    probe.publish(keys.control(fleet), encode(Control("start")))
    assert wait(lambda: world.t0 is not None and len(frames) > 5)
    frame = frames[-1]
    command(probe, fleet, 3, frame, (0.1, 0.0, 0.0))  # robot 3 heads at 1 rad
    # the fake transport delivers inside publish(): sent by now means sent on arrival, not at
    # the loop's next tick
    assert link.sent, "not sent on arrival"
    _, robot, twist = link.sent[0]
    assert robot == 3
    assert twist == pytest.approx((0.1 * math.cos(1.0), -0.1 * math.sin(1.0), 0.0))
    n = len(link.sent)
    command(probe, fleet, 3, frame, (0.1, 0.0))  # wrong shape for an omni robot
    command(probe, fleet, 4, frame, (math.nan, 0.0, 0.0))  # non-finite
    probe.publish(keys.cmd(fleet, 1), encode(Command(2, frame.t, frame.seq, (0.1, 0.0))))
    old = frames[-1]
    time.sleep(0.3)  # 0.3 s > 5 control periods of a 100 Hz robot: stale
    newest = frames[-1]
    command(probe, fleet, 4, old, (0.1, 0.0, 0.0))
    assert [s for s in link.sent[n:] if s[2] != (0.0, 0.0, 0.0) and s[1] != 3] == []
    assert wait(lambda: any(e.kind == "stale_command" for e in events))
    stale = next(e for e in events if e.kind == "stale_command")
    # the age is on the frames' clock, which lags the wall clock after an overrun of the loop
    # (a loaded machine): at least what the frames' clock advanced, at most the 0.3 s slept
    # (plus 0.5 s for a process stalled on a loaded machine)
    assert newest.t - old.t > 0.05  # stale by the frames' own clock: 5 control periods
    assert stale.data["robot"] == 4 and newest.t - old.t <= stale.data["age"] < 0.3 + 0.5
    assert wait(lambda: any(e.kind == "malformed_message" for e in events), timeout=3.0)


def test_frames_carry_the_newest_poses_with_their_offset_on_the_sims_keys(bridge):
    scenario, _process, world, _link, probe, frames, _events = bridge
    world.on_pose(2, 1.0, -1.0, 0.5)
    assert wait(lambda: frames and frames[-1].pose(2) == (1.0, -1.0, 0.5))
    at_frames: list[MocapFrame] = []
    offsets = {s for r in scenario.robots if (s := scenario.frame_offset(r.id))}
    for s in offsets:
        probe.subscribe(keys.mocap_at(scenario.fleet, s),
                        lambda k, p: at_frames.append(decode(MocapFrame, p)))
    probe.publish(keys.control(scenario.fleet), encode(Control("start")))
    assert wait(lambda: len(at_frames) > 3)
    assert all(f.t > scenario.sim.mocap_rate ** -1 * f.seq for f in at_frames)  # sampled later
    assert at_frames[-1].pose(2) == (1.0, -1.0, 0.5)


def test_lockstep_is_refused(tmp_path):
    scenario = load_scenario(FLEET_FILE)
    lab_path = tmp_path / "lab.toml"
    lab_path.write_text(lab_toml([(r.id, r.kind) for r in scenario.robots], 3))
    world = HardwareWorld(scenario, load_lab(lab_path), Link())
    with pytest.raises(HardwareError, match="realtime only"):
        BridgeProcess(FakeNetwork().transport("hw"), scenario,
                      SimConfig.for_scenario(scenario, mode="lockstep"), world)
