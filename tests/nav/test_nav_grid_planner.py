"""Global planner: A* lengths checked by hand, smoothing, blocked start/goal, no path, distances."""

from __future__ import annotations

import heapq
import math

import numpy as np
import pytest
import tlfleet.agent.nav.grid_planner as grid_planner
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from hypothesis_budget import examples
from nav_scenarios import scenario3
from tlfleet.agent.model.scenario import Arena, DiscObstacle, RectObstacle, Region, Robot, Scenario
from tlfleet.agent.nav.errors import NoPathError
from tlfleet.agent.nav.grid import arena_clearance, grid_from_arena, grid_from_occupancy
from tlfleet.agent.nav.grid_planner import (
    astar_cells,
    line_of_sight,
    path_length_function,
    plan_path,
)
from tlfleet.bus.errors import TlfleetError

SQRT2 = math.sqrt(2.0)


def _free(nx: int, ny: int) -> np.ndarray:
    return np.zeros((ny, nx), dtype=bool)


def test_straight_line_on_an_empty_grid_is_9_cells_long():
    grid = grid_from_occupancy(_free(10, 3), resolution=1.0)
    path = plan_path(grid, (0.5, 1.5), (9.5, 1.5))
    assert path.grid_length == pytest.approx(9.0)
    assert path.length == pytest.approx(9.0)
    assert path.waypoints.tolist() == [[0.5, 1.5], [9.5, 1.5]]


def test_diagonal_on_an_empty_grid_is_5_sqrt2():
    result = astar_cells(_free(6, 6), (0, 0), (5, 5))
    assert result is not None
    cells, length = result
    assert length == pytest.approx(5 * SQRT2)
    assert cells[0] == (0, 0) and cells[-1] == (5, 5) and len(cells) == 6


def test_around_a_wall_the_octile_length_is_6_plus_4_sqrt2():
    # 7 × 5 cells; a wall in column ix = 3 for iy = 0..3, the gap is cell (3, 4).
    occupied = _free(7, 5)
    occupied[0:4, 3] = True
    # The gap can only be entered from (2, 4) and left to (4, 4): diagonals would cut the
    # corner of (3, 3). (0,0)→(2,4): 2 diagonals + 2 straight = 2√2 + 2; then 2 straight
    # moves through the gap; (4,4)→(6,0): 2√2 + 2 again. Total 6 + 4√2.
    result = astar_cells(occupied, (0, 0), (6, 0))
    assert result is not None
    cells, length = result
    assert length == pytest.approx(6 + 4 * SQRT2)
    assert (3, 4) in cells
    assert not any(occupied[iy, ix] for ix, iy in cells)


def test_smoothed_path_around_a_wall_in_the_arena_matches_the_tangent_construction():
    # A 0.2 m thick wall from the south wall up to y = 2.5, robot inflation 0.25 m. In
    # c-space its top is two quarter-discs of radius r = 0.25 at (∓0.1, 2.5) joined by a
    # 0.2 m segment at y = 2.75. The shortest path from S = (−2, −2) to G = (2, −2) is:
    # tangent S→disc, arc to the top, 0.2 m across, arc, tangent disc→G (symmetric).
    arena = Arena(obstacles=(RectObstacle(-0.1, -3.5, 0.1, 2.5),))
    grid = grid_from_arena(arena, inflation=0.25)
    r = 0.25
    sc = math.hypot(1.9, 4.5)  # |S − C1|, C1 = (−0.1, 2.5)
    tangent = math.sqrt(sc**2 - r**2)
    direction = math.atan2(4.5, 1.9) + math.asin(r / sc)  # heading of the tangent line [rad]
    arc = r * direction  # the path turns from that heading to horizontal (0) on the arc
    expected = 2 * tangent + 0.2 + 2 * arc  # ≈ 10.57 m
    path = plan_path(grid, (-2.0, -2.0), (2.0, -2.0))
    assert expected * 0.99 <= path.length <= expected * 1.03
    assert path.grid_length > path.length  # octile detours are longer than the smoothed path
    for a, b in zip(path.waypoints[:-1], path.waypoints[1:], strict=True):
        assert line_of_sight(grid, a, b[None, :])[0]


