"""Transition system, product and optimal prefix–suffix plans (ltl-planning.md §3–§5)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from ltl_helpers import brute_force_optimum
from tlfleet.agent.ltl.buchi import buchi_step, translate
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.planner import plan, plan_robot, replan
from tlfleet.agent.ltl.product import explore
from tlfleet.agent.ltl.transition_system import START, TransitionSystem, from_regions, from_scenario
from tlfleet.agent.model.scenario import Arena, Region, Robot, Scenario
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.errors import UnsatisfiableTask


def labels_of(ts: TransitionSystem, names) -> list[frozenset[str]]:
    return [ts.labels[ts.index(n)] for n in names]


def run_cost(ts: TransitionSystem, names) -> float:
    return sum(ts.weight(a, b) for a, b in itertools.pairwise(names))


def check_plan_is_consistent(p, ts: TransitionSystem, formula: str) -> None:
    """The plan's word satisfies the formula and its costs are the weights it drives along."""
    assert p.suffix, "the suffix (repeated cycle) must not be empty"
    assert holds(formula, labels_of(ts, p.prefix), labels_of(ts, p.suffix))
    path = [*p.prefix, p.suffix[0]]
    assert p.prefix_cost == pytest.approx(run_cost(ts, path))
    assert p.suffix_cost == pytest.approx(run_cost(ts, [*p.suffix, p.suffix[0]]))
    assert p.cost == pytest.approx(p.prefix_cost + p.beta * p.suffix_cost)
    assert p.prefix == tuple(r for r, _q in p.prefix_run)
    assert p.suffix == tuple(r for r, _q in p.suffix_run)


def region(name: str, x: float, y: float, labels=()) -> Region:
    return Region(name, (x, y), 0.25, frozenset(labels) if labels else frozenset())


def scenario_with(regions, robots) -> Scenario:
    return Scenario("test", "test", 10.0, Arena(), tuple(regions), tuple(robots))


# --------------------------------------------------------------------------- transition system


def test_transition_system_weights_self_loops_and_initial_region():
    regions = [region("a", 0, 0), region("b", 3, 4)]
    ts = from_regions(regions, (0.1, 0.0))
    assert ts.names == ("a", "b")
    assert ts.names[ts.initial] == "a"
    assert ts.weight("a", "a") == 0.0
    assert ts.weight("a", "b") == pytest.approx(5.0)
    assert ts.labels == (frozenset({"a"}), frozenset({"b"}))


def test_virtual_start_state_when_outside_every_region():
    ts = from_regions([region("a", 0, 0), region("b", 3, 4)], (0.0, 4.0))
    assert ts.names[ts.initial] == START
    assert ts.labels[ts.initial] == frozenset()
    assert ts.weight(START, "b") == pytest.approx(3.0)
    assert all(j != ts.initial for out in ts.edges for j, _w in out)  # no way back to start


def test_custom_distance_and_missing_paths():
    def distance(p, q):
        return math.inf if {p, q} == {(0.0, 0.0), (3.0, 4.0)} else 2 * math.dist(p, q)

    ts = from_regions([region("a", 0, 0), region("b", 3, 4), region("c", 0, 4)], (0, 0), distance)
    with pytest.raises(KeyError, match="no transition a -> b"):
        ts.weight("a", "b")
    assert ts.weight("a", "c") == pytest.approx(8.0)


def test_product_is_built_on_the_fly_and_reads_the_source_label():
    regions = [region(f"r{i}", i, 0) for i in range(6)]
    ts = from_regions(regions, (0, 0)).without_edges([(f"r{i}", "r5") for i in range(5)])
    buchi = translate("F r1")  # 2 states: waiting, done
    graph = explore(ts, buchi, [(ts.initial, q) for q in buchi.initial])
    # r5 cannot be reached: none of its pairs is built.
    assert all(ts.names[r] != "r5" for r, _q in graph.pairs)
    assert graph.num_states == 5 * buchi.num_states
    (acc,) = buchi.accepting
    entering = [
        (ts.names[r], q) for k, (r, q) in enumerate(graph.pairs) for k2, _w in graph.succ[k]
        if graph.pairs[k2][1] == acc and q != acc
    ]
    # entering the accepting state requires *leaving* r1 (the source label is read)
    assert entering and {name for name, _q in entering} == {"r1"}


