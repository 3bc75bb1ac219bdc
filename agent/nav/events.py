"""What the plan executor reports: events and progress (ltl-planning.md §6).

All frozen dataclasses of plain values, so the agent runtime can encode them into ``event`` and
``robot/<id>/status`` messages (architecture.md §2) without touching numpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar


@dataclass(frozen=True)
class RegionVisited:
    """The robot entered ``region`` (or came within xy_goal_tolerance of its centre)."""

    kind: ClassVar[str] = "region_visited"
    t: float  # [s]
    region: str
    visits: int  # visits of this region so far, this one included


@dataclass(frozen=True)
class CycleCompleted:
    """One more full pass through the plan's suffix (the GF cycle)."""

    kind: ClassVar[str] = "cycle_completed"
    t: float  # [s]
    cycles: int
    cycle_time: float  # [s] since the previous completion (or since the suffix was entered)


@dataclass(frozen=True)
class PlanFinished:
    """The plan has no more moves (its suffix loops on one region): the robot holds there."""

    kind: ClassVar[str] = "plan_finished"
    t: float  # [s]
    region: str


@dataclass(frozen=True)
class PlanAccepted:
    """A new plan from the runtime replaced the old one."""

    kind: ClassVar[str] = "plan_accepted"
    t: float  # [s]
    prefix: tuple[str, ...]
    suffix: tuple[str, ...]


@dataclass(frozen=True)
class NoPathFound:
    """The global planner found no path to the target (it keeps trying every replan period)."""

    kind: ClassVar[str] = "no_path"
    t: float  # [s]
    target: str
    reason: str


@dataclass(frozen=True)
class Stuck:
    """No progress towards ``target`` since ``since``: recovery (rotate, back off) begins."""

    kind: ClassVar[str] = "stuck"
    t: float  # [s]
    target: str
    since: float  # [s] time of the last progress
    position: tuple[float, float]  # [m]


@dataclass(frozen=True)
class ReplanRequest:
    """Ask the LTL planner for a new plan with the edge ``from_region → to_region`` penalised.

    ``from_region`` is the last region visited (None before the first visit: the edge leaves the
    start state). ``penalty`` [m] is to be added to that edge's weight (ltl-planning.md §5,
    replanning); ``position`` is where the robot is now.
    """

    kind: ClassVar[str] = "replan_request"
    t: float  # [s]
    from_region: str | None
    to_region: str
    penalty: float  # [m]
    position: tuple[float, float]  # [m]


NavEvent = (
    RegionVisited
    | CycleCompleted
    | PlanFinished
    | PlanAccepted
    | NoPathFound
    | Stuck
    | ReplanRequest
)


@dataclass(frozen=True)
class Progress:
    """Executor status for ``robot/<id>/status``: where it is in the plan and how far it got."""

    target: str | None  # region currently driven to (None when holding)
    step: int  # index of the target in prefix · suffix^ω
    visits: tuple[tuple[str, int], ...]  # (region, visits) for every region of the plan
    cycles: int  # completed suffix passes
    rounds: int  # GF progress: visits of the least visited suffix region
    control_cycles: int  # executor steps so far
    mode: str  # "navigate", "rotate", "back_off" or "hold"
    stuck_count: int
    distance_to_target: float  # [m] remaining global-path length (inf if unknown)
