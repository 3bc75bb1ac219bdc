"""The simulator survives hostile commands and ignores stale ones."""

from __future__ import annotations

from sim_helpers import FakeAgent, Observer, SimRun, omni, scenario
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Command, MocapFrame


class Lagging:
    """Answers frame k with its command for frame k − lag (computed from old poses)."""

    def __init__(self, agent_robot: int, lag: int, u: tuple[float, ...]):
        self.robot, self.lag, self.u = agent_robot, lag, u
        self.agent: FakeAgent | None = None

    def __call__(self, frame: MocapFrame, robot: int):
        if frame.seq >= self.lag and self.agent is not None:
            old = frame.seq - self.lag
            self.agent.send(old, self.u, old / 100)
        return None


def run_realtime(policy_lag: int, **sim):
    net = FakeNetwork()
    observer = Observer(net)
    lagging = Lagging(1, policy_lag, (0.2, 0.0, 0.0))
    lagging.agent = FakeAgent(net, 1, lagging, realtime_divider=1)
    with SimRun(net, scenario(omni(1, 0.0, 0.0), duration=0.4, **sim), mode="realtime") as run:
        observer.start_mission()
        assert run.join() == 0
    return observer, run


def test_realtime_ignores_commands_answering_old_frames_and_the_robot_stays_stopped():
    observer, _run = run_realtime(policy_lag=20)  # 0.2 s old, the bound is 0.05 s
    stats = observer.events_of("sim_stats")[0].data
    assert stats["stale_commands"] >= 10
    (event,) = observer.events_of("stale_command")  # one per episode
    assert event.data["robot"] == 1 and event.data["age"] > 0.15
    final = [f for f in observer.frames if f.seq > 0][-1]
    assert final.pose(1)[0] == 0.0  # never moved: no stale command was applied


def test_fresh_commands_are_applied():
    observer, _ = run_realtime(policy_lag=1)
    assert observer.events_of("sim_stats")[0].data["stale_commands"] == 0
    assert [f for f in observer.frames if f.seq > 0][-1].pose(1)[0] > 0.02


def test_hostile_commands_are_counted_per_key_and_never_move_a_robot():
    net = FakeNetwork()
    observer = Observer(net)
    FakeAgent(net, 1, lambda frame, robot: (0.0, 0.0, 0.0))
    rogue = net.transport("rogue")
    key = keys.cmd("simtest", 1)
    with SimRun(net, scenario(omni(1, 0.0, 0.0), duration=0.2)) as run:
        observer.start_mission()
        for payload in (b"\x81\xa1v\x91" * 8, encode(Command(1, 0.05, 5, (1e308, 0.0, 0.0))),
                        encode(Command(1, 60.0, 5, (0.2, 0.0, 0.0))),  # t ≠ seq / rate
                        encode(Command(1, 0.05, 5, (50.0, 0.0, 0.0)))):  # 250× the limit
            rogue.publish(key, payload)
        assert run.join() == 0
    stats = observer.events_of("sim_stats")[0].data
    assert stats["malformed_by_key"] == {key: 4}
    assert [f for f in observer.frames if f.seq > 0][-1].pose(1) == (0.0, 0.0, 0.0)
