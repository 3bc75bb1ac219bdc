"""The typed run record: what ``summary.json`` and ``report.json`` hold, as frozen dataclasses.

:class:`RunSummary` is the summary of a run directory
(:func:`tlfleet.coordinator.report.summary.summarise`), :class:`Report` the report built on it
(:func:`tlfleet.coordinator.report.run_report.build_report`); the renderers
(:mod:`tlfleet.coordinator.report.render`), the figures, the verdict and the CLI's ``--json`` read
these types, and the JSON files are written from them and read back through them
(:mod:`tlfleet.coordinator.record.typed_json`: one key per field, in order). Times are sim time
[s], distances and robustness [m] (ρ of a distance predicate), latencies [ms]. A robustness is a
float (±inf: an empty window) or None (not evaluated).

Schema versions (the ``schema`` key of each file):

* ``summary.json`` 1: the first with a version; the run's ``mode`` and ``wall_time`` replace the
  copy of ``run.json`` it held under ``run`` (``run.json`` lies beside it).
* ``report.json`` 4: every object has a fixed set of keys, null where a value is absent: a
  fault's ``detection`` always has ``after_wall`` and ``by``; a process death is
  ``{t, process, how, returncode, wall}``, not a copy of its event's data. 3 added ``tasks`` (the
  task tally), 2 made ``r_bar`` the least r in force. :func:`read_report` reads 3 and 4.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, TypeVar

from tlfleet.coordinator.record import rundir
from tlfleet.coordinator.record.typed_json import (
    Json,
    RecordError,
    fields_from_json,
    fields_to_json,
    from_json,
    to_json,
)

__all__ = ["REPORT_SCHEMA", "SUMMARY_SCHEMA", "RecordError", "Report", "RunSummary",
           "read_report", "read_summary", "write_record"]

SUMMARY_SCHEMA = 1
REPORT_SCHEMA = 5
READABLE_REPORT_SCHEMAS = (3, 4, 5)  # each only adds keys, whose defaults say "absent"


def _schema_checked(value: object, where: str, name: str, readable: tuple[int, ...]) -> None:
    if not isinstance(value, Mapping):
        raise RecordError(where, f"expected an object ({name}), got {type(value).__name__}")
    schema = value.get("schema")
    if schema not in readable or isinstance(schema, bool):
        raise RecordError(_at(where, "schema"), f"{name} schema {schema!r}: this tlfleet "
                                                f"reads {' and '.join(map(str, readable))}")


def _at(where: str, name: str) -> str:
    return f"{where}.{name}" if where else name


# ------------------------------------------------------------------------------------ summary


@dataclass(frozen=True)
class StlSubtaskSummary:
    """One STL sub-task of the summary: ρ from the trajectory and the funnel's r."""

    task: str
    window: tuple[float, float] | None  # [a, b] [s]
    robustness: float | None  # standard ρ^φ recomputed from trajectory.csv
    r_least: float | None  # r̄: the least r in force over the sub-task (ρ^φ ≥ r̄)
    r_last: float | None  # r of the last status row (the final funnel's)
    repairs_status: tuple[int, ...]  # the agent's repair counters per stage 1, 2, 3


@dataclass(frozen=True)
class StlRobotSummary:
    robustness: float | None  # min over its sub-tasks
    subtasks: tuple[StlSubtaskSummary, ...]
    repair_events: Mapping[int, int]  # stage → ``repair`` events
    error: str  # why ρ could not be recomputed ("" when it was)


@dataclass(frozen=True)
class LtlRobotSummary:
    task: str
    plan_regions: tuple[str, ...]
    visits_reported: Mapping[str, int]  # region → visits the agent reported
    visits_trajectory: Mapping[str, int]  # region → disc entries in the trajectory
    rounds: int | None  # GF rounds the agent reported (None: no status row)
    all_plan_regions_visited: bool


@dataclass(frozen=True)
class Contacts:
    robot_robot: int
    robot_wall: int
    pairs: Mapping[str, int]  # "3-4" or "3-wall" → contact events


@dataclass(frozen=True)
class ClosestApproach:
    """The least gap of two robots over the run: centre distance minus both radii."""

    pair: tuple[int, int]
    gap: float  # [m]
    t: float  # [s]


