"""What the plan executor reports: events and progress (ltl-planning.md §6).

All frozen dataclasses of plain values, so the agent runtime can encode them into ``event`` and
``robot/<id>/status`` messages (architecture.md §2) without touching numpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar


@dataclass(frozen=True)
class RegionVisited:
    """The robot's centre entered ``region``, the target of its plan (a planned letter of the
    run's word, docs/ltl-navigation.md §1)."""

    kind: ClassVar[str] = "region_visited"
    t: float  # [s]
    region: str
    visits: int  # entries of this region so far, this one included


@dataclass(frozen=True)
class RegionEntered:
    """The robot's centre entered ``region``, which its plan did not schedule: the run's word
    has a letter the plan's word lacks (docs/ltl-navigation.md §1). ``target`` is the region
    the plan was driving to, ``previous`` the word's letter before this one (None: start)."""

    kind: ClassVar[str] = "region_entered"
    t: float  # [s]
    region: str
    target: str | None
    previous: str | None
    visits: int


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
class Recovered:
    """The recovery after ``Stuck`` (rotate, back off, wait) ended and the robot drives on to the
    same ``target``, still reachable (docs/ltl-navigation.md §5); ``attempt`` counts the
    recoveries on the way to it."""

    kind: ClassVar[str] = "recovered"
    t: float  # [s]
    target: str
    attempt: int


@dataclass(frozen=True)
class Yielding:
    """Head-on or crossing traffic (docs/ltl-navigation.md §6): ``state`` "begin" when the robot
    stops to give way to robot ``other``, "end" when it drives on."""

    kind: ClassVar[str] = "yield"
    t: float  # [s]
    state: str
    other: int
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
    | RegionEntered
    | Recovered
    | Yielding
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
    mode: str  # "navigate", "rotate", "back_off", "wait", "yield", "hold" or "lost"
    stuck_count: int
    distance_to_target: float  # [m] remaining global-path length (inf if unknown)
