"""The task tally (tlfleet.coordinator.report.task_tally): every task of the scenario judged from
the trajectory it produced, counted, and the exit code of ``--require-tasks``."""

from __future__ import annotations

import numpy as np
import pytest
from tlfleet.agent.scenario import parse_scenario
from tlfleet.agent.stl.monitor import Trajectory
from tlfleet.coordinator.live.supervisor import Outcome
from tlfleet.coordinator.live.verdict import Verdict
from tlfleet.coordinator.record.rundir import RunFiles
from tlfleet.coordinator.report.summary import summarise
from tlfleet.coordinator.report.task_tally import TASKS_NOT_MET, TaskTally, task_tally
from tlfleet.coordinator.supervise import RunResult

SCENARIO = parse_scenario({
    "name": "tally", "duration": 10.0,
    "regions": [{"name": "a1", "center": [1.0, 1.0]}, {"name": "a2", "center": [2.0, 2.0]}],
    "robots": [
        {"id": 1, "kind": "unicycle", "pose": [0.0, 0.0, 0.0], "ltl": "F a1 & F a2"},
        {"id": 2, "kind": "omni", "pose": [0.0, -1.0, 0.0],
         "stl": ["G[0,5] (dist(p2, [0,-1]) <= 0.5)", "F[6,8] (dist(p2, [3,-1]) <= 0.1)"]},
    ],
})


def files(tmp_path, *, visits_a2: bool, t_end: float = 10.0) -> RunFiles:
    """Robot 2 stands at its start (G holds with ρ = 0.5; the F goal 3 m away: violated by
    3 − 0.1 = 2.9); robot 1 drives to a1, then to a2 unless ``visits_a2`` is false."""
    t = np.arange(0.0, t_end + 1e-9, 0.1)
    s1 = np.zeros((len(t), 3))
    s1[t >= 2.0, :2] = (1.0, 1.0)
    if visits_a2:
        s1[t >= 4.0, :2] = (2.0, 2.0)
    s2 = np.zeros((len(t), 3))
    s2[:, 1] = -1.0
    return RunFiles(tmp_path, SCENARIO, {}, (), (), Trajectory(t, {1: s1, 2: s2}), "")


def tally_of(run: RunFiles) -> TaskTally:
    _text, summary = summarise(run)
    return task_tally(run, summary)


def test_each_task_is_judged_from_the_trajectory(tmp_path):
    tally = tally_of(files(tmp_path, visits_a2=True))
    rows = [(r.robot, r.label, r.outcome) for r in tally.results]
    assert rows == [(1, "LTL", "met"), (2, "stl[0]", "met"), (2, "stl[1]", "violated")]
    assert tally.results[2].by == pytest.approx(2.9)
    assert (tally.met, tally.total, tally.all_met) == (2, 3, False)
    assert tally.line == "tasks: 2 of 3 met; robot 2 stl[1] violated by 2.900"


def test_an_ltl_word_that_misses_a_region_and_a_window_the_run_never_closed_are_not_met(tmp_path):
    tally = tally_of(files(tmp_path, visits_a2=False, t_end=7.0))
    assert [r.outcome for r in tally.results] == ["not met", "met", "not evaluated"]
    assert tally.line == ("tasks: 1 of 3 met; robot 1 LTL not met, robot 2 stl[1] not "
                          "evaluated")
    assert tally.to_json()["results"][2]["reason"].startswith("the run ended at t = 7.00 s")


@pytest.mark.parametrize("label,all_met,required,code", [
    ("clean", True, True, 0), ("clean", False, False, 0), ("clean", False, True, TASKS_NOT_MET),
    ("degraded", False, True, TASKS_NOT_MET), ("degraded", True, True, 4),
    ("failed", False, True, 3), ("interrupted", False, True, 130),
])
def test_require_tasks_exit_code(tmp_path, label, all_met, required, code):
    tally = tally_of(files(tmp_path, visits_a2=True))
    if all_met:
        tally = TaskTally(tuple(r for r in tally.results if r.met))
    result = RunResult(tmp_path, Outcome("sim_done", 10.0), {}, True, verdict=Verdict(label),
                       tasks=tally)
    assert result.exit_code(require_tasks=required) == code
