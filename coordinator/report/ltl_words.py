"""LTL robots in the run report: the executed word and its accepting condition.

**LTL robots: the executed word and its accepting condition.** Definitions (ltl-planning.md §3,
the planner's transition system):

* *word*: the robot's region visits in time order. A visit is an entry into a region's disc with
  the hysteresis of :func:`tlfleet.coordinator.report.summary.region_entries` (re-entry counts only
  after leaving by ``REGION_HYSTERESIS``); consecutive visits of the same region collapse into one
  (a stutter). Each visit is the letter ``labels(region)``. Travel between regions is *not* a letter
  (the transition system jumps region to region); a robot that starts outside every region starts
  with the letter ∅ (the planner's ``start`` state). Collapsing stutters is exact for X-free
  formulas (stutter-invariant), the only ones the scenarios use.
* *plan cycle*: the suffix of the plan in the last LTL status row (``prefix``/``suffix``; the
  plan is recomputed with ``tlfleet.agent.policy.ltl.plan_on_map``, as the agent plans, only
  when there is no status row), collapsed cyclically: ``[a12, a11, a12]`` → ``c = (a12, a11)``.
* *completed cycle*: when ``|c| ≥ 2``, every index ``j`` of the word with
  ``word[j−|c| … j] = c₀ c₁ … c_{|c|−1} c₀``; its *cycle time* is the time between the entries at
  ``j − |c|`` and ``j`` [s] (for back-to-back cycles, the time between successive completions).
  A suffix of one region (a task that needs no cycle, e.g. ``F a & F b``) has no cycles.
* *lasso*: with at least one completed cycle, the last one ending at ``j`` closes the run:
  ``u = word[0 … j−|c|)`` and ``v = word[j−|c| … j)``; otherwise (no cycle needed, or none
  completed) ``u = word[0 … n−1)`` and ``v = word[n−1]``: the robot's final label repeated forever.
* *accepting condition met* ⇔ ``u·v^ω ⊨ φ`` by the exact lasso evaluator
  ``tlfleet.agent.ltl.lasso.holds`` **and** the Büchi automaton
  ``tlfleet.agent.ltl.buchi.translate(φ)`` accepts ``u·v^ω``
  (:func:`tlfleet.agent.ltl.emptiness.accepts_lasso`); both are reported and must agree. A robot
  that never completes the cycle its task needs therefore does not meet it (its final label repeated
  does not satisfy ``G F a & G F b``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from tlfleet.agent.ltl.emptiness import accepts_lasso
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.task import robot_formula, task_automaton
from tlfleet.agent.model import Scenario
from tlfleet.agent.policy.ltl import plan_on_map
from tlfleet.agent.stl.monitor import Trajectory
from tlfleet.bus.errors import UnsatisfiableTask
from tlfleet.bus.protocol.messages import LtlStatus
from tlfleet.coordinator.record.run_record import (
    Accepting,
    Lasso,
    LtlRobotReport,
    LtlRobotSummary,
    Plan,
    Visits,
    WordLetter,
)
from tlfleet.coordinator.report.summary import REGION_HYSTERESIS, region_entry_indices

START = "start"  # the planner's name of the state outside every region (ltl-planning.md §3)


def region_word(t: np.ndarray, xy: np.ndarray, scenario: Scenario,
                hysteresis: float = REGION_HYSTERESIS) -> list[tuple[float, str]]:
    """The executed word as ``[(entry time [s], region name)]`` (see the module docstring):
    ``t`` (N,) [s], ``xy`` (N, 2) [m]; ``"start"`` at t[0] if no region holds the first sample."""
    if len(t) == 0:
        return []
    entries = sorted((k, region.name) for region in scenario.regions
                     for k in region_entry_indices(xy, region.center, region.radius, hysteresis))
    word: list[tuple[float, str]] = []
    if not entries or entries[0][0] != 0:
        word.append((float(t[0]), START))
    for k, name in entries:
        if not word or word[-1][1] != name:
            word.append((float(t[k]), name))
    return word


def plan_cycle(suffix: list[str]) -> list[str]:
    """The plan's suffix with consecutive repeats collapsed cyclically: [a, b, a] → [a, b]."""
    cycle: list[str] = []
    for name in suffix:
        if not cycle or cycle[-1] != name:
            cycle.append(name)
    while len(cycle) > 1 and cycle[-1] == cycle[0]:
        cycle.pop()
    return cycle