# --------------------------------------------------------------------------- scenarios (golden)


def scenario_robots(scenarios_dir):
    for i in (1, 2, 3):
        scenario = load_scenario(scenarios_dir / f"scenario{i}.toml")
        for robot in scenario.robots:
            if robot.ltl is not None:
                yield scenario, robot


def test_scenario_plans_are_optimal_and_satisfy_their_tasks(scenarios_dir):
    robots = list(scenario_robots(scenarios_dir))
    assert len(robots) == 5  # 2 + 2 + 1 LTL robots
    for scenario, robot in robots:
        p = plan_robot(scenario, robot.id)
        ts = from_scenario(scenario, robot.id)
        check_plan_is_consistent(p, ts, robot.ltl)
        expected = brute_force_optimum(translate(robot.ltl), ts, scenario.ltl.suffix_weight)
        assert p.cost == pytest.approx(expected)
        assert p.robot == robot.id
        assert p.buchi_states == translate(robot.ltl).num_states


def test_scenario_1_robot_1_cycles_between_its_two_regions(scenarios_dir):
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    p = plan_robot(scenario, 1)
    assert set(p.suffix) == {"a11", "a12"}
    assert p.suffix_cost == pytest.approx(2 * math.dist((-2.0, -2.5), (-2.0, 2.5)))
    assert p.prefix[0] == "a11"  # the robot starts inside a11
    assert p.buchi_states == 3


def test_scenario_3_robot_1_visits_all_regions_in_the_cheapest_order(scenarios_dir):
    scenario = load_scenario(scenarios_dir / "scenario3.toml")
    robot = scenario.robot(1)
    p = plan_robot(scenario, 1)
    start = robot.pose[:2]
    centres = {r.name: r.center for r in scenario.regions}

    def tour(order) -> float:
        points = [start, *(centres[n] for n in order)]
        return sum(math.dist(a, b) for a, b in itertools.pairwise(points))

    best = min(tour(order) for order in itertools.permutations(sorted(centres)))
    visited = list(dict.fromkeys(n for n in (*p.prefix, *p.suffix) if n != START))
    assert sorted(visited) == ["a1", "a2", "a3", "a4", "a5"]
    assert tour(visited) == pytest.approx(best)
    assert p.cost == pytest.approx(best)  # the suffix is a zero-cost stay
    assert p.suffix_cost == 0.0
    assert p.buchi_states == 32


# --------------------------------------------------------------------------- optimality

FORMULAS = [
    "G F a & G F b",
    "F a & F b & F c",
    "F (a & F (b & F c))",
    "G F a & G !c",
    "G (a -> X (!a U b)) & G F a",
    "F G b",
    "G F (a | c) & F b",
    "(!b U a) & G F b",
    "G F a & G F b & G (a -> X !b)",
    "F a & G (b -> F c)",
]


@pytest.mark.parametrize("seed", range(40))
def test_planner_matches_brute_force_on_random_systems(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 6))
    names = [f"r{i}" for i in range(n)]
    regions = []
    for name in names:
        labels = {x for x in "abc" if rng.random() < 0.4} or {name}
        regions.append(region(name, *rng.uniform(-3, 3, size=2), labels))
    start = (0.0, 0.0) if rng.random() < 0.5 else regions[0].center
    ts = from_regions(regions, start)
    # Block a few transitions at random to make the graph non-complete.
    blocked = [(a, b) for a in names for b in names if a != b and rng.random() < 0.3]
    ts = ts.without_edges(blocked)
    formula = FORMULAS[seed % len(FORMULAS)]
    beta = float(rng.choice([0.0, 1.0, 10.0]))
    expected = brute_force_optimum(translate(formula), ts, beta)
    if math.isinf(expected):
        with pytest.raises(UnsatisfiableTask):
            plan(formula, ts, beta)
        return
    p = plan(formula, ts, beta)
    assert p.cost == pytest.approx(expected)
    check_plan_is_consistent(p, ts, formula)
    for a, b in itertools.pairwise([*p.prefix, *p.suffix, p.suffix[0]]):
        assert (a, b) not in blocked


