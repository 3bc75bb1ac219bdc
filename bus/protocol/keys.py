"""Zenoh key expressions of a fleet (architecture.md §2), built here and nowhere else.

Every key lives under ``tlfleet/<fleet>/``. Functions return plain strings, so this module needs
no zenoh import; the runtime hands them to the session.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

ROOT = "tlfleet"
_SEGMENT = re.compile(r"[A-Za-z0-9_-]+\Z")
ROLES = ("sim", "agent", "coordinator", "router")


def _check_segment(value: str, what: str) -> str:
    if not _SEGMENT.match(value):
        raise ValueError(f"{what} {value!r} is not a key segment: use letters, digits, _ and -")
    return value


def prefix(fleet: str) -> str:
    return f"{ROOT}/{_check_segment(fleet, 'fleet')}"


def clock(fleet: str) -> str:
    """Sim → all: ``Clock`` every sim tick."""
    return f"{prefix(fleet)}/clock"


def mocap(fleet: str) -> str:
    """Sim → all: one ``MocapFrame`` with every robot per mocap period."""
    return f"{prefix(fleet)}/mocap"


def mocap_every(fleet: str, divider: int, phase: int = 0) -> str:
    """Sim → the agents of robots with control divider ``divider`` = d ≥ 2 and phase
    ``phase`` = φ ∈ [0, d): the same ``MocapFrame`` as ``mocap``, but only the frames with
    ``seq % d == φ`` (architecture.md §2–§3; ``Scenario.control_phase``).

    A robot with divider d and phase φ can only be due at those ticks, so its agent subscribes
    here instead of ``mocap`` and is not woken for the other d − 1 frames of each control period
    (an LTL agent at 5 Hz with 100 Hz mocap: 95 % of the frames). The recorder and the viewer
    keep reading ``mocap``.
    """
    d, p = int(divider), int(phase)
    if d < 2:
        raise ValueError(f"mocap_every: divider must be ≥ 2 (divider 1 reads mocap), got {d}")
    if not 0 <= p < d:
        raise ValueError(f"mocap_every: phase must be in [0, {d}), got {p}")
    return f"{prefix(fleet)}/mocap_every/{d}/{p}"


def mocap_at(fleet: str, offset: int) -> str:
    """Sim → the agents of the every-tick robots whose frames are sampled ``offset`` = s ≥ 1
    physics steps after the tick (``Scenario.frame_offset``, architecture.md §3): in realtime
    the ``MocapFrame`` of that instant (t = t_k + s·dt, seq k), in lockstep the tick's frame
    (the same payload as ``mocap``). Robots at offset 0 read ``mocap``."""
    s = int(offset)
    if s < 1:
        raise ValueError(f"mocap_at: offset must be ≥ 1 (offset 0 reads mocap), got {s}")
    return f"{prefix(fleet)}/mocap_at/{s}"


def robot_frames(fleet: str, divider: int, phase: int, offset: int) -> str:
    """The one frame key the agent of a robot with control divider d, phase φ and frame offset
    s reads: ``mocap_every/d/φ`` (d ≥ 2), ``mocap_at/s`` (d = 1, s ≥ 1) or ``mocap``."""
    if int(divider) > 1:
        return mocap_every(fleet, divider, phase)
    return mocap_at(fleet, offset) if int(offset) > 0 else mocap(fleet)


Schedule = tuple[int, int]  # (divider d ≥ 1, phase φ ∈ [0, d)) of a robot's control ticks


def frame_keys(fleet: str, seq: int, schedules: tuple[Schedule, ...]) -> tuple[str, ...]:
    """Every key the frame ``seq`` is published on: ``mocap``, then ``mocap_every/d/φ`` for each
    schedule (d ≥ 2, φ) in ``schedules`` (sorted, distinct) with ``seq % d == φ``."""
    return (mocap(fleet), *(mocap_every(fleet, d, p) for d, p in schedules
                            if d > 1 and seq % d == p))


def frame_schedules(schedules: Iterable[Schedule]) -> tuple[Schedule, ...]:
    """The distinct control schedules (d, φ) with d ≥ 2 of a fleet, sorted: the
    ``mocap_every`` keys its simulator publishes."""
    return tuple(sorted({(int(d), int(p)) for d, p in schedules if int(d) > 1}))


def sim_backfill(fleet: str) -> str:
    """Queryable of the simulator: ``BackfillRequest`` → ``BackfillReply``, the frames a
    recorder missed during a link cut, from the simulator's ring."""
    return f"{prefix(fleet)}/sim/backfill"


def cmd(fleet: str, robot: int) -> str:
    """Agent → sim: ``Command`` of robot ``robot``."""
    return f"{prefix(fleet)}/robot/{int(robot)}/cmd"


def all_cmds(fleet: str) -> str:
    return f"{prefix(fleet)}/robot/*/cmd"


