"""An agent with control divider d ≥ 2 reads only ``mocap_every/<d>``, and frames reach
the loop through a channel read by its own thread (the fake bus's queue here; zenoh's FIFO
channel in tests/transport)."""

from __future__ import annotations

import threading
import time

import pytest
from runtime_helpers import FakeClock
from tlfleet.agent.runtime.inbox import MalformedCounter
from tlfleet.agent.runtime.loop import AgentLoop, LoopConfig, TickOutput
from tlfleet.bus.fake import FakeChannel, FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import Clock, Command, Control, Event, MocapFrame

FLEET = "frames"
POSES = ((1, 0.0, 0.0, 0.0), (2, 1.0, 0.0, 0.0))


class SeqCore:
    robot = 1
    zero = (0.0, 0.0)

    def step(self, state, inputs):
        return state, TickOutput((float(inputs.frame.seq), 0.0))


def make(network, **config):
    clock = FakeClock()
    loop = AgentLoop(network.transport("agent1"), LoopConfig(FLEET, 1, **config), SeqCore(), 0,
                     malformed=MalformedCounter("agent/1", clock=clock), clock=clock)
    loop.open()
    loop.ready()
    return loop, clock


def publish(network, key, message):
    network.transport("sim").publish(key, encode(message))


def commands(network):
    return [decode(Command, p) for k, p in network.published if k == keys.cmd(FLEET, 1)]


def test_a_decimated_loop_reads_only_its_frame_key():
    network = FakeNetwork()
    loop, _ = make(network, divider=20, decimated=True)
    publish(network, keys.control(FLEET), Control("start"))
    for seq in (1, 2, 3):  # on mocap only: never seen
        publish(network, keys.mocap(FLEET), MocapFrame(seq / 100, seq, POSES))
        loop.run_once(0.0)
    assert loop.stats.frames == 0 and commands(network) == []
    publish(network, keys.mocap_every(FLEET, 20), MocapFrame(0.2, 20, POSES, due=(1,)))
    loop.run_once(0.0)
    assert [(c.seq, c.u) for c in commands(network)] == [(20, (20.0, 0.0))]
    # realtime (due = ()): every frame of the key starts a new control period
    publish(network, keys.mocap_every(FLEET, 20), MocapFrame(0.4, 40, POSES))
    loop.run_once(0.0)
    assert [c.seq for c in commands(network)] == [20, 40]


def test_a_staggered_loop_reads_and_answers_the_ticks_of_its_phase():
    """Phase 10 of 20 — decimated, only ``mocap_every/20/10``; reading every frame
    in realtime, a new control period begins at seq ≡ 10 (mod 20)."""
    network = FakeNetwork()
    loop, _ = make(network, divider=20, phase=10, decimated=True)
    assert loop._keys["mocap"] == keys.mocap_every(FLEET, 20, 10)
    publish(network, keys.control(FLEET), Control("start"))
    publish(network, keys.mocap_every(FLEET, 20), MocapFrame(0.2, 20, POSES))  # phase 0's
    loop.run_once(0.0)
    for seq in (10, 30):
        publish(network, keys.mocap_every(FLEET, 20, 10), MocapFrame(seq / 100, seq, POSES))
        loop.run_once(0.0)
    assert [c.seq for c in commands(network)] == [10, 30]
    loop.close()
    network = FakeNetwork()
    loop, _ = make(network, divider=20, phase=10)
    publish(network, keys.control(FLEET), Control("start"))
    for seq in range(5, 55):
        publish(network, keys.mocap(FLEET), MocapFrame(seq / 100, seq, POSES))
        loop.run_once(0.0)
    # the first frame after the start, then the first of each period (10, 30, 50)
    assert [c.seq for c in commands(network)] == [5, 10, 30, 50]
    with pytest.raises(ValueError, match="phase must be in"):
        LoopConfig(FLEET, 1, divider=20, phase=20)


def test_divider_1_or_not_decimated_reads_mocap():
    network = FakeNetwork()
    for config in ({"divider": 1, "decimated": True}, {"divider": 20}):
        loop, _ = make(network, **config)
        assert loop._keys["mocap"] == keys.mocap(FLEET)
        loop.close()


def test_the_staleness_limit_of_a_decimated_loop_adds_two_frame_gaps():
    assert LoopConfig(FLEET, 1, 20, 0.5).stale_limit == 0.5
    assert LoopConfig(FLEET, 1, 20, 0.5, decimated=True).stale_limit == 0.5 + 2 * 19 / 100
    assert LoopConfig(FLEET, 1, 1, 0.5, decimated=True).stale_limit == 0.5
    network = FakeNetwork()
    loop, clock = make(network, divider=20, decimated=True, stale_after=0.5)
    publish(network, keys.control(FLEET), Control("start"))
    publish(network, keys.mocap_every(FLEET, 20), MocapFrame(0.2, 20, POSES, due=(1,)))
    loop.run_once(0.0)
    clock.advance(0.8)  # beyond stale_after, within the decimated limit (0.88 s)
    loop.run_once(0.0)
    assert loop.stats.stale_episodes == 0
    clock.advance(0.1)
    loop.run_once(0.0)
    assert loop.stats.stale_episodes == 1


def test_the_fake_channel_skips_queued_wakeups_and_times_out():
    channel = FakeChannel()
    assert channel.recv(0.0) is None
    began = time.monotonic()
    assert channel.recv(0.05) is None and time.monotonic() - began >= 0.04
    channel.wake()
    channel._put("k", b"1")
    assert channel.recv(1.0) == ("k", b"1")  # the wake-up before it is skipped
    channel.wake()
    began = time.monotonic()
    assert channel.recv(5.0) is None and time.monotonic() - began < 1.0


