"""The executor's periodic global re-plan is deferred until after the command.

The step that finds a re-plan due keeps following its current path and records the request
(``ExecutorState.pending``); ``Executor.refresh`` runs it. Whether the caller refreshes after
each step (the agent runtime, once the command is sent) or leaves it to the next step, the
trajectory is the same; with ``deferred_replan=False`` the step plans at once (the old rule).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from nav_harness import ExecutorController, SimRobot, simulate
from nav_scenarios import scenario1
from tlfleet.agent.nav.executor import Executor, ExecutorConfig, ExecutorInputs
from tlfleet.agent.nav.grid_planner import plan_path

PLAN = (("a11",), ("a12", "a11"))


def run(refresh: bool, config: ExecutorConfig | None = None, seconds: float = 30.0):
    """Robot 1 of Scenario 1 on its GF cycle, robot 2 parked near its route."""
    scenario = scenario1()
    executor = Executor.from_scenario(scenario, 1, config)
    controller = ExecutorController(executor, executor.initial_state(*PLAN), [1, 2],
                                    refresh=refresh)
    robots = [SimRobot(scenario.robot(1).pose), SimRobot((0.0, -0.5, 0.0))]
    parked = lambda t, i, p: (0.0, 0.0)  # noqa: E731
    result = simulate(robots, [controller, parked], seconds, scenario.arena)
    return controller, result


def test_refreshing_after_each_step_or_not_gives_the_same_trajectory():
    eager, eager_run = run(refresh=True)
    lazy, lazy_run = run(refresh=False)
    commands = [(o.v, o.omega) for o in eager.outputs]
    assert commands == [(o.v, o.omega) for o in lazy.outputs]
    assert np.array_equal(eager_run.poses, lazy_run.poses)
    assert eager.state.pending is None  # the runtime's order leaves nothing pending
    assert len(commands) == 150 and sum(1 for o in eager.outputs if len(o.path)) > 100
    # the requests really were deferred: planning at once drives another trajectory
    at_once, _ = run(refresh=True, config=replace(ExecutorConfig(), deferred_replan=False))
    assert [(o.v, o.omega) for o in at_once.outputs] != commands


def test_the_step_follows_the_current_path_and_refresh_installs_the_planned_one():
    scenario = scenario1()
    executor = Executor.from_scenario(scenario, 1)
    state = executor.initial_state(*PLAN)
    pose = (-2.0, -2.0, math.pi / 2)
    others = np.array([[2.0, -2.0, -1.0, 0.0]])
    state, first = executor.step(state, ExecutorInputs(0.0, pose, others))
    assert state.pending is None and len(first.path)  # a new target is planned at once
    later = (-2.0, -1.0, math.pi / 2)
    t = executor.config.replan_period
    due, out = executor.step(state, ExecutorInputs(t, later, others))
    assert np.array_equal(out.path, first.path)  # this command still follows the old path
    request = due.pending
    assert request is not None and request.t == t and due.path_time == t
    assert np.array_equal(request.start, np.asarray(later[:2]))
    refreshed = executor.refresh(due)
    # the request's robots are stamped when it runs, the way the step would have stamped them
    centers, radii = executor._stamps(request.pose, request.others, full=request.blocked,
                                      goal=request.goal)
    grid = executor.paths.grid_for(request.allowed).with_discs(centers, radii)
    expected = plan_path(grid, request.start, request.goal,
                         prefer=executor.config.path_clearance).waypoints
    assert refreshed.pending is None and np.array_equal(refreshed.path, expected)
    assert not np.array_equal(refreshed.path, first.path)
    # refresh is pure and a state with nothing pending is returned as it is
    assert due.pending is request and executor.refresh(refreshed) is refreshed


def test_without_deferral_the_step_plans_at_once():
    config = replace(ExecutorConfig(), deferred_replan=False)
    scenario = scenario1()
    executor = Executor.from_scenario(scenario, 1, config)
    state = executor.initial_state(*PLAN)
    others = np.array([[2.0, -2.0, -1.0, 0.0]])
    state, _ = executor.step(state, ExecutorInputs(0.0, (-2.0, -2.0, math.pi / 2), others))
    t = config.replan_period
    state, out = executor.step(state, ExecutorInputs(t, (-2.0, -1.0, math.pi / 2), others))
    assert state.pending is None and state.path_time == t
    assert np.allclose(out.path[0], (-2.0, -1.0), atol=executor.grid.resolution)


def test_a_new_plan_drops_a_pending_request():
    scenario = scenario1()
    executor = Executor.from_scenario(scenario, 1)
    state = executor.initial_state(*PLAN)
    pose = (-2.0, -2.0, math.pi / 2)
    state, _ = executor.step(state, ExecutorInputs(0.0, pose, np.zeros((0, 4))))
    due, _ = executor.step(state, ExecutorInputs(1.0, pose, np.zeros((0, 4))))
    assert due.pending is not None
    # a new plan arrives before the refresh: the step runs the request first (same target),
    # then the plan resets the path; nothing stays pending for the old target
    after, _out = executor.step(due, ExecutorInputs(1.2, pose, np.zeros((0, 4)),
                                                    new_plan=(("a12",), ("a12",))))
    assert after.pending is None and after.path_target == "a12"
