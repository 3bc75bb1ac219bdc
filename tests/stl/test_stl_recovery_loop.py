"""Closed loop (pure harness, stl-funnel.md §11 style) of robustness recovery and the 6th-robot
case of issue 15: an escort tracking an exogenous leader."""

from __future__ import annotations

import math

import numpy as np
import pytest
from stl_harness import ScriptedRobot, authors_design, run_closed_loop
from tlfleet.agent.policy.stl import single_agent
from tlfleet.agent.stl.recovery import RecoveryParams
from tlfleet.agent.stl.task import build_task


def _leader_runaway(t: float, stop: float = 8.0, speed: float = 0.35):
    """Drives away at 0.35 m/s (faster than the escort's 0.2 m/s) until ``stop``, then parks."""
    return (0.8 + speed * min(t, stop), 0.0, 0.0)


def _leader_shuttle(t: float):
    """Scenario 1/2's robot 1 pattern: along x = −2 between y = −2.5 and 2.5 at 0.3 m/s."""
    period = 2 * 5.0 / 0.3
    phase = (t % period) / period
    y = -2.5 + 10 * phase if phase < 0.5 else 2.5 - 10 * (phase - 0.5)
    return (-2.0, y, math.pi / 2)


def _run(formula: str, start, leader, duration: float, recovery: bool):
    task = build_task(formula, 2, 0, robot_ids=(1, 2), stl_ids=(2,))
    agent = single_agent(2, [task], **authors_design(recovery=RecoveryParams(enabled=recovery)))
    result = run_closed_loop([agent], {2: start}, duration,
                             exogenous=[ScriptedRobot(1, pose_at=leader)])
    traj = result.trajectory
    d = np.hypot(*(traj.states[2][:, :2] - traj.states[1][:, :2]).T)
    return traj.t, d, result


def test_after_a_forced_slowdown_recovery_brings_rho_back_within_10_s():
    """The leader outruns the escort (repairs lower r below −0.9), then stops at t = 8 s: with
    recovery ρ^ψ = 1 − d is back to ≥ 0 within 10 s and stays there; without it the escort
    stops in the middle of its relaxed funnel, short of the predicate."""
    formula = "G[0,40] (dist(p2, p1) <= 1.0)"
    t, d, res = _run(formula, (0.0, 0.0, 0.0), _leader_runaway, 40.0, recovery=True)
    rho = 1.0 - d
    assert min(r.r for r in res.logs[2] if t[0] <= r.t <= 8.0) < -0.9  # repairs lowered r
    back = t[(t >= 8.0) & (rho >= 0.0)]
    assert back.size and back[0] <= 18.0
    assert np.all(rho[t >= back[0] + 2.0] >= 0.0)
    recoveries = [r.t for r in res.logs[2] if r.recovered]
    assert recoveries and all(8.0 < x < 18.0 for x in recoveries[:1])
    (outcome,) = res.states[2].outcomes
    assert outcome.recoveries == len(recoveries)
    # r̄ is the least r in force: ρ^φ ≥ r̄ still holds
    assert outcome.rho_phi >= outcome.final_r
    assert float(rho[(t >= 0.0) & (t <= 40.0)].min()) >= outcome.final_r - 1e-9

    t0, d0, res0 = _run(formula, (0.0, 0.0, 0.0), _leader_runaway, 40.0, recovery=False)
    assert not any(r.recovered for r in res0.logs[2])
    assert float((1.0 - d0)[t0 >= 18.0].max()) < 0.0  # never back without recovery


def test_sixth_robot_far_from_its_leader_follows_it():
    """G[0,60] (dist(p6, p1) <= 0.6) from 4.6 m. Cause: the task starts late (a = 0)
    violated, so the funnel is constant (stl-funnel.md §5 late start) and as wide as the initial
    error; once ρ^ψ reaches its middle, ε ≈ 0 and the robot stops, never touching a boundary —
    no critical event, no repair, no motion. Recovery re-contracts the funnel once ρ has room."""
    formula = "G[0,60] (dist(p2, p1) <= 0.6)"
    start = (1.0, 1.0, 0.0)
    t, d, res = _run(formula, start, _leader_shuttle, 60.0, recovery=False)
    assert not any(r.repair for r in res.logs[2])  # the reported symptom, reproduced
    assert float(np.median(d[t >= 20.0])) > 2.0
    t, d, res = _run(formula, start, _leader_shuttle, 60.0, recovery=True)
    assert any(r.recovered for r in res.logs[2]) and any(r.repair for r in res.logs[2])
    # it follows: the leader drives at 0.3 m/s, the escort is capped at 0.2 m/s
    assert float(np.median(d[t >= 20.0])) < 1.0
    (outcome,) = res.states[2].outcomes
    assert outcome.rho_phi >= outcome.final_r


@pytest.mark.parametrize("recovery", [True, False])
def test_scenario1_style_g_task_with_room_is_unchanged_when_satisfied(recovery):
    """A G task met without repairs never recovers (r is still its original value)."""
    task = build_task("G[5,15] (dist(p2, [0.5, 0]) <= 0.1)", 2, 0, robot_ids=(2,), stl_ids=(2,))
    agent = single_agent(2, [task], recovery=RecoveryParams(enabled=recovery))
    res = run_closed_loop([agent], {2: (0.0, 0.0, 0.0)}, 15.0)
    assert not any(r.recovered for r in res.logs[2])
    assert not any(r.repair for r in res.logs[2])


@pytest.mark.parametrize("formula", ["G[0,30] (dist(p2, [0, 0]) <= 0.5)",
                                     "F[0,30] (dist(p2, [0, 0]) <= 0.5)"])
def test_a_satisfied_stl_robot_still_yields_to_a_robot_entering_its_collision_radius(formula):
    """No deadlock: the STL robot sits satisfied (G: mid-funnel, ε ≈ 0; F: done and
    idle); an LTL robot drives at it and stops 0.45 m away. Eq. (6)'s collision term is always
    mixed in, so the STL robot moves out of the way."""
    task = build_task(formula, 2, 0, robot_ids=(1, 2), stl_ids=(2,))
    agent = single_agent(2, [task])

    def intruder(t: float):  # stops 0.45 m from the STL robot's place, inside R1 = 0.6 m
        return (-2.0 + 0.3 * min(t, 1.55 / 0.3), 0.0, 0.0)

    result = run_closed_loop([agent], {2: (0.0, 0.0, 0.0)}, 12.0,
                             exogenous=[ScriptedRobot(1, pose_at=intruder)])
    traj = result.trajectory
    gap = np.hypot(*(traj.states[2][:, :2] - traj.states[1][:, :2]).T)
    moved = np.hypot(*(traj.states[2][-1, :2] - traj.states[2][0, :2]))
    assert moved > 0.1  # it yielded
    assert gap.min() > 0.4  # never in contact (radii 0.2 + 0.2)
    assert gap[-1] >= 0.6  # out of the intruder's full-repulsion radius R1
