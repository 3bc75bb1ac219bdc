"""Occupancy grid: layout, exact clearance, inflation, stamping other robots, distance transform."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from hypothesis_budget import examples
from tlfleet.agent.model.scenario import Arena, DiscObstacle, RectObstacle, Region, Robot, Scenario
from tlfleet.agent.nav.grid import (
    arena_clearance,
    euclidean_distance_transform,
    grid_from_arena,
    grid_from_occupancy,
    grid_from_scenario,
)


def test_paper_arena_is_140_by_140_cells_with_origin_at_the_corner():
    grid = grid_from_arena(Arena(), inflation=0.25)
    assert grid.shape == (140, 140)
    assert grid.origin == (-3.5, -3.5)
    assert grid.extent == pytest.approx((-3.5, 3.5, -3.5, 3.5))


@pytest.mark.parametrize(
    ("point", "expected"),
    [
        ((0.0, 0.0), 3.5),  # centre: 3.5 m to every wall
        ((-3.0, 0.5), 0.5),  # 0.5 m from the west wall
        ((2.0, 3.2), 0.3),  # 0.3 m from the north wall
        ((-3.6, 0.0), -0.1),  # outside the arena: negative
    ],
)
def test_wall_clearance_is_the_distance_to_the_nearest_wall(point, expected):
    assert float(arena_clearance(Arena(), np.array(point))) == pytest.approx(expected)


def test_obstacle_clearance_is_exact_for_rectangles_and_discs():
    arena = Arena(obstacles=(RectObstacle(0.0, 0.0, 1.0, 1.0), DiscObstacle((-2.0, -2.0), 0.5)))
    pts = np.array([[2.0, 0.5], [2.0, 2.0], [0.5, 0.5], [-2.0, -1.0], [-2.0, -2.0]])
    # right of the box by 1; off its corner by √2; inside it 0.5 from every side;
    # 1 m from the disc centre (0.5 from its surface); at the disc centre (−0.5).
    expected = [1.0, math.sqrt(2.0), -0.5, 0.5, -0.5]
    assert arena_clearance(arena, pts) == pytest.approx(expected)


def test_blocked_cells_are_those_closer_than_the_inflation_radius():
    grid = grid_from_arena(Arena(), inflation=0.25)
    res = grid.resolution
    # Column of cells along y = 0: centres at x = -3.475, -3.425, ...; blocked iff x < -3.25.
    row = grid.blocked[70]
    centres_x = -3.5 + (np.arange(140) + 0.5) * res
    assert np.array_equal(row, (centres_x < -3.25) | (centres_x > 3.25))
    assert not grid.is_free(np.array([-3.3, 0.0]))
    assert grid.is_free(np.array([-3.2, 0.0]))
    assert not grid.is_free(np.array([5.0, 0.0]))  # off the grid


def test_grid_from_scenario_inflates_by_robot_radius_plus_margin():
    scenario = Scenario(
        name="s",
        fleet="f",
        duration=1.0,
        arena=Arena(),
        regions=(Region("a", (0.0, 0.0)),),
        robots=(Robot(1, "unicycle", (0.0, 0.0, 0.0), radius=0.3, ltl="F a"),),
    )
    grid = grid_from_scenario(scenario, margin=0.1)
    assert grid.inflation == pytest.approx(0.4)


def test_with_discs_blocks_inflated_discs_and_leaves_the_original_untouched():
    grid = grid_from_arena(Arena(), inflation=0.25)
    stamped = grid.with_discs(np.array([[1.0, 1.0]]), [0.2])
    assert not stamped.is_free(np.array([1.0, 1.0]))
    assert not stamped.is_free(np.array([1.4, 1.0]))  # 0.4 < 0.2 + 0.25
    assert stamped.is_free(np.array([1.5, 1.0]))  # 0.5 > 0.45
    assert float(stamped.clearance_at(np.array([1.6, 1.0]))) == pytest.approx(0.4, abs=0.04)
    assert grid.is_free(np.array([1.0, 1.0]))
    assert grid.with_discs(np.zeros((0, 2)), []) is grid



@pytest.mark.parametrize("seed", range(4))
def test_with_disc_blocks_blocks_exactly_the_cells_with_discs_blocks(seed):
    """The planning stamp (windows around each disc) against the whole-grid stamp, cell for
    cell: discs inside, at the edge of and beyond the grid, overlapping, of zero radius."""
    rng = np.random.default_rng(seed)
    grid = grid_from_arena(Arena(), inflation=0.25)
    for _ in range(40):
        k = int(rng.integers(1, 9))
        centers = rng.uniform(-4.2, 4.2, size=(k, 2))
        radii = rng.choice([0.0, 0.05, 0.2, 0.45, 1.2], size=k)
        whole = grid.with_discs(centers, radii)
        windows = grid.with_disc_blocks(centers, radii)
        assert np.array_equal(windows.blocked, whole.blocked)
        assert np.array_equal(windows.occupied, whole.occupied)
        assert windows.clearance is grid.clearance  # the static layer, as documented
    assert grid.with_disc_blocks(np.zeros((0, 2)), []) is grid
    stamped = grid.with_disc_blocks([[0.025, 0.025]], [0.1])
    assert not grid.blocked[70, 70] and stamped.blocked[70, 70]

def test_cell_centre_round_trip():
    grid = grid_from_arena(Arena(), inflation=0.0)
    cells = np.array([[0, 0], [139, 139], [70, 12]])
    assert np.array_equal(grid.cell_of(grid.center_of(cells)), cells)
    assert grid.center_of(np.array([0, 0])) == pytest.approx([-3.475, -3.475])


def _brute_force_edt(occupied: np.ndarray) -> np.ndarray:
    iy, ix = np.nonzero(occupied)
    yy, xx = np.mgrid[0 : occupied.shape[0], 0 : occupied.shape[1]]
    d2 = (yy[..., None] - iy) ** 2 + (xx[..., None] - ix) ** 2
    return np.sqrt(d2.min(axis=-1))


@settings(max_examples=examples(60))
@given(arrays(bool, st.tuples(st.integers(1, 12), st.integers(1, 12))))
def test_distance_transform_matches_brute_force(occupied):
    if not occupied.any():
        assert np.all(np.isinf(euclidean_distance_transform(occupied)))
        return
    assert euclidean_distance_transform(occupied) == pytest.approx(_brute_force_edt(occupied))


def test_hand_made_grid_blocks_exactly_the_occupied_cells_without_inflation():
    occupied = np.zeros((5, 6), dtype=bool)
    occupied[2, 3] = True
    grid = grid_from_occupancy(occupied, resolution=1.0)
    assert np.array_equal(grid.blocked, occupied)
    # Cell (ix=0, iy=2) is 3 cells from the obstacle centre and 1 cell from the border wall.
    assert grid.clearance[2, 0] == pytest.approx(0.5)
    assert grid.clearance[2, 3] == pytest.approx(-0.5)
    assert grid.inflated(1.0).blocked[2, 2]


def test_coordinate_and_point_lookups_equal_clearance_at():
    """The DWA's lookups on coordinate arrays and on one point read the same cells and
    values as ``clearance_at`` — on the grid, on cell borders and off it."""
    grid = grid_from_arena(Arena(obstacles=(RectObstacle(-0.1, -3.5, 0.1, 1.0),)), 0.3)
    rng = np.random.default_rng(7)
    ox, _oy = grid.origin
    xmin, xmax, ymin, ymax = grid.extent
    border = np.array([ox + k * grid.resolution for k in range(0, 141, 7)])
    x = np.concatenate([rng.uniform(xmin - 1, xmax + 1, 399), border, [xmin, xmax]])
    y = np.concatenate([rng.uniform(ymin - 1, ymax + 1, 399), border[::-1], [ymax, ymin]])
    expected = grid.clearance_at(np.stack([x, y], axis=-1))
    assert np.array_equal(grid.clearance_xy(x, y), expected)
    assert np.array_equal(grid.clearance_xy(x.reshape(-1, 2), y.reshape(-1, 2)),
                          expected.reshape(-1, 2))
    points = zip(x, y, strict=True)
    assert [grid.clearance_point(float(a), float(b)) for a, b in points] == list(expected)
    assert (expected == -grid.resolution).any() and (expected > 0).any()
    # the planner's one-point lookups
    cells = grid.cell_of(np.stack([x, y], axis=-1))
    free = grid.is_free(np.stack([x, y], axis=-1))
    for k, (a, b) in enumerate(zip(x.tolist(), y.tolist(), strict=True)):
        assert grid.cell_of_point(a, b) == tuple(cells[k]) and grid.is_free_point(a, b) == free[k]
    assert free.any() and not free.all()
    # the DWA's promise that every point lies within reach of a centre: the same values whether
    # the disc lies inside the grid (the test is skipped) or crosses its edge (it is not)
    for cx, cy in ((0.0, 0.0), (2.9, -2.9), (3.4, 0.0)):
        px, py = cx + rng.uniform(-0.5, 0.5, 200), cy + rng.uniform(-0.5, 0.5, 200)
        inside_reach = np.hypot(px - cx, py - cy) <= 0.5
        px, py = px[inside_reach], py[inside_reach]
        assert np.array_equal(grid.clearance_xy(px, py, within=(cx, cy, 0.5)),
                              grid.clearance_at(np.stack([px, py], axis=-1)))
