"""The STL corpus of ``scenarios/stl/`` (docs/stl-saturation.md): what each scenario's sub-tasks
should give, and a judge of a recorded run, shared by the system tests (seed 1) and
``bench/stl_maps_bench.py`` (seeds 1–5).

Every sub-task is *feasible* (met: ρ^φ > 0 required) unless listed with its best possible
robustness, derived in the scenario file's comment (``too_far``). The judge recomputes everything
from ``trajectory.csv`` and ``events.jsonl`` with numpy: each literal's h by the generic array
evaluator (not the agents' compiled code, not the report's monitor), the standard min over the
conjuncts, min (G) or max (F) over the window's samples; robot–robot contacts from the
simulator's contact events; wall contacts from the trajectory (a gap to a wall or obstacle of at
most ``CONTACT_GAP`` is a contact sample), counting the samples of each contact beyond its first
second.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tlfleet.agent.nav.grid import arena_clearance
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.stl.evaluate import evaluate_array
from tlfleet.agent.stl.syntax import Not, literals, predicate_function
from trajectory_csv import load_trajectory

ROOT = Path(__file__).resolve().parents[1]
CORPUS_DIR = ROOT / "scenarios" / "stl"
CONTACT_GAP = 0.005  # [m] a body this close to a wall or obstacle touches it
INFEASIBLE_TOLERANCE = 0.05  # infeasible sub-tasks within this of their best possible

# scenario -> {(robot, sub-task index): best possible ρ^φ} for the infeasible sub-tasks
INFEASIBLE: dict[str, dict[tuple[int, int], float]] = {
    "too_far": {(1, 0): 0.2 - (3.5 - 0.2 * 10.0), (2, 0): 0.3 - 1.0, (3, 0): 0.3 - 1.0},
}
# the corpus, the quick ones first; the system tests mark the others slow
QUICK = ("reach_tight", "rendezvous", "too_far", "reach_two_thirds", "box_stay", "corner",
         "escort", "door", "pillars")
SLOW = ("crossing", "errand")
NAMES = QUICK + SLOW


@dataclass
class SubTaskResult:
    robot: int
    index: int
    text: str
    rho: float
    best: float | None  # best possible for an infeasible sub-task, None for a feasible one

    @property
    def ok(self) -> bool:
        if self.best is None:
            return self.rho > 0.0
        return self.rho <= self.best + 1e-9 and self.rho >= self.best - INFEASIBLE_TOLERANCE


@dataclass
class RunJudgement:
    name: str
    subtasks: list[SubTaskResult] = field(default_factory=list)
    robot_contacts: int = 0
    wall_contact_samples: int = 0  # samples in contact with a wall or obstacle
    wall_beyond_1s: int = 0  # ... of them beyond each contact's first second
    repairs: int = 0

    @property
    def ok(self) -> bool:
        return (all(s.ok for s in self.subtasks) and self.robot_contacts == 0
                and self.wall_beyond_1s == 0)


def _psi(task, states: dict[int, np.ndarray]) -> np.ndarray:
    values = []
    for literal in literals(task.psi):
        pred = literal.pred if isinstance(literal, Not) else literal
        h = np.asarray(evaluate_array(predicate_function(pred), states), dtype=float)
        values.append(-h if isinstance(literal, Not) else h)
    n = len(next(iter(states.values())))
    return np.min(np.vstack([np.broadcast_to(v, (n,)) for v in values]), axis=0)


def judge(name: str, run_dir: Path) -> RunJudgement:
    """Everything the corpus asks of one recorded run (module docstring)."""
    from tlfleet.agent.scenario.stl_setup import stl_sequences

    scenario = load_scenario(CORPUS_DIR / f"{name}.toml")
    out = RunJudgement(name)
    infeasible = INFEASIBLE.get(name, {})
    path = run_dir / "trajectory.csv"
    if not path.exists() or len(path.read_text().splitlines()) < 3:
        # nothing recorded: the fleet did not start (e.g. an agent died at launch)
        for robot_id, tasks in stl_sequences(scenario).items():
            out.subtasks += [SubTaskResult(robot_id, task.index, task.text, math.nan,
                                           infeasible.get((robot_id, task.index)))
                             for task in tasks]
        return out
    t, states = load_trajectory(run_dir)
    for robot_id, tasks in stl_sequences(scenario).items():
        for task in tasks:
            psi = _psi(task, states)
            window = (t >= task.a - 1e-9) & (t <= task.b + 1e-9)
            rho = float(psi[window].min() if task.kind == "G" else psi[window].max()) \
                if window.any() else math.nan
            out.subtasks.append(SubTaskResult(robot_id, task.index, task.text, rho,
                                              infeasible.get((robot_id, task.index))))
    events = [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()
              if line.strip()]
    for e in events:
        data = e.get("data", {})
        if e["kind"] == "contact" and "wall" not in (data.get("a"), data.get("b")):
            out.robot_contacts += 1
        if e["kind"] == "repair":
            out.repairs += 1
    dt = float(np.median(np.diff(t)))
    per_second = round(1.0 / dt)
    for robot in scenario.robots:
        gap = arena_clearance(scenario.arena, states[robot.id][:, :2]) - robot.radius
        touching = gap <= CONTACT_GAP
        out.wall_contact_samples += int(touching.sum())
        run = 0
        for flag in touching:
            run = run + 1 if flag else 0
            if run > per_second:
                out.wall_beyond_1s += 1
    return out
