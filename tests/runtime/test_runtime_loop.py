"""The agent loop's protocol (architecture.md §3): start, due frames, stale mocap, malformed
payloads, stop — with a recording core, on the fake network."""

from __future__ import annotations

import threading
import time
import types

import numpy as np
import pytest
from runtime_helpers import FakeClock, FakeSim, stl_loop
from tlfleet.agent.policy.stl import build_agents
from tlfleet.agent.runtime.config import AgentConfig
from tlfleet.agent.runtime.inbox import CollabInbox, Mailbox, MalformedCounter
from tlfleet.agent.runtime.loop import AgentLoop, LoopConfig, TickInput, TickOutput
from tlfleet.agent.runtime.process import run_agent
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import CollabMessage, CollabReply, Command, MocapFrame

FLEET = "loop"
POSES = {1: (0.0, 0.0, 0.0), 2: (1.0, 0.0, 0.0)}


class RecordingCore:
    """Answers frame seq k with u = (k, 0): the loop's decisions are visible in the commands."""

    robot = 1
    zero = (0.0, 0.0)

    def __init__(self):
        self.inputs: list[TickInput] = []

    def step(self, state, inputs):
        self.inputs.append(inputs)
        return state + 1, TickOutput((float(inputs.frame.seq), 0.0))


def make_loop(network, divider=1, stale_after=0.5, clock=None):
    clock = clock or FakeClock()
    core = RecordingCore()
    loop = AgentLoop(network.transport("agent1"), LoopConfig(FLEET, 1, divider, stale_after),
                     core, 0, malformed=MalformedCounter("agent/1", clock=clock), clock=clock)
    loop.open()
    loop.ready()
    return loop, core, clock


def test_nothing_is_sent_before_start_and_due_frames_are_answered():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, core, _ = make_loop(network)
    assert keys.alive(FLEET, "agent", 1) in network.alive_keys()
    for _ in range(3):  # the sim's pre-start frames: t = 0, seq = 0, due = ()
        sim.frame(0.0, 0, POSES)
        assert loop.run_once(0.0)
    assert sim.commands == [] and core.inputs == []
    sim.control("start")
    sim.frame(0.0, 0, POSES, due=[1, 2])
    loop.run_once(0.0)
    sim.frame(0.01, 1, POSES, due=[2])  # lockstep: not due for robot 1
    loop.run_once(0.0)
    sim.frame(0.02, 2, POSES, due=[1, 2])
    loop.run_once(0.0)
    assert [(c.robot, c.seq, c.t, c.u) for c in sim.commands] == [(1, 0, 0.0, (0.0, 0.0)),
                                                                  (1, 2, 0.02, (2.0, 0.0))]
    assert loop.state == 2


def test_a_frame_listing_the_robot_starts_it_without_control():
    """A lockstep sim lists agents in ``due`` only after the start, so the first due frame may
    overtake Control(start) without a deadline miss."""
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, _, _ = make_loop(network)
    sim.frame(0.0, 0, POSES, due=[1])
    loop.run_once(0.0)
    assert loop.started and [c.seq for c in sim.commands] == [0]


def test_a_preview_frame_after_start_does_not_hide_tick_0():
    """Control(start) may overtake the sim's last preview frame (t = 0, seq = 0, due = ()): it is
    not answered, so the lockstep tick-0 frame (same seq) still is."""
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, _, _ = make_loop(network)
    sim.control("start")
    sim.frame(0.0, 0, POSES)
    loop.run_once(0.0)
    assert sim.commands == []
    sim.frame(0.0, 0, POSES, due=[1])
    loop.run_once(0.0)
    assert [c.seq for c in sim.commands] == [0]


