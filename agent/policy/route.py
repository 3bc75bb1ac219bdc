"""Routes around obstacles for an STL robot whose goal is out of sight (docs/stl-saturation.md §8).

The funnel law (paper eq. (5)) drives robot i along ∂ρ^ψ/∂z_i; when the straight line to the
sub-task's goal point g (the own position that maximises ρ^ψ, ``tlfleet.agent.stl.supremum``)
crosses an obstacle, that direction ends at the obstacle, where eq. (6)'s repulsion and the
funnel's pull cancel: the robot stops at the wall until the window is over. Here the grid
planner of the LTL robots (``tlfleet.agent.nav.grid_planner``: A* on the arena grid inflated by the
robot's body and the wall term's outer radius, line-of-sight smoothing) gives waypoints
w_1, …, w_n = g, and the funnel controls the *route robustness*

    ρ̃(x̄) = ρ^ψ(x̄) − (L(z_i) − ‖z_i − g‖),      L(z_i) = ‖z_i − w_1‖ + Σ_{k≥1} ‖w_k − w_{k+1}‖

(L is the length left along the route; L ≥ ‖z_i − g‖ by the triangle inequality, so ρ̃ ≤ ρ^ψ and
a funnel guarantee ρ̃ > r carries over to ρ^ψ). Its gradient in z_i is
∂ρ^ψ/∂z_i − (z_i − w_1)/‖z_i − w_1‖ + (z_i − g)/‖z_i − g‖: for a reach c − ‖z_i − g‖ exactly the
unit vector towards the next waypoint, and ρ̃ = c − L rises at the robot's speed along the route,
so the saturation-aware funnel (docs/stl-saturation.md §3) is planned with the route's length.
A waypoint is dropped once the robot is within ``reach`` of it; with g alone left the penalty is
0 and ρ̃ = ρ^ψ. Pure: numbers in, numbers out; the grids are built once per robot.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from tlfleet.agent.model.scenario import Arena
from tlfleet.agent.nav.errors import NoPathError
from tlfleet.agent.nav.grid import OccupancyGrid, grid_from_arena
from tlfleet.agent.nav.grid_planner import line_of_sight, plan_path


@dataclass(frozen=True, slots=True)
class Route:
    """The waypoints left (x [m], y [m]); the last one is the goal point g."""

    waypoints: tuple[tuple[float, float], ...]

    def penalty(self, x: float, y: float) -> tuple[float, float, float]:
        """(L − ‖z − g‖ [m], ∂(−penalty)/∂x, ∂(−penalty)/∂y) at z = (x, y) (module docstring)."""
        w = self.waypoints
        gx, gy = w[-1]
        wx, wy = w[0]
        to_w = math.hypot(x - wx, y - wy)
        to_g = math.hypot(x - gx, y - gy)
        length = to_w
        for (ax, ay), (bx, by) in itertools.pairwise(w):
            length += math.hypot(bx - ax, by - ay)
        dx = dy = 0.0
        if to_w > 0.0:
            dx -= (x - wx) / to_w
            dy -= (y - wy) / to_w
        if to_g > 0.0:
            dx += (x - gx) / to_g
            dy += (y - gy) / to_g
        return length - to_g, dx, dy

    def advanced(self, x: float, y: float, reach: float) -> Route | None:
        """The route with the waypoints within ``reach`` [m] of z dropped; None when only the goal
        is left (it is in sight: the route was planned so)."""
        w = self.waypoints
        k = 0
        while k < len(w) - 1 and math.hypot(x - w[k][0], y - w[k][1]) <= reach:
            k += 1
        if k >= len(w) - 1:
            return None
        return self if k == 0 else Route(w[k:])


class RoutePlanner:
    """Grids of one robot's arena and its routes (module docstring).

    ``clearance`` [m]: the inflation of the planning grid (robot radius + the wall term's outer
    radius margin), so a route keeps clear of the repulsion; ``tight`` [m], used when no route
    exists at ``clearance`` (a door narrower than that), the body plus the full-repulsion margin.
    """

    def __init__(self, arena: Arena, clearance: float, tight: float, reach: float = 0.15,
                 resolution: float = 0.05):
        self.arena = arena
        self.clearance = clearance
        self.tight = tight
        self.reach = reach  # [m] a waypoint this close is reached
        self.resolution = resolution
        self._grids: dict[float, OccupancyGrid] = {}

    def grid(self, inflation: float) -> OccupancyGrid:
        grid = self._grids.get(inflation)
        if grid is None:
            grid = self._grids[inflation] = grid_from_arena(self.arena, inflation,
                                                            self.resolution)
        return grid

    def in_sight(self, start: tuple[float, float], goal: tuple[float, float]) -> bool:
        """Whether the straight segment start → goal keeps ``clearance`` from every obstacle (or
        ``tight`` where the start itself is closer than ``clearance``)."""
        a, b = np.array(start, dtype=float), np.array([goal], dtype=float)
        for inflation in (self.clearance, self.tight):
            grid = self.grid(inflation)
            if grid.is_free_point(*start) or inflation == self.tight:
                return bool(line_of_sight(grid, a, b)[0])
        return True

    def plan(self, start: tuple[float, float], goal: tuple[float, float]) -> Route | None:
        """A route start → goal, or None when the goal is in sight or no route exists."""
        if not self.arena.obstacles or self.in_sight(start, goal):
            return None
        for inflation in (self.clearance, self.tight):
            try:
                path = plan_path(self.grid(inflation), start, goal)
            except NoPathError:
                continue
            points = [tuple(float(v) for v in p) for p in path.waypoints[1:]]
            if not points:
                return None
            if not path.goal_snapped:
                points[-1] = (float(goal[0]), float(goal[1]))
            return Route(tuple(points)).advanced(start[0], start[1], self.reach)
        return None
