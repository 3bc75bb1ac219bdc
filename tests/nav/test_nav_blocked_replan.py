"""No navigation deadlock: a robot blocked by another robot re-plans around it."""

from __future__ import annotations

import numpy as np
from tlfleet.agent.model.scenario import Arena, Region
from tlfleet.agent.nav.executor import Executor, ExecutorConfig, ExecutorInputs
from tlfleet.agent.nav.grid import grid_from_arena
from tlfleet.agent.nav.polyline import distance_to_polyline

CONFIG = ExecutorConfig()
REGIONS = (Region("a1", (2.0, 0.0), 0.25, frozenset({"a1"})),)
GRID = grid_from_arena(Arena(), CONFIG.robot_radius + CONFIG.inflation_margin, CONFIG.resolution)


def test_after_blocked_after_without_progress_the_path_avoids_robots_at_full_size():
    executor = Executor(REGIONS, GRID, CONFIG, robot_id=1)
    state = executor.initial_state(("a1",), ("a1",))
    blocker = np.array([[2, 0.55, 0.0, 0.0]])  # sits on the straight line, 0.55 m ahead
    pose = (0.0, 0.0, 0.0)
    period = CONFIG.dwa.controller_period
    flags = []
    for k in range(int(7.0 / period)):
        # the robot does not move (it is blocked): no progress
        state, out = executor.step(state, ExecutorInputs(k * period, pose, blocker))
        flags.append((k * period, state.blocked_plan, out.path.copy()))
    before = [f for t, f, _ in flags if t < CONFIG.blocked_after - 1e-9]
    after = [(f, path) for t, f, path in flags if t >= CONFIG.blocked_after + period]
    assert not any(before)
    assert after and all(f for f, _ in after)
    # past the escape leg from the start (which the planner snaps out of the disc), the path
    # keeps the blocker's full radius r + margin plus the grid's inflation, less one cell
    normal = [path for t, f, path in flags if t < CONFIG.blocked_after - 1e-9][-1]
    path = after[-1][1]
    full = 0.2 + CONFIG.other_robot_margin + GRID.inflation - GRID.resolution
    assert float(distance_to_polyline(blocker[:, 1:3], path[1:])[0]) >= full
    assert float(distance_to_polyline(blocker[:, 1:3], normal[1:])[0]) < full
    # with progress (the blocker gone) the executor plans normally again: the step defers the
    # periodic re-plan (it still follows the blocked path), refresh (after the command) runs it
    state, out = executor.step(state, ExecutorInputs(7.2, (0.5, 0.0, 0.0), np.zeros((0, 4))))
    assert state.pending is not None and not state.pending.blocked and state.blocked_plan
    state = executor.refresh(state)
    assert state.pending is None and not state.blocked_plan
