"""Collision-avoidance velocity ū_col,i of paper §III-B (stl-funnel.md §6.2)::

    D(z_i, z_j) = (z_i − z_j)/‖z_i − z_j‖
    ū_col,i = Σ_{j: d_ij < R1} u_max·D + Σ_{j: R1 ≤ d_ij ≤ R} k·(R − d_ij)/(d_ij³·R)·D,
    k = u_max·R·R1³/(R − R1)            (continuous at d = R1, zero at d = R)

z in m, velocities in m/s. All robots within R count (LTL ones included); the angular entry is 0.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class CollisionParams:
    """Collision-avoidance constants (scenario values of stl-funnel.md §10.1)."""

    r1: float = 0.6  # [m] R1, full-repulsion radius
    r_sense: float = 0.7  # [m] R, sensing radius (R > R1)
    beta: float = 2.0  # β_i ≥ 0, weight of ū_col in eq. (6)
    max_lin: float = 0.2  # [m/s] u_max,i

    @property
    def gain(self) -> float:
        """k_i = u_max·R·R1³/(R − R1)."""
        return self.max_lin * self.r_sense * self.r1**3 / (self.r_sense - self.r1)


def repulsion_magnitude(d: float, params: CollisionParams) -> float:
    """|ū_col| contributed by one neighbour at distance d [m]: u_max below R1, the k-branch on
    [R1, R], 0 beyond R."""
    if d < params.r1:
        return params.max_lin
    if d <= params.r_sense:
        return params.gain * (params.r_sense - d) / (d**3 * params.r_sense)
    return 0.0


def collision_velocity(z_i: tuple[float, float], neighbours: Iterable[Sequence[float]],
                       params: CollisionParams) -> tuple[float, float, float]:
    """ū_col,i = (v_x, v_y, 0) [m/s] from the positions of the other robots (any number; those
    beyond R contribute nothing): (x, y) or poses (x, y, θ), of which only x and y are read.
    Coincident positions (d = 0) have no direction and are skipped, so robot i's own pose may be
    among them."""
    xi, yi = z_i
    r1, big_r, umax = params.r1, params.r_sense, params.max_lin
    k = params.gain
    r2 = big_r * big_r
    vx = vy = 0.0
    for z_j in neighbours:
        dx = xi - z_j[0]
        dy = yi - z_j[1]
        if dx * dx + dy * dy > r2:
            continue
        d = math.hypot(dx, dy)  # exact also for tiny offsets, where dx² + dy² underflows
        if d == 0.0:
            continue
        mag = umax if d < r1 else k * (big_r - d) / (d * d * d * big_r)
        vx += mag * (dx / d)  # unit direction first: mag·dx can underflow for tiny offsets
        vy += mag * (dy / d)
    return vx, vy, 0.0


@dataclass(frozen=True)
class StaticAvoidance:
    """Walls and static obstacles in eq. (6) (docs/stl-saturation.md §8): the arena's border
    ``bounds`` = (xmin, xmax, ymin, ymax) [m], axis-aligned ``rects`` (xmin, ymin, xmax, ymax) and
    ``discs`` (cx, cy, radius) [m]; ``r1`` and ``r_sense`` are distances from the robot's centre to
    a surface [m] (robot radius plus the margins)."""

    bounds: tuple[float, float, float, float]
    rects: tuple[tuple[float, float, float, float], ...] = ()
    discs: tuple[tuple[float, float, float], ...] = ()
    r1: float = 0.23  # [m] full repulsion below this centre-to-surface distance
    r_sense: float = 0.30  # [m] no repulsion beyond it
    max_lin: float = 0.2  # [m/s]

    @property
    def gain(self) -> float:
        """k = u_max·R·R1³/(R − R1), as for two robots (continuous at R1, zero at R)."""
        return self.max_lin * self.r_sense * self.r1**3 / (self.r_sense - self.r1)


def static_velocity(z_i: tuple[float, float], static: StaticAvoidance
                    ) -> tuple[float, float, float]:
    """ū_col,i of the walls and obstacles (docs/stl-saturation.md §8): eq. (6)'s repulsion with
    the closest point q of each wall or obstacle in place of z_j, d = ‖z_i − q‖ and
    D = (z_i − q)/d, the magnitude u_max below R1 and k(R − d)/(d³R) on [R1, R]. A centre inside
    an obstacle (d = 0) is pushed out through the nearest face. Returns (v_x, v_y, 0) [m/s]."""
    x, y = z_i
    big_r = static.r_sense
    vx = vy = 0.0
    xmin, xmax, ymin, ymax = static.bounds
    # the four walls: the closest point is straight across
    for d, nx, ny in ((x - xmin, 1.0, 0.0), (xmax - x, -1.0, 0.0),
                      (y - ymin, 0.0, 1.0), (ymax - y, 0.0, -1.0)):
        if d <= big_r:
            mag = _static_magnitude(d, static)
            vx += mag * nx
            vy += mag * ny
    for rxmin, rymin, rxmax, rymax in static.rects:
        qx = rxmin if x < rxmin else rxmax if x > rxmax else x
        qy = rymin if y < rymin else rymax if y > rymax else y
        dx, dy = x - qx, y - qy
        if dx > big_r or -dx > big_r or dy > big_r or -dy > big_r:
            continue
        d = math.hypot(dx, dy)
        if d > big_r:
            continue
        if d == 0.0:  # inside: out through the nearest face
            faces = ((x - rxmin, -1.0, 0.0), (rxmax - x, 1.0, 0.0),
                     (y - rymin, 0.0, -1.0), (rymax - y, 0.0, 1.0))
            _, ux, uy = min(faces)
        else:
            ux, uy = dx / d, dy / d
        mag = _static_magnitude(d, static)
        vx += mag * ux
        vy += mag * uy
    for cx, cy, radius in static.discs:
        dx, dy = x - cx, y - cy
        centre = math.hypot(dx, dy)
        d = centre - radius
        if d > big_r:
            continue
        ux, uy = (dx / centre, dy / centre) if centre > 0.0 else (1.0, 0.0)
        mag = _static_magnitude(max(d, 0.0), static)
        vx += mag * ux
        vy += mag * uy
    return vx, vy, 0.0


def _static_magnitude(d: float, static: StaticAvoidance) -> float:
    if d < static.r1:
        return static.max_lin
    if d <= static.r_sense:
        return static.gain * (static.r_sense - d) / (d * d * d * static.r_sense)
    return 0.0
