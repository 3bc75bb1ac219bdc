"""The LTL maps corpus (``scenarios/ltl_maps/``) and what a run of it must show, recomputed from
the run directory independently of the report (shared by ``tests/system/test_system_ltl_maps.py``
and ``bench/ltl_maps_bench.py``).

For every LTL robot of a run this reads ``trajectory.csv``, ``status.csv`` and ``events.jsonl``
and computes, without the coordinator's report code:

* the **word** (docs/ltl-navigation.md §1): the regions whose disc the robot's centre enters, in
  time order, an entry counted again only after leaving the disc by 5 cm, stutters collapsed,
  ``start`` first when the robot starts in no region;
* whether the task holds on that word, closed into a lasso as the report closes it (the last
  completed pass through the plan's cycle, else the last letter repeated), by the exact lasso
  evaluator (``tlfleet.agent.ltl.lasso.holds``);
* **unplanned entries**: word letters that are not the target the robot was driving to, read
  from its last status row before the entry;
* **contacts** (the simulator's ``contact`` events) and **standstills**: 5 s or more in which
  the robot moved less than 5 cm and turned less than 0.1 rad before its plan finished (or its
  task was lost); time spent yielding (between a ``yield`` begin and end event) is waiting for
  the right of way, so a standstill counts when it lasted 5 s or more outside its yields, or
  when it waited longer than ``YIELD_LIMIT`` inside them.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.scenario import load_scenario
from trajectory_csv import load_trajectory

ROOT = Path(__file__).resolve().parent.parent
CORPUS_DIR = ROOT / "scenarios" / "ltl_maps"
HYSTERESIS = 0.05  # [m] leave a disc by this much before a re-entry counts
STILL_WINDOW = 5.0  # [s]
STILL_DISTANCE = 0.05  # [m]
STILL_TURN = 0.1  # [rad]
YIELD_LIMIT = 15.0  # [s] a head-on yield may wait this long


@dataclass(frozen=True)
class Case:
    """One corpus file and how long its test runs [s] (None: the file's duration)."""

    name: str
    test_duration: float | None = None
    slow: bool = False

    @property
    def path(self) -> Path:
        return CORPUS_DIR / f"{self.name}.toml"


# test durations: the task's lasso is met at seed 1 with about 10 % to spare
CORPUS: tuple[Case, ...] = (
    Case("forbidden_on_path", 70.0),
    Case("until_order", 35.0),
    Case("sequence_with_wall", 70.0),
    Case("request_response", 70.0),
    Case("wall_door", 85.0),
    Case("pillars"),
    Case("corridor_080"),
    Case("corridor_100"),
    Case("corridor_120"),
    Case("swap_corridor", 50.0),
    Case("hall_crossing", slow=True),
    Case("warehouse_12x9", slow=True),
    Case("shared_charger", 75.0),
    Case("pick_then_home", 45.0),
)


@dataclass
class RobotOutcome:
    """What one LTL robot's run showed (module docstring)."""

    robot: int
    task: str
    word: list[tuple[float, str]]
    met: bool
    unplanned: list[tuple[float, str, str | None]]  # (t, region entered, target then)
    standstills: list[tuple[float, float]]  # [s] (start, end)
    reported_unplanned: int  # the agent's unplanned_region events
    cycles: int
    yields: list[tuple[float, float]] = field(default_factory=list)  # [s]


@dataclass
class RunOutcome:
    scenario: str
    robots: dict[int, RobotOutcome]
    contacts: list[dict]
    t_end: float

    @property
    def met(self) -> bool:
        return all(r.met for r in self.robots.values())

    @property
    def unplanned(self) -> int:
        return sum(len(r.unplanned) for r in self.robots.values())

    @property
    def standstills(self) -> int:
        return sum(len(r.standstills) for r in self.robots.values())

    def summary(self) -> str:
        lines = [f"{self.scenario}: t_end {self.t_end:.1f} s, contacts {len(self.contacts)}"]
        for r in self.robots.values():
            word = " ".join(name for _t, name in r.word)
            lines.append(
                f"  r{r.robot} {r.task}: met {r.met}, word [{word}], cycles {r.cycles}, "
                f"unplanned {[(round(t, 1), n, g) for t, n, g in r.unplanned]} "
                f"(agent says {r.reported_unplanned}), standstills "
                f"{[(round(a, 1), round(b, 1)) for a, b in r.standstills]}, "
                f"yields {[(round(a, 1), round(b, 1)) for a, b in r.yields]}")
        return "\n".join(lines)


def _events(run_dir: Path) -> list[dict]:
    return [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()
            if line.strip()]


def _statuses(run_dir: Path) -> dict[int, list[dict]]:
    out: dict[int, list[dict]] = {}
    with open(run_dir / "status.csv", newline="") as handle:
        for row in csv.DictReader(handle):
            if row["kind"] == "ltl":
                out.setdefault(int(row["robot"]), []).append(row)
    return out


def word_of(t: np.ndarray, xy: np.ndarray, regions) -> list[tuple[float, str]]:
    """Region entries of the centre path ``xy`` (N, 2) [m] (module docstring)."""
    entries: list[tuple[int, str]] = []
    for region in regions:
        d = np.hypot(xy[:, 0] - region.center[0], xy[:, 1] - region.center[1])
        inside = False
        for k, value in enumerate(d.tolist()):
            if not inside and value <= region.radius:
                entries.append((k, region.name))
                inside = True
            elif inside and value > region.radius + HYSTERESIS:
                inside = False
    entries.sort()
    word: list[tuple[float, str]] = []
    if not entries or entries[0][0] != 0:
        word.append((float(t[0]), "start"))
    for k, name in entries:
        if not word or word[-1][1] != name:
            word.append((float(t[k]), name))
    return word


def _cycle(suffix: list[str]) -> list[str]:
    cycle: list[str] = []
    for name in suffix:
        if not cycle or cycle[-1] != name:
            cycle.append(name)
    while len(cycle) > 1 and cycle[-1] == cycle[0]:
        cycle.pop()
    return cycle


def lasso_met(formula: str, names: list[str], suffix: list[str], labels: dict[str, frozenset]
              ) -> tuple[bool, int]:
    """Whether ``formula`` holds on the word ``names`` closed into a lasso (module docstring),
    and the number of completed passes through the plan's cycle."""
    cycle = _cycle(suffix)
    k = len(cycle)
    ends = ([j for j in range(k, len(names)) if names[j - k:j + 1] == [*cycle, cycle[0]]]
            if k >= 2 else [])
    if ends:
        j = ends[-1]
        u, v = names[:j - k], names[j - k:j]
    else:
        u, v = names[:-1], names[-1:]
    letters = [labels.get(n, frozenset()) for n in u], [labels.get(n, frozenset()) for n in v]
    return holds(formula, *letters), len(ends)


def _standstills(t: np.ndarray, pose: np.ndarray, until: float,
                 yields: list[tuple[float, float]]) -> list[tuple[float, float]]:
    dt = float(np.median(np.diff(t)))
    n = max(1, round(STILL_WINDOW / dt))
    if len(t) <= n:
        return []
    moved = np.hypot(*(pose[n:, :2] - pose[:-n, :2]).T)
    turned = np.abs(np.unwrap(pose[:, 2])[n:] - np.unwrap(pose[:, 2])[:-n])
    still = (moved < STILL_DISTANCE) & (turned < STILL_TURN) & (t[n:] <= until)
    out = []
    k = 0
    while k < len(still):
        if not still[k]:
            k += 1
            continue
        j = k
        while j + 1 < len(still) and still[j + 1]:
            j += 1
        start, end = float(t[k]), float(t[j + n])
        waited = sum(max(0.0, min(end, b) - max(start, a)) for a, b in yields)
        if end - start - waited >= STILL_WINDOW or waited > YIELD_LIMIT:
            out.append((start, end))
        k = j + 1
    return out


def analyse(run_dir: Path) -> RunOutcome:
    """The outcome of the run in ``run_dir`` (module docstring)."""
    scenario = load_scenario(run_dir / "scenario.toml")
    t, states = load_trajectory(run_dir)
    events = _events(run_dir)
    statuses = _statuses(run_dir)
    labels = {r.name: frozenset(r.labels) for r in scenario.regions}
    contacts = [e["data"] for e in events if e["kind"] == "contact"]
    robots: dict[int, RobotOutcome] = {}
    for robot in scenario.robots:
        if not robot.is_ltl or robot.id not in states:
            continue
        source = f"agent/{robot.id}"
        mine = [e for e in events if e["source"] == source]
        finished = min((e["t"] for e in mine if e["kind"] == "plan_finished"), default=math.inf)
        lost = min((e["t"] for e in mine if e["kind"] == "task_lost"), default=math.inf)
        yields, begun = [], None
        for e in mine:
            if e["kind"] == "yield" and e["data"].get("state") == "begin":
                begun = e["t"]
            elif e["kind"] == "yield" and e["data"].get("state") == "end" and begun is not None:
                yields.append((begun, e["t"]))
                begun = None
        if begun is not None:
            yields.append((begun, float(t[-1])))
        word = word_of(t, states[robot.id][:, :2], scenario.regions)
        rows = statuses.get(robot.id, [])
        row_t = np.array([float(r["t"]) for r in rows])
        unplanned = []
        for when, name in word[1:]:
            k = int(np.searchsorted(row_t, when, side="left")) - 1
            target = (rows[k]["target"] or None) if k >= 0 else None
            if name != target:
                unplanned.append((when, name, target))
        suffix = rows[-1]["suffix"].split() if rows else []
        met, cycles = lasso_met(robot.ltl, [n for _t, n in word], suffix, labels)
        robots[robot.id] = RobotOutcome(
            robot=robot.id, task=robot.ltl, word=word, met=met, unplanned=unplanned,
            standstills=_standstills(t, states[robot.id], min(finished, lost), yields),
            reported_unplanned=sum(1 for e in mine if e["kind"] == "unplanned_region"),
            cycles=cycles, yields=yields)
    return RunOutcome(scenario.name, robots, contacts, float(t[-1]))
