"""Minimal times over the arena: from a pose to where ψ holds, and from one sub-task to the next
(docs/stl-saturation.md §1, §6.2, §6.3). Shared by the STL agents (the funnel's rate and the
look-ahead deadline) and ``tlfleet check`` (sequences infeasible at the speed limit).

The bound of separate conjuncts (``tlfleet.agent.stl.timing.minimal_time``) misses that conjuncts
on different axes must be met *at once*: ``x1 >= 1.5 & y1 >= 0.5`` from 3.5 m and 2.5 m away needs
‖(3.5, 2.5)‖ = 4.3 m of driving, not 3.5 m. Here the robot's positions are a grid over its
workspace (the arena minus the walls' and obstacles' clearance), and the set S_ℓ(ψ) where every
conjunct of ψ that does not involve the robot's own heading is ≥ ℓ (the others where they are)
is a mask on it; the straight-line distance d(z, S) from each cell (the exact Euclidean distance
transform of ``tlfleet.agent.nav.grid``) over u_max,lin is the time to get there, obstacles
ignored (a lower bound, less one grid spacing for the discretisation). Headings turn at
u_max,ang and are left to the conjunct bound.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from tlfleet.agent.model.scenario import Arena
from tlfleet.agent.nav.grid import arena_clearance, euclidean_distance_transform
from tlfleet.agent.stl.evaluate import evaluate_array
from tlfleet.agent.stl.syntax import Not, StateVar, literals, predicate_function
from tlfleet.agent.stl.task import Task
from tlfleet.agent.stl.timing import conjunct_rates, minimal_time

SPACING = 0.05  # [m]


@dataclass(frozen=True, eq=False)
class PositionGrid:
    """Cell centres ``points`` (ny, nx, 2) [m] at ``spacing`` [m]; ``free``: those the robot's
    centre can take (at least ``clearance`` [m] from every wall and obstacle)."""

    points: np.ndarray
    free: np.ndarray
    spacing: float


def position_grid(arena: Arena, clearance: float, spacing: float = SPACING) -> PositionGrid:
    xs = np.arange(arena.xmin + spacing / 2, arena.xmax, spacing)
    ys = np.arange(arena.ymin + spacing / 2, arena.ymax, spacing)
    points = np.stack(np.meshgrid(xs, ys), axis=-1)
    return PositionGrid(points, arena_clearance(arena, points) >= clearance, spacing)


def uses_heading(node, robot: int) -> bool:
    """Whether robot ``robot``'s heading θ enters an expression or literal."""
    if isinstance(node, StateVar):
        return node.robot == robot and node.component == "th"
    for name in getattr(node, "__dataclass_fields__", {}):
        value = getattr(node, name)
        items = value if isinstance(value, tuple) else (value,)
        if any(hasattr(item, "__dataclass_fields__") and uses_heading(item, robot)
               for item in items):
            return True
    return False


def held(task: Task, robot: int, grid: PositionGrid, poses: Mapping[int, Sequence[float]],
         level: float) -> np.ndarray:
    """Mask (ny, nx) of the free cells where every conjunct of ``task`` not involving robot
    ``robot``'s heading is ≥ ``level`` with robot ``robot`` there (the others at ``poses``)."""
    ny, nx = grid.free.shape
    flat = grid.points.reshape(-1, 2)
    states = {j: np.tile(np.asarray(poses[j], dtype=float)[:3], (len(flat), 1))
              for j in task.participants if j != robot}
    states[robot] = np.column_stack([flat, np.zeros(len(flat))])
    mask = grid.free.copy()
    for literal in literals(task.psi):
        if uses_heading(literal, robot):
            continue
        pred = literal.pred if isinstance(literal, Not) else literal
        value = np.broadcast_to(np.asarray(evaluate_array(predicate_function(pred), states),
                                           dtype=float), (len(flat),)).reshape(ny, nx)
        mask &= (-value if isinstance(literal, Not) else value) >= level
    return mask


