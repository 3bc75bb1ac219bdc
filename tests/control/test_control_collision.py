"""Collision-avoidance term ū_col of paper §III-B (stl-funnel.md §6.2)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from tlfleet.agent.control.collision import CollisionParams, collision_velocity, repulsion_magnitude

PARAMS = CollisionParams(r1=0.6, r_sense=0.7, beta=2.0, max_lin=0.2)


def test_worked_values_of_6_2():
    assert PARAMS.gain == pytest.approx(0.3024, abs=1e-9)
    assert repulsion_magnitude(0.65, PARAMS) == pytest.approx(0.078653, abs=1e-6)
    assert repulsion_magnitude(0.7, PARAMS) == 0.0
    assert repulsion_magnitude(0.6, PARAMS) == pytest.approx(0.2)
    assert repulsion_magnitude(0.3, PARAMS) == 0.2


def test_direction_points_away_and_sums_over_neighbours():
    vx, vy, w = collision_velocity((0.0, 0.0), [(0.5, 0.0)], PARAMS)
    assert (vx, vy, w) == pytest.approx((-0.2, 0.0, 0.0))
    vx, vy, _ = collision_velocity((0.0, 0.0), [(0.5, 0.0), (-0.5, 0.0), (0.0, 0.65)], PARAMS)
    assert (vx, vy) == pytest.approx((0.0, -0.078653), abs=1e-6)
    assert collision_velocity((0.0, 0.0), [(0.0, 0.0), (3.0, 0.0)], PARAMS) == (0.0, 0.0, 0.0)


params = st.builds(lambda r1, gap, u: CollisionParams(r1=r1, r_sense=r1 + gap, max_lin=u),
                   st.floats(0.1, 1.0), st.floats(0.01, 0.5), st.floats(0.05, 1.0))


@given(p=params, eps=st.floats(1e-12, 1e-7))
def test_continuous_at_r1(p, eps):
    below = repulsion_magnitude(p.r1 - eps, p)
    above = repulsion_magnitude(p.r1 + eps, p)
    assert below == p.max_lin
    # the k-branch has slope −u/(R − R1) − 3u/R1 at R1: the jump over 2·eps is bounded by it
    slope = p.max_lin / (p.r_sense - p.r1) + 3 * p.max_lin / p.r1
    assert abs(above - below) <= 2 * eps * slope + 1e-12


# offsets of at least 1 nm (or exactly 0): below, positions are subnormal floats whose direction
# is not representable at all
@given(p=params, d=st.one_of(st.just(0.0), st.floats(1e-9, 10.0)), angle=st.floats(0, 2 * math.pi))
def test_zero_beyond_r_and_bounded_inside(p, d, angle):
    z_j = (d * math.cos(angle), d * math.sin(angle))
    vx, vy, w = collision_velocity((0.0, 0.0), [z_j], p)
    assert w == 0.0
    if d > p.r_sense:
        assert (vx, vy) == (0.0, 0.0)
    elif d > 0:
        assert math.hypot(vx, vy) <= p.max_lin * (1 + 1e-9)
        assert vx * z_j[0] + vy * z_j[1] <= 1e-15  # pushes away from the neighbour


@given(p=params, d=st.floats(0.0, 2.0))
def test_magnitude_is_non_increasing_in_distance(p, d):
    assert repulsion_magnitude(d, p) >= repulsion_magnitude(d + 1e-3, p) - 1e-12


coords = st.floats(-3.0, 3.0)


@given(p=params, own=st.tuples(coords, coords),
       others=st.lists(st.tuples(coords, coords, st.floats(-math.pi, math.pi)), max_size=8))
def test_poses_with_the_own_one_among_them_give_the_same_sum(p, own, others):
    """The agent passes every pose of the frame, its own included, as (x, y, θ) (no
    per-tick list of the others): the own pose is at distance 0 and adds nothing, θ is not read,
    and the sum is the same to the last bit as over the others' (x, y)."""
    positions = [(x, y) for x, y, _ in others]
    expected = collision_velocity(own, positions, p)
    with_own = [*others[:len(others) // 2], (*own, 0.3), *others[len(others) // 2:]]
    assert collision_velocity(own, with_own, p) == expected
