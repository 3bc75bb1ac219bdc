"""What the coordinator believes of the messages it records.

**Events are authenticated by their key** (:mod:`tlfleet.bus.protocol.events`): every process
publishes on ``event/<role>/<id>`` and, in a secured fleet, the router lets each identity write
only its own key. :func:`event_problem` accepts an event only when

* its key is the event key of a process of this fleet (the simulator, or the agent of one of the
  scenario's robots; the coordinator's own events are recorded when made, never received);
* its ``source`` is that key's identity (a payload claiming another source is *flagged*);
* its kind is one that identity makes: the simulator's kinds (``sim_done``, ``sim_stats``,
  contacts, deadline misses, watchdog stops…) only from the simulator, an agent's only from an
  agent;

and its data has the types its readers expect (otherwise it is *malformed*: counted, dropped).
A flagged event is not recorded as the event it claims to be but as ``Event(kind=
"flagged_event")`` of the coordinator naming the key, the claimed source and kind and why.

Without ``--secure`` any local process can publish on any key, so the key proves nothing; the
coordinator then also flags claims that contradict what it recorded (:class:`RecordCheck`): a
second ``sim_done`` or ``sim_stats``, a ``sim_stats`` counting more ticks than the frames
recorded, a robot–robot contact between robots the frames show apart, a deadline miss of a tick
the simulator has not reached. A ``sim_done`` is also trusted only when the simulator has ended
or the frames reached the end of the run (:func:`sim_done_plausible`).

A status on ``robot/<id>/status`` must be robot ``id``'s (:func:`status_problem`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Collection, Mapping
from typing import Any

from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.events import AGENT_KINDS, SIM_KINDS, data_problem, source_of_key
from tlfleet.bus.protocol.messages import Event, MocapFrame

FLAGGED = "flagged_event"
OWN = "coordinator"  # the coordinator's own key: its events are recorded when made


class Malformed(ValueError):
    """An event whose data does not have the types its kind's readers expect."""


def event_problem(event: Event, key: str, robot_ids: Collection[int]) -> str | None:
    """Why ``event``, received on ``key``, is not what it claims to be, or None. Raises
    :class:`Malformed` when its data has wrong types."""
    parsed = keys.parse_event(key)
    expected = source_of_key(*parsed) if parsed is not None else None
    if expected is None or (expected.startswith("agent/")
                            and int(expected.partition("/")[2]) not in robot_ids):
        return f"key {key[-40:]!r} is no event key of this fleet's processes"
    if event.source != expected:
        return f"source {event.source[:40]!r} claimed on {expected}'s key"
    if expected == "sim" and event.kind in AGENT_KINDS:
        return f"kind {event.kind!r} is an agent's, not the simulator's"
    if expected.startswith("agent/") and event.kind in SIM_KINDS:
        return f"kind {event.kind!r} is the simulator's, not {expected}'s"
    problem = data_problem(event.kind, event.data)
    if problem is not None:
        raise Malformed(problem)
    return None


def status_problem(key_robot: int | None, status: Any) -> str | None:
    """Why a status published on robot ``key_robot``'s key is not that robot's, or None."""
    if key_robot is not None and status.robot != key_robot:
        return f"status of robot {status.robot} on robot {key_robot}'s key"
    return None


def sim_done_plausible(last_t: float, duration: float, sim_ended: bool) -> bool:
    """A ``sim_done`` is the simulator's when the simulator has ended, or when the newest frame
    (``last_t`` [s]) is within max(0.2 s, 2 %) of the run's ``duration`` [s]."""
    return sim_ended or last_t >= duration - max(0.2, 0.02 * duration)


CONTACT_SLACK = 0.15  # [m] beyond the sum of the radii: two robots this far apart touch nothing
FRAMES_KEPT = 400  # recent frames a contact is checked against (4 s of sim time at 100 Hz)


class RecordCheck:
    """Flags the simulator's claims that contradict what the coordinator recorded (module
    docstring). Fed every recorded frame (:meth:`on_frame`), asked about every event of the
    simulator (:meth:`contradiction`). ``ticks``: the run's last tick (duration × mocap rate)."""

    def __init__(self, radii: Mapping[int, float], mocap_rate: float, ticks: int):
        self.radii = dict(radii)
        self.period = 1.0 / mocap_rate  # [s]
        self.ticks = ticks
        # frames the coordinator may lag behind the simulator's own count (drain order, a
        # backlog, frames still to be backfilled): 1 s of ticks
        self.slack = max(2, round(mocap_rate))
        self.frames: deque[MocapFrame] = deque(maxlen=FRAMES_KEPT)
        self.newest_seq = -1
        # sim_done / sim_stats -> (t, the newest frame's seq) of the one accepted
        self.once: dict[str, tuple[float, int]] = {}

    def on_frame(self, frame: MocapFrame) -> None:
        self.newest_seq = max(self.newest_seq, frame.seq)
        self.frames.append(frame)

    def contradiction(self, event: Event) -> str | None:
        kind, data = event.kind, event.data
        if kind in ("sim_done", "sim_stats"):
            first = self.once.get(kind)
            # a first one that frames followed was not the end: this one may be
            if first is not None and self.newest_seq <= first[1] + self.slack:
                return f"a second {kind} (the first at t = {first[0]:.2f} s)"
            ticks = data.get("ticks")
            if isinstance(ticks, int):
                if ticks > self.ticks + 2:
                    return f"{kind} counts {ticks} ticks, the run has {self.ticks}"
                if not self.newest_seq - 1 <= ticks <= self.newest_seq + self.slack:
                    return (f"{kind} counts {ticks} ticks, the frames recorded reach tick "
                            f"{self.newest_seq}")
            due = data.get("due")
            if isinstance(due, int) and isinstance(ticks, int) and \
                    due > (ticks + 1) * len(self.radii):
                return f"sim_stats: {due} deadlines due in {ticks} ticks of {len(self.radii)} " \
                       "robots"
            self.once[kind] = (event.t, self.newest_seq)
        elif kind == "deadline_miss":
            seq = data.get("seq")
            if isinstance(seq, int) and seq > self.newest_seq + self.slack:
                return f"a missed deadline of tick {seq}, the frames reach tick {self.newest_seq}"
        elif kind == "contact":
            return self._contact(event)
        return None

    def _contact(self, event: Event) -> str | None:
        a, b = event.data.get("a"), event.data.get("b")
        if not (isinstance(a, int) and isinstance(b, int)) or a not in self.radii \
                or b not in self.radii:
            return None  # a wall contact: obstacles are the world's business, not checked
        near = [f for f in self.frames if abs(f.t - event.t) <= 1.5 * self.period]
        if not near:
            return None  # no frame of that time kept: nothing to compare with
        gaps = []
        for frame in near:
            pa, pb = frame.pose(a), frame.pose(b)
            if pa is None or pb is None:
                return None
            gaps.append(math.hypot(pa[0] - pb[0], pa[1] - pb[1]) - self.radii[a] - self.radii[b])
        if min(gaps) > CONTACT_SLACK:
            return (f"contact of robots {a} and {b} at t = {event.t:.2f} s, {min(gaps):.2f} m "
                    "apart in the frames recorded")
        return None