def test_plan_accepts_text_trees_and_automata_alike():
    ts = from_regions([region("a", 0, 0), region("b", 1, 0)], (0, 0))
    buchi = translate("G F a & G F b")
    plans = [plan(task, ts) for task in ("G F a & G F b", parse("G F a & G F b"), buchi)]
    assert len({(p.prefix, p.suffix, p.cost) for p in plans}) == 1
    assert plans[0].suffix_cost == pytest.approx(2.0)  # a → b → a


# --------------------------------------------------------------------------- replanning


def follow(buchi, ts, names):
    """Büchi states after leaving each region of ``names`` in turn."""
    states = frozenset(buchi.initial)
    for name in names:
        states = buchi_step(buchi, states, ts.labels[ts.index(name)])
    return states


@pytest.mark.parametrize("formula", ["G F a & G F b & G F c", "F a & F b & F c",
                                     "F(a & F(b & F c))", "G(a -> F c) & G F b"])
def test_tracking_the_plan_with_buchi_step_follows_its_run(formula):
    """What the LTL agent does: read the label of each region it leaves; the plan's Büchi
    states are always among the tracked ones, and the accepting state recurs on the suffix."""
    ts = from_regions([region("a", 0, 0), region("b", 2, 0), region("c", 0, 3)], (1, 1))
    buchi = translate(formula)
    p = plan(buchi, ts)
    states = frozenset(buchi.initial)
    run = [*p.prefix_run, *p.suffix_run * 3]
    for name, q in run:
        assert q in states
        states = buchi_step(buchi, states, ts.labels[ts.index(name)])
    assert p.suffix_run[0][1] in buchi.accepting


def test_replan_from_the_start_equals_plan():
    ts = from_regions([region("a", 0, 0), region("b", 2, 0), region("c", 0, 3)], (1, 1))
    buchi = translate("F a & F b & F c")
    fresh = plan(buchi, ts)
    again = replan(buchi, ts, ts.names[ts.initial], buchi.initial)
    assert again.cost == pytest.approx(fresh.cost)
    assert again.prefix == fresh.prefix and again.suffix == fresh.suffix


def test_replan_mid_mission_keeps_what_was_already_done(scenarios_dir):
    scenario = load_scenario(scenarios_dir / "scenario3.toml")
    ts = from_scenario(scenario, 1)
    formula = scenario.robot(1).ltl
    buchi = translate(formula)
    p = plan(buchi, ts, scenario.ltl.suffix_weight)
    done = list(p.prefix[:3])  # start, first and second region visited
    current = p.prefix[3]
    states = follow(buchi, ts, done)
    q = replan(buchi, ts, current, states, scenario.ltl.suffix_weight)
    # Only the regions still missing are left to visit; the rest of the old plan is optimal.
    assert q.cost == pytest.approx(p.cost - run_cost(ts, [*done, current]))
    assert set(q.prefix + q.suffix) >= {"a1", "a2", "a3", "a4", "a5"} - set(done)
    assert holds(formula, labels_of(ts, [*done, *q.prefix]), labels_of(ts, q.suffix))


def test_replan_around_a_blocked_transition():
    regions = [region("a", 0, 0), region("b", 4, 0), region("c", 2, 1)]
    ts = from_regions(regions, (0, 0))
    formula = "G F a & G F b"
    direct = plan(formula, ts)
    assert direct.suffix_cost == pytest.approx(8.0)
    blocked = ts.without_edges([("a", "b"), ("b", "a")])
    buchi = translate(formula)
    states = follow(buchi, ts, direct.prefix)
    detour = replan(buchi, blocked, direct.suffix[0], states)
    assert "c" in detour.suffix
    assert detour.suffix_cost == pytest.approx(4 * math.dist((0, 0), (2, 1)))
    for a, b in itertools.pairwise([*detour.prefix, *detour.suffix, detour.suffix[0]]):
        assert {a, b} != {"a", "b"}


def test_replan_after_a_violation_is_unsatisfiable():
    ts = from_regions([region("a", 0, 0), region("b", 1, 0)], (0, 0))
    buchi = translate("G !b & G F a")
    states = follow(buchi, ts, ["a", "b"])
    assert states == frozenset()
    with pytest.raises(UnsatisfiableTask, match="already violate"):
        replan(buchi, ts, "a", states)


