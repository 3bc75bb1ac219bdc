"""Every receiver survives: garbage never displaces the newest valid frame, implausible
frames and jumps are dropped and counted per key and source, an agent resuming after a freeze
answers the newest frame only; the sim ignores stale commands."""

from __future__ import annotations

import msgpack
from runtime_helpers import FakeClock, FakeSim
from tlfleet.agent.runtime.inbox import MalformedCounter
from tlfleet.agent.runtime.loop import AgentLoop, LoopConfig, TickOutput
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.bounds import FleetBounds
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Command, MocapFrame
from tlfleet.bus.protocol.plausibility import FrameGate, Verdict, max_jump_ticks
from tlfleet.sim.command_age import CommandAge

FLEET = "hard"
POSES = {1: (0.0, 0.0, 0.0), 2: (1.0, 0.0, 0.0)}
BOUNDS = FleetBounds((-3.5, 3.5, -3.5, 3.5), 90.0, 100.0, {1: (0.3, 1.0), 2: (0.2, 6.28)})


class Core:
    robot = 1
    zero = (0.0, 0.0)

    def __init__(self):
        self.seqs: list[int] = []

    def step(self, state, inputs):
        self.seqs.append(inputs.frame.seq)
        return state, TickOutput((0.0, 0.0))


def make(network, **config):
    clock = FakeClock()
    core = Core()
    loop = AgentLoop(network.transport("agent1"),
                     LoopConfig(FLEET, 1, 1, 0.5, bounds=BOUNDS, max_jump=100, **config),
                     core, 0, malformed=MalformedCounter("agent/1", clock=clock), clock=clock)
    loop.open()
    loop.ready()
    return loop, core, clock


def test_frame_gate_holds_single_jumps_and_accepts_confirmed_ones():
    gate = FrameGate(10)
    assert [gate.offer(s) for s in (0, 1, 5, 15)] == [Verdict.ACCEPTED] * 4
    assert gate.offer(10 ** 9) is Verdict.HELD  # one spoofed frame
    assert gate.offer(16) is Verdict.ACCEPTED  # the real stream goes on
    assert gate.offer(3) is Verdict.HELD  # backwards
    assert gate.offer(500) is Verdict.HELD  # a real jump (freeze) ...
    assert gate.offer(501) is Verdict.CONFIRMED  # ... confirmed by the next frame
    assert (gate.last, gate.held, gate.confirmed) == (501, 3, 1)
    fresh = FrameGate(10)
    assert fresh.offer(400) is Verdict.HELD and fresh.offer(401) is Verdict.CONFIRMED
    assert max_jump_ticks(100.0, [1, 20]) == 100 and max_jump_ticks(10.0, [20]) == 42


def test_garbage_and_implausible_frames_never_displace_the_newest_valid_frame():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, core, _ = make(network)
    rogue = network.transport("rogue")
    mocap = keys.mocap(FLEET)
    sim.control("start")
    loop.run_once(0.0)
    sim.frame(0.5, 50, POSES)  # the valid frame, then a burst of garbage on the same key
    rogue.publish(mocap, b"\xc1garbage")
    rogue.publish(mocap, msgpack.packb({"v": 1, "k": "MocapFrame", "t": [1], "seq": 1}))
    rogue.publish(mocap, encode(MocapFrame(1e5, 10 ** 7, ((1, 0.0, 0.0, 0.0),))))  # t=seq/rate
    rogue.publish(mocap, encode(MocapFrame(0.51, 51, ((1, 99.0, 0.0, 0.0),))))  # off the arena
    rogue.publish(mocap, encode(MocapFrame(60.0, 51, ((1, 0.0, 0.0, 0.0),))))  # t ≠ seq/rate
    assert loop.run_once(0.0)
    assert core.seqs == [50]  # the valid frame was answered
    assert sim.commands[-1].seq == 50 and sim.commands[-1].t == 0.5
    counter = loop.malformed
    assert counter.counts[mocap] == 5
    assert counter.kinds == {"malformed": 2, "implausible": 3}
    assert counter.by_source[(mocap, "sim")] == 5
    events = [e for e in sim.events if e.kind == "malformed_message"]
    assert len(events) == 1 and events[0].data["count"] == 1  # rate-limited: one report
    sim.frame(0.52, 52, POSES)  # the real stream goes on past the held jump
    loop.run_once(0.0)
    assert core.seqs == [50, 52]


def test_an_old_frame_after_a_newer_one_is_ignored():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, core, _ = make(network, )
    sim.control("start")
    sim.frame(0.5, 50, POSES)
    loop.run_once(0.0)
    loop.gate.last = 40  # as if the gate had let an older frame through (reordering)
    sim.frame(0.45, 45, POSES)
    loop.run_once(0.0)
    assert core.seqs == [50] and loop.stats.old_frames == 1


def test_resuming_after_a_freeze_drops_the_backlog_and_answers_the_newest_frame():
    network = FakeNetwork()
    sim = FakeSim(network, FLEET)
    loop, core, clock = make(network)
    sim.control("start")
    sim.frame(0.5, 50, POSES)
    loop.run_once(0.0)
    clock.advance(3.0)  # frozen for 3 s: the transport then delivers the backlog
    sim.frame(0.6, 60, POSES)
    backlog = [MocapFrame(t / 100, t, ((1, 0.0, 0.0, 0.0), (2, 1.0, 0.0, 0.0)))
               for t in range(61, 66)]
    original = loop.mailbox.newer_frame

    def delivering(timeout):  # each settle wait sees one more backlog frame arrive
        if backlog:
            frame = backlog.pop(0)
            loop.mailbox.put_frame(encode(frame), frame)
        return original(timeout)

    loop.mailbox.newer_frame = delivering
    loop.run_once(0.0)
    assert core.seqs == [50, 65]  # one answer, to the newest frame
    assert loop.stats.resumes == 1 and loop.stats.backlog_dropped == 5
    resumed = [e for e in sim.events if e.kind == "resumed"]
    assert resumed and resumed[0].data["to_t"] == 0.65 and resumed[0].data["gap"] >= 3.0


def test_the_sim_ignores_commands_older_than_their_bound():
    ages = CommandAge({1: 1, 2: 20}, 100.0)
    assert ages.bound == {1: 0.05, 2: 1.0}  # 5 control periods, at least 50 ms
    commands = [Command(1, 0.90, 90, (0.0, 0.0, 0.0)), Command(2, 0.2, 20, (0.1, 0.0))]
    fresh, started = ages.fresh(commands, 1.0)  # robot 1's is 0.1 s old, robot 2's 0.8 s
    assert [c.robot for c in fresh] == [2] and [c.robot for c in started] == [1]
    fresh, started = ages.fresh([Command(1, 0.91, 91, (0.0, 0.0, 0.0))], 1.0)
    assert fresh == [] and started == []  # same episode: one report
    fresh, _ = ages.fresh([Command(1, 0.99, 99, (0.0, 0.0, 0.0))], 1.0)
    assert len(fresh) == 1 and ages.stale[1] == 2 and ages.episodes[1] == 1
    assert CommandAge({1: 1}, 100.0, max_age=0.5).bound == {1: 0.5}