def test_realtime_frames_are_due_once_per_control_period():
    """due = () (realtime): compute when seq // divider changes — every 20th frame at 5 Hz, and
    still once per period when the loop only sees every 7th frame."""
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, _, _ = make_loop(network, divider=20)
    sim.control("start")
    for k in range(100):
        sim.frame(k / 100, k, POSES)
        loop.run_once(0.0)
    assert [c.seq for c in sim.commands] == [1, 20, 40, 60, 80]  # tick 0 = the preview frame
    sim.commands.clear()
    for k in range(100, 200, 7):  # a slow loop: the slot keeps only the newest frame
        sim.frame(k / 100, k, POSES)
        loop.run_once(0.0)
    assert [c.seq // 20 for c in sim.commands] == [5, 6, 7, 8, 9]


def test_stale_mocap_means_zero_command_until_frames_return():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, _, clock = make_loop(network, stale_after=0.5)
    sim.control("start")
    sim.frame(1.0, 100, POSES, due=[1])
    loop.run_once(0.0)
    clock.advance(0.4)
    loop.run_once(0.0)
    assert [c.u for c in sim.commands] == [(100.0, 0.0)] and sim.kinds() == []
    clock.advance(0.2)  # 0.6 s without a frame
    loop.run_once(0.0)
    assert sim.commands[-1] == Command(1, 1.0, 100, (0.0, 0.0))
    assert sim.kinds() == ["stale_mocap"] and sim.events[0].data["silence"] >= 0.5
    clock.advance(0.1)
    loop.run_once(0.0)  # no new event, no new command within stale_after
    clock.advance(0.5)
    loop.run_once(0.0)  # the zero command is repeated every stale_after
    assert [c.u for c in sim.commands] == [(100.0, 0.0), (0.0, 0.0), (0.0, 0.0)]
    assert sim.kinds() == ["stale_mocap"]
    sim.frame(1.01, 101, POSES, due=[1])  # frames are back: normal commands
    loop.run_once(0.0)
    assert sim.commands[-1].u == (101.0, 0.0)
    clock.advance(0.6)
    loop.run_once(0.0)  # a second episode: a second event
    assert sim.kinds() == ["stale_mocap", "stale_mocap"] and loop.stats.stale_episodes == 2


def test_the_loop_blocks_until_its_next_staleness_check_and_at_most_wait_slice():
    """``block_for``: a wait ends when ``_check_stale`` can next act — the
    frame limit, then every zero command while stale — so a zenoh channel's timer need wake no
    more often; never longer than ``wait_slice``, never less than 1 ms."""
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, _, clock = make_loop(network, stale_after=0.5)
    assert loop.block_for() == loop.config.wait_slice == 0.25  # before start: the slice
    sim.control("start")
    sim.frame(1.0, 100, POSES, due=[1])
    loop.run_once(0.0)
    assert loop.block_for() == 0.25
    clock.advance(0.39)
    assert loop.block_for() == pytest.approx(0.11)
    clock.advance(0.109)  # 1 ms before the limit: not stale yet
    loop.run_once(0.0)
    assert loop.stats.stale_episodes == 0 and loop.block_for() == pytest.approx(0.001)
    clock.advance(0.002)  # 1 ms past it: stale, a zero command
    loop.run_once(0.0)
    assert loop.stats.stale_episodes == 1 and loop.stats.stale_commands == 1
    assert loop.block_for() == 0.25
    clock.advance(0.4)
    assert loop.block_for() == pytest.approx(0.1)  # the next zero command
    clock.advance(0.099)
    loop.run_once(0.0)
    assert loop.stats.stale_commands == 1
    clock.advance(0.002)
    assert loop.block_for() == 0.001
    loop.run_once(0.0)
    assert loop.stats.stale_commands == 2


def test_no_stale_commands_before_start():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, _, clock = make_loop(network)
    clock.advance(10.0)
    loop.run_once(0.0)
    assert sim.commands == [] and sim.events == []


@pytest.mark.parametrize("payload", [b"", b"\xc1", b"garbage", encode(Command(1, 0.0, 0, (0.0,))),
                                     b"\x82\xa1v\x01\xa1k\xaaMocapFrame"])
def test_malformed_mocap_and_control_are_counted_and_reported(payload):
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, _, clock = make_loop(network)
    sim.control("start")
    sim.raw(keys.mocap(FLEET), payload)
    assert loop.run_once(0.0)
    sim.raw(keys.control(FLEET), payload)
    assert loop.run_once(0.0)
    sim.raw(keys.mocap(FLEET), payload)  # within the report interval: counted, not reported
    assert loop.run_once(0.0)
    assert loop.malformed.counts == {keys.mocap(FLEET): 2, keys.control(FLEET): 1}
    events = [e for e in sim.events if e.kind == "malformed_message"]
    assert [e.data["key"] for e in events] == [keys.mocap(FLEET), keys.control(FLEET)]
    clock.advance(1.0)
    sim.raw(keys.mocap(FLEET), payload)
    loop.run_once(0.0)
    last = [e for e in sim.events if e.kind == "malformed_message"][-1]
    assert last.data["count"] == 3 and last.data["new"] == 2
    sim.frame(0.0, 0, POSES, due=[1])  # still answering (after a stale episode: 1 s of junk)
    loop.run_once(0.0)
    assert sim.commands[-1].seq == 0 and loop.stats.steps == 1


def test_a_frame_without_the_own_row_is_malformed():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, core, _ = make_loop(network)
    sim.frame(0.0, 0, {2: (1.0, 0.0, 0.0)}, due=[1])
    loop.run_once(0.0)
    assert core.inputs == [] and sim.commands == []
    assert loop.malformed.total == 1


def test_malformed_collab_queries_are_rejected_and_counted():
    scenario = load_scenario("scenarios/scenario1.toml")
    network = FakeNetwork()
    sim = FakeSim(network, scenario.fleet)
    loop, _ = stl_loop(network, scenario.fleet, build_agents(scenario, robots=[4])[4])
    asker = network.transport("asker")
    key = keys.collab_from(scenario.fleet, 4, 3)  # robot 3's key to robot 4
    wrong = CollabMessage("status", 3, 5, 0.0, 0)  # addressed to robot 5
    no_funnel = CollabMessage("request", 3, 4, 0.0, 0)
    no_time = CollabMessage("status", 3, 4, float("nan"), 0)
    impostor = CollabMessage("status", 5, 4, 0.0, 0)  # robot 5's message on robot 3's key
    for payload in (b"\x00\x01", encode(wrong), encode(no_funnel), encode(no_time),
                    encode(impostor)):
        (reply,) = asker.query(key, payload, 0.1)
        answer = decode(CollabReply, reply)
        assert not answer.accepted and answer.reason
    # well-formed, but for a sub-task robot 4 takes no part in: refused, counted, not malformed
    (reply,) = asker.query(key, encode(CollabMessage("release", 3, 4, 0.0, 7)), 0.1)
    assert not decode(CollabReply, reply).accepted and loop.link.refused == 1
    good = CollabMessage("status", 3, 4, 0.0, 0, c=0, task_kind="G", a=21.0, b=30.0)
    (reply,) = asker.query(key, encode(good), 0.1)
    assert decode(CollabReply, reply).accepted
    assert loop.malformed.counts == {key: 5}
    assert len(loop.link.inbox) == 1
    sim.control("start")
    poses = {r.id: r.pose for r in scenario.robots}
    sim.frame(0.01, 1, poses, due=[4])
    loop.run_once(0.0)  # the loop reports the malformed queries and keeps working
    assert "malformed_message" in sim.kinds("agent/4")
    assert [c.seq for c in sim.commands] == [1] and len(loop.link.inbox) == 0


def test_control_stop_ends_the_loop_running_in_a_thread():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, _, _ = make_loop(network)
    loop.clock = time.monotonic
    result = {}
    thread = threading.Thread(target=lambda: result.setdefault("code", loop.run()))
    thread.start()
    try:
        sim.control("start")
        sim.frame(0.0, 0, POSES, due=[1])
        for _ in range(200):
            if sim.commands:
                break
            threading.Event().wait(0.01)
        sim.control("stop")
        thread.join(2.0)
        assert not thread.is_alive() and result["code"] == 0
        assert [c.seq for c in sim.commands] == [0]
    finally:
        loop.close()
        thread.join(2.0)
    assert keys.alive(FLEET, "agent", 1) not in network.alive_keys()


def test_a_stop_event_ends_the_loop():
    network = FakeNetwork()
    loop, _, _ = make_loop(network)
    stop = threading.Event()
    stop.set()
    assert loop.run(stop) == 0


# ----------------------------------------------------------------------------- inbox pieces


def test_mailbox_keeps_only_the_newest_frame_and_wakes_on_stop():
    box = Mailbox()
    box.put_frame(b"1")
    box.put_frame(b"2")
    box.put_control(b"c")
    wake = box.wait(0.0)
    assert wake.frame == b"2" and wake.controls == (b"c",) and not wake.stopped
    assert box.frames_overwritten == 1
    assert box.wait(0.0).frame is None
    threading.Timer(0.05, box.stop).start()
    assert box.wait(5.0).stopped


def test_collab_inbox_hands_over_in_harness_order_with_one_tick_latency():
    inbox = CollabInbox()
    inbox.put(1.00, 4, "4@1.00")
    inbox.put(0.99, 5, "5@0.99")
    inbox.put(0.99, 3, "3@0.99")
    inbox.put(1.01, 3, "3@1.01")
    assert inbox.take_before(1.00) == ("3@0.99", "5@0.99")
    assert inbox.take_before(1.00) == ()
    assert inbox.take_before(1.01) == ("4@1.00",)
    assert len(inbox) == 1


def test_loop_config_rejects_bad_values():
    with pytest.raises(ValueError, match="divider"):
        LoopConfig("f", 1, divider=0)
    with pytest.raises(ValueError, match="stale_after"):
        LoopConfig("f", 1, stale_after=0.0)


def test_mocap_frame_poses_reach_the_core_whole():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, core, _ = make_loop(network)
    sent = sim.frame(0.5, 50, POSES, due=[1])
    loop.run_once(0.0)
    assert core.inputs[0].frame == sent
    assert isinstance(core.inputs[0].frame, MocapFrame)
    assert np.allclose([row[1:] for row in sent.poses], [POSES[1], POSES[2]])


def test_a_failing_core_is_a_fault_event_and_exit_code_1():
    class BrokenCore:
        robot = 1
        zero = (0.0, 0.0)

        def step(self, state, inputs):
            raise RuntimeError("boom")

    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    config = AgentConfig(robot=1, stale_after=0.5)
    scenario = types.SimpleNamespace(fleet=FLEET, control_divider=lambda _robot: 1,
                                     control_phase=lambda _robot: 0)
    result = {}
    thread = threading.Thread(target=lambda: result.setdefault("code", run_agent(
        config, scenario, lambda *_: (BrokenCore(), 0, (), None),
        transport=network.transport("a1"), stop=threading.Event())))
    thread.start()
    try:
        deadline = time.monotonic() + 10
        while not network.alive_keys() and time.monotonic() < deadline:
            time.sleep(0.005)
        sim.control("start")
        sim.frame(0.01, 1, POSES, due=[1])
        thread.join(10)
        assert result["code"] == 1
    finally:
        sim.control("stop")
        thread.join(10)
    (fault,) = [e for e in sim.events if e.kind == "fault"]
    assert fault.source == "agent/1" and fault.data["error"] == "RuntimeError: boom"
    assert network.alive_keys() == []


class DeferringCore(RecordingCore):
    """Records, in ``after``, how many commands the sim held when ``after_command`` ran."""

    def __init__(self, sim):
        super().__init__()
        self.sim = sim
        self.after: list[tuple[int, int]] = []  # (state, commands at the sim)

    def after_command(self, state):
        self.after.append((state, len(self.sim.commands)))
        return state + 100


@pytest.mark.parametrize("lockstep", [True, False])
def test_after_command_runs_once_per_step_after_the_command_is_published(lockstep):
    """The work a step defers (the LTL global re-plan) runs after its command."""
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    clock = FakeClock()
    core = DeferringCore(sim)
    loop = AgentLoop(network.transport("agent1"), LoopConfig(FLEET, 1), core, 0,
                     malformed=MalformedCounter("agent/1", clock=clock), clock=clock)
    loop.open()
    loop.ready()
    sim.control("start")
    for seq in (1, 2, 3):
        sim.frame(0.01 * seq, seq, POSES, due=[1] if lockstep else [])
        loop.run_once(0.0)
    # the state after_command returns is the one the next step gets: 0 → 1 → 101 → 102 → ...
    assert core.after == [(1, 1), (102, 2), (203, 3)]
    assert loop.state == 303 and [c.seq for c in sim.commands] == [1, 2, 3]
    assert loop.summary()["mean_after_command_ms"] >= 0.0
