"""Plan executor on the harness: Scenario 1 GF cycling, Scenario 3 visiting order, stuck handling.

Plans come from the LTL planner (``tlfleet.agent.ltl.planner.plan_robot``, with the grid planner's
path lengths as edge weights) and, independently of it, from hand-written sequences.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from nav_harness import ExecutorController, HarnessConfig, HarnessResult, SimRobot, simulate
from nav_scenarios import scenario1, scenario3
from tlfleet.agent.model.scenario import Arena, RectObstacle, Region, Robot, Scenario
from tlfleet.agent.nav.dwa import DwaConfig
from tlfleet.agent.nav.errors import InvalidPlanError
from tlfleet.agent.nav.events import PlanAccepted, PlanFinished, RegionVisited, ReplanRequest, Stuck
from tlfleet.agent.nav.executor import Executor, ExecutorConfig, ExecutorInputs
from tlfleet.agent.nav.grid_planner import path_length_function

TOLERANCE = DwaConfig().xy_goal_tolerance




def planner_plan(scenario: Scenario) -> tuple[tuple[str, ...], tuple[str, ...]]:
    planner = pytest.importorskip("tlfleet.agent.ltl.planner")
    plan = planner.plan_robot(scenario, 1, distance=path_length_function(scenario))
    return plan.prefix, plan.suffix


def run_single(
    scenario: Scenario, plan, duration: float, disturbance: float = 0.0
) -> tuple[ExecutorController, HarnessResult]:
    """Robot 1 alone on the harness; a disturbance ‖w‖ ≤ ``disturbance`` [m/s], seed 0."""
    executor = Executor.from_scenario(scenario, 1)
    controller = ExecutorController(executor, executor.initial_state(*plan), [1])
    robot = scenario.robot(1)
    result = simulate(
        [SimRobot(robot.pose, robot.radius, robot.unicycle)],
        [controller],
        duration,
        scenario.arena,
        HarnessConfig(disturbance=disturbance),
        rng=np.random.default_rng(0),
    )
    return controller, result


def visited(controller: ExecutorController) -> list[tuple[float, str]]:
    return [(e.t, e.region) for e in controller.events if isinstance(e, RegionVisited)]


def assert_commands_within_limits(commands: np.ndarray, config: DwaConfig) -> None:
    dt = config.controller_period
    assert np.all(np.abs(commands[:, 0]) <= config.max_vel_x + 1e-12)
    assert np.all(np.abs(commands[:, 1]) <= config.max_rot_vel + 1e-12)
    steps = np.abs(np.diff(np.vstack([[0.0, 0.0], commands]), axis=0))
    assert np.all(steps[:, 0] <= config.acc_lim_x * dt + 1e-9)
    assert np.all(steps[:, 1] <= config.acc_lim_theta * dt + 1e-9)


# ------------------------------------------------------------------ Scenario 1


SCENARIO1_PLANS = {
    "hand": (("a11",), ("a12", "a11")),
    "planner": None,  # filled in by the test from tlfleet.agent.ltl.planner
}


@pytest.mark.parametrize(
    ("source", "disturbance"), [("hand", 0.0), ("planner", 0.0), ("hand", 0.05)]
)
def test_scenario1_robot1_completes_three_gf_rounds_in_90_s(source, disturbance):
    scenario = scenario1()
    plan = SCENARIO1_PLANS[source] or planner_plan(scenario)
    controller, result = run_single(scenario, plan, 90.0, disturbance)
    visits = visited(controller)
    # It starts in a11 and then alternates; a GF round = both regions visited once more.
    names = [name for _, name in visits]
    assert names == ["a11", "a12"] * (len(names) // 2) + ["a11"] * (len(names) % 2)
    assert controller.state.rounds >= 3
    assert controller.outputs[-1].progress.rounds == controller.state.rounds
    # Each 5 m leg takes at least (5 − 2·0.25) m / 0.3 m/s = 15 s; ours stay within 20 s.
    legs = np.diff([t for t, _ in visits])
    assert np.all(legs >= 15.0) and np.all(legs <= 20.0)
    assert result.contacts == ()
    assert_commands_within_limits(result.commands[:, 0, :], controller.executor.config.dwa)


# ------------------------------------------------------------------ Scenario 3


@pytest.mark.parametrize("source", ["hand", "planner"])
def test_scenario3_robot1_visits_all_five_regions_in_plan_order(source):
    scenario = scenario3()
    plan = (("start", "a1", "a2", "a3", "a4", "a5"), ("a5",))
    if source == "planner":
        plan = planner_plan(scenario)
    controller, result = run_single(scenario, plan, 100.0)
    expected = [name for name in plan[0] if name != "start"]
    expected += [name for name in plan[1] if name != expected[-1]]
    assert [name for _, name in visited(controller)] == expected
    assert sorted(expected) == ["a1", "a2", "a3", "a4", "a5"]
    finished = [e for e in controller.events if isinstance(e, PlanFinished)]
    assert len(finished) == 1 and finished[0].region == expected[-1]
    # Holding: the robot settles at the last region's centre and stays there.
    last = scenario.region(expected[-1]).center
    assert np.linalg.norm(result.poses[-1, 0, :2] - last) <= TOLERANCE
    assert controller.outputs[-1].progress.mode == "hold"
    assert result.contacts == ()
    assert result.min_wall_gap > 0.5


# ------------------------------------------------------------------ stuck, recovery, replanning


def test_blocked_target_triggers_stuck_recovery_and_a_replan_request():
    # Robot 9 is parked on a12's centre: a12 cannot be entered, the global planner's goal is
    # moved next to it, the robot stops there and makes no further progress.
    regions = (
        Region("a11", (-2.0, -2.5)),
        Region("a12", (-2.0, 2.5)),
        Region("a13", (0.5, 0.5)),
    )
    robots = (
        Robot(1, "unicycle", (-2.0, -2.5, math.pi / 2), ltl="G F a11 & G F a12"),
        Robot(9, "unicycle", (-2.0, 2.5, 0.0)),
    )
    scenario = Scenario("blocked", "f", 60.0, Arena(), regions, robots)
    config = ExecutorConfig(stuck_timeout=5.0)
    executor = Executor.from_scenario(scenario, 1, config)
    controller = ExecutorController(
        executor, executor.initial_state(("a11",), ("a12", "a11")), [1, 9]
    )

    def parked(t, index, poses):
        return (0.0, 0.0)

    def replan_seen(t, poses):
        return any(isinstance(e, ReplanRequest) for e in controller.events)

    sim_robots = [SimRobot(r.pose, r.radius) for r in robots]
    result = simulate(sim_robots, [controller, parked], 60.0, scenario.arena, stop=replan_seen)
    assert result.contacts == ()
    stuck = [e for e in controller.events if isinstance(e, Stuck)]
    requests = [e for e in controller.events if isinstance(e, ReplanRequest)]
    assert len(stuck) == 1 and len(requests) == 1
    assert stuck[0].target == "a12"
    assert stuck[0].t - stuck[0].since >= config.stuck_timeout
    assert math.dist(stuck[0].position, (-2.0, 2.5)) < 1.0  # it got next to the blocker
    request = requests[0]
    assert (request.from_region, request.to_region) == ("a11", "a12")
    assert request.penalty == config.blocked_edge_penalty
    # Recovery (rotate, then back off) lies between the two events.
    assert request.t - stuck[0].t >= config.rotate_time
    modes = [out.progress.mode for out in controller.outputs]
    assert "rotate" in modes and "back_off" in modes
    assert controller.state.stuck_count == 1
    assert "a12" not in dict((n, c) for n, c in controller.state.visits if c)
    assert_commands_within_limits(result.commands[:, 0, :], config.dwa)

    # The runtime answers with a plan that avoids the blocked edge: from a11 (where the planner
    # takes the robot to be) to a13 instead. a11 is not driven back to nor counted again.
    controller.pending_plan = (("a11", "a13"), ())
    poses = result.poses[-1]
    restart = [SimRobot(tuple(poses[k]), robots[k].radius) for k in range(2)]
    result2 = simulate(restart, [controller, parked], 40.0, scenario.arena, t0=result.times[-1])
    assert any(isinstance(e, PlanAccepted) for e in controller.events)
    after = [name for t, name in visited(controller) if t > request.t]
    assert after == ["a13"]
    assert dict(controller.state.visits)["a11"] == 1
    assert controller.state.mode == "hold"
    assert result2.contacts == ()


def test_a_new_plan_starting_at_the_last_region_with_nothing_else_holds_at_once():
    executor = Executor.from_scenario(scenario1(), 1)
    state = executor.initial_state(("a11",), ("a12", "a11"))
    state, _ = executor.step(state, ExecutorInputs(t=0.0, pose=(-2.0, -2.5, math.pi / 2)))
    pose = (-2.0, -1.0, math.pi / 2)
    state, out = executor.step(state, ExecutorInputs(t=0.2, pose=pose, new_plan=(("a11",), ())))
    kinds = [e.kind for e in out.events]
    assert kinds == ["plan_accepted", "plan_finished"]
    assert out.progress.mode == "hold" and out.progress.target is None


# ------------------------------------------------------------------ the step itself


def test_step_is_pure_and_deterministic():
    scenario = scenario1()
    executor = Executor.from_scenario(scenario, 1)
    state = executor.initial_state(("a11",), ("a12", "a11"))
    others = np.array([[2.0, 1.0, 0.0, 0.0]])
    inputs = ExecutorInputs(t=0.0, pose=(-2.0, -2.0, math.pi / 2), others=others)
    first_state, first = executor.step(state, inputs)
    second_state, second = executor.step(state, inputs)
    assert (first.v, first.omega) == (second.v, second.omega)
    assert np.array_equal(first_state.path, second_state.path)
    assert first.progress == second.progress
    assert state.control_cycles == 0 and state.path is None  # input state untouched
    assert first_state.control_cycles == 1
    assert first.progress.target == "a11"
    assert 0.0 <= first.v <= 0.2 + 1e-12 and abs(first.omega) <= 0.4 + 1e-12  # dynamic window


def test_first_step_in_the_start_region_visits_it_and_targets_the_next():
    executor = Executor.from_scenario(scenario1(), 1)
    state = executor.initial_state(("a11", "a12", "a11"), ("a11", "a12", "a11"))
    state, out = executor.step(state, ExecutorInputs(t=0.0, pose=(-2.0, -2.5, math.pi / 2)))
    assert [e.region for e in out.events if isinstance(e, RegionVisited)] == ["a11"]
    assert out.progress.target == "a12"
    assert out.progress.visits == (("a11", 1), ("a12", 0))
    assert out.path.shape[1] == 2 and len(out.path) >= 2
    assert out.progress.distance_to_target == pytest.approx(5.0, abs=0.05)


@pytest.mark.parametrize(
    ("plan", "match"),
    [
        (((), ()), "no region"),
        ((("a11", "nowhere"), ()), "unknown regions \\['nowhere'\\]"),
        ((("a11",), ("start",)), "unknown regions \\['start'\\]"),
    ],
)
def test_invalid_plans_are_rejected(plan, match):
    executor = Executor.from_scenario(scenario1(), 1)
    with pytest.raises(InvalidPlanError, match=match):
        executor.initial_state(*plan)


def test_target_walled_off_by_static_obstacles_reports_no_path_then_stuck_and_replan():
    walls = (
        RectObstacle(-2.8, 1.9, -1.2, 2.0),
        RectObstacle(-2.8, 3.0, -1.2, 3.1),
        RectObstacle(-2.8, 1.9, -2.7, 3.1),
        RectObstacle(-1.3, 1.9, -1.2, 3.1),
    )
    regions = (Region("a11", (-2.0, -2.5)), Region("a12", (-2.0, 2.5)))
    robot = Robot(1, "unicycle", (-2.0, -2.5, math.pi / 2), ltl="G F a11 & G F a12")
    scenario = Scenario("walled", "f", 30.0, Arena(obstacles=walls), regions, (robot,))
    config = ExecutorConfig(stuck_timeout=4.0)
    executor = Executor.from_scenario(scenario, 1, config)
    controller = ExecutorController(executor, executor.initial_state(("a11",), ("a12", "a11")), [1])
    result = simulate([SimRobot(robot.pose)], [controller], 15.0, scenario.arena)
    kinds = [e.kind for e in controller.events]
    assert kinds[:4] == ["region_visited", "no_path", "stuck", "replan_request"]
    assert kinds.count("no_path") == 1  # reported once, retried silently
    no_path = controller.events[1]
    assert no_path.target == "a12" and "not reachable" in no_path.reason
    request = next(e for e in controller.events if isinstance(e, ReplanRequest))
    assert (request.from_region, request.to_region) == ("a11", "a12")
    assert result.contacts == ()


def test_a_robot_escorting_closely_behind_does_not_bend_the_global_path():
    # An STL robot 0.5 m behind (scenario 2 keeps one within 0.6 m): its inflated stamp would
    # swallow our own position, so it is shrunk; the path to a12 stays the straight line.
    executor = Executor.from_scenario(scenario1(), 1)
    state = executor.initial_state(("a12",), ("a11", "a12"))
    escort = np.array([[3.0, -2.0, -2.0, math.pi / 2]])
    _, out = executor.step(
        state, ExecutorInputs(t=0.0, pose=(-2.0, -1.5, math.pi / 2), others=escort)
    )
    assert out.path.tolist() == [[-2.0, -1.5], [-2.0, 2.5]]


def test_a_robot_ahead_is_passed_on_the_right():
    executor = Executor.from_scenario(scenario1(), 1)
    state = executor.initial_state(("a12",), ("a11", "a12"))
    ahead = np.array([[2.0, -2.0, 0.5, -math.pi / 2]])  # right on the straight line, facing us
    _, out = executor.step(
        state, ExecutorInputs(t=0.0, pose=(-2.0, -1.5, math.pi / 2), others=ahead)
    )
    # Heading north, "right" is east: the detour passes the other robot at x > -2.
    beside = out.path[np.argmin(np.abs(out.path[:, 1] - 0.5))]
    assert len(out.path) > 2
    assert np.max(out.path[:, 0]) > -2.0 + 0.5
    assert np.min(out.path[:, 0]) >= -2.0 - 1e-9
    assert beside[0] >= -2.0


def test_the_whole_pose_frame_may_be_passed_own_row_is_ignored():
    executor = Executor.from_scenario(scenario1(), 1)
    state = executor.initial_state(("a12",), ("a11", "a12"))
    pose = (-2.0, -1.5, math.pi / 2)
    frame = np.array([[1.0, *pose], [2.0, 2.5, -2.0, math.pi / 2]])
    _, with_self = executor.step(state, ExecutorInputs(t=0.0, pose=pose, others=frame))
    _, without = executor.step(state, ExecutorInputs(t=0.0, pose=pose, others=frame[1:]))
    assert (with_self.v, with_self.omega) == (without.v, without.omega)
    assert with_self.path.tolist() == [[-2.0, -1.5], [-2.0, 2.5]]


@pytest.mark.parametrize(("n_robots", "may_get_stuck"), [(4, False), (6, True)])
def test_robots_swapping_places_through_the_centre_all_arrive_without_contact(
    n_robots, may_get_stuck
):
    """Robots on a 2 m circle each drive to the opposite point. With 4 the keep-right rule
    resolves the crossing at once; 6 jam symmetrically and stuck recovery unjams them."""
    starts = [
        (
            2.0 * math.cos(2 * math.pi * k / n_robots + 0.3),
            2.0 * math.sin(2 * math.pi * k / n_robots + 0.3),
        )
        for k in range(n_robots)
    ]
    regions = tuple(Region(f"g{k}", (-x, -y)) for k, (x, y) in enumerate(starts))
    robots = tuple(
        Robot(k + 1, "unicycle", (x, y, math.atan2(-y, -x))) for k, (x, y) in enumerate(starts)
    )
    scenario = Scenario("swap", "f", 60.0, Arena(), regions, robots)
    ids = [r.id for r in robots]
    controllers = []
    for k, robot in enumerate(robots):
        executor = Executor.from_scenario(scenario, robot.id)
        controllers.append(
            ExecutorController(executor, executor.initial_state((f"g{k}",), ()), ids)
        )
    result = simulate(
        [SimRobot(r.pose) for r in robots],
        controllers,
        60.0,
        scenario.arena,
        HarnessConfig(disturbance=0.01),
        rng=np.random.default_rng(1),
    )
    assert result.contacts == ()
    for controller in controllers:
        assert controller.state.mode == "hold"
        if not may_get_stuck:
            assert controller.state.stuck_count == 0
