"""Sub-task sequencing (stl-funnel.md §9): validation, merge, activation with phase_start_times."""

from __future__ import annotations

import numpy as np
import pytest
from stl_harness import run_closed_loop
from tlfleet.agent.policy.stl import StepInput, single_agent
from tlfleet.agent.stl.errors import StlTaskError
from tlfleet.agent.stl.sequencer import build_sequence, check_phase_start_times, overall_robustness
from tlfleet.agent.stl.syntax import And


def test_same_window_g_tasks_are_merged():
    seq = build_sequence(1, ["G[0,5] (x1 <= 1)", "G[0,5] (y1 <= 2)", "F[6,8] (dist(p1, [0,0]) "
                                                                      "<= 0.1)"],
                         rho_opt=[3.0])
    assert len(seq) == 2
    assert isinstance(seq[0].psi, And) and len(seq[0].psi.children) == 2
    assert seq[0].rho_opt == 3.0 and seq[1].rho_opt == pytest.approx(0.1)
    assert [t.index for t in seq] == [0, 1]


@pytest.mark.parametrize(("texts", "message"), [
    (["G[0,5] (dist(p1, [0,0]) <= 1)", "F[4,8] (dist(p1, [0,0]) <= 1)"],
     r"robot 1 sub-task 2: window \[4, 8\] starts before the previous one ends \(b = 5\)"),
    (["F[0,5] (dist(p1, [0,0]) <= 1)", "F[0,5] (dist(p1, [1,0]) <= 1)"],
     r"sub-task 2: window \[0, 5\] starts before"),
])
def test_overlapping_windows_are_rejected(texts, message):
    with pytest.raises(StlTaskError, match=message):
        build_sequence(1, texts)


def test_phase_start_times_validation():
    seq = build_sequence(3, ["G[21,30] (dist(p3, [0,-2]) <= 0.1)",
                             "F[57,58] (dist(p3, [1.5,-1.5]) <= 0.1)"])
    assert check_phase_start_times(3, seq, [30]) == (30.0,)
    assert check_phase_start_times(3, seq, None) is None
    with pytest.raises(StlTaskError, match=r"phase_start_times\[0\] = 25 precedes the end b = 30"):
        check_phase_start_times(3, seq, [25])
    with pytest.raises(StlTaskError, match="has 2 entries, expected 1"):
        check_phase_start_times(3, seq, [30, 40])
    assert overall_robustness([0.2, -0.1]) == -0.1


def test_forced_activation_time_and_idle_gap():
    seq = build_sequence(1, ["F[0,1] (dist(p1, [0,0]) <= 0.5)",
                             "F[5,6] (dist(p1, [1,0]) <= 0.1)"])
    agent = single_agent(1, seq, phase_start_times=[3.0])
    result = run_closed_loop([agent], {1: (0.0, 0.0, 0.0)}, 4.0)
    logs = result.logs[1]
    first_done = result.states[1].outcomes[0].t_done
    assert first_done == 0.0  # ρ = 0.5 − 0 inside (r, ρ_max) at t = 0
    gap = [rec for rec in logs if 0 < rec.t < 3.0]
    assert all(rec.subtask == 1 and rec.c == -1 and np.isnan(rec.rho) for rec in gap)
    traj = result.trajectory.states[1]
    assert np.allclose(traj[: round(3.0 * 100) + 1], 0.0)  # idle until the forced time
    active = [rec for rec in logs if rec.t >= 3.0]
    assert active[0].t == 3.0 and active[0].c == 0 and not np.isnan(active[0].rho)
    assert traj[-1][0] > 0  # moving towards (1, 0) after t = 3


def test_without_phase_start_times_next_subtask_starts_right_after():
    seq = build_sequence(1, ["F[0,1] (dist(p1, [0,0]) <= 0.5)",
                             "F[5,6] (dist(p1, [1,0]) <= 0.1)"])
    agent = single_agent(1, seq)
    state = agent.initial_state()
    pose = {1: np.zeros(3)}
    state, _ = agent.step(state, StepInput(0.0, pose))
    assert state.k == 1 and not state.active
    state, out = agent.step(state, StepInput(0.01, pose))
    assert state.active and state.funnel.t_r == 0.01 and out.log.subtask == 1