def status(fleet: str, robot: int) -> str:
    """Agent → coordinator: ``LtlStatus`` or ``StlStatus``."""
    return f"{prefix(fleet)}/robot/{int(robot)}/status"


def all_statuses(fleet: str) -> str:
    return f"{prefix(fleet)}/robot/*/status"


def collab(fleet: str, robot: int) -> str:
    """The stage-2 collaboration keys of STL agent ``robot``: its queryable serves
    ``collab/*`` (:func:`collab_all`), and robot j queries ``collab/j`` (:func:`collab_from`)."""
    return f"{prefix(fleet)}/robot/{int(robot)}/collab"


def collab_from(fleet: str, receiver: int, sender: int) -> str:
    """Where STL agent ``sender`` sends its ``CollabMessage`` s to ``receiver``: a key of its
    own, so in a secured fleet (the access policy lets robot i query only ``…/collab/i``) the
    key names the sender, and the receiver can check the message's claimed ``sender``."""
    return f"{collab(fleet, receiver)}/{int(sender)}"


def collab_all(fleet: str, receiver: int) -> str:
    """The queryable of STL agent ``receiver``: every sender's collaboration key."""
    return f"{collab(fleet, receiver)}/*"


def collab_sender(key: str) -> int | None:
    """The sender named by a :func:`collab_from` key, or ``None``."""
    match = re.search(r"/robot/\d+/collab/(\d+)$", key)
    return int(match.group(1)) if match else None


def event(fleet: str, role: str, ident: str | int) -> str:
    """Process → coordinator: its ``Event`` s, on a key of its own (``event/sim/0``,
    ``event/agent/3``, ``event/coordinator/0``): the access policy lets each identity write only
    its own, so the key names the publisher (``tlfleet.bus.protocol.events``)."""
    if role not in ROLES or role == "router":
        raise ValueError(f"role {role!r} publishes no events; expected sim, agent or coordinator")
    return f"{prefix(fleet)}/event/{role}/{_check_segment(str(ident), 'process id')}"


def all_events(fleet: str) -> str:
    return f"{prefix(fleet)}/event/*/*"


def parse_event(key: str) -> tuple[str, str] | None:
    """``(role, id)`` of an event key, or ``None`` when it is not one."""
    match = re.search(r"/event/([A-Za-z]+)/([A-Za-z0-9_-]+)$", key)
    return (match.group(1), match.group(2)) if match else None


def control(fleet: str) -> str:
    """Coordinator → all: ``Control`` (start / stop)."""
    return f"{prefix(fleet)}/control"


def alive(fleet: str, role: str, ident: str | int) -> str:
    """Liveliness token of one process, e.g. ``alive/agent/3`` or ``alive/sim/0``."""
    if role not in ROLES:
        raise ValueError(f"unknown role {role!r}; expected one of {', '.join(ROLES)}")
    return f"{prefix(fleet)}/alive/{role}/{_check_segment(str(ident), 'process id')}"


def all_alive(fleet: str) -> str:
    return f"{prefix(fleet)}/alive/**"


def robot_of(key: str) -> int | None:
    """The robot id in a ``.../robot/<id>/...`` key, or ``None``."""
    match = re.search(r"/robot/(\d+)/", key + "/")
    return int(match.group(1)) if match else None


def parse_alive(key: str) -> tuple[str, str] | None:
    """``(role, id)`` of a liveliness key, or ``None`` when it is not one."""
    match = re.search(r"/alive/([A-Za-z]+)/([A-Za-z0-9_-]+)$", key)
    return (match.group(1), match.group(2)) if match else None


def publisher_of(key: str) -> str:
    """Who publishes on ``key``, read from the key layout above (architecture.md §2): ``sim``
    (clock, frames, backfill), ``robot<N>`` (its commands, statuses, collaboration),
    ``coordinator`` (control), the owner of an event key (``event/sim/0``: ``sim``,
    ``event/agent/N``: ``robotN``, ``event/coordinator/0``: ``coordinator``),
    ``<role> <id>`` for a liveliness token, else ``?``."""
    alive = parse_alive(key)
    if alive is not None:
        return f"{alive[0]} {alive[1]}"
    parts = key.split("/")
    if len(parts) < 3 or parts[0] != ROOT:
        return "?"
    rest = parts[2:]
    if rest[0] in ("clock", "mocap", "mocap_every", "mocap_at", "sim"):
        return "sim"
    if rest[0] == "robot" and len(rest) >= 2 and rest[1].isdigit():
        return f"robot{rest[1]}"
    if rest[0] == "control":
        return "coordinator"
    event = parse_event(key)
    if event is not None and rest[0] == "event":
        role, ident = event
        if role == "agent" and ident.isdigit():
            return f"robot{ident}"
        return role if role in ("sim", "coordinator") else "?"
    return "?"
