"""Scenario 1's joint optimum of φ′3, φ′4, φ′5 (tlfleet.coordinator.report.joint_optimum,
docs/coupling.md §3).

The closed form is checked against the project's robustness of the scenario's own parsed
predicates (``tlfleet.agent.stl.robustness.psi_array``,
``tlfleet.agent.stl.monitor.task_robustness``) on sampled configurations and trajectories: never
exceeded, attained, and equal to a brute-force search over robot 4's position.
"""

from __future__ import annotations

import numpy as np
import pytest
from tlfleet.agent.scenario.loader import load_scenario
from tlfleet.agent.stl.monitor import Trajectory, task_robustness
from tlfleet.agent.stl.parser import robot_subtasks
from tlfleet.agent.stl.robustness import psi_array
from tlfleet.coordinator.report import paper_values
from tlfleet.coordinator.report.joint_optimum import find_pinches

RNG_SEED = 15
SAMPLES = 4000


@pytest.fixture(scope="module")
def s1(scenarios_dir):
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    (pinch,) = find_pinches(scenario)
    tasks = {j: robot_subtasks(scenario.robot(j))[0] for j in (3, 4, 5)}
    return scenario, pinch, tasks


def _states(z3, z4, z5):
    """One (N, 3) pose array per robot from (N, 2) positions (headings 0)."""
    pad = lambda z: np.column_stack([z, np.zeros(len(z))])  # noqa: E731
    return {3: pad(z3), 4: pad(z4), 5: pad(z5)}


def _rho(tasks, states):
    return {j: psi_array(tasks[j].body, states) for j in (3, 4, 5)}


def _in_disc(rng, centre, radius, n):
    angle, frac = rng.uniform(0, 2 * np.pi, n), np.sqrt(rng.uniform(0, 1, n))
    return np.asarray(centre) + (radius * frac)[:, None] * np.column_stack([np.cos(angle),
                                                                             np.sin(angle)])


def test_scenario1_has_one_pinch_from_its_own_geometry(s1, scenarios_dir):
    _, pinch, _ = s1
    (r3, r5) = pinch.regions
    assert (pinch.leader, pinch.leader_index) == (4, 0) and pinch.reach == (1.0, 1.0)
    assert (r3.robot, r3.centre, r3.radius) == (3, (0.0, -2.0), 0.1)
    assert (r5.robot, r5.centre, r5.radius) == (5, (0.0, 2.0), 0.1)
    assert pinch.window == (5.0, 30.0) and pinch.common == (21.0, 30.0)
    assert pinch.plane == pytest.approx(-0.9, abs=1e-12)  # (1 + 1 − 4 + 0.1 + 0.1)/2
    for n in (2, 3):  # the other scenarios have none
        assert find_pinches(load_scenario(scenarios_dir / f"scenario{n}.toml")) == []


def test_no_configuration_beats_the_leader_bound(s1):
    """Robots 3 and 5 anywhere in (or near) their discs, robot 4 anywhere in the arena or on the
    segment between them: ρ(ψ′4) ≤ bound(ρ(ψ′3), ρ(ψ′5)) at every sampled instant."""
    _, pinch, tasks = s1
    rng = np.random.default_rng(RNG_SEED)
    z3 = _in_disc(rng, (0.0, -2.0), 0.4, SAMPLES)
    z5 = _in_disc(rng, (0.0, 2.0), 0.4, SAMPLES)
    mid = (z3 + z5) / 2 + rng.normal(0, 0.05, (SAMPLES, 2))
    for z4 in (rng.uniform(-3.5, 3.5, (SAMPLES, 2)), mid):
        rho = _rho(tasks, _states(z3, z4, z5))
        bound = np.array([pinch.leader_bound(a, b) for a, b in zip(rho[3], rho[5], strict=True)])
        assert np.all(rho[4] <= bound + 1e-12)
        assert np.all(rho[4] <= pinch.plane - (np.minimum(rho[3], 0.1)
                                               + np.minimum(rho[5], 0.1)) / 2 + 1e-12)