def test_a_control_wakes_a_loop_blocked_on_its_channel():
    network = FakeNetwork()
    loop, _ = make(network)
    assert loop._channel is not None  # the fake bus has channels: frames are read by the loop
    done = threading.Event()

    def blocked():
        loop.run_once(5.0)
        done.set()

    thread = threading.Thread(target=blocked)
    thread.start()
    time.sleep(0.05)
    publish(network, keys.control(FLEET), Control("start"))
    assert done.wait(2.0), "the control did not wake the loop"
    thread.join(2.0)
    assert loop.started


def test_the_channel_loop_keeps_the_newest_valid_frame():
    network = FakeNetwork()
    loop, _ = make(network)
    publish(network, keys.control(FLEET), Control("start"))
    for seq in (5, 6, 7):
        publish(network, keys.mocap(FLEET), MocapFrame(seq / 100, seq, POSES))
    network.transport("x").publish(keys.mocap(FLEET), b"garbage")
    loop.run_once(0.0)
    assert [c.seq for c in commands(network)] == [7]
    assert loop.mailbox.frames_overwritten == 2 and loop.malformed.total == 1


def test_a_decimated_loop_with_heartbeat_notices_a_silent_simulator_within_stale_after():
    """The clock key (every tick) is the decimated loop's heartbeat; frames alone
    would take stale_after plus two frame gaps."""
    network = FakeNetwork()
    loop, clock = make(network, divider=20, decimated=True, stale_after=0.15, heartbeat=True)
    assert loop.config.watches_clock
    publish(network, keys.control(FLEET), Control("start"))
    publish(network, keys.mocap_every(FLEET, 20), MocapFrame(0.2, 20, POSES, due=(1,)))
    loop.run_once(0.0)
    for k in range(21, 30):  # the sim ticks on; its frames for robot 1 come every 20 ticks
        clock.advance(0.01)
        publish(network, keys.clock(FLEET), Clock(k / 100, k, "lockstep"))
        loop.run_once(0.0)
    assert loop.stats.stale_episodes == 0  # 0.09 s after the frame, the sim is still heard
    # the next check: the heartbeat's silence limit (0.15 s after the last Clock), before the
    # frame limit (0.15 + 2·19/100 s after the frame)
    assert loop.block_for() == pytest.approx(0.15)
    clock.advance(0.14)  # 0.14 s of silence: not yet
    loop.run_once(0.0)
    assert loop.stats.stale_episodes == 0
    network.transport("x").publish(keys.clock(FLEET), b"\x93garbage")  # no heartbeat
    clock.advance(0.02)  # 0.16 s without a Clock, 0.25 s after the frame: stale
    loop.run_once(0.0)
    assert loop.stats.stale_episodes == 1 and loop.malformed.total == 1
    assert commands(network)[-1].u == (0.0, 0.0)
    stale = [decode(Event, p) for k, p in network.published if keys.parse_event(k)
             if decode(Event, p).kind == "stale_mocap"]
    assert len(stale) == 1 and abs(stale[0].data["sim_silence"] - 0.16) < 1e-9
    assert abs(stale[0].data["silence"] - 0.25) < 1e-9
    # without the heartbeat the same silence is within the frame limit (0.15 + 2·19/100 s)
    quiet = FakeNetwork()
    loop, clock = make(quiet, divider=20, decimated=True, stale_after=0.15)
    assert not loop.config.watches_clock
    assert keys.clock(FLEET) not in [expr for _, expr, _ in quiet._subscribers]
    publish(quiet, keys.control(FLEET), Control("start"))
    publish(quiet, keys.mocap_every(FLEET, 20), MocapFrame(0.2, 20, POSES, due=(1,)))
    loop.run_once(0.0)
    clock.advance(0.25)
    loop.run_once(0.0)
    assert loop.stats.stale_episodes == 0


def test_a_decimated_loop_in_a_slow_lockstep_fleet_is_not_stale_at_the_fleets_pace():
    """A lockstep fleet slower than real time spaces a decimated loop's frames beyond the nominal
    divider / mocap_rate (here 0.8 s instead of 0.2 s): after a few such frames the limit follows
    the pace (LoopConfig.stale_limit_at), so waiting for the fleet is not stale mocap; a real
    outage at that pace still is."""
    assert LoopConfig(FLEET, 1, 20, 0.5, decimated=True).stale_limit_at(0.2) == \
        LoopConfig(FLEET, 1, 20, 0.5, decimated=True).stale_limit  # real time: unchanged
    assert LoopConfig(FLEET, 1, 20, 0.5, decimated=True).stale_limit_at(0.8) == \
        pytest.approx(0.5 + 2 * 0.79)
    assert LoopConfig(FLEET, 1, 1, 0.5).stale_limit_at(0.8) == 0.5  # not decimated
    network = FakeNetwork()
    loop, clock = make(network, divider=20, decimated=True, stale_after=0.5)
    publish(network, keys.control(FLEET), Control("start"))
    for n in range(1, 6):  # five frames, 0.8 s apart
        publish(network, keys.mocap_every(FLEET, 20), MocapFrame(0.2 * n, 20 * n, POSES, due=(1,)))
        loop.run_once(0.0)
        clock.advance(0.5)
        loop.run_once(0.0)
        clock.advance(0.3)
        loop.run_once(0.0)
    assert loop.stats.stale_episodes == 0 and loop.stats.frames == 5
    clock.advance(2.2 - 0.8)  # 2.2 s since the last frame: beyond 0.5 + 2·0.79 = 2.08 s
    loop.run_once(0.0)
    assert loop.stats.stale_episodes == 1
