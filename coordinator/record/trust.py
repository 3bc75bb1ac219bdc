"""What the coordinator believes of the messages it records.

The transport does not say which session published a sample (full authentication comes with the
security issue), so the coordinator checks what it can: that a message's claimed identity is one
of the fleet's processes and owns what it claims.

* An ``Event``'s ``source`` must be ``sim`` or ``agent/<id>`` of a robot of the scenario, and the
  kinds only the simulator makes (:data:`SIM_KINDS`: ``sim_done``, ``sim_stats``, contacts,
  deadline misses, watchdog stops…) must come from ``sim``; the kinds only an agent makes
  (:data:`AGENT_KINDS`) from an agent. Anything else is *flagged*: not recorded as the event it
  claims to be, but as ``Event(kind="flagged_event")`` of the coordinator naming the claimed source,
  kind and why — so a spoofed ``sim_done`` neither ends the run nor reads as genuine.
* A status on ``robot/<id>/status`` must be robot ``id``'s.
* A ``sim_done`` is trusted only when the simulator has ended or the frames have reached the end
  of the run (:func:`sim_done_plausible`): the genuine one comes after the final frame.

``coordinator`` itself is not a source anyone else may use: the tap drops such events (its own are
recorded when made).
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

SIM_KINDS = frozenset({"sim_done", "sim_stats", "contact", "deadline_miss", "watchdog_stop",
                       "stale_command"})
AGENT_KINDS = frozenset({"agent_stats", "stale_mocap", "resumed", "plan_ready", "fault"})
FLAGGED = "flagged_event"


def event_problem(event: Any, robot_ids: Collection[int]) -> str | None:
    """Why ``event`` (an Event) does not come from the identity it claims, or None."""
    source = event.source
    if source == "sim":
        if event.kind in AGENT_KINDS - {"fault"}:
            return f"kind {event.kind!r} is an agent's, not the simulator's"
        return None
    prefix, _, ident = source.partition("/")
    if prefix != "agent" or not ident.isdigit() or int(ident) not in robot_ids:
        return f"source {source[:40]!r} is no process of this fleet"
    if event.kind in SIM_KINDS:
        return f"kind {event.kind!r} is the simulator's, not {source}'s"
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
