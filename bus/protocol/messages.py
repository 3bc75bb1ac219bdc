"""Messages that travel over Zenoh (docs/architecture.md §2): frozen dataclasses, one per payload
kind.

Units: times [s] of the mission clock (t = 0 at ``Control(start)``), positions [m], angles [rad],
velocities [m/s] and [rad/s]. Commands are world-frame ``(vx, vy, ω)`` for omni robots and
``(v, ω)`` for unicycles. ``tlfleet.bus.protocol.codec`` turns them into bytes and back.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

TimeMode = Literal["lockstep", "realtime"]


@dataclass(frozen=True, slots=True)
class Clock:
    """Sim time of one tick."""

    t: float
    tick: int
    mode: TimeMode


@dataclass(frozen=True, slots=True)
class MocapFrame:
    """Every robot's pose at sim time ``t``: rows ``(id, x, y, θ)``, ids ascending.

    ``due`` lists the robots whose agents must answer this frame with a command (lockstep mode:
    the sim waits for them; realtime mode: empty).
    """

    t: float
    seq: int
    poses: tuple[tuple[int, float, float, float], ...]
    due: tuple[int, ...] = ()

    def pose(self, robot: int) -> tuple[float, float, float] | None:
        for row in self.poses:
            if row[0] == robot:
                return row[1], row[2], row[3]
        return None


@dataclass(frozen=True, slots=True)
class Command:
    """Velocity command of ``robot`` computed from the frame ``seq`` (sim time ``t``)."""

    robot: int
    t: float
    seq: int
    u: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class LtlStatus:
    """What an LTL agent reports (≤ 10 Hz): its plan, target, Büchi states and visits."""

    robot: int
    t: float
    prefix: tuple[str, ...]
    suffix: tuple[str, ...]
    target: str | None
    buchi_states: tuple[int, ...]
    visits: tuple[tuple[str, int], ...]
    rounds: int
    mode: str


@dataclass(frozen=True, slots=True)
class StlStatus:
    """What an STL agent reports (≤ 10 Hz): funnel, robustness and repair state
    (docs/stl-funnel.md §8).

    ``rho``/``rho_max``/``lower``/``r`` are NaN while the agent is idle; ``follow`` is −1 when the
    agent follows nobody; ``events`` counts critical events per stage (1, 2, 3).
    """

    robot: int
    t: float
    subtask: int
    rho: float
    rho_max: float
    lower: float
    r: float
    stage: int
    ce: int
    c: int
    follow: int
    events: tuple[int, int, int] = (0, 0, 0)


@dataclass(frozen=True, slots=True)
class FunnelWire:
    """The funnel of a task as sent in stage-2 messages (docs/stl-funnel.md §5, §7.5; t_r included):
    the wire form of :class:`tlfleet.agent.stl.funnel.Funnel`, field for field (not to be confused
    with :class:`tlfleet.agent.stl.funnel.FunnelParams`, the funnel *design* parameters of a
    robot)."""

    kind: Literal["G", "F"]
    a: float
    b: float
    rho_opt: float
    rho_max: float
    r: float
    gamma0: float
    gamma_inf: float
    l: float
    t_star: float
    t_r: float
    zeta_u: float
    ramp: float = 0.0  # the lower boundary's climb before the knee (0: no ramp)
    t_knee: float = 0.0


CollabKind = Literal["request", "update", "release", "status"]


@dataclass(frozen=True, slots=True)
class CollabMessage:
    """One stage-2 message from ``sender`` to ``receiver`` (docs/stl-funnel.md §7.5).

    ``request``/``update`` carry the requester's ``funnel``; ``release`` none; ``status`` announces
    the sender's ``c`` and active sub-task (``task_kind``, ``a``, ``b``) for the stage-2 rule.
    ``t`` is the sender's sim time when it sent the message.
    """

    kind: CollabKind
    sender: int
    receiver: int
    t: float
    subtask: int
    funnel: FunnelWire | None = None
    c: int = 0
    task_kind: Literal["G", "F", ""] = ""
    a: float = 0.0
    b: float = 0.0
    all_done: bool = False


@dataclass(frozen=True, slots=True)
class CollabReply:
    """The receiver's answer to a ``CollabMessage``."""

    accepted: bool
    reason: str = ""


@dataclass(frozen=True, slots=True)
class Event:
    """Something worth recording: plan ready, critical event, repair, collision, fault…

    ``data[EVENT_REPLAYED]`` (True) marks an agent's event published again after the
    coordinator came back into reach (``tlfleet.agent.runtime.event_log``): the same event, late.
    """

    t: float
    source: str
    kind: str
    data: dict[str, object] = field(default_factory=dict)


EVENT_REPLAYED = "replayed"  # Event.data field of a replayed event


@dataclass(frozen=True, slots=True)
class Control:
    """Coordinator → all: start the mission (t0 = sim time of mission start) or stop."""

    cmd: Literal["start", "stop"]
    t0: float = 0.0


@dataclass(frozen=True, slots=True)
class BackfillRequest:
    """Recorder → simulator (query on ``sim/backfill``): publish again, as a reply, the
    frames with ``first`` ≤ seq ≤ ``last`` that the recorder missed (a link cut longer than the
    zenoh lease loses what the simulator published meanwhile)."""

    first: int
    last: int


@dataclass(frozen=True, slots=True)
class BackfillReply:
    """Simulator → recorder: the answer to a :class:`BackfillRequest` from the simulator's ring
    of recent frames (``tlfleet.sim.frame_ring``).

    The reply *covers* the seqs ``first``..``last`` (``last`` ≤ the requested one: less when the
    reply's byte or frame budget ran out, and the recorder asks again from ``last + 1``);
    ``frames`` holds each frame of that range the ring still has, as the very payload published
    on ``mocap`` (an encoded :class:`MocapFrame`, decoded and checked like a live one). A seq the
    reply covers without a frame is gone for good. ``oldest`` is the ring's oldest seq (−1 when
    empty): why such a seq is gone (evicted, older than the ring's span).
    """

    first: int
    last: int
    oldest: int
    frames: tuple[bytes, ...] = ()


Message = (Clock | MocapFrame | Command | LtlStatus | StlStatus | CollabMessage | CollabReply
           | Event | Control | BackfillRequest | BackfillReply)
