"""Joint optimum of a G task pinched between two region G tasks (Scenario 1's φ′3, φ′4, φ′5).

The best achievable values of ``scenarios.md`` are per sub-task. Where one robot's task asks it to
stay near two robots whose own tasks hold them in distant regions, the three values are coupled:
they cannot all reach their best at once. This module finds that pattern in a scenario and gives
the jointly achievable bounds (derivation: docs/coupling.md §3, paper §II-B notation).

Pattern (a *pinch*): robot L has a sub-task
``G[a_L,b_L] (dist(pL, pj) <= d_j & dist(pL, pk) <= d_k)`` and robots j, k each have
``G[a,b] (dist(pj, c_j) <= r_j)`` with constant centres c_j, c_k, the three windows sharing an
instant. Over the common window, with ρ_j, ρ_k the standard robustness of the region tasks
(ρ_j ≤ r_j), the robots sit ‖z_j − z_k‖ ≥ D_min = ‖c_j − c_k‖ − (r_j − ρ_j) − (r_k − ρ_k) apart,
and for any z_L

    min(d_j − ‖z_L − z_j‖, d_k − ‖z_L − z_k‖) ≤ min(d_j, d_k, (d_j + d_k − ‖z_j − z_k‖)/2),

(triangle inequality; equality on the segment z_j z_k), so
ρ_L ≤ min(d_j, d_k, (d_j + d_k − D_min)/2). While D_min ≥ |d_j − d_k| that is the plane
ρ_L + (ρ_j + ρ_k)/2 ≤ K with

    K = (d_j + d_k − ‖c_j − c_k‖ + r_j + r_k)/2    (Scenario 1: (1 + 1 − 4 + 0.1 + 0.1)/2 = −0.9).

All distances in m, robustness values in m (the predicates are distances).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.stl.analysis import literal_value
from tlfleet.agent.stl.monitor import Trajectory
from tlfleet.agent.stl.parser import robot_subtasks
from tlfleet.agent.stl.syntax import And, Call, Position, Predicate, Temporal, VecLit


@dataclass(frozen=True)
class RegionTask:
    """``G[a,b] (dist(p_robot, centre) <= radius)``: sub-task ``index`` of ``robot``."""

    robot: int
    index: int
    centre: tuple[float, float]  # [m]
    radius: float  # [m]
    window: tuple[float, float]  # [s]


@dataclass(frozen=True)
class Pinch:
    """Leader sub-task ``leader_index`` of robot ``leader`` near ``regions`` = (j, k) (module
    docstring): ``reach`` = (d_j, d_k) [m]; ``window`` = the leader's [a_L, b_L] [s];
    ``common`` = the instants all three windows share [s]."""

    leader: int
    leader_index: int
    reach: tuple[float, float]
    regions: tuple[RegionTask, RegionTask]
    window: tuple[float, float]
    common: tuple[float, float]

    @property
    def plane(self) -> float:
        """K of ρ_L + (ρ_j + ρ_k)/2 ≤ K [m] (module docstring)."""
        (d_j, d_k), (rj, rk) = self.reach, self.regions
        return (d_j + d_k - _gap(rj.centre, rk.centre) + rj.radius + rk.radius) / 2.0

    def _pair_bound(self, gap: float | np.ndarray) -> float | np.ndarray:
        d_j, d_k = self.reach
        return np.minimum(min(d_j, d_k), (d_j + d_k - gap) / 2.0)

    def leader_bound(self, rho_j: float, rho_k: float) -> float:
        """Best ρ_L given the region tasks' ρ_j, ρ_k [m] (each capped at its radius)."""
        rj, rk = self.regions
        gap = (_gap(rj.centre, rk.centre) - (rj.radius - min(rho_j, rj.radius))
               - (rk.radius - min(rho_k, rk.radius)))
        return float(self._pair_bound(max(gap, 0.0)))

    def region_bound(self, which: int, rho_leader: float, rho_other: float) -> float:
        """Best ρ of region task ``which`` (0: j, 1: k) given ρ_L and the other region's ρ [m]:
        the plane solved for it, capped by its radius (valid while D_min ≥ |d_j − d_k|)."""
        own = self.regions[which].radius
        return float(min(own, 2.0 * (self.plane - rho_leader) - rho_other))

    def trajectory_bound(self, traj: Trajectory) -> float:
        """Best ρ_L any robot L could have had beside robots j and k as they moved: min over the
        leader's window of min(d_j, d_k, (d_j + d_k − ‖z_j − z_k‖)/2) [m]."""
        inside = traj.window(*self.window)
        if not inside.any():
            return math.inf
        j, k = (r.robot for r in self.regions)
        gap = np.hypot(*(traj.states[j][inside, :2] - traj.states[k][inside, :2]).T)
        return float(np.min(self._pair_bound(gap)))


def _gap(a: tuple[float, float], b: tuple[float, float]) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _dist_at_most(pred) -> tuple[object, object, float] | None:
    """(a, b, c) for ``dist(a, b) <= c`` with constant c, else None."""
    if not isinstance(pred, Predicate) or pred.cmp not in ("<=", "<"):
        return None
    c = literal_value(pred.rhs)
    if c is None or not (isinstance(pred.lhs, Call) and pred.lhs.func == "dist"
                         and len(pred.lhs.args) == 2):
        return None
    return pred.lhs.args[0], pred.lhs.args[1], c


def region_task(robot: int, index: int, phi: Temporal) -> RegionTask | None:
    """The :class:`RegionTask` that ``phi`` is, or None."""
    parts = _dist_at_most(phi.body) if phi.op == "G" else None
    if parts is None:
        return None
    a, b, radius = parts
    if isinstance(b, Position):
        a, b = b, a
    if not (isinstance(a, Position) and a.robot == robot and isinstance(b, VecLit)):
        return None
    cx, cy = literal_value(b.x), literal_value(b.y)
    if cx is None or cy is None:
        return None
    return RegionTask(robot, index, (cx, cy), radius, (phi.a, phi.b))


def find_pinches(scenario: Scenario) -> list[Pinch]:
    """Every pinch of ``scenario`` (module docstring), in robot order."""
    regions = {}
    for robot in scenario.robots:
        for index, phi in enumerate(robot_subtasks(robot)):
            found = region_task(robot.id, index, phi)
            if found is not None:
                regions.setdefault(robot.id, []).append(found)
    pinches = []
    for robot in scenario.robots:
        for index, phi in enumerate(robot_subtasks(robot)):
            if phi.op != "G" or not isinstance(phi.body, And) or len(phi.body.children) != 2:
                continue
            partners = []
            for child in phi.body.children:
                parts = _dist_at_most(child)
                if parts is None:
                    break
                a, b, reach = parts
                ends = {e.robot if isinstance(e, Position) else None for e in (a, b)}
                if robot.id not in ends or len(ends - {robot.id, None}) != 1:
                    break
                partners.append(((ends - {robot.id, None}).pop(), reach))
            if len(partners) != 2 or partners[0][0] == partners[1][0]:
                continue
            for rj in regions.get(partners[0][0], []):
                for rk in regions.get(partners[1][0], []):
                    lo = max(phi.a, rj.window[0], rk.window[0])
                    hi = min(phi.b, rj.window[1], rk.window[1])
                    if lo <= hi:
                        pinches.append(Pinch(robot.id, index, (partners[0][1], partners[1][1]),
                                             (rj, rk), (phi.a, phi.b), (lo, hi)))
    return pinches