def test_no_path_raises_naming_start_and_goal():
    occupied = _free(7, 7)
    occupied[2:5, 2] = occupied[2:5, 4] = True
    occupied[2, 2:5] = occupied[4, 2:5] = True  # a closed box around cell (3, 3)
    grid = grid_from_occupancy(occupied, resolution=1.0)
    with pytest.raises(NoPathError, match=r"no path from \(0\.500, 0\.500\) to \(3\.500, 3\.500\)"):
        plan_path(grid, (0.5, 0.5), (3.5, 3.5))
    assert issubclass(NoPathError, TlfleetError)


def test_no_free_cell_at_all_raises():
    grid = grid_from_occupancy(np.ones((3, 3), dtype=bool), resolution=1.0)
    with pytest.raises(NoPathError, match="no free cell"):
        plan_path(grid, (0.5, 0.5), (2.5, 2.5))


def test_start_inside_an_inflated_obstacle_is_moved_to_the_nearest_free_cell():
    arena = Arena(obstacles=(DiscObstacle((0.0, 0.0), 0.5),))
    grid = grid_from_arena(arena, inflation=0.25)
    start = (0.6, 0.0)  # clearance 0.1 m < 0.25 m
    path = plan_path(grid, start, (2.5, 0.0))
    assert path.start_snapped and not path.goal_snapped
    assert path.waypoints[0].tolist() == list(start)
    assert grid.is_free(path.waypoints[1])
    # The nearest free cell centre lies just beyond 0.75 m from the obstacle centre.
    assert np.linalg.norm(path.waypoints[1] - start) <= 0.15 + 0.05 * SQRT2
    assert path.waypoints[-1].tolist() == [2.5, 0.0]


def test_goal_inside_an_obstacle_is_moved_to_the_nearest_free_cell():
    arena = Arena(obstacles=(DiscObstacle((0.0, 0.0), 0.5),))
    grid = grid_from_arena(arena, inflation=0.25)
    path = plan_path(grid, (-2.5, 0.0), (0.0, 0.0))
    assert path.goal_snapped
    reached = np.array(path.goal)
    assert grid.is_free(reached)
    assert 0.75 <= np.linalg.norm(reached) <= 0.75 + 0.05 * SQRT2
    assert reached[0] < 0  # the side facing the start is the nearest
    assert path.length == pytest.approx(2.5 - np.linalg.norm(reached), abs=0.06)


def _dijkstra_length(blocked: np.ndarray, start, goal) -> float | None:
    """Reference: plain Dijkstra with the same moves (no corner cutting)."""
    ny, nx = blocked.shape
    dist = {start: 0.0}
    heap = [(0.0, start)]
    while heap:
        d, (x, y) = heapq.heappop(heap)
        if (x, y) == goal:
            return d
        if d > dist[(x, y)]:
            continue
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                vx, vy = x + dx, y + dy
                if (dx, dy) == (0, 0) or not (0 <= vx < nx and 0 <= vy < ny) or blocked[vy, vx]:
                    continue
                if dx and dy and (blocked[y, vx] or blocked[vy, x]):
                    continue
                nd = d + (SQRT2 if dx and dy else 1.0)
                if nd < dist.get((vx, vy), math.inf):
                    dist[(vx, vy)] = nd
                    heapq.heappush(heap, (nd, (vx, vy)))
    return None


@settings(max_examples=examples(80))
@given(
    arrays(bool, st.tuples(st.integers(2, 14), st.integers(2, 14)), elements=st.booleans()),
    st.data(),
)
def test_astar_length_equals_dijkstra_on_random_grids(blocked, data):
    ny, nx = blocked.shape
    start = (data.draw(st.integers(0, nx - 1)), data.draw(st.integers(0, ny - 1)))
    goal = (data.draw(st.integers(0, nx - 1)), data.draw(st.integers(0, ny - 1)))
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    expected = _dijkstra_length(blocked, start, goal)
    result = astar_cells(blocked, start, goal)
    if expected is None:
        assert result is None
    else:
        assert result is not None
        assert result[1] == pytest.approx(expected)



def test_distance_is_euclidean_on_the_papers_obstacle_free_arena():
    scenario = scenario3()
    distance = path_length_function(scenario)
    centres = [r.center for r in scenario.regions]
    for p in centres:
        for q in centres:
            assert distance(p, q) == pytest.approx(math.dist(p, q))