def completed_cycles(names: list[str], cycle: list[str]) -> list[int]:
    """Indices ``j`` of ``names`` closing the cycle: ``names[j−k … j] == cycle + [cycle[0]]``."""
    k = len(cycle)
    if k < 2:
        return []
    pattern = [*cycle, cycle[0]]
    return [j for j in range(k, len(names)) if names[j - k:j + 1] == pattern]


def _labels(scenario: Scenario, name: str) -> frozenset[str]:
    return frozenset() if name == START else scenario.region(name).labels


def ltl_robot_report(scenario: Scenario, robot_id: int, traj: Trajectory | None,
                     status: LtlStatus | None, summary: LtlRobotSummary) -> LtlRobotReport:
    """The report entry of LTL robot ``robot_id``: plan, visits, word, cycles, lasso and the
    accepting condition (module docstring); ``status`` is its last status."""
    robot = scenario.robot(robot_id)
    formula = robot.ltl or ""
    if status is not None:
        plan = Plan(tuple(status.prefix), tuple(status.suffix),
                    "status.csv (last LTL status row)")
    else:
        try:
            p = plan_on_map(scenario, robot_id)
            plan = Plan(tuple(p.prefix), tuple(p.suffix), "recomputed (no LTL status row)")
        except UnsatisfiableTask as exc:
            plan = Plan((), (), f"none ({exc})")
    visits = {name: Visits(summary.visits_reported.get(name, 0),
                           summary.visits_trajectory.get(name))
              for name in summary.plan_regions}
    cycle = plan_cycle(list(plan.suffix))
    unevaluated = LtlRobotReport(
        task=formula, plan=plan, visits=visits, rounds=summary.rounds, word=(),
        cycle=tuple(cycle), cycles_completed=0, cycle_times=(), cycle_time_mean=None,
        lasso=None, accepting=Accepting(lasso=None, buchi=None, agree=None, met=False),
        note="")
    if traj is None or robot_id not in traj.states:
        return replace(unevaluated, note="no trajectory for this robot: accepting condition "
                                         "not evaluated")
    word = region_word(traj.t, traj.states[robot_id][:, :2], scenario)
    names = [name for _t, name in word]
    times = [t for t, _name in word]
    ends = completed_cycles(names, cycle)
    cycle_times = [times[j] - times[j - len(cycle)] for j in ends]
    if ends:
        j = ends[-1]
        u, v = names[:j - len(cycle)], names[j - len(cycle):j]
        closed_by = f"last completed cycle (ends at t = {times[j]:.2f} s)"
    else:
        u, v = names[:-1], names[-1:]
        closed_by = ("final label repeated (the plan needs no cycle)" if len(cycle) < 2
                     else "final label repeated (no cycle completed)")
    prefix = [_labels(scenario, n) for n in u]
    loop = [_labels(scenario, n) for n in v]
    by_lasso = holds(robot_formula(robot), prefix, loop)
    by_buchi = accepts_lasso(task_automaton(robot_formula(robot)), prefix, loop)
    return replace(
        unevaluated,
        word=tuple(WordLetter(t, name) for t, name in word),
        cycles_completed=len(ends),
        cycle_times=tuple(cycle_times),
        cycle_time_mean=float(np.mean(cycle_times)) if cycle_times else None,
        lasso=Lasso(tuple(u), tuple(v), closed_by),
        accepting=Accepting(lasso=by_lasso, buchi=by_buchi, agree=by_lasso == by_buchi,
                            met=by_lasso and by_buchi),
        note=("the lasso evaluator and the Büchi automaton disagree: a bug to report"
              if by_lasso != by_buchi else ""))