@dataclass(frozen=True)
class SimStats:
    """The simulator's ``sim_stats`` event: the counters the coordinator reads, typed, and the
    event's data as recorded (``counters``: what ``summary.json`` keeps of it)."""

    due: int = 0  # control deadlines due
    missed: int = 0  # of them missed
    latency_p50_ms: float | None = None  # frame publication → command arrival [ms]
    latency_p99_ms: float | None = None  # [ms]
    latency_max_ms: float | None = None  # [ms]
    counters: Mapping[str, object] = field(default_factory=dict)

    @classmethod
    def from_event(cls, data: Mapping[str, object]) -> SimStats:
        def count(key: str) -> int:
            value = data.get(key)
            return int(value) if isinstance(value, int | float) and not isinstance(
                value, bool) and value >= 0 else 0

        def ms(key: str) -> float | None:
            value = data.get(key)
            return float(value) if isinstance(value, int | float) and not isinstance(
                value, bool) else None

        return cls(count("due"), count("missed"), ms("latency_p50_ms"), ms("latency_p99_ms"),
                   ms("latency_max_ms"), dict(data))

    def to_json(self) -> Json:
        return to_json(self.counters)

    @classmethod
    def from_json(cls, value: object, where: str = "") -> SimStats:
        if not isinstance(value, Mapping):
            raise RecordError(where, "expected an object (the sim_stats event's data)")
        return cls.from_event(value)


@dataclass(frozen=True)
class Deadlines:
    """Deadline, watchdog, stale-mocap and malformed counts of a run."""

    deadline_miss: int  # lockstep deadline misses reported by the agents
    deadline_miss_by_robot: Mapping[str, int]
    sim_stats: SimStats | None  # None: no sim_stats event recorded
    watchdog_stop: int
    stale_mocap: int  # episodes during the mission
    stale_mocap_at_end: int  # episodes once the frames stopped at the end (expected)
    malformed: int
    malformed_by_source: Mapping[str, int]


@dataclass(frozen=True)
class ProcessDeath:
    t: float  # [s] sim time
    process: str
    how: str = ""
    returncode: int | None = None
    wall: float | None = None  # [s] wall clock (time.time())


@dataclass(frozen=True)
class RunSummary:
    """``summary.json``: per robot its tasks' figures, then contacts, deadlines and deaths."""

    scenario: str
    run_dir: Path
    mode: str | None  # lockstep | realtime (None: run.json does not say)
    wall_time: float | None  # [s]
    frames: int
    t_end: float  # [s] the last frame's time
    trajectory_error: str  # why trajectory.csv could not be read ("" when it was)
    stl: Mapping[int, StlRobotSummary]  # robot id → …, in id order
    ltl: Mapping[int, LtlRobotSummary]
    contacts: Contacts
    closest_approach: ClosestApproach | None
    deadlines: Deadlines
    process_deaths: tuple[ProcessDeath, ...]

    def to_json(self) -> Json:
        return {"schema": SUMMARY_SCHEMA, **fields_to_json(self)}

    @classmethod
    def from_json(cls, value: object, where: str = "") -> RunSummary:
        _schema_checked(value, where, "summary.json", (SUMMARY_SCHEMA,))
        return fields_from_json(cls, value, where)


# ------------------------------------------------------------------------------------- report


@dataclass(frozen=True)
class PaperComparison:
    """A sub-task of the paper's scenarios beside the value the paper reports."""

    label: str  # the paper's name, e.g. "φ′3"
    printed: str  # the printed bound, e.g. "≥ -0.18"
    bound: float  # what ρ must reach to meet the paper
    best: float | None  # best achievable ρ
    best_note: str
    note: str
    met: bool | None  # ρ ≥ bound (None: not evaluated)
    gap_to_best: float | None  # ρ − best


@dataclass(frozen=True)
class StageCounts:
    stage1: int | None
    stage2: int | None
    stage3: int | None


@dataclass(frozen=True)
class StlSubtaskReport:
    index: int
    task: str
    op: str  # "F" or "G"
    window: tuple[float, float] | None  # [a, b] [s]
    label: str
    robustness: float | None  # ρ^φ from the trajectory
    r_bar: float | None  # the least r in force
    r_final: float | None  # the last funnel's r
    robustness_ge_r_bar: bool | None
    repairs: StageCounts  # the agent's counters
    repair_events: StageCounts  # ``repair`` events
    paper: PaperComparison | None


@dataclass(frozen=True)
class StlRobotReport:
    robustness: float | None
    subtasks: tuple[StlSubtaskReport, ...]
    repair_events: Mapping[int, int]  # stage → events
    error: str