def test_distance_goes_around_obstacles_is_symmetric_and_cached(monkeypatch):
    arena = Arena(obstacles=(RectObstacle(-0.1, -3.5, 0.1, 2.5),))
    grid = grid_from_arena(arena, inflation=0.0)
    distance = path_length_function(grid, robot_radius=0.2, margin=0.05)
    calls = []
    real = grid_planner.plan_path
    monkeypatch.setattr(grid_planner, "plan_path", lambda *a, **k: calls.append(a) or real(*a, **k))
    d = distance((-2.0, -2.0, 0.3), (2.0, -2.0))  # poses are accepted, θ ignored
    assert d == pytest.approx(plan_path(grid.inflated(0.25), (-2.0, -2.0), (2.0, -2.0)).length)
    assert d > 4.0 * 2.5
    assert distance((2.0, -2.0), (-2.0, -2.0)) == d
    assert len(calls) == 1
    assert distance((-2.0, -2.0), (-2.0, -2.0)) == 0.0


def test_penalised_edges_add_the_penalty_in_the_blocked_direction_only():
    distance = path_length_function(grid_from_arena(Arena(), inflation=0.25))
    a11, a12 = (-2.0, -2.5), (-2.0, 2.5)
    penalised = grid_planner.with_penalised_edges(distance, [(a11, a12)], penalty=10.0)
    assert penalised(a11, a12) == pytest.approx(15.0)
    assert penalised(a12, a11) == pytest.approx(5.0)
    assert penalised((-2.0, -2.5001), a12) == pytest.approx(15.0, abs=1e-3)  # matched to 1 mm


@settings(max_examples=examples(25), deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(-2.5, 2.5), st.floats(-2.5, 2.5), st.floats(0.1, 0.6)),
        max_size=6,
    ),
    st.tuples(st.floats(-3.2, 3.2), st.floats(-3.2, 3.2)),
    st.tuples(st.floats(-3.2, 3.2), st.floats(-3.2, 3.2)),
)
def test_smoothed_paths_are_collision_free_and_no_longer_than_the_grid_path(discs, start, goal):
    arena = Arena(obstacles=tuple(DiscObstacle((x, y), r) for x, y, r in discs))
    grid = grid_from_arena(arena, inflation=0.25)
    try:
        path = plan_path(grid, start, goal)
    except NoPathError:
        return
    # Shortcutting only shortens the polyline start → cell centres → end (triangle inequality).
    centres = grid.center_of(path.cells)
    legs = np.linalg.norm(centres[0] - start) + np.linalg.norm(centres[-1] - path.goal)
    assert path.length <= path.grid_length + legs + 1e-9
    # Every point of a free cell has clearance ≥ 0.25 − half a cell diagonal; the segments
    # between free cells may graze cell corners, so allow that much: still > the 0.2 m radius.
    free_from = 1 if path.start_snapped else 0  # the escape leg starts inside the inflation
    s = np.linspace(0.0, 1.0, 200)[:, None]
    for a, b in zip(path.waypoints[free_from:-1], path.waypoints[free_from + 1 :], strict=True):
        points = a + s * (b - a)
        assert np.min(arena_clearance(arena, points)) >= 0.25 - 0.05 * SQRT2 / 2 - 1e-9


def test_unreachable_region_is_an_infinite_distance_and_the_planner_names_it():
    """A region walled in by obstacles: no transition to it, so `F a2` is unsatisfiable."""
    from tlfleet.agent.ltl.planner import plan_robot
    from tlfleet.bus.errors import UnsatisfiableTask

    box = (RectObstacle(1.0, 1.0, 3.0, 1.2), RectObstacle(1.0, 2.8, 3.0, 3.0),
           RectObstacle(1.0, 1.0, 1.2, 3.0), RectObstacle(2.8, 1.0, 3.0, 3.0))
    regions = (Region("a1", (-2.0, -2.0)), Region("a2", (2.0, 2.0)))
    robot = Robot(1, "unicycle", (-2.0, -2.0, 0.0), ltl="F a1 & F a2")
    scenario = Scenario("boxed", "f", 10.0, Arena(obstacles=box), regions, (robot,))
    distance = path_length_function(scenario)
    assert distance((-2.0, -2.0), (2.0, 2.0)) == math.inf
    assert distance((-2.0, -2.0), (-2.0, 2.0)) == pytest.approx(4.0)
    with pytest.raises(UnsatisfiableTask, match=r"robot 1: task 'F a1 & F a2' cannot be satisfied"):
        plan_robot(scenario, 1, distance=distance)
