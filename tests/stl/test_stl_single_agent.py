"""Closed-loop regression values of stl-funnel.md §11.1, §11.2 and §11.5 (single agent, Δt = 0.01 s,
explicit Euler, normalised gradient, no disturbance, ρ^φ sampled at the control instants)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from stl_harness import authors_design, run_closed_loop
from tlfleet.agent.policy.stl import StepInput, single_agent
from tlfleet.agent.stl.control_law import ControlParams
from tlfleet.agent.stl.monitor import task_robustness
from tlfleet.agent.stl.repair import ProtocolParams
from tlfleet.agent.stl.task import build_task

G_REGION = "dist(p1, [0,-2]) <= 0.1"


def run_single(text, start, duration, **params):
    task = build_task(text, 1)
    agent = single_agent(1, [task], **authors_design(**params))
    result = run_closed_loop([agent], {1: (*start, 0.0)}, duration)
    (outcome,) = result.states[1].outcomes
    return task, result, outcome


def test_11_1_g_task_no_event():
    task, result, outcome = run_single(f"G[21,30] ({G_REGION})", (1, -1), 30)
    assert result.events(1) == []
    assert outcome.events == (0, 0, 0)
    rho_phi = task_robustness(task, result.trajectory)
    assert round(rho_phi, 4) == 0.0562
    assert outcome.rho_phi == pytest.approx(rho_phi, abs=1e-12)
    assert outcome.t_done == 30.0 and outcome.satisfied
    # first command, §11.1: u_raw = (−1.138, −1.138) saturated to (−0.1414214, −0.1414214)
    first = result.trajectory.states[1][1] - result.trajectory.states[1][0]
    assert first[:2] / 0.01 == pytest.approx([-0.1414214, -0.1414214], abs=1e-6)


def test_11_2_f_task_with_hold_rule_is_done_at_44():
    task, result, outcome = run_single("F[44,47] (dist(p1, [-1,0.5]) <= 0.1)", (0, 2), 47)
    assert result.events(1) == []
    assert outcome.t_done == 44.0 and outcome.satisfied and outcome.ended_by == "satisfaction"
    assert round(task_robustness(task, result.trajectory), 7) == 0.0225018
    # the agent stops once ρ > r and stays (done → u_nom = 0)
    z = result.trajectory.states[1]
    assert np.allclose(z[-1], z[(44 * 100)])


def test_11_2_f_task_without_hold_rule():
    task, result, outcome = run_single("F[44,47] (dist(p1, [-1,0.5]) <= 0.1)", (0, 2), 47,
                                       control=ControlParams(hold_F_when_above_r=False))
    assert result.events(1) == []
    assert outcome.t_done == 44.0
    assert round(task_robustness(task, result.trajectory), 7) == 0.0545941


def test_11_2_f_task_without_hold_and_without_completion_rule():
    task, result, outcome = run_single("F[44,47] (dist(p1, [-1,0.5]) <= 0.1)", (0, 2), 47.01,
                                       control=ControlParams(hold_F_when_above_r=False),
                                       protocol=ProtocolParams(complete_on_satisfaction=False))
    assert result.events(1) == []
    assert outcome.t_done == 47.01 and outcome.ended_by == "window_end" and outcome.satisfied
    assert round(task_robustness(task, result.trajectory), 7) == 0.0590655


@pytest.mark.parametrize(("start", "n_events", "final_r", "rho_phi"), [
    ((1, -1), 23, -0.4144, -0.3142),
    ((3, -1), 107, -2.0944, -2.0623),
])
def test_11_5_infeasible_under_saturation(start, n_events, final_r, rho_phi):
    task, result, outcome = run_single(f"G[5,30] ({G_REGION})", start, 30)
    events = result.events(1)
    assert len(events) == n_events
    # two stage-1 repairs (r: 0.0225 → 0.01125 → 0.005625), then stage 3 only (V = {1})
    assert [stage for _, stage in events[:2]] == [1, 1]
    assert {stage for _, stage in events[2:]} == {3}
    assert outcome.events == (2, 0, n_events - 2)
    rs = [rec.r for rec in result.logs[1] if not math.isnan(rec.r)]
    r_values = list(dict.fromkeys(rs))
    assert r_values[:3] == pytest.approx([0.0225, 0.01125, 0.005625])
    assert round(outcome.final_r, 4) == final_r
    measured = task_robustness(task, result.trajectory)
    assert round(measured, 4) == rho_phi
    assert measured >= outcome.final_r  # ρ^φ ≥ r̄ (paper Alg. 2 line 28)


def test_log_record_fields_and_funnel_containment_after_every_repair():
    _, result, _ = run_single(f"G[5,30] ({G_REGION})", (1, -1), 30)
    logs = result.logs[1]
    for rec in logs:
        assert rec.subtask == 0 and rec.follow is None and rec.c in (0, -1)
        if rec.repair:  # after the repair of this step, ρ is strictly inside the new funnel
            assert rec.lower < rec.rho < rec.rho_max
    assert logs[-1].ce == 23
    assert logs[0].t == 0.0 and logs[-1].t == 30.0


def test_step_is_pure_and_idle_after_completion():
    task = build_task("F[1,2] (dist(p1, [0.05,0]) <= 0.1)", 1)
    agent = single_agent(1, [task], **authors_design())
    state = agent.initial_state()
    poses = {1: np.array([0.0, 0.0, 0.0])}
    s1, out1 = agent.step(state, StepInput(0.0, poses))
    s1b, out1b = agent.step(state, StepInput(0.0, poses))
    assert s1 == s1b and out1 == out1b  # same inputs → same outputs, input state untouched
    assert state == agent.initial_state()
    # ρ = 0.05 > r: hold (u = 0) before the window, done inside it, then idle
    assert out1.u == (0.0, 0.0, 0.0)
    s2, _ = agent.step(s1, StepInput(1.0, poses))
    assert s2.k == 1 and s2.c == -1 and s2.outcomes[0].satisfied
    _, out3 = agent.step(s2, StepInput(1.01, {1: np.array([0.0, 0.0, 0.0]),
                                              2: np.array([0.5, 0.0, 0.0])}))
    assert out3.log.subtask == -1 and math.isnan(out3.log.rho)
    assert out3.u[0] < 0 and out3.u[1] == 0.0  # collision avoidance stays active when idle


@settings(max_examples=examples(25), deadline=None)
@given(kind=st.sampled_from(["G", "F"]), a=st.integers(0, 12), length=st.integers(0, 6),
       x=st.floats(-3, 3), y=st.floats(-3, 3), seed=st.integers(0, 2**16),
       disturbance=st.sampled_from([0.0, 0.05, 0.15]))
def test_repair_loop_keeps_invariants_under_disturbance(kind, a, length, x, y, seed,
                                                        disturbance):
    """Random windows, starts and bounded disturbances: no funnel invariant is ever violated
    (FunnelInvariantError would propagate), ρ is re-contained after every repair, and for G the
    achieved ρ^φ is at least the final r̄ (paper Alg. 2 line 28)."""
    text = f"{kind}[{a},{a + length}] (dist(p1, [0.5,-0.5]) <= 0.2)"
    task = build_task(text, 1)
    result = run_closed_loop([single_agent(1, [task], **authors_design())], {1: (x, y, 0.0)},
                             a + length + 0.5,
                             disturbance=disturbance, rng=np.random.default_rng(seed))
    for rec in result.logs[1]:
        if rec.repair:
            assert rec.lower < rec.rho < rec.rho_max
    (outcome,) = result.states[1].outcomes
    if kind == "G":
        assert task_robustness(task, result.trajectory, smooth=True) >= outcome.final_r


def test_code_faithful_random_mode_is_reproducible_and_keeps_the_bound():
    def run(seed):
        return run_single(f"G[5,30] ({G_REGION})", (1, -1), 30, random_seed=seed)

    task, first, outcome = run(11)
    _, again, outcome_again = run(11)
    _, other, _ = run(12)
    assert outcome == outcome_again
    assert first.events(1) == again.events(1)
    assert first.events(1) != other.events(1)
    assert 0 < first.logs[1][0].r < 0.5 * first.logs[1][0].rho_max  # r = ρ_max·U(0,1)/2
    assert task_robustness(task, first.trajectory) >= outcome.final_r


def test_tuple_poses_taken_as_they_are_step_as_the_copied_ones(repo_root):
    """``StepInput(tuples=True)`` (the runtime's decoded rows) skips the step's copy of
    the poses: along a kinematic replay of Scenario 1's three coupled STL agents (repairs and
    stage 2 included) every state and output equals the copying step's."""
    from tlfleet.agent.policy.stl import build_agents
    from tlfleet.agent.scenario import load_scenario

    scenario = load_scenario(repo_root / "scenarios" / "scenario1.toml")
    agents = build_agents(scenario)
    poses = {r.id: tuple(map(float, r.pose)) for r in scenario.robots}
    copied = {i: a.initial_state() for i, a in agents.items()}
    taken = dict(copied)
    inbox_copied: dict[int, list] = {i: [] for i in agents}
    inbox_taken: dict[int, list] = {i: [] for i in agents}
    dt, repaired = 0.01, 0
    for k in range(1500):
        t = k * dt
        sent_copied, sent_taken = [], []
        for i, agent in agents.items():
            copied[i], out_c = agent.step(copied[i], StepInput(t, dict(poses), inbox_copied[i]))
            taken[i], out_t = agent.step(taken[i], StepInput(t, dict(poses), inbox_taken[i],
                                                             tuples=True))
            assert taken[i] == copied[i] and out_t == out_c, (i, t)
            repaired += bool(out_c.log.repair)
            sent_copied += out_c.messages
            sent_taken += out_t.messages
            x, y, th = poses[i]
            vx, vy, w = out_c.u
            poses[i] = (x + dt * vx, y + dt * vy, th + dt * w)
        for i in agents:
            inbox_copied[i] = [m for m in sent_copied if m.receiver == i]
            inbox_taken[i] = [m for m in sent_taken if m.receiver == i]
    assert repaired > 0  # the replay went through the repair paths, not only nominal steps