def test_replan_diagnoses_from_the_given_states():
    """After leaving 'a', only `G b` is left: from 'a' the run fails on its first letter,
    from 'b' the robot stays forever."""
    ts = from_regions([region("a", 0, 0), region("b", 1, 0)], (0, 0))
    buchi = translate("a & X G b")
    states = follow(buchi, ts, ["a"])  # now `G b` remains, the robot is in 'a'
    with pytest.raises(UnsatisfiableTask, match="fails where it starts: 'a' carries \\{a\\}"):
        replan(buchi, ts, "a", states)
    assert replan(buchi, ts, "b", states).suffix == ("b",)


def test_replan_rejects_unknown_states_and_regions():
    ts = from_regions([region("a", 0, 0)], (0, 0))
    buchi = translate("G F a")
    with pytest.raises(ValueError, match="out of range"):
        replan(buchi, ts, "a", [7])
    with pytest.raises(KeyError, match="no region 'z'"):
        replan(buchi, ts, "z", buchi.initial)


# --------------------------------------------------------------------------- unsatisfiable tasks

SCENARIO1_REGIONS = [region("a11", -2.0, -2.5), region("a12", -2.0, 2.5)]


@pytest.mark.parametrize(
    ("formula", "message"),
    [
        ("GF(a11 & a12)",
         r"robot 1: task 'GF\(a11 & a12\)' cannot be satisfied: "
         r"no region carries a11 and a12 together$"),
        ("F(a11 & a12) & G F a11",
         r"cannot be satisfied: no region carries a11 and a12 together$"),
        ("G F a11 & G F zz", r"cannot be satisfied: no region carries zz$"),
        ("G F a11 & G !a11", r"the formula is unsatisfiable: no infinite word satisfies it$"),
    ],
)
def test_unsatisfiable_tasks_say_what_is_missing(formula, message):
    robot = Robot(1, "unicycle", (-2.0, -2.5, 0.0), ltl=formula)
    scenario = scenario_with(SCENARIO1_REGIONS, [robot])
    with pytest.raises(UnsatisfiableTask, match=message) as info:
        plan_robot(scenario, 1)
    assert info.value.robot == 1
    assert info.value.formula == formula


def test_paper_literal_scenario_3_task_is_reported():
    regions = [region(f"a{i}", x, y) for i, (x, y) in
               enumerate([(-1.5, -1.5), (1.5, -1.5), (1.5, 1.5), (-1.5, 1.5), (0, 0)], 1)]
    formula = "F(a1 & a2 & a3 & a4 & a5)"
    robot = Robot(1, "unicycle", (-2.0, -2.0, 0.0), ltl=formula)
    with pytest.raises(UnsatisfiableTask, match="no region carries a1, a2, a3, a4 and a5 together"):
        plan_robot(scenario_with(regions, [robot]), 1)


def test_unreachable_accepting_cycle_is_reported():
    ts = from_regions(SCENARIO1_REGIONS, (-2.0, -2.5))
    ts = ts.without_edges([("a11", "a12")])
    with pytest.raises(UnsatisfiableTask, match="no accepting cycle is reachable from 'a11'"):
        plan("G F a11 & G F a12", ts, robot=1)


def test_task_failing_at_the_start_is_reported():
    ts = from_regions(SCENARIO1_REGIONS, (0.0, 0.0))  # outside both regions
    with pytest.raises(UnsatisfiableTask, match=r"fails where it starts: 'start' carries \{\}"):
        plan("G a11", ts)


def test_generic_proposition_on_several_regions():
    regions = [region("x", 0, 0, {"dock"}), region("y", 5, 0, {"dock"}), region("w", 1, 0)]
    robot = Robot(1, "unicycle", (1.0, 0.0, 0.0), ltl="G F dock & G F w")
    p = plan_robot(scenario_with(regions, [robot]), 1)
    assert set(p.suffix) == {"x", "w"}  # the nearer dock
    assert p.suffix_cost == pytest.approx(2.0)


def test_plan_to_dict_is_json_ready(scenarios_dir):
    import json

    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    data = json.loads(json.dumps(plan_robot(scenario, 1).to_dict()))
    assert data["robot"] == 1 and data["buchi"]["states"] == 3
    assert set(data["timings"]) == {"parse", "translate", "product", "search", "total"}
