"""The LTL maps corpus (``scenarios/ltl_maps/``) as system tests: each file once through
``tlfleet run --lockstep`` at seed 1 (real router, simulator and agent processes), judged from
the run directory by ``tests/ltl_corpus.py`` — the word recomputed from ``trajectory.csv`` and the
task evaluated on it with the exact lasso evaluator, no unplanned region entry (nor one the
agent reported), no contact, no standstill while the task wants motion (a yield's wait excepted,
up to 15 s). Durations are the shortest in which the task's lasso can close, plus a margin
(``Case.test_duration``); the two large fleets are marked slow. The benchmark
``bench/ltl_maps_bench.py`` runs the same files over seeds 1-5 with their full durations."""

from __future__ import annotations

import pytest
from ltl_corpus import CORPUS, analyse
from system_helpers import run
from tlfleet.agent.scenario import load_scenario

pytestmark = pytest.mark.system


@pytest.mark.parametrize("case", [pytest.param(c, id=c.name,
                                               marks=[pytest.mark.slow] if c.slow else [])
                                  for c in CORPUS])
def test_corpus_scenario_meets_its_task_with_no_unplanned_entry_contact_or_stall(tmp_path, case):
    duration = case.test_duration or load_scenario(case.path).duration
    result = run(case.path, tmp_path / "run", duration=duration, seed=1)
    # the run reached its end; stale-mocap notes under a loaded machine may degrade it, the
    # lockstep trajectory does not depend on them
    assert result.outcome.reason in ("sim_done", "duration"), result.summary_text
    assert result.verdict.label in ("clean", "degraded"), result.summary_text
    outcome = analyse(tmp_path / "run")
    assert outcome.t_end == pytest.approx(duration)
    report = outcome.summary()
    assert outcome.robots, report
    for robot in outcome.robots.values():
        assert robot.met, report
        assert robot.unplanned == [], report
        assert robot.reported_unplanned == 0, report
        assert robot.standstills == [], report
    assert outcome.contacts == [], report