@dataclass(frozen=True)
class Plan:
    prefix: tuple[str, ...]
    suffix: tuple[str, ...]
    source: str  # where it came from (status.csv, recomputed, none)


@dataclass(frozen=True)
class Visits:
    agent: int  # visits the agent reported
    trajectory: int | None  # disc entries in the trajectory (None: no trajectory)


@dataclass(frozen=True)
class WordLetter:
    t: float  # [s] entry time
    region: str


@dataclass(frozen=True)
class Lasso:
    prefix: tuple[str, ...]  # u
    loop: tuple[str, ...]  # v of u·v^ω
    closed_by: str


@dataclass(frozen=True)
class Accepting:
    lasso: bool | None  # u·v^ω ⊨ φ by the exact evaluator
    buchi: bool | None  # the Büchi automaton accepts u·v^ω
    agree: bool | None
    met: bool


@dataclass(frozen=True)
class LtlRobotReport:
    task: str
    plan: Plan
    visits: Mapping[str, Visits]
    rounds: int | None
    word: tuple[WordLetter, ...]
    cycle: tuple[str, ...]
    cycles_completed: int
    cycle_times: tuple[float, ...]  # [s]
    cycle_time_mean: float | None  # [s]
    lasso: Lasso | None
    accepting: Accepting
    note: str


@dataclass(frozen=True)
class Timing:
    deadline_miss_events: int
    deadline_miss_by_robot: Mapping[str, int]
    control_due: int | None
    control_missed: int | None
    latency_p50_ms: float | None  # [ms]
    latency_p99_ms: float | None  # [ms]
    latency_max_ms: float | None  # [ms]
    watchdog_stop: int
    stale_mocap: int
    malformed: int
    sim_stats_present: bool


@dataclass(frozen=True)
class Detection:
    """The first sign of a fault: the event's kind and sim time [s], the delay after the fault's
    start in sim time and, where both events carry it, wall time [s]."""

    kind: str
    t: float  # [s]
    after_sim: float  # [s]
    after_wall: float | None = None  # [s]
    by: str | None = None  # the event's source, for a partition noticed by its targets


@dataclass(frozen=True)
class LostFrames:
    """A stretch of sim time ``trajectory.csv`` has no frame for (a gap, or a short end)."""

    t_from: float  # [s] the last frame before it
    t_to: float  # [s] the first frame after it, or the run's end
    frames: int  # how many frames are missing


@dataclass(frozen=True)
class FaultRow:
    spec: str
    kind: str | None
    targets: tuple[str, ...]
    start_t: float | None  # [s]; None: never injected (a skipped fault, ``error`` says why)
    end_t: float | None  # [s]
    lasted: float | None  # [s] wall
    error: str | None  # why the fault could not be injected
    detection: Detection | None
    min_clearance: float | None  # [m] over every robot pair during the fault


SubtaskOutcome = Literal["satisfied", "violated", "not evaluated"]


@dataclass(frozen=True)
class SubtaskVerdict:
    """``satisfied``, ``violated`` by ``by`` = −ρ^φ, or ``not evaluated`` (``reason``); ``held``:
    the share of the window's samples with ρ^ψ ≥ 0."""

    verdict: SubtaskOutcome
    by: float | None = None
    reason: str = ""
    held: float | None = None
    label: str = ""


@dataclass(frozen=True)
class StationaryEpisode:
    robot: int
    t_start: float  # [s]
    t_end: float  # [s]


@dataclass(frozen=True)
class StlDesign:
    """The STL switches in force (docs/stl-saturation.md §9)."""

    saturation_aware: bool
    saturation_share: float
    f_semantics: str
    rho_opt_from_arena: bool
    r1: float  # [m]
    r_sense: float  # [m]
    coupled_radii: Mapping[str, tuple[float, float]]  # "i-j" → (R1_ij, R_ij) [m]
    wall_avoidance: bool
    route_around: bool


@dataclass(frozen=True)
class Verdicts:
    coupling_aware: bool
    coupling_share: float
    recovery: bool
    recoveries: Mapping[str, int]  # robot → robustness recoveries
    subtasks: Mapping[int, tuple[SubtaskVerdict, ...]]  # robot → its sub-tasks in order
    stationary: tuple[StationaryEpisode, ...]
    stl_design: StlDesign | None = None


Outcome = Literal["met", "not met", "violated", "not evaluated"]