def test_the_leader_bound_is_attained(s1):
    """For every (ρ3, ρ5) ≤ 0.1: 3 and 5 on the centre line, pushed towards each other by
    r − ρ, robot 4 midway reaches the bound exactly: the bound is the joint optimum."""
    _, pinch, tasks = s1
    rng = np.random.default_rng(RNG_SEED + 1)
    want3, want5 = rng.uniform(-0.3, 0.1, 200), rng.uniform(-0.3, 0.1, 200)
    z3 = np.column_stack([np.zeros(200), -2.0 + (0.1 - want3)])
    z5 = np.column_stack([np.zeros(200), 2.0 - (0.1 - want5)])
    rho = _rho(tasks, _states(z3, (z3 + z5) / 2, z5))
    np.testing.assert_allclose(rho[3], want3, atol=1e-12)
    np.testing.assert_allclose(rho[5], want5, atol=1e-12)
    bound = [pinch.leader_bound(a, b) for a, b in zip(want3, want5, strict=True)]
    np.testing.assert_allclose(rho[4], bound, atol=1e-12)
    # and the region bounds invert the plane: given ρ4 and ρ5, ρ3 can reach exactly want3
    np.testing.assert_allclose([pinch.region_bound(0, r4, r5) for r4, r5
                                in zip(rho[4], want5, strict=True)], want3, atol=1e-12)


def test_trajectory_bound_matches_a_brute_force_search_over_robot4(s1):
    """Random trajectories of robots 3 and 5: the trajectory bound equals, at each instant, the
    best ψ′4 over a 2 mm grid of robot 4's positions (to the grid's resolution), and ρ(φ′4) of
    any robot 4 stays below it; with the trajectories' own ρ(φ′3), ρ(φ′5) below the plane."""
    _, pinch, tasks = s1
    rng = np.random.default_rng(RNG_SEED + 2)
    n = 26
    t = np.linspace(5.0, 30.0, n)
    z3 = np.array([0.0, -2.0]) + np.cumsum(rng.normal(0, 0.02, (n, 2)), axis=0)
    z5 = np.array([0.0, 2.0]) + np.cumsum(rng.normal(0, 0.02, (n, 2)), axis=0)
    z4 = rng.uniform(-1, 1, (n, 2))
    traj = Trajectory(t, _states(z3, z4, z5))
    xs, ys = np.meshgrid(np.arange(-0.6, 0.6, 0.002), np.arange(-0.6, 0.6, 0.002))
    grid = np.column_stack([xs.ravel(), ys.ravel()])
    best = []
    for i in range(n):
        m = len(grid)
        states = _states(np.repeat(z3[i:i + 1], m, 0), grid, np.repeat(z5[i:i + 1], m, 0))
        best.append(psi_array(tasks[4].body, states).max())
    assert pinch.trajectory_bound(traj) == pytest.approx(min(best), abs=2e-3)
    assert pinch.trajectory_bound(traj) >= min(best) - 1e-12
    rho = {j: task_robustness(tasks[j], traj) for j in (3, 4, 5)}
    assert rho[4] <= pinch.trajectory_bound(traj) <= pinch.leader_bound(rho[3], rho[5]) + 1e-12


def test_the_three_goals_meet_only_at_one_point(s1):
    """Goal = best of scenarios.md − 0.05 for each of φ′3, φ′4, φ′5: the plane leaves zero slack,
    so the goals hold together only with ρ′3 = ρ′5 = 0.05 and ρ′4 = −0.95 exactly."""
    scenario, pinch, _ = s1
    best = {j: paper_values.lookup(scenario.name, j, scenario.robot(j).stl[0]).best
            for j in (3, 4, 5)}
    goal = {j: best[j] - 0.05 for j in (3, 4, 5)}
    assert pinch.leader_bound(goal[3], goal[5]) == pytest.approx(goal[4], abs=1e-12)
    assert pinch.plane - goal[4] - (goal[3] + goal[5]) / 2 == pytest.approx(0.0, abs=1e-12)
    # any slack taken by one task is lost by another
    assert pinch.leader_bound(goal[3] + 0.001, goal[5]) < goal[4]
    assert pinch.region_bound(1, goal[4] + 0.001, goal[3]) < goal[5]
