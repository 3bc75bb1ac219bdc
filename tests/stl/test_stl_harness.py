"""The pure closed-loop harness: integration, exogenous robots, disturbance, latency."""

from __future__ import annotations

import math

import numpy as np
import pytest
from stl_harness import ScriptedRobot, run_closed_loop
from tlfleet.agent.policy.stl import build_agents, single_agent
from tlfleet.agent.stl.monitor import task_robustness
from tlfleet.agent.stl.sequencer import build_sequence


def tracking_agent():
    """Scenario 2 style: robot 3 tracks exogenous (LTL) robot 1; G[0,20] uses the late start."""
    (task,) = build_sequence(3, ["G[0,20] (dist(p3, p1) <= 0.6)"], stl_ids=[3])
    return task, single_agent(3, [task])


def test_tracks_a_scripted_exogenous_robot_and_avoids_it():
    task, agent = tracking_agent()
    assert task.participants == (1, 3) and task.v_ctrl == (3,)
    leader = ScriptedRobot(1, pose_at=lambda t: (-2.0 + 0.1 * t, -2.5, 0.0))
    result = run_closed_loop([agent], {3: (-1.5, -1.0, 0.0)}, 20.0, exogenous=[leader])
    traj = result.trajectory
    assert traj.robot_ids == (1, 3)
    assert traj.states[1][-1] == pytest.approx([0.0, -2.5, 0.0])
    gap = np.hypot(*(traj.states[3][:, :2] - traj.states[1][:, :2]).T)
    assert gap.min() > 0.4  # collision avoidance against the LTL robot
    # late start (a = 0, ρ_0 < r): constant funnel, the robot settles inside it, closer than at t=0
    assert gap[-1] < gap[0] - 0.5
    outcome = result.states[3].outcomes[0]
    assert task_robustness(task, traj) >= outcome.final_r


def test_disturbance_is_bounded_seeded_and_reproducible():
    task, _ = tracking_agent()
    standing = [ScriptedRobot(1, (0.0, 0.0, 0.0))]

    def run(seed):
        agent = single_agent(3, [task])
        return run_closed_loop([agent], {3: (1.0, 1.0, 0.0)}, 2.0, exogenous=standing,
                               disturbance=0.05, rng=np.random.default_rng(seed)).trajectory

    a, b, c = run(1), run(1), run(2)
    assert np.array_equal(a.states[3], b.states[3])
    assert not np.array_equal(a.states[3], c.states[3])
    steps = np.diff(a.states[3][:, :2], axis=0) / 0.01
    assert np.hypot(*steps.T).max() <= 0.2 + 0.05 + 1e-9  # ‖u‖ ≤ u_max plus ‖w‖ ≤ 0.05
    with pytest.raises(ValueError, match=r"needs a numpy\.random\.Generator"):
        run_closed_loop([single_agent(3, [task])], {3: (1.0, 1.0, 0.0)}, 1.0,
                        exogenous=standing, disturbance=0.1)


def test_zero_order_hold_euler_and_sample_times():
    _, agent = tracking_agent()
    result = run_closed_loop([agent], {3: (1.0, 1.0, 0.0)}, 0.05,
                             exogenous=[ScriptedRobot(1, (0.0, 0.0, 0.0))])
    traj = result.trajectory
    assert list(traj.t) == [0.0, 0.01, 0.02, 0.03, 0.04, 0.05]
    logs = result.logs[3]
    assert [rec.t for rec in logs] == list(traj.t)


def test_scenario3_formation_agents_build_and_run(scenarios_dir):
    from tlfleet.agent.scenario.loader import load_scenario

    scenario = load_scenario(scenarios_dir / "scenario3.toml")
    agents = build_agents(scenario)
    assert sorted(agents) == [2, 3, 4]
    for agent in agents.values():
        assert agent.cfg.subtasks[0].v_ctrl == (agent.robot_id,)
        assert agent.cfg.subtasks[0].rho_opt == pytest.approx(
            -math.log(math.exp(-1.0) + math.exp(-0.9)) / 10)
    leader = ScriptedRobot(1, pose_at=lambda t: (-2.0 + 0.05 * t, -2.0, 0.0))
    poses = {j: scenario.robot(j).pose for j in (2, 3, 4)}
    result = run_closed_loop(list(agents.values()), poses, 12.0, exogenous=[leader])
    for j in (2, 3, 4):
        assert result.logs[j][-1].rho > result.logs[j][0].rho
