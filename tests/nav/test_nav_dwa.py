"""DWA local planner: unit behaviour, and closed loop on the harness (goals, limits, avoidance)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from nav_harness import ExecutorController, HarnessResult, SimRobot, simulate
from tlfleet.agent.model.scenario import Arena, Region, Robot, Scenario
from tlfleet.agent.nav.dwa import (
    DwaConfig,
    MovingDiscs,
    braking_command,
    dwa_control,
    inflation_cost,
    rollouts,
    velocity_window,
)
from tlfleet.agent.nav.executor import Executor
from tlfleet.agent.nav.grid import grid_from_arena
from tlfleet.agent.nav.grid_planner import plan_path

ARENA = Arena()
GRID = grid_from_arena(ARENA, inflation=0.25)
CONFIG = DwaConfig()


class DwaGoTo:
    """Harness controller: one global path to ``goal``, then DWA every control period, with the
    other robots as discs whose velocity is estimated from the last two pose frames."""

    def __init__(self, goal: tuple[float, float], config: DwaConfig = CONFIG):
        self.goal = goal
        self.config = config
        self.command = (0.0, 0.0)
        self.path: np.ndarray | None = None
        self.previous: np.ndarray | None = None
        self.reached = False

    def __call__(self, t: float, index: int, poses: np.ndarray) -> tuple[float, float]:
        if self.path is None:
            self.path = plan_path(GRID, poses[index, :2], self.goal).waypoints
        others = np.delete(poses, index, axis=0)[:, :2]
        velocity = np.zeros_like(others)
        if self.previous is not None:
            velocity = (others - self.previous) / self.config.controller_period
        self.previous = others.copy()
        discs = MovingDiscs(others, velocity, np.full(len(others), 0.2))
        result = dwa_control(poses[index], self.command, self.path, GRID, 0.2, discs, self.config)
        self.reached |= result.goal_reached
        self.command = (result.v, result.omega)
        return self.command


def assert_commands_within_limits(commands: np.ndarray, config: DwaConfig = CONFIG) -> None:
    """Every command (C, 2) within the velocity bounds and one period's acceleration of the
    previous command (the first relative to standstill)."""
    dt = config.controller_period
    assert np.all(commands[:, 0] <= config.max_vel_x + 1e-12)
    assert np.all(commands[:, 0] >= config.min_vel_x - 1e-12)
    assert np.all(np.abs(commands[:, 1]) <= config.max_rot_vel + 1e-12)
    steps = np.abs(np.diff(np.vstack([[0.0, 0.0], commands]), axis=0))
    assert np.all(steps[:, 0] <= config.acc_lim_x * dt + 1e-9)
    assert np.all(steps[:, 1] <= config.acc_lim_theta * dt + 1e-9)


def distance_to(result: HarnessResult, robot: int, point) -> np.ndarray:
    return np.linalg.norm(result.poses[:, robot, :2] - np.asarray(point), axis=1)


# ------------------------------------------------------------------ unit behaviour


def test_velocity_window_is_one_period_of_acceleration_clipped_to_the_limits():
    assert velocity_window(0.0, 0.0, CONFIG) == pytest.approx((0.0, 0.2, -0.4, 0.4))
    assert velocity_window(0.25, 0.9, CONFIG) == pytest.approx((0.05, 0.3, 0.5, 1.0))
    assert braking_command(0.25, -0.9, CONFIG) == pytest.approx((0.05, -0.5))


def test_rollouts_are_exact_arcs_and_lines():
    times = np.array([1.0, math.pi])
    points, theta = rollouts((0.0, 0.0, 0.0), np.array([0.3, 0.3]), np.array([0.0, 1.0]), times)
    assert points[0, 0] == pytest.approx([0.3, 0.0])  # straight
    assert points[1, 1] == pytest.approx([0.0, 0.6], abs=1e-12)  # half circle of radius 0.3
    assert theta[1, 1] == pytest.approx(math.pi)


def test_goal_within_tolerance_brakes_and_reports_reached():
    path = np.array([[0.0, 0.0], [1.0, 0.0]])
    result = dwa_control((0.9, 0.0, 0.0), (0.3, 0.2), path, GRID, 0.2, None, CONFIG)
    assert result.goal_reached
    assert (result.v, result.omega) == pytest.approx((0.1, 0.0))


def test_robot_in_a_closing_ring_of_robots_has_no_admissible_rollout_and_brakes():
    angles = np.linspace(0, 2 * math.pi, 12, endpoint=False)
    ring = 0.5 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    others = MovingDiscs(ring, -0.6 * ring, np.full(12, 0.2))  # all closing in at 0.3 m/s
    path = np.array([[0.0, 0.0], [2.0, 0.0]])
    result = dwa_control((0.0, 0.0, 0.0), (0.2, 0.0), path, GRID, 0.2, others, CONFIG)
    assert result.n_valid == 0
    assert (result.v, result.omega) == pytest.approx((0.0, 0.0))


def test_robot_in_a_static_ring_of_robots_only_turns_in_place():
    angles = np.linspace(0, 2 * math.pi, 12, endpoint=False)
    ring = 0.45 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    path = np.array([[0.0, 0.0], [2.0, 0.0]])
    result = dwa_control(
        (0.0, 0.0, 0.3), (0.2, 0.0), path, GRID, 0.2, MovingDiscs.static(ring, 0.2), CONFIG
    )
    assert result.n_valid > 0
    assert result.v == 0.0
    assert result.omega < 0.0  # towards the path heading (θ = 0)


def test_robot_facing_a_wall_does_not_drive_into_it():
    # 0.45 m from the east wall, facing it, goal behind the wall's direction is impossible:
    # the path goal lies along the wall, the DWA must not pick a rollout that hits it.
    path = np.array([[3.05, 0.0], [3.05, 2.0]])
    result = dwa_control((3.05, 0.0, 0.0), (0.3, 0.0), path, GRID, 0.2, None, CONFIG)
    points, _ = rollouts(
        (3.05, 0.0, 0.0),
        np.array([result.v]),
        np.array([result.omega]),
        np.linspace(0.1, CONFIG.sim_time, 13),
    )
    assert np.all(GRID.clearance_at(points[0]) >= 0.2)


@pytest.mark.parametrize("field", ["max_vel_x", "sim_time", "controller_period"])
def test_config_rejects_non_positive_values(field):
    with pytest.raises(ValueError, match=field):
        DwaConfig(**{field: 0.0})


# ------------------------------------------------------------------ closed loop


@pytest.mark.parametrize("heading_index", range(8))
def test_reaches_the_goal_from_every_heading_without_touching_walls(heading_index):
    # Start 0.6 m from the west wall (0.4 m between its surface and the wall).
    heading = heading_index * math.pi / 4
    goal = (1.5, 0.5)
    controller = DwaGoTo(goal)
    result = simulate([SimRobot((-2.9, 0.0, heading))], [controller], 30.0, ARENA)
    assert result.contacts == ()
    assert result.min_wall_gap > 0.0
    assert controller.reached
    assert distance_to(result, 0, goal)[-1] <= CONFIG.xy_goal_tolerance
    assert_commands_within_limits(result.commands[:, 0, :])


def _crossing_disc(t: float, index: int, poses: np.ndarray) -> tuple[float, float]:
    """A robot that ignores everybody: north at 0.25 m/s for 14 s, then stops."""
    return (0.25, 0.0) if t < 14.0 else (0.0, 0.0)


def test_a_disc_crossing_the_path_is_avoided():
    robots = [SimRobot((-2.0, 0.0, 0.0)), SimRobot((0.0, -2.0, math.pi / 2))]
    # Sanity: driving straight on would hit it.
    blind = simulate(robots, [lambda t, i, p: (0.3, 0.0), _crossing_disc], 14.0, ARENA)
    assert [c.kind for c in blind.contacts] == ["robot"]
    controller = DwaGoTo((2.0, 0.0))
    result = simulate(robots, [controller, _crossing_disc], 30.0, ARENA)
    assert result.contacts == ()
    assert result.min_robot_gap > 0.0
    assert controller.reached
    assert_commands_within_limits(result.commands[:, 0, :])


def test_two_robots_crossing_head_on_both_arrive_without_contact():
    """The DWA inside the navigation stack (global path re-planned around the other robot, as
    move_base does): both robots swap ends of a 4 m corridor line."""
    regions = (Region("east", (2.0, 0.0)), Region("west", (-2.0, 0.0)))
    robots = (Robot(1, "unicycle", (-2.0, 0.0, 0.0)), Robot(2, "unicycle", (2.0, 0.0, math.pi)))
    scenario = Scenario("head-on", "f", 40.0, ARENA, regions, robots)
    controllers = []
    for robot_id, goal in ((1, "east"), (2, "west")):
        executor = Executor.from_scenario(scenario, robot_id)
        controllers.append(
            ExecutorController(executor, executor.initial_state((goal,), ()), [1, 2])
        )
    result = simulate([SimRobot(r.pose) for r in robots], controllers, 40.0, ARENA)
    assert result.contacts == ()
    assert result.min_robot_gap > 0.1
    assert distance_to(result, 0, (2.0, 0.0))[-1] <= CONFIG.xy_goal_tolerance
    assert distance_to(result, 1, (-2.0, 0.0))[-1] <= CONFIG.xy_goal_tolerance
    for k in range(2):
        assert_commands_within_limits(result.commands[:, k, :])
        assert all(e.kind != "stuck" for e in controllers[k].events)


def test_inflation_cost_never_increases_with_clearance():
    """dwa_control scores a rollout's worst occupancy cost as the cost of its least clearance,
    which is the same value only because the cost does not increase with the clearance."""
    config = DwaConfig()
    d = np.sort(np.concatenate([np.linspace(-0.5, 1.5, 2001), [0.2, 0.5, config.inflation_radius]]))
    cost = inflation_cost(d, 0.2, config)
    assert np.all(np.diff(cost) <= 0.0)
    rows = np.random.default_rng(3).uniform(-0.2, 1.0, (50, 13))
    assert np.array_equal(inflation_cost(rows, 0.2, config).max(axis=1),
                          inflation_cost(rows.min(axis=1), 0.2, config))