@dataclass(frozen=True)
class TaskResult:
    """One task of one robot: ``label`` (``LTL``, the paper's name of an STL sub-task or
    ``stl[k]``), the task's text, the outcome and, for a violated STL sub-task, by how much
    (``by`` = −ρ)."""

    robot: int
    label: str
    task: str
    outcome: Outcome
    by: float | None = None
    reason: str = ""

    @property
    def met(self) -> bool:
        return self.outcome == "met"

    @property
    def text(self) -> str:
        """``robot 8 stl[1] violated by 0.860``."""
        what = f"violated by {self.by:.3f}" if self.outcome == "violated" else self.outcome
        return f"robot {self.robot} {self.label} {what}"

    def to_json(self) -> Json:
        return {"robot": self.robot, "label": self.label, "task": self.task,
                "outcome": self.outcome, "met": self.met, "by": self.by, "reason": self.reason}


@dataclass(frozen=True)
class TaskTally:
    """Every task's result, robots in id order, an LTL robot's task before nothing and an STL
    robot's sub-tasks in order."""

    results: tuple[TaskResult, ...]

    @property
    def met(self) -> int:
        return sum(r.met for r in self.results)

    @property
    def total(self) -> int:
        return len(self.results)

    @property
    def all_met(self) -> bool:
        return self.met == self.total

    @property
    def line(self) -> str:
        """``tasks: 5 of 7 met; robot 3 LTL not met, robot 8 stl[1] violated by 0.860``."""
        head = f"tasks: {self.met} of {self.total} met"
        missed = [r.text for r in self.results if not r.met]
        return head + (f"; {', '.join(missed)}" if missed else "")

    def to_json(self) -> Json:
        return {"met": self.met, "total": self.total, "all_met": self.all_met,
                "line": self.line, "results": [to_json(r) for r in self.results]}


@dataclass(frozen=True)
class Report:
    """``report.json``: the summary's figures beside the paper's values, the LTL words and their
    acceptance, per-sub-task verdicts, the task tally, faults and the figures' names."""

    scenario: str
    description: str
    run_dir: Path
    duration: float  # [s] the scenario's
    mode: str | None
    frames: int
    t_end: float  # [s]
    trajectory_error: str
    events_skipped_lines: tuple[int, ...]  # events.jsonl lines that were not JSON
    paper_note: str
    stl: Mapping[int, StlRobotReport]
    ltl: Mapping[int, LtlRobotReport]
    contacts: Contacts
    closest_approach: ClosestApproach | None
    timing: Timing
    process_deaths: tuple[ProcessDeath, ...]
    faults: tuple[FaultRow, ...]
    figure_windows: tuple[tuple[float, float], ...]  # [s] of the trajectory figures
    verdicts: Verdicts
    tasks: TaskTally
    figures: tuple[str, ...] = ()  # file names in run_dir
    lost_frames: tuple[LostFrames, ...] = ()  # sim time without a frame (schema 5)

    @property
    def figure_paths(self) -> tuple[Path, ...]:
        return tuple(self.run_dir / name for name in self.figures)

    def to_json(self) -> Json:
        return {"schema": REPORT_SCHEMA, **fields_to_json(self)}

    @classmethod
    def from_json(cls, value: object, where: str = "") -> Report:
        _schema_checked(value, where, "report.json", READABLE_REPORT_SCHEMAS)
        return fields_from_json(cls, value, where)


# -------------------------------------------------------------------------------------- files

R = TypeVar("R", RunSummary, Report)


def write_record(path: Path, record: RunSummary | Report) -> None:
    """``summary.json`` or ``report.json`` from its record."""
    rundir.write_json(path, to_json(record))


def read_summary(path: Path) -> RunSummary:
    """``summary.json`` read back; :class:`RecordError` names the file and the field that does
    not fit."""
    return _read(RunSummary, path)


def read_report(path: Path) -> Report:
    """``report.json`` (schema 3 or 4) read back; :class:`RecordError` names the file and the
    field that does not fit."""
    return _read(Report, path)


def _read(kind: type[R], path: Path) -> R:
    missing = object()
    value = rundir.read_json(path, missing)
    if value is missing:
        raise RecordError(str(path), "missing, unreadable or not JSON")
    try:
        return from_json(kind, value)
    except RecordError as exc:
        raise RecordError(f"{path}: {exc.where}" if exc.where else str(path),
                          exc.message) from None
