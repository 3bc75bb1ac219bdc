"""Keep-out paths between regions (docs/ltl-navigation.md §2) and the clearance-preferring global
planner they use: checked against brute force and against the geometry, not against the code's
own numbers."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tlfleet.agent.ltl.planner import plan_robot
from tlfleet.agent.ltl.transition_system import from_regions
from tlfleet.agent.model.scenario import Arena, RectObstacle, Region, Robot, Scenario
from tlfleet.agent.nav.errors import NoPathError
from tlfleet.agent.nav.grid import arena_clearance, grid_from_arena
from tlfleet.agent.nav.grid_planner import plan_path
from tlfleet.agent.nav.keep_out import RegionPaths
from tlfleet.agent.policy.ltl import plan_on_map
from tlfleet.bus.errors import UnsatisfiableTask

INFLATION = 0.25  # robot radius 0.2 + margin 0.05
RES = 0.05


def _samples(waypoints: np.ndarray, step: float = 0.01) -> np.ndarray:
    out = []
    for a, b in itertools.pairwise(waypoints):
        n = max(2, math.ceil(float(np.linalg.norm(b - a)) / step) + 1)
        out.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    return np.vstack(out)


def test_a_path_between_two_regions_keeps_off_a_third_on_the_straight_line():
    regions = (Region("a", (-2.5, 0.0), 0.3), Region("b", (2.5, 0.0), 0.3),
               Region("c", (0.0, 0.0), 0.5))
    paths = RegionPaths(regions, grid_from_arena(Arena(), INFLATION))
    path = paths.path("a", "b")
    assert path is not None
    points = _samples(path.waypoints)
    # every point of the path keeps the robot's body (0.2 m) off c's disc, less a cell
    assert np.min(np.hypot(points[:, 0], points[:, 1])) >= 0.5 + INFLATION - RES
    assert paths.length("a", "b") == pytest.approx(path.length)
    assert paths.length("a", "b") > 5.0 + 0.1  # a detour, not the straight 5 m
    # without c the same pair is the straight line
    free = RegionPaths(regions[:2], grid_from_arena(Arena(), INFLATION))
    assert free.length("a", "b") == pytest.approx(5.0)


def test_a_region_closing_the_only_passage_removes_the_edge_and_is_named():
    # a wall with one 1.2 m gap; region c sits in the gap
    wall = (RectObstacle(-0.1, -3.5, 0.1, -0.6), RectObstacle(-0.1, 0.6, 0.1, 3.5))
    regions = (Region("a", (-2.0, 0.0), 0.3), Region("b", (2.0, 0.0), 0.3),
               Region("c", (0.0, 0.0), 0.3))
    paths = RegionPaths(regions, grid_from_arena(Arena(obstacles=wall), INFLATION))
    assert paths.path("a", "b") is None
    assert math.isinf(paths.length("a", "b"))
    assert paths.blockers("a", "b") == ("c",)
    # going *to* c is allowed: a -> c -> b exists
    assert math.isfinite(paths.length("a", "c")) and math.isfinite(paths.length("c", "b"))
    ts = from_regions(regions, (-2.0, 0.0), edge_length=paths.edge_length)
    a, b, c = (ts.index(n) for n in "abc")
    assert b not in [j for j, _ in ts.edges[a]] and c in [j for j, _ in ts.edges[a]]


def _scenario(task: str, regions, obstacles=()) -> Scenario:
    robots = (Robot(1, "unicycle", (-2.0, -1.5, 0.0), ltl=task),)
    return Scenario("keep", "keep", 60.0, Arena(obstacles=tuple(obstacles)), tuple(regions),
                    robots)


def test_no_plan_under_the_rule_says_which_region_is_in_the_way():
    wall = (RectObstacle(-0.1, -3.5, 0.1, -0.6), RectObstacle(-0.1, 0.6, 0.1, 3.5))
    regions = (Region("a", (-2.0, 0.0), 0.3), Region("b", (2.0, 0.0), 0.3),
               Region("c", (0.0, 0.0), 0.3))
    scenario = _scenario("G F a & G F b & G !c", regions, wall)
    # the map alone (no keep-out rule) has a plan, straight through the gap
    assert plan_robot(scenario, 1).suffix
    with pytest.raises(UnsatisfiableTask, match=r"every way from a to b enters region 'c'"):
        plan_on_map(scenario, 1)
    # and the message is one line
    try:
        plan_on_map(scenario, 1)
    except UnsatisfiableTask as exc:
        assert "\n" not in str(exc) and "robot 1" in str(exc)


def test_the_plan_goes_around_a_forbidden_region_and_its_word_avoids_it():
    regions = (Region("a", (-2.5, 0.0), 0.3), Region("b", (2.5, 0.0), 0.3),
               Region("c", (0.0, 0.0), 0.5))
    scenario = _scenario("G F a & G F b & G !c", regions)
    plan = plan_on_map(scenario, 1)
    assert "c" not in plan.prefix + plan.suffix
    paths = RegionPaths.from_scenario(scenario, 1)
    assert plan.suffix_cost == pytest.approx(2 * paths.length("a", "b"))


def test_a_target_covered_by_another_regions_zone_has_no_path():
    # b's centre lies 0.35 m from c's: inside c's keep-out zone, so the goal the planner can
    # reach is outside b's 0.1 m disc
    regions = (Region("a", (-2.0, 0.0), 0.3), Region("b", (1.0, 0.0), 0.1),
               Region("c", (1.35, 0.0), 0.2))
    paths = RegionPaths(regions, grid_from_arena(Arena(), INFLATION))
    assert paths.path("a", "b") is None
    assert paths.path("a", "c") is not None  # c's own centre is free when c is the target


regions_strategy = st.lists(
    st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(0.1, 0.6)),
    min_size=2, max_size=7)


@settings(max_examples=40, deadline=None)
@given(regions_strategy, st.data())
def test_keep_out_grid_is_the_static_grid_plus_every_other_region_brute_force(raw, data):
    """The cached three-nearest-regions layers give, for any allowed pair, the clearance
    min(static clearance, distance to every region not allowed) of a direct computation."""
    regions = tuple(Region(f"r{k}", (x, y), r) for k, (x, y, r) in enumerate(raw))
    grid = grid_from_arena(Arena(obstacles=(RectObstacle(-1.0, -0.5, 0.5, 0.2),)), INFLATION,
                           0.1)
    paths = RegionPaths(regions, grid)
    names = [r.name for r in regions]
    allowed = data.draw(st.lists(st.sampled_from(names), max_size=3, unique=True))
    keep = paths.grid_for(allowed)
    ny, nx = grid.shape
    xs = grid.origin[0] + (np.arange(nx) + 0.5) * grid.resolution
    ys = grid.origin[1] + (np.arange(ny) + 0.5) * grid.resolution
    expected = grid.clearance.copy()
    for region in regions:
        if region.name not in allowed:
            d = np.hypot(xs[None, :] - region.center[0], ys[:, None] - region.center[1])
            expected = np.minimum(expected, d - region.radius)
    np.testing.assert_allclose(keep.clearance, expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(keep.blocked, expected < INFLATION)


def test_the_global_path_runs_down_the_middle_of_a_corridor():
    # a 1.0 m corridor from x = -1.5 to 1.5: the shortest path grazes its walls' inflation,
    # the clearance-preferring one keeps to the middle
    walls = (RectObstacle(-1.5, 0.5, 1.5, 3.5), RectObstacle(-1.5, -3.5, 1.5, -0.5))
    arena = Arena(obstacles=walls)
    grid = grid_from_arena(arena, INFLATION)
    start, goal = (-3.0, -1.5), (3.0, 1.5)
    shortest = _samples(plan_path(grid, start, goal).waypoints)
    centred = _samples(plan_path(grid, start, goal, prefer=0.3).waypoints)
    inside = lambda p: np.abs(p[:, 0]) < 1.4  # noqa: E731 - the corridor's samples
    gap_short = arena_clearance(arena, shortest[inside(shortest)])
    gap_centred = arena_clearance(arena, centred[inside(centred)])
    assert gap_short.min() < 0.3  # grazing: 0.25 m inflation and a little
    assert gap_centred.min() > 0.42  # the middle is 0.5 m from both walls
    # in the open the preference changes nothing: the straight line
    open_path = plan_path(grid_from_arena(Arena(), INFLATION), (-2.0, -2.0), (2.0, 1.0),
                          prefer=0.3)
    assert open_path.length == pytest.approx(5.0)


def test_clearance_preference_never_ends_a_path_in_an_obstacle_and_stays_free():
    rng = np.random.default_rng(3)
    for _ in range(20):
        obstacles = []
        for _ in range(4):
            x, y = rng.uniform(-3.0, 2.0, 2)
            w, h = rng.uniform(0.2, 1.5, 2)
            obstacles.append(RectObstacle(x, y, x + w, y + h))
        arena = Arena(obstacles=tuple(obstacles))
        grid = grid_from_arena(arena, INFLATION)
        free = np.argwhere(~grid.blocked)
        a, b = grid.center_of(free[rng.choice(len(free), 2, replace=False)][:, ::-1])
        try:
            path = plan_path(grid, a, b, prefer=0.3)
        except NoPathError:  # disconnected: the shortest planner agrees
            with pytest.raises(NoPathError):
                plan_path(grid, a, b)
            continue
        points = _samples(path.waypoints, 0.02)
        assert np.all(arena_clearance(arena, points) > 0.2 - 1e-9)  # the body never touches
        assert path.length >= math.dist(a, b) - 1e-9
