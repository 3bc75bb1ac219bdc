"""Hypothesis properties of the world: angles wrap into (−π, π], clipped commands respect the
limits, and whatever the commands, robots stay in the arena and do not pass through each other."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from sim_helpers import distance, omni, scenario, unicycle
from tlfleet.agent.model.scenario import Arena
from tlfleet.sim.world import World, wrap_angle

finite = st.floats(-1e6, 1e6, allow_nan=False)
speed = st.floats(-3.0, 3.0, allow_nan=False)


@given(finite)
def test_wrap_angle_is_in_range_and_equivalent(theta):
    wrapped = wrap_angle(theta)
    assert -math.pi < wrapped <= math.pi
    assert math.isclose(math.cos(wrapped), math.cos(theta), abs_tol=1e-9)
    assert math.isclose(math.sin(wrapped), math.sin(theta), abs_tol=1e-9)


@given(st.tuples(finite, finite, finite), st.tuples(finite, finite))
def test_clipped_commands_respect_the_limits(u_omni, u_uni):
    w = World.from_scenario(
        scenario(omni(1, 0, 0, max_lin=0.2, max_ang=6.28), unicycle(2, 1, 1, max_v=0.3,
                                                                    max_omega=1.0)),
        np.random.default_rng(0))
    vx, vy, om = w.robots[1].clipped(u_omni)
    assert math.hypot(vx, vy) <= 0.2 and abs(om) <= 6.28
    if math.hypot(*u_omni[:2]) > 0:  # direction kept
        assert vx * u_omni[1] - vy * u_omni[0] <= 1e-9 * math.hypot(*u_omni[:2])
    assert w.robots[1].clipped((vx, vy, om)) == (vx, vy, om)  # idempotent
    v, om2 = w.robots[2].clipped(u_uni)
    assert abs(v) <= 0.3 and abs(om2) <= 1.0


commands = st.lists(st.tuples(speed, speed, speed, speed), min_size=1, max_size=5)


@settings(max_examples=examples(25), deadline=None)
@given(commands, st.integers(0, 2**32 - 1))
def test_robots_stay_in_the_arena_and_apart(plan, seed):
    arena = Arena(-1.0, 1.0, -1.0, 1.0)  # small: walls and each other are hit often
    robots = (omni(1, -0.5, 0.0, max_lin=1.5), omni(2, 0.5, 0.0, max_lin=1.5),
              unicycle(3, 0.0, 0.5, max_v=1.5, max_omega=3.0))
    w = World.from_scenario(scenario(*robots, arena=arena, disturbance=0.1),
                            np.random.default_rng(seed))
    slack = 0.01  # [m] collision slop and one physics step at ≤ 1.6 m/s
    for k, (a, b, c, d) in enumerate(plan):
        w.set_command(1, (a, b, c), t=0.2 * k)
        w.set_command(2, (-b, a, d), t=0.2 * k)
        w.set_command(3, (c, d), t=0.2 * k)
        for _ in range(20):
            w.step(0.01)
            poses = w.poses()
            for _, x, y, _ in poses:
                assert -1.0 + 0.2 - slack <= x <= 1.0 - 0.2 + slack
                assert -1.0 + 0.2 - slack <= y <= 1.0 - 0.2 + slack
            for i in range(3):
                for j in range(i + 1, 3):
                    assert distance(poses[i][1:], poses[j][1:]) >= 0.4 - slack
