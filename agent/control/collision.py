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
