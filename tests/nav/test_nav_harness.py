"""Unicycle harness: kinematics, velocity tracking limits, disturbance, contact reports."""

from __future__ import annotations

import math

import numpy as np
import pytest
from nav_harness import HarnessConfig, SimRobot, simulate
from tlfleet.agent.model.scenario import Arena, RectObstacle, UnicycleLimits


def constant(v: float, omega: float):
    return lambda t, i, poses: (v, omega)


def test_straight_drive_covers_v_times_t_minus_the_acceleration_lag():
    # v̇ = min(a, (v_cmd − v)/τ): with τ = 0.05 s and a = 1 m/s² the 0.3 m/s command is reached
    # after 0.3 s (the rate limit binds until |v_cmd − v| < a·τ = 0.05 m/s, then decays).
    result = simulate([SimRobot((0.0, 0.0, 0.0))], [constant(0.3, 0.0)], 10.0, Arena())
    x_final = result.poses[-1, 0, 0]
    assert 0.3 * 10.0 - 0.3 * 0.3 / 2 - 0.02 <= x_final <= 0.3 * 10.0 - 0.3 * 0.3 / 2 + 0.005
    assert result.poses[-1, 0, 1] == pytest.approx(0.0, abs=1e-12)
    assert result.times[-1] == pytest.approx(10.0)
    assert result.commands.shape == (50, 1, 2)


def test_turning_in_place_integrates_heading():
    result = simulate([SimRobot((0.0, 0.0, 0.0))], [constant(0.0, 1.0)], 2.0, Arena())
    # ω ramps at 2 rad/s² to 1 rad/s (0.5 s, 0.25 rad lost, minus the τ tail): θ ≈ 2 − 0.25.
    assert result.poses[-1, 0, 2] == pytest.approx(1.75, abs=0.06)
    assert np.allclose(result.poses[-1, 0, :2], 0.0)


def test_actual_velocities_never_change_faster_than_the_acceleration_limits():
    limits = UnicycleLimits(max_v=0.3, max_omega=1.0, acc_v=1.0, acc_omega=2.0)

    def bang_bang(t, i, poses):
        return (0.3, 1.0) if int(t / 0.4) % 2 == 0 else (0.0, -1.0)

    config = HarnessConfig()
    result = simulate([SimRobot((0.0, 0.0, 0.0), limits=limits)], [bang_bang], 4.0, Arena())
    dv = np.abs(np.diff(result.velocities[:, 0, :], axis=0)) / config.control_period
    assert np.all(dv[:, 0] <= limits.acc_v + 1e-9)
    assert np.all(dv[:, 1] <= limits.acc_omega + 1e-9)


def test_wall_contact_is_reported_once_when_it_begins():
    result = simulate([SimRobot((2.5, 0.0, 0.0))], [constant(0.3, 0.0)], 6.0, Arena())
    assert len(result.contacts) == 1
    contact = result.contacts[0]
    assert contact.kind == "wall" and contact.a == 0 and contact.b == -1
    # The robot front touches x = 3.5 when its centre passes 3.3: 0.8 m at ~0.3 m/s.
    assert 0.8 / 0.3 < contact.t < 0.8 / 0.3 + 0.3
    assert result.min_wall_gap < 0


def test_static_obstacles_count_as_walls():
    arena = Arena(obstacles=(RectObstacle(1.0, -1.0, 1.5, 1.0),))
    result = simulate([SimRobot((0.0, 0.0, 0.0))], [constant(0.3, 0.0)], 4.0, arena)
    assert [c.kind for c in result.contacts] == ["wall"]


def test_robot_contact_between_two_robots_driving_at_each_other():
    robots = [SimRobot((-1.0, 0.0, 0.0)), SimRobot((1.0, 0.0, math.pi))]
    result = simulate(robots, [constant(0.3, 0.0), constant(0.3, 0.0)], 5.0, Arena())
    kinds = [(c.kind, c.a, c.b) for c in result.contacts]
    assert kinds == [("robot", 0, 1)]
    # They meet when each has covered (2 − 0.4) / 2 = 0.8 m.
    assert 0.8 / 0.3 < result.contacts[0].t < 0.8 / 0.3 + 0.3


def test_no_contact_when_robots_stay_apart():
    robots = [SimRobot((-1.0, 0.0, 0.0)), SimRobot((1.0, 0.0, 0.0))]
    result = simulate(robots, [constant(0.2, 0.0), constant(0.2, 0.0)], 5.0, Arena())
    assert result.contacts == ()
    assert result.min_robot_gap == pytest.approx(1.6)


def test_disturbance_is_bounded_and_reproducible_with_a_seeded_generator():
    config = HarnessConfig(disturbance=0.05)
    runs = [
        simulate(
            [SimRobot((0.0, 0.0, 0.0))],
            [constant(0.0, 0.0)],
            2.0,
            Arena(),
            config,
            rng=np.random.default_rng(7),
        )
        for _ in range(2)
    ]
    assert np.array_equal(runs[0].poses, runs[1].poses)
    drift = np.linalg.norm(np.diff(runs[0].poses[:, 0, :2], axis=0), axis=1)
    assert np.all(drift <= 0.05 * config.control_period + 1e-12)
    assert np.any(drift > 0)


def test_disturbance_without_a_generator_is_rejected():
    with pytest.raises(ValueError, match="Generator"):
        simulate(
            [SimRobot((0.0, 0.0, 0.0))],
            [constant(0.0, 0.0)],
            1.0,
            Arena(),
            HarnessConfig(disturbance=0.1),
        )


def test_stop_condition_ends_the_run_early():
    result = simulate(
        [SimRobot((0.0, 0.0, 0.0))],
        [constant(0.3, 0.0)],
        10.0,
        Arena(),
        stop=lambda t, poses: poses[0, 0] > 1.0,
    )
    assert result.duration < 5.0
    assert result.poses[-1, 0, 0] > 1.0
