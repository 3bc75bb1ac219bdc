"""A scripted fake simulator on the ``FakeNetwork`` for agent-runtime tests (no sockets).

``FakeSim`` publishes mocap frames the test builds (lockstep ``due`` or realtime), collects every
command, status and event the agents publish, and integrates nothing itself: the tests drive
their own kinematics so they know exactly what the agents saw.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode, peek_kind
from tlfleet.bus.protocol.messages import Command, Control, Event, LtlStatus, MocapFrame, StlStatus


class FakeSim:
    def __init__(self, network: FakeNetwork, fleet: str):
        self.fleet = fleet
        self.transport = network.transport("sim")
        self.commands: list[Command] = []
        self._by_seq: dict[tuple[int, int], Command] = {}
        self.events: list[Event] = []
        self.statuses: list[LtlStatus | StlStatus] = []
        self.transport.subscribe(keys.all_cmds(fleet), self._on_cmd)
        self.transport.subscribe(keys.all_events(fleet), self._on_event)
        self.transport.subscribe(keys.all_statuses(fleet), self._on_status)

    def _on_cmd(self, _key: str, payload: bytes) -> None:
        command = decode(Command, payload)
        self.commands.append(command)
        self._by_seq[(command.robot, command.seq)] = command

    def _on_event(self, _key: str, payload: bytes) -> None:
        self.events.append(decode(Event, payload))

    def _on_status(self, _key: str, payload: bytes) -> None:
        kind = peek_kind(payload)
        self.statuses.append(decode(LtlStatus if kind == "LtlStatus" else StlStatus, payload))

    def control(self, cmd: str) -> None:
        self.transport.publish(keys.control(self.fleet), encode(Control(cmd)))

    def frame(self, t: float, seq: int, poses: Mapping[int, Sequence[float]],
              due: Iterable[int] = (), offsets: Iterable[int] = ()) -> MocapFrame:
        """Publish a frame on ``mocap`` and, as a lockstep simulator does, on ``mocap_at/s``
        for each frame offset s ≥ 1 in ``offsets`` (``Scenario.frame_offset``)."""
        frame = MocapFrame(t, seq, tuple((int(j), float(p[0]), float(p[1]), float(p[2]))
                                         for j, p in sorted(poses.items())), tuple(due))
        payload = encode(frame)
        self.transport.publish(keys.mocap(self.fleet), payload)
        for offset in sorted(set(offsets) - {0}):
            self.transport.publish(keys.mocap_at(self.fleet, offset), payload)
        return frame

    def raw(self, key: str, payload: bytes) -> None:
        self.transport.publish(key, payload)

    def command(self, robot: int, seq: int) -> Command:
        """The (last) command of ``robot`` for frame ``seq``."""
        found = self._by_seq.get((robot, seq))
        if found is None:
            raise AssertionError(f"no command of robot {robot} for frame {seq}")
        return found

    def kinds(self, source: str | None = None) -> list[str]:
        return [e.kind for e in self.events if source is None or e.source == source]


class FakeClock:
    """A wall clock the test moves by hand [s]."""

    def __init__(self, now: float = 100.0):
        self.now = now

    def __call__(self) -> float:
        return self.now

    def advance(self, seconds: float) -> None:
        self.now += seconds


def stl_loop(network: FakeNetwork, fleet: str, agent, clock=None, stale_after: float = 0.5):
    """An STL agent loop on its own fake transport, opened and alive."""
    from tlfleet.agent.runtime.inbox import MalformedCounter
    from tlfleet.agent.runtime.loop import AgentLoop, LoopConfig
    from tlfleet.agent.runtime.peers import CollabLink
    from tlfleet.agent.runtime.stl_agent import StlCore

    transport = network.transport(f"agent{agent.robot_id}")
    extra = {"clock": clock} if clock is not None else {}
    malformed = MalformedCounter(f"agent/{agent.robot_id}", **extra)
    link = CollabLink(transport, fleet, agent.robot_id, agent.cfg.peers, malformed,
                      check=agent.collab_problem, **extra)
    core = StlCore(agent)
    loop = AgentLoop(transport, LoopConfig(fleet, agent.robot_id, 1, stale_after), core,
                     core.initial_state(), link=link, malformed=malformed, **extra)
    loop.open()
    loop.ready()
    return loop, transport