def time_field(grid: PositionGrid, mask: np.ndarray, max_lin: float) -> np.ndarray:
    """(d(z, S) − spacing)⁺/u_max,lin [s] for every cell z, S the cells of ``mask`` (inf
    everywhere when S is empty)."""
    if not mask.any():
        return np.full(mask.shape, np.inf)
    d = euclidean_distance_transform(mask) * grid.spacing
    return np.maximum(d - grid.spacing, 0.0) / max_lin


def reach_time(task: Task, robot: int, poses: Mapping[int, Sequence[float]], grid: PositionGrid,
               level: float, max_lin: float, max_ang: float, smooth: float = 0.0) -> float:
    """The minimal-time bound [s] for robot ``robot`` at ``poses[robot]`` to bring every
    conjunct of ``task`` to ``level`` + ``smooth``: the longer of the separate conjuncts' bound
    and the straight-line distance to the set where the positional ones hold at once."""
    rates = conjunct_rates(task, task.stacked_state(poses), robot, max_lin, max_ang)
    separate = minimal_time(rates, level, smooth=smooth)
    mask = held(task, robot, grid, poses, level + smooth)
    if not mask.any():
        return math.inf if separate == 0.0 else separate
    x, y = poses[robot][0], poses[robot][1]
    cells = grid.points[mask]
    d = float(np.min(np.hypot(cells[:, 0] - x, cells[:, 1] - y)))
    return max(separate, max(d - grid.spacing, 0.0) / max_lin)


def transfer_time(before: Task, after: Task, robot: int, poses: Mapping[int, Sequence[float]],
                  grid: PositionGrid, max_lin: float, level_before: float = 0.0,
                  level_after: float = 0.0) -> float:
    """The minimal-time bound [s] from the best cell where ψ_before is at ``level_before`` to one
    where ψ_after is at ``level_after`` (module docstring); inf when either set is empty."""
    start = held(before, robot, grid, poses, level_before)
    if not start.any():
        return math.inf
    field = time_field(grid, held(after, robot, grid, poses, level_after), max_lin)
    return float(field[start].min())


@dataclass(frozen=True)
class Infeasible:
    """Sub-task ``to`` of a sequence cannot be met at the speed limit: from the start pose
    (``source`` = -1) or from where sub-task ``source`` can end (at ``t_from`` [s] or later), the
    minimal-time bound is ``needed`` [s], but it must be met by ``due`` [s] (a for G, b for F)."""

    source: int
    to: int
    t_from: float
    needed: float
    due: float


def sequence_infeasibilities(tasks: Sequence[Task], robot: int,
                             poses: Mapping[int, Sequence[float]], grid: PositionGrid,
                             max_lin: float, max_ang: float,
                             forced: Sequence[float] | None = None) -> list[Infeasible]:
    """Where robot ``robot``'s sequence of sub-tasks is infeasible at its speed limits by the
    minimal-time bound with level 0 (docs/stl-saturation.md §6.3): the first sub-task from the
    start pose; sub-task k+1 from the best cell where ψ_k holds at the earliest time sub-task k
    can end (F: max(a, arrival), G: b; ``forced`` phase starts respected), the other robots at
    ``poses``. Lower bounds all through, so a warning means the sequence cannot be met."""
    out: list[Infeasible] = []
    if not tasks:
        return out
    first = tasks[0]
    need = reach_time(first, robot, poses, grid, 0.0, max_lin, max_ang)
    due = first.a if first.kind == "G" else first.b
    if need > due + 1e-9:
        out.append(Infeasible(-1, 0, 0.0, need, due))
    end = first.b if first.kind == "G" else max(first.a, min(need, first.b))
    for k in range(len(tasks) - 1):
        after = tasks[k + 1]
        start = end if forced is None else max(end, forced[k])
        travel = transfer_time(tasks[k], after, robot, poses, grid, max_lin)
        due = after.a if after.kind == "G" else after.b
        if math.isfinite(travel) and start + travel > due + 1e-9:
            out.append(Infeasible(k, k + 1, start, travel, due))
        arrival = start + (travel if math.isfinite(travel) else 0.0)
        end = after.b if after.kind == "G" else max(after.a, min(arrival, after.b))
    return out
