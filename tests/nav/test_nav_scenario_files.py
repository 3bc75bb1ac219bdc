"""Navigation on the real scenario files: loader → LTL planner (grid path lengths) → executors."""

from __future__ import annotations

import pytest
from nav_harness import ExecutorController, SimRobot, simulate
from tlfleet.agent.nav.events import RegionVisited
from tlfleet.agent.nav.executor import Executor
from tlfleet.agent.nav.grid_planner import path_length_function
from tlfleet.agent.scenario import load_scenario

planner = pytest.importorskip("tlfleet.agent.ltl.planner")


def run_ltl_robots(scenario, duration):
    """All unicycle robots of the scenario together, each following its optimal plan."""
    robots = [r for r in scenario.robots if r.kind == "unicycle"]
    ids = [r.id for r in robots]
    distance = path_length_function(scenario)
    controllers = []
    for robot in robots:
        plan = planner.plan_robot(scenario, robot.id, distance=distance)
        executor = Executor.from_scenario(scenario, robot.id)
        controllers.append(
            ExecutorController(executor, executor.initial_state(plan.prefix, plan.suffix), ids)
        )
    sim_robots = [SimRobot(r.pose, r.radius, r.unicycle) for r in robots]
    return controllers, simulate(sim_robots, controllers, duration, scenario.arena)


def test_scenario1_both_ltl_robots_keep_cycling_without_contact(scenarios_dir):
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    controllers, result = run_ltl_robots(scenario, scenario.duration)
    assert result.contacts == ()
    for controller in controllers:
        assert controller.state.rounds >= 3, controller.state.visits


def test_scenario3_robot1_follows_the_planners_order(scenarios_dir):
    scenario = load_scenario(scenarios_dir / "scenario3.toml")
    (controller,), result = run_ltl_robots(scenario, scenario.duration)
    order = [e.region for e in controller.events if isinstance(e, RegionVisited)]
    plan = controller.state
    expected = [n for n in dict.fromkeys((*plan.prefix, *plan.suffix)) if n != "start"]
    assert order == expected
    assert sorted(order) == ["a1", "a2", "a3", "a4", "a5"]
    assert controller.state.mode == "hold"
    assert result.contacts == ()
