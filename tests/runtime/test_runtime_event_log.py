"""Events lost while an agent's link was down are published again when the coordinator's token
returns, and the recorder keeps each event once (tlfleet.agent.runtime.event_log,
tlfleet.coordinator.record.replay_dedup)."""

from __future__ import annotations

import json

import pytest
from tlfleet.agent.runtime.event_log import CAPACITY, EventLog
from tlfleet.agent.runtime.loop import AgentLoop, LoopConfig
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode
from tlfleet.bus.protocol.messages import EVENT_REPLAYED, Event
from tlfleet.coordinator.record.recorder import Recorder, RecorderTap
from tlfleet.coordinator.record.replay_dedup import REMEMBERED, EventDedup, identity

FLEET = "f"


class Wall:
    """A settable wall clock [s]."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def published_events(net: FakeNetwork) -> list[Event]:
    return [decode(Event, p) for k, p in net.published if keys.parse_event(k) is not None]


def test_replays_the_window_before_the_loss_and_after_it_when_the_coordinator_returns():
    net, wall = FakeNetwork(), Wall()
    agent, coord = net.transport("agent"), net.transport("coordinator")
    log = EventLog(agent, FLEET, "agent/1", window=5.0, clock=wall)
    handle = log.watch()
    old = Event(1.0, "agent/1", "plan_ready", {"n": 1})
    log.publish(old)  # wall 0: older than the window at the loss
    token = coord.declare_alive(keys.alive(FLEET, "coordinator", 0))  # first declaration
    wall.now = 10.0
    before = Event(2.0, "agent/1", "resumed", {"gap": 3.1})
    log.publish(before)  # published before the loss was noticed: the race of a frozen agent
    wall.now = 12.0
    token.close()  # the agent sees the coordinator's token go
    wall.now = 13.0
    during = Event(2.5, "agent/1", "stale_mocap", {})
    log.publish(during)
    assert log.replayed == 0 and len(published_events(net)) == 3
    wall.now = 14.0
    coord.declare_alive(keys.alive(FLEET, "coordinator", 0))
    replays = published_events(net)[3:]
    assert [(e.t, e.kind) for e in replays] == [(2.0, "resumed"), (2.5, "stale_mocap")]
    assert all(e.data[EVENT_REPLAYED] is True for e in replays)
    assert replays[0].data["gap"] == 3.1  # the original's data, untouched
    assert EVENT_REPLAYED not in before.data  # the kept event is not mutated
    assert (log.replays, log.replayed) == (1, 2)
    handle.close()


def test_no_replay_without_a_loss_and_the_ring_is_bounded():
    net, wall = FakeNetwork(), Wall()
    agent, coord = net.transport("agent"), net.transport("coordinator")
    coord.declare_alive(keys.alive(FLEET, "coordinator", 0))
    log = EventLog(agent, FLEET, "agent/1", capacity=4, clock=wall)
    log.watch()  # the token is already there: history, not a return
    for i in range(10):
        log.publish(Event(float(i), "agent/1", "repair", {"i": i}))
    assert log.replays == 0
    other = net.transport("other")
    other.declare_alive(keys.alive(FLEET, "coordinator", 0))  # a duplicate declaration
    assert log.replays == 0 and len(published_events(net)) == 10
    with pytest.raises(ValueError, match="capacity"):
        EventLog(agent, FLEET, "agent/1", capacity=0)
    with pytest.raises(ValueError, match="window"):
        EventLog(agent, FLEET, "agent/1", window=float("nan"))


def test_ring_keeps_only_the_last_capacity_events():
    net, wall = FakeNetwork(), Wall()
    agent, coord = net.transport("agent"), net.transport("coordinator")
    token = coord.declare_alive(keys.alive(FLEET, "coordinator", 0))
    log = EventLog(agent, FLEET, "agent/1", capacity=4, clock=wall)
    log.watch()
    for i in range(10):
        log.publish(Event(float(i), "agent/1", "repair", {"i": i}))
    token.close()
    coord.declare_alive(keys.alive(FLEET, "coordinator", 0))
    assert [e.data["i"] for e in published_events(net)[10:]] == [6, 7, 8, 9]


def test_dedup_admits_originals_and_only_replays_whose_original_is_missing():
    dedup = EventDedup(remembered=3)
    a = Event(1.0, "agent/1", "repair", {"stage": 3, "r": 0.1})
    assert dedup.admit(a) and dedup.admit(a)  # two originals: two facts
    assert not dedup.admit(Event(1.0, "agent/1", "repair", {"stage": 3, "r": 0.1,
                                                            EVENT_REPLAYED: True}))
    lost = Event(2.0, "agent/1", "resumed", {"gap": 3.0, EVENT_REPLAYED: True})
    assert dedup.admit(lost)  # its original never came
    assert not dedup.admit(lost)  # a second replay of it
    # another source with the same event is another event
    assert dedup.admit(Event(1.0, "agent/2", "repair", {"stage": 3, "r": 0.1,
                                                        EVENT_REPLAYED: True}))
    assert (dedup.replayed, dedup.duplicates) == (2, 2)
    # the memory is bounded per source: the oldest identity goes first
    for i in range(3):
        dedup.admit(Event(10.0 + i, "agent/1", "repair", {}))
    assert dedup.admit(Event(1.0, "agent/1", "repair", {"stage": 3, "r": 0.1,
                                                        EVENT_REPLAYED: True}))
    assert identity(a) == identity(Event(1.0, "agent/1", "repair",
                                         {"r": 0.1, "stage": 3, EVENT_REPLAYED: True}))


def test_the_recorder_keeps_each_event_once_after_a_replay(tmp_path):
    """The frozen-agent race end to end on the fake bus: an event published on a link that is
    already gone, the loss noticed after it, the coordinator back → events.jsonl has every
    event once, the late one marked."""
    net = FakeNetwork()
    coordinator = net.transport("coordinator")
    recorder = Recorder(tmp_path, [1])
    tap = RecorderTap(coordinator, FLEET, recorder)
    recorder.start()
    token = coordinator.declare_alive(keys.alive(FLEET, "coordinator", 0))
    agent = net.transport("agent")
    loop = AgentLoop(agent, LoopConfig(fleet=FLEET, robot=1), core=None, state=None)
    loop.open()
    loop.publish_event(Event(1.0, "agent/1", "plan_ready", {"cost": 4.0}))  # delivered
    agent.closed = True  # the router has dropped the agent: what it publishes is lost
    loop.publish_event(Event(35.5, "agent/1", "resumed", {"gap": 3.1}))
    agent.closed = False  # reconnected; its zenoh now reports the coordinator's token…
    token.close()  # …gone with the old session,
    coordinator.declare_alive(keys.alive(FLEET, "coordinator", 0))  # …and back with the new
    tap.drain()
    tap.close()
    recorder.close()
    lines = [json.loads(x) for x in (tmp_path / "events.jsonl").read_text().splitlines()]
    assert [(e["kind"], e["data"].get(EVENT_REPLAYED)) for e in lines] == [
        ("plan_ready", None), ("resumed", True)]
    assert (tap.dedup.replayed, tap.dedup.duplicates) == (1, 1)
    assert loop.summary()["events_replayed"] == 2
    loop.close()
    assert CAPACITY >= 16  # an agent's burst around a resumption fits
    assert REMEMBERED >= 4 * CAPACITY  # the recorder remembers every original a replay repeats


def test_start_up_events_are_published_again_at_the_start_and_recorded_once(tmp_path):
    """An agent's ``plan_ready`` is made before the start, when its session may not yet know
    the coordinator's subscriber (the original is then dropped): the loop publishes it again,
    marked replayed, when ``Control(start)`` arrives; the recorder keeps one copy either way."""
    from tlfleet.bus.protocol.codec import encode
    from tlfleet.bus.protocol.messages import Control

    for original_lost in (False, True):
        net = FakeNetwork()
        agent, coord = net.transport("agent"), net.transport("coordinator")
        recorder = Recorder(tmp_path / f"run{original_lost}", [1])
        tap = None if original_lost else RecorderTap(coord, FLEET, recorder)
        loop = AgentLoop(agent, LoopConfig(FLEET, 1, 1, 0.5), core=None, state=None)
        loop.open()
        ready = Event(0.0, "agent/1", "plan_ready", {"prefix": ["a"], "suffix": ["b"]})
        loop.publish_startup_event(ready)
        if tap is None:  # the coordinator subscribes only now: the original is gone
            tap = RecorderTap(coord, FLEET, recorder)
        coord.publish(keys.control(FLEET), encode(Control("start")))
        loop.run_once(0.0)
        loop.run_once(0.0)
        assert loop.started
        sent = published_events(net)
        assert [(e.kind, e.data.get(EVENT_REPLAYED, False)) for e in sent] == [
            ("plan_ready", False), ("plan_ready", True)]
        tap.drain()
        recorder.close()
        lines = [json.loads(x) for x in
                 (tmp_path / f"run{original_lost}" / "events.jsonl").read_text().splitlines()]
        assert [(x["kind"], x["data"].get(EVENT_REPLAYED, False)) for x in lines] == [
            ("plan_ready", original_lost)]
        loop.close()
