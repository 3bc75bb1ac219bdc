"""Shared helpers of the simulator tests: small scenarios, a fake agent, a sim run in a thread."""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable
from dataclasses import replace

from tlfleet.agent.model.scenario import (
    Arena,
    LtlParams,
    OmniLimits,
    Robot,
    Scenario,
    SimParams,
    StlParams,
    UnicycleLimits,
)
from tlfleet.bus.fake import FakeNetwork, FakeTransport
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import ProtocolError, decode, encode
from tlfleet.bus.protocol.messages import Command, Control, Event, MocapFrame
from tlfleet.sim.process import SimConfig, SimProcess

FLEET = "simtest"
WAIT = 10.0  # [s] wall: generous upper bound on every condition a test waits for


def omni(rid: int, x: float, y: float, theta: float = 0.0, radius: float = 0.2,
         **limits: float) -> Robot:
    return Robot(rid, "omni", (x, y, theta), radius=radius, stl=("F[0,1] (dist(p1, [0,0]) <= 1)",),
                 omni=OmniLimits(**limits))


def unicycle(rid: int, x: float, y: float, theta: float = 0.0, radius: float = 0.2,
             **limits: float) -> Robot:
    return Robot(rid, "unicycle", (x, y, theta), radius=radius, ltl="G F a",
                 unicycle=UnicycleLimits(**limits))


def scenario(*robots: Robot, duration: float = 1.0, arena: Arena | None = None,
             stl_rate: float = 100.0, ltl_rate: float = 5.0, **sim: float) -> Scenario:
    return Scenario(name="simtest", fleet=FLEET, duration=duration, arena=arena or Arena(),
                    regions=(), robots=tuple(robots), ltl=LtlParams(control_rate=ltl_rate),
                    stl=StlParams(control_rate=stl_rate), sim=SimParams(**sim))


Policy = Callable[[MocapFrame, int], tuple[float, ...] | None]
"""(frame, robot) → the command to send, or ``None`` to stay silent."""


def constant(u: tuple[float, ...]) -> Policy:
    return lambda frame, robot: u


class FakeAgent:
    """An agent on the fake network: alive token, answers the frames where it is due.

    ``policy`` decides the command (``None``: no answer). ``realtime_divider`` makes it answer
    on ``seq % divider == 0`` instead of ``due`` (realtime mode). Answers are published from
    inside the sim's own ``publish`` call (fake delivery is synchronous).
    """

    def __init__(self, network: FakeNetwork, robot: int, policy: Policy,
                 realtime_divider: int | None = None, started: bool = False):
        self.robot = robot
        self.policy = policy
        self.divider = realtime_divider
        self.started = started  # True: it had the start before its token appeared
        self.frames: list[MocapFrame] = []
        self.transport: FakeTransport = network.transport(f"agent{robot}")
        self.transport.subscribe(keys.mocap(FLEET), self._on_frame)
        self.transport.subscribe(keys.control(FLEET), self._on_control)
        self.transport.declare_alive(keys.alive(FLEET, "agent", robot))

    def _on_control(self, _key: str, payload: bytes) -> None:
        with contextlib.suppress(ProtocolError):  # some tests send junk on the control key
            self.started = decode(Control, payload).cmd == "start"

    def _on_frame(self, _key: str, payload: bytes) -> None:
        frame = decode(MocapFrame, payload)
        self.frames.append(frame)
        if not self.started:
            return
        due = (frame.seq % self.divider == 0) if self.divider else self.robot in frame.due
        if not due:
            return
        u = self.policy(frame, self.robot)
        if u is not None:
            self.send(frame.seq, u, frame.t)

    def send(self, seq: int, u: tuple[float, ...], t: float | None = None) -> None:
        """A command for frame ``seq``, stamped by default with that frame's time (100 Hz)."""
        t = seq / 100 if t is None else t
        self.transport.publish(keys.cmd(FLEET, self.robot),
                               encode(Command(self.robot, t, seq, u)))


class Observer:
    """Records what the sim publishes (frames, events) and lets a test wait on conditions."""

    def __init__(self, network: FakeNetwork):
        self.transport = network.transport("observer")
        self._cond = threading.Condition()
        self.frames: list[MocapFrame] = []
        self.frame_bytes: list[bytes] = []
        self.events: list[Event] = []
        self.transport.subscribe(keys.mocap(FLEET), self._on_frame)
        self.transport.subscribe(keys.all_events(FLEET), self._on_event)

    def _on_frame(self, _key: str, payload: bytes) -> None:
        with self._cond:
            self.frames.append(decode(MocapFrame, payload))
            self.frame_bytes.append(payload)
            self._cond.notify_all()

    def _on_event(self, _key: str, payload: bytes) -> None:
        with self._cond:
            self.events.append(decode(Event, payload))
            self._cond.notify_all()

    def wait_for(self, predicate: Callable[[], bool], timeout: float = WAIT) -> bool:
        with self._cond:
            return self._cond.wait_for(predicate, timeout)

    def events_of(self, kind: str) -> list[Event]:
        with self._cond:
            return [e for e in self.events if e.kind == kind]

    def wait_first_frame(self) -> None:
        assert self.wait_for(lambda: bool(self.frames)), "the sim published no frame"

    def start_mission(self) -> None:
        """Wait until the sim is up (its first frame), then send ``Control(start)``."""
        self.wait_first_frame()
        self.send_control("start")

    def send_control(self, cmd: str) -> None:
        self.transport.publish(keys.control(FLEET), encode(Control(cmd)))  # type: ignore[arg-type]


class SimRun:
    """The sim's loop on a thread of its own, on a fake network."""

    def __init__(self, network: FakeNetwork, scen: Scenario, **config: object):
        config.setdefault("duration", scen.duration)
        self.process = SimProcess(network.transport("sim"), scen, SimConfig(**config))
        self.result: list[int] = []
        self.thread = threading.Thread(target=lambda: self.result.append(self.process.run()),
                                       daemon=True)

    def start(self) -> SimRun:
        self.thread.start()
        return self

    def join(self, timeout: float = WAIT) -> int:
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "the sim loop did not end"
        return self.result[0]

    def stop(self) -> None:
        self.process.stop_event.set()
        self.thread.join(WAIT)

    def __enter__(self) -> SimRun:
        return self.start()

    def __exit__(self, *_exc: object) -> None:
        self.stop()  # a failed test must not leave the loop running


def run_lockstep(scen: Scenario, policies: dict[int, Policy], **config: object
                 ) -> tuple[Observer, SimRun, dict[int, FakeAgent]]:
    """Run a whole lockstep mission on a fake network; returns when ``sim_done`` came."""
    net = FakeNetwork()
    observer = Observer(net)
    agents = {rid: FakeAgent(net, rid, policy) for rid, policy in policies.items()}
    with SimRun(net, scen, **config) as run:
        observer.start_mission()
        assert run.join() == 0
    return observer, run, agents


def poses_of(frames: list[MocapFrame], robot: int) -> list[tuple[float, float, float]]:
    return [p for p in (f.pose(robot) for f in frames) if p is not None]


def distance(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def with_sim(scen: Scenario, **sim: float) -> Scenario:
    return replace(scen, sim=replace(scen.sim, **sim))


def mission_frames(frames: list[MocapFrame]) -> list[MocapFrame]:
    """The frames from tick 0 on (the previews before start also have seq 0 and come first)."""
    last_zero = max(i for i, f in enumerate(frames) if f.seq == 0)
    return frames[last_zero:]
