"""Right of way (docs/ltl-navigation.md §6): who yields in a narrow passage and at a crossing —
the rule's decisions, that two robots applying it never both wait or both go, and closed loops
on the harness (a head-on swap through a 1 m corridor, three robots crossing a hall's centre)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from nav_harness import SimRobot, simulate
from tlfleet.agent.model.scenario import Arena, RectObstacle, Region, Robot, Scenario
from tlfleet.agent.nav.grid import grid_from_arena
from tlfleet.agent.nav.polyline import distance_to_polyline
from tlfleet.agent.nav.traffic import (
    Traffic,
    TrafficConfig,
    crossing_conflict,
    narrow_conflict,
    refuge,
)
from tlfleet.agent.policy.ltl import LtlAgent, LtlStepInput

CORRIDOR = Arena(xmin=-4.5, xmax=4.5, ymin=-2.5, ymax=2.5,
                 obstacles=(RectObstacle(-1.5, 0.5, 1.5, 2.5), RectObstacle(-1.5, -2.5, 1.5, -0.5)))
GRID = grid_from_arena(CORRIDOR, 0.25)
RULE = TrafficConfig()
EAST = [[-3.5, 0.0], [3.5, 0.0]]  # a path through the corridor, west to east
WEST = [[3.5, 0.0], [-3.5, 0.0]]


def _traffic(rows, ruled=True) -> Traffic:
    """rows: (id, x, y, vx, vy)."""
    a = np.array(rows, dtype=float).reshape(-1, 5)
    return Traffic.of(a[:, 0].astype(np.int64), a[:, 1:3], a[:, 3:5], np.full(len(a), 0.2),
                      np.full(len(a), ruled, dtype=bool))


def _ahead(path, position):
    """The path from ``position`` on (as the executor hands it over)."""
    return [list(position), *path[1:]]


@pytest.mark.parametrize(("me", "other", "i_yield"), [
    (1, 2, False),  # both outside, at the two mouths: the lower id goes
    (2, 1, True),
])
def test_both_outside_the_lower_id_goes(me, other, i_yield):
    mine = (-2.4, 0.0)  # 0.9 m before the narrow stretch (it begins near x = -1.99)
    theirs = (2.4, 0.0)
    got = narrow_conflict(me, mine, 0.2, _ahead(EAST, mine), GRID,
                          _traffic([(other, *theirs, -0.2, 0.0)]), RULE)
    assert (got == other) is i_yield
    back = narrow_conflict(other, theirs, 0.2, _ahead(WEST, theirs), GRID,
                           _traffic([(me, *mine, 0.2, 0.0)]), RULE)
    assert (back == me) is (not i_yield)  # never both wait, never both go


def test_the_robot_inside_the_passage_has_the_right_of_way_whatever_its_id():
    inside, outside = (0.5, 0.0), (-2.4, 0.0)  # robot 5 in the corridor, robot 1 at a mouth
    assert narrow_conflict(1, outside, 0.2, _ahead(EAST, outside), GRID,
                           _traffic([(5, *inside, -0.25, 0.0)]), RULE) == 5
    assert narrow_conflict(5, inside, 0.2, _ahead(WEST, inside), GRID,
                           _traffic([(1, *outside, 0.0, 0.0)]), RULE) is None


def test_a_robot_going_our_way_is_followed_and_a_robot_that_applies_no_rule_is_let_pass():
    me = (-2.4, 0.0)
    ahead_same_way = _traffic([(2, 0.0, 0.0, 0.25, 0.0)])  # in the corridor, heading east
    assert narrow_conflict(1, me, 0.2, _ahead(EAST, me), GRID, ahead_same_way, RULE) is None
    stl_robot = _traffic([(7, 2.4, 0.0, -0.2, 0.0)], ruled=False)  # at the far mouth
    assert narrow_conflict(1, me, 0.2, _ahead(EAST, me), GRID, stl_robot, RULE) == 7


def test_no_conflict_in_the_open_or_far_from_the_passage():
    open_grid = grid_from_arena(Arena(), 0.25)
    me = (-2.0, 0.0)
    oncoming = _traffic([(2, 1.0, 0.0, -0.3, 0.0)])
    assert narrow_conflict(2 + 1, me, 0.2, _ahead(EAST, me), open_grid, oncoming, RULE) is None
    far = (-4.2, 0.0)  # 2.2 m before the stretch: not yet concerned
    assert narrow_conflict(3, far, 0.2, _ahead(EAST, far), GRID, oncoming, RULE) is None


def test_at_a_crossing_only_the_higher_ids_wait_so_no_cycle_of_waiting_robots_forms():
    # three robots heading for the origin from 120° apart, 2 m out, at 0.25 m/s
    rng = np.random.default_rng(0)
    for _ in range(20):
        angles = rng.uniform(0, 2 * math.pi) + np.array([0.0, 2.1, 4.2])
        ids = rng.permutation([1, 2, 3])
        pos = 2.0 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
        vel = -0.25 * pos / 2.0
        waits = {}
        for k in range(3):
            rows = [(ids[j], *pos[j], *vel[j]) for j in range(3) if j != k]
            waits[int(ids[k])] = crossing_conflict(int(ids[k]), pos[k], 0.2, (0.0, 0.0),
                                                   _traffic(rows), RULE)
        assert waits[1] is None  # the lowest id never waits
        for me, other in waits.items():
            assert other is None or other < me  # only for a lower id: the order is total


def test_a_refuge_is_off_the_path_free_and_near():
    me = (-2.4, 0.0)
    spot = refuge(me, _ahead(EAST, me), GRID, 0.2, 0.2, RULE)
    assert spot is not None
    need = 0.2 + 0.2 + 2 * RULE.passing_margin + RULE.refuge_gap
    assert distance_to_polyline(np.array([spot]), np.array(_ahead(EAST, me)))[0] >= need - 1e-9
    assert GRID.clearance_at(np.array(spot)) >= 0.2 + RULE.passing_margin
    assert math.dist(spot, me) <= RULE.refuge_reach + 1e-9


# ----------------------------------------------------------------------------- closed loops

def _fleet(scenario: Scenario, duration: float):
    ids = [r.id for r in scenario.robots]
    agents = {r.id: LtlAgent(scenario, r.id) for r in scenario.robots}
    states = {j: a.initial_state(a.plan())[0] for j, a in agents.items()}
    notices = {j: [] for j in ids}

    def controller(j):
        def step(t, i, poses):
            frame = np.hstack([np.asarray(ids, dtype=float)[:, None], poses])
            states[j], out = agents[j].step(states[j], LtlStepInput(
                t, tuple(poses[i]), np.delete(frame, i, axis=0)))
            states[j] = agents[j].after_command(states[j])
            notices[j] += out.notices
            return out.u
        return step

    result = simulate([SimRobot(r.pose, r.radius) for r in scenario.robots],
                      [controller(j) for j in ids], duration, scenario.arena)
    return result, notices


def _standstills(result, robot: int, until: float, window: float = 5.0) -> list[float]:
    """Lengths [s] of the episodes before ``until`` [s] in which the robot moved < 5 cm over
    ``window`` seconds."""
    keep = result.times <= until
    t, p = result.times[keep], result.poses[keep, robot, :2]
    n = round(window / (t[1] - t[0]))
    still = np.hypot(*(p[n:] - p[:-n]).T) < 0.05
    runs = [len(list(g)) for k, g in itertools.groupby(still) if k]
    return [(r + n) * (t[1] - t[0]) for r in runs]


def test_two_robots_swap_rooms_through_a_1_m_corridor():
    regions = (Region("west", (-3.8, 0.0), 0.3), Region("east", (3.8, 0.0), 0.3))
    robots = (Robot(1, "unicycle", (-3.0, 0.0, 0.0), ltl="F G east"),
              Robot(2, "unicycle", (3.0, 0.0, math.pi), ltl="F G west"))
    result, notices = _fleet(Scenario("swap", "swap", 60.0, CORRIDOR, regions, robots), 60.0)
    assert result.contacts == ()
    for j, target in ((1, "east"), (2, "west")):
        kinds = [(n.kind, n.data.get("region")) for n in notices[j]]
        assert ("plan_finished", target) in kinds, kinds
        assert "stuck" not in [k for k, _ in kinds]
    yields = {j: [n for n in notices[j] if n.kind == "yield"] for j in (1, 2)}
    assert not yields[1] and [n.data["state"] for n in yields[2]] == ["begin", "end"]
    begin, end = (n.t for n in yields[2])
    assert end - begin <= RULE.max_wait + 0.2
    # standing still (before its plan finished) only while yielding, no longer than allowed
    done = {j: next(n.t for n in notices[j] if n.kind == "plan_finished") for j in (1, 2)}
    assert _standstills(result, 0, done[1]) == []  # robot 1 (index 0)
    assert max(_standstills(result, 1, done[2]), default=0.0) <= RULE.max_wait  # robot 2


def test_three_robots_crossing_a_hall_centre_keep_apart_and_keep_cycling():
    regions = (Region("p1", (-3.0, 0.0), 0.3), Region("q1", (3.0, 0.0), 0.3),
               Region("p2", (-1.5, -2.6), 0.3), Region("q2", (1.5, 2.6), 0.3),
               Region("p3", (-1.5, 2.6), 0.3), Region("q3", (1.5, -2.6), 0.3))
    robots = (Robot(1, "unicycle", (-3.0, 0.0, 0.0), ltl="G F p1 & G F q1"),
              Robot(2, "unicycle", (1.5, 2.6, -2.09), ltl="G F p2 & G F q2"),
              Robot(3, "unicycle", (1.5, -2.6, 2.09), ltl="G F p3 & G F q3"))
    hall = Arena(xmin=-4.0, xmax=4.0, ymin=-3.5, ymax=3.5)
    result, notices = _fleet(Scenario("hall", "hall", 90.0, hall, regions, robots), 90.0)
    assert result.contacts == ()
    assert result.min_robot_gap > 0.05
    for j in (1, 2, 3):
        kinds = [n.kind for n in notices[j]]
        word = [n.data["region"] for n in notices[j] if n.kind == "region_visited"]
        assert len(word) >= 4 and all(a != b for a, b in itertools.pairwise(word))
        assert "stuck" not in kinds and "unplanned_region" not in kinds
    assert any(n.kind == "yield" for j in (2, 3) for n in notices[j])
    assert not any(n.kind == "yield" for n in notices[1])  # robot 1 never waits
