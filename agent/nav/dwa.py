"""Dynamic window approach (DWA) local planner for a unicycle (ltl-planning.md §6).

Fox, Burgard & Thrun, "The dynamic window approach to collision avoidance", IEEE RAM 1997, in
the form of ROS ``dwa_local_planner`` that the paper's TurtleBots ran (paper §III-A).

Each control period ``Δt`` [s] (0.2 s at 5 Hz):

1. **Dynamic window** around the current velocity ``(v, ω)``:
   ``V = [max(v_min, v − a_v Δt), min(v_max, v + a_v Δt)]`` [m/s] and
   ``Ω = [max(−ω_max, ω − a_ω Δt), min(ω_max, ω + a_ω Δt)]`` [rad/s], sampled with
   ``vx_samples × vtheta_samples`` evenly spaced values (plus ω = 0 when inside Ω).
2. **Rollouts**: every sample ``(v_s, ω_s)`` held for ``sim_time``, integrated in closed form
   ``θ(t) = θ0 + ω t``, ``x(t) = x0 + v/ω (sin θ(t) − sin θ0)``, ``y(t) = y0 − v/ω (cos θ(t) −
   cos θ0)`` (straight line when ω → 0) at ``t_k = k·sim_dt``; all samples at once, array
   (S, T, 2).
3. **Clearance** ``d`` [m] from the robot centre to the nearest obstacle surface along each
   rollout: static obstacles from the grid's clearance layer, other robots as discs moving with
   constant velocity ``c_j + u_j t``. A rollout with ``min d < r_robot + collision_margin`` is
   inadmissible (unless the robot already sits closer than that, then it may not get closer).
4. **Score** (lower is better; ROS costs, distances in metres instead of cells):
   ``J = path_distance_bias · (d_path(end) + d_path(front))
       + goal_distance_bias · (‖end − g‖ + ‖front − g‖)
       + occdist_scale · max_t c(d_static) + robot_occdist_scale · max_t c(d_robots)
       + speed_bias · (v_max − v_s) / v_max``
   where ``end`` is the rollout end point, ``front = end + forward_point_distance·(cos θ, sin θ)``
   (the alignment point), ``d_path`` the distance to the remaining global path, ``g`` the
   look-ahead point ``carrot_distance`` along the path, and ``c(d)`` the costmap_2d inflation
   cost ``252·exp(−cost_scaling_factor·(d − r_robot))`` for ``d ≤ inflation_radius`` (0 beyond),
   of the clearance to the map (walls, obstacles, keep-out zones) and to the other robots apart:
   the map is known exactly and asks only to stay off it, the robots' motion is predicted and
   asks for a wider berth (docs/ltl-navigation.md §4).
   The ``front`` terms use the path extended by ``forward_point_distance`` past the goal and the
   look-ahead point that much further on (ROS instead drops them near the goal), so alignment
   never holds the robot short of its goal.
5. **Coupling limits** (optional, ``tlfleet.agent.nav.coupling_limits``, docs/coupling.md): the
   window is first clipped to the limits' largest admissible |v| and |ω|, and a sample whose
   ``a_v·|v| + a_ω·|ω|`` exceeds a constraint's bound is inadmissible. When no collision-free
   sample meets them (the robot still moves faster than the limits), the collision-free samples
   of least excess are kept: the robot slows down as fast as its accelerations allow.
6. **No standing still by choice** (ROS ``dwa_local_planner``'s ``min_vel_trans`` and
   ``min_vel_theta``): a sample with ``|v| < min_trans_vel`` and ``|ω| < min_rot_vel`` moves
   nothing; while any other sample is admissible (and within the coupling limits), those are
   left out. Next to a wall end or a door frame the cost terms can make standing the cheapest
   sample (the alignment point already lies on the path and every move forward is cut off), and
   the robot stood there until the stuck timeout; now it turns in place and drives on. Under
   coupling limits the thresholds are at most half the limits' largest |v| and |ω|: a leader its
   formation holds to slow motions may still turn slowly in place, instead of being pushed to
   drive on at ``min_trans_vel`` in whatever direction it faces.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from tlfleet.agent.nav import dwa_native
from tlfleet.agent.nav.coupling_limits import VelocityLimits
from tlfleet.agent.nav.grid import OccupancyGrid
from tlfleet.agent.nav.polyline import (
    distance_to_polyline_xy,
    point_along_vertices,
    remaining_vertices,
)
from tlfleet.bus.errors import TlfleetError

KERNEL_CHOICES = ("auto", "native", "python")


class DwaKernelError(TlfleetError, ValueError):
    """``DwaConfig.kernel`` (or ``$TLFLEET_DWA``) is unknown or asks for the C kernel, which was
    not built."""


def native_kernel_available() -> bool:
    """Whether the DWA's C kernel (``tlfleet.agent.nav._dwa``) was built at install time."""
    return dwa_native.available()


def _default_kernel() -> str:
    return os.environ.get("TLFLEET_DWA", "auto")


@dataclass(frozen=True)
class DwaConfig:
    """DWA parameters; defaults are the authors' Kobuki settings (ltl-planning.md §6)."""

    max_vel_x: float = 0.3  # [m/s]
    min_vel_x: float = 0.0  # [m/s]
    max_rot_vel: float = 1.0  # [rad/s]
    acc_lim_x: float = 1.0  # [m/s²]
    acc_lim_theta: float = 2.0  # [rad/s²]
    sim_time: float = 1.3  # [s] rollout horizon
    sim_dt: float = 0.1  # [s] rollout sampling step (ours; ROS uses sim_granularity 0.025 m)
    vx_samples: int = 6
    vtheta_samples: int = 20
    path_distance_bias: float = 64.0  # [1/m]
    goal_distance_bias: float = 24.0  # [1/m]
    # ROS's 0.5 with ROS's path and goal biases per 0.05 m cell: ours are per metre (20× less),
    # so the occupancy term is scaled alike; at 0.5 it outweighed progress next to wall ends and
    # door frames and the robot stood still (docs/ltl-navigation.md §4)
    occdist_scale: float = 0.025  # [1/cost]
    robot_occdist_scale: float = 0.5  # [1/cost] the other robots' inflation cost (ROS's scale)
    xy_goal_tolerance: float = 0.15  # [m]
    controller_period: float = 0.2  # [s] (5 Hz)
    forward_point_distance: float = 0.325  # [m] ROS default
    inflation_radius: float = 0.5  # [m] costmap inflation (turtlebot_navigation)
    cost_scaling_factor: float = 5.0  # [1/m] costmap inflation decay (turtlebot_navigation)
    collision_margin: float = 0.03  # [m] beyond the robot radius, rollouts closer are rejected
    carrot_distance: float = 0.8  # [m] look-ahead along the global path for the goal term
    speed_bias: float = 2.0  # weight of the speed term (ours; ROS has none)
    # ROS dwa_local_planner's min_vel_trans / min_vel_theta: a sample slower than both does not
    # move the robot and is left out while any moving one is admissible (step 6)
    min_trans_vel: float = 0.1  # [m/s]
    min_rot_vel: float = 0.4  # [rad/s]
    # where the cycle runs: "native" (C, tlfleet.agent.nav._dwa), "python" (numpy), or "auto" (C
    # when it was built); the same commands either way. Default: $TLFLEET_DWA, else "auto".
    kernel: str = field(default_factory=_default_kernel)

    def __post_init__(self) -> None:
        if self.kernel not in KERNEL_CHOICES:
            raise DwaKernelError(
                f"DwaConfig.kernel (or $TLFLEET_DWA): expected one of "
                f"{', '.join(KERNEL_CHOICES)}, got {self.kernel!r}")
        if self.kernel == "native" and not dwa_native.available():
            raise DwaKernelError(
                "DwaConfig.kernel (or $TLFLEET_DWA) = 'native', but the DWA's C kernel "
                "(tlfleet.agent.nav._dwa) was not built: reinstall with a C compiler")
        for name in (
            "max_vel_x",
            "max_rot_vel",
            "acc_lim_x",
            "acc_lim_theta",
            "sim_time",
            "sim_dt",
            "controller_period",
        ):
            if getattr(self, name) <= 0:
                raise ValueError(f"DwaConfig.{name} must be positive, got {getattr(self, name)}")
        if self.vx_samples < 1 or self.vtheta_samples < 1:
            raise ValueError("DwaConfig needs at least one sample per velocity axis")
        if self.min_vel_x > self.max_vel_x:
            raise ValueError(f"min_vel_x {self.min_vel_x} > max_vel_x {self.max_vel_x}")

    @property
    def native(self) -> bool:
        """Whether cycles of this configuration run in C."""
        return self.kernel == "native" or (self.kernel == "auto" and dwa_native.available())


@dataclass(frozen=True, eq=False)
class MovingDiscs:
    """Dynamic layer of the local cost map: other robots as discs moving at constant velocity.

    ``centers`` (K, 2) [m], ``velocities`` (K, 2) [m/s] (world frame), ``radii`` (K,) [m].
    """

    centers: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray

    @staticmethod
    def empty() -> MovingDiscs:
        return MovingDiscs(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0))

    @staticmethod
    def static(centers: Sequence[Sequence[float]], radii: float | Sequence[float]) -> MovingDiscs:
        c = np.asarray(centers, dtype=float).reshape(-1, 2)
        r = np.broadcast_to(np.asarray(radii, dtype=float), (len(c),)).copy()
        return MovingDiscs(c, np.zeros_like(c), r)

    def __len__(self) -> int:
        return len(self.centers)


@dataclass(frozen=True, eq=False)
class DwaResult:
    """One DWA decision: the command ``(v, omega)`` [m/s, rad/s] and why.

    ``n_valid`` counts admissible samples (0: no safe rollout, the command then brakes);
    ``goal_reached`` is True within ``xy_goal_tolerance`` of the path's end; ``trajectory``
    (T, 2) [m] is the chosen rollout (empty when braking).
    """

    v: float
    omega: float
    cost: float
    n_valid: int
    goal_reached: bool
    trajectory: np.ndarray


def velocity_window(v: float, omega: float, config: DwaConfig) -> tuple[float, float, float, float]:
    """Dynamic window ``(v_lo, v_hi, ω_lo, ω_hi)`` reachable within one controller period."""
    dt = config.controller_period
    v = min(max(v, config.min_vel_x), config.max_vel_x)
    omega = min(max(omega, -config.max_rot_vel), config.max_rot_vel)
    v_lo = max(config.min_vel_x, v - config.acc_lim_x * dt)
    v_hi = min(config.max_vel_x, v + config.acc_lim_x * dt)
    w_lo = max(-config.max_rot_vel, omega - config.acc_lim_theta * dt)
    w_hi = min(config.max_rot_vel, omega + config.acc_lim_theta * dt)
    return v_lo, v_hi, w_lo, w_hi


def braking_command(v: float, omega: float, config: DwaConfig) -> tuple[float, float]:
    """The velocity closest to standstill inside the dynamic window."""
    v_lo, v_hi, w_lo, w_hi = velocity_window(v, omega, config)
    return min(max(0.0, v_lo), v_hi), min(max(0.0, w_lo), w_hi)


def rollouts(
    pose: Sequence[float], v: np.ndarray, omega: np.ndarray, times: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form unicycle arcs: positions (S, T, 2) [m] and headings (S, T) [rad].

    ``v`` (S,) [m/s], ``omega`` (S,) [rad/s] held constant; ``times`` (T,) [s].
    """
    x, y, theta = _arcs(pose, v, omega, times)
    return np.stack([x, y], axis=-1), theta


def _arcs(pose: Sequence[float], v: np.ndarray, omega: np.ndarray, times: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``rollouts`` as coordinate arrays x, y [m] and headings θ [rad], each (S, T)."""
    x, y, theta, _, _ = _arcs_with_trig(pose, v, omega, times)
    return x, y, theta


def _arcs_with_trig(pose: Sequence[float], v: np.ndarray, omega: np.ndarray, times: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``_arcs`` and cos θ, sin θ (S, T). A sample with |ω| ≤ 1e-9 is a straight line."""
    x0, y0, th0 = float(pose[0]), float(pose[1]), float(pose[2])
    theta = np.multiply.outer(omega, times)
    theta += th0
    turning = np.abs(omega) > 1e-9
    radius = (v / np.where(turning, omega, 1.0))[:, None]
    sin_t, cos_t = np.sin(theta), np.cos(theta)
    x = sin_t - math.sin(th0)
    x *= radius
    x += x0
    y = cos_t - math.cos(th0)
    y *= radius
    np.subtract(y0, y, out=y)
    if not turning.all():
        line = ~turning
        vt = np.multiply.outer(v[line], times)
        x[line] = x0 + vt * math.cos(th0)
        y[line] = y0 + vt * math.sin(th0)
    return x, y, theta, cos_t, sin_t


def _linspace(lo: float, hi: float, num: int) -> list[float]:
    """``np.linspace(lo, hi, num)`` in plain floats, value for value (``i·step + lo``, the last
    one ``hi``)."""
    if num == 1:
        return [lo]
    div = num - 1
    delta = hi - lo
    step = delta / div
    if step == 0.0:
        values = [i / div * delta + lo for i in range(num)]
    else:
        values = [i * step + lo for i in range(num)]
    values[-1] = hi
    return values


def _samples(v: float, omega: float, config: DwaConfig,
             limits: VelocityLimits | None = None) -> tuple[np.ndarray, np.ndarray]:
    v_lo, v_hi, w_lo, w_hi = velocity_window(v, omega, config)
    if limits:
        # clip the window to the box of the coupling limits, staying inside the dynamic window
        v_cap, w_cap = limits.v_max, limits.omega_max
        v_hi = max(v_lo, min(v_hi, v_cap))
        w_lo, w_hi = min(w_hi, max(w_lo, -w_cap)), max(w_lo, min(w_hi, w_cap))
    vs = _linspace(v_lo, v_hi, config.vx_samples) if v_hi > v_lo else [v_lo]
    ws = _linspace(w_lo, w_hi, config.vtheta_samples) if w_hi > w_lo else [w_lo]
    if w_lo < 0.0 < w_hi and 0.0 not in ws:
        ws = sorted([*ws, 0.0])
    # the (v, ω) grid, v-major
    return np.array([v_s for v_s in vs for _ in ws]), np.array(ws * len(vs))


def _extend(path: list[list[float]], position: tuple[float, float], length: float
            ) -> list[list[float]]:
    """The path (a vertex list) with one more vertex ``length`` [m] past its end, along its last
    leg."""
    (ex, ey) = path[-1]
    bx, by = path[-2] if len(path) >= 2 else position
    dx, dy = ex - bx, ey - by
    norm = math.sqrt(dx * dx + dy * dy)
    if norm < 1e-9:
        return path
    scale = length / norm
    return [*path, [ex + dx * scale, ey + dy * scale]]


def inflation_cost(d: np.ndarray, robot_radius: float, config: DwaConfig) -> np.ndarray:
    """costmap_2d inflation cost of a clearance ``d`` [m]: 253 inside the robot's radius,
    ``252·exp(−k (d − r))`` up to ``inflation_radius``, 0 beyond."""
    decay = 252.0 * np.exp(-config.cost_scaling_factor * np.maximum(d - robot_radius, 0.0))
    return np.where(d < robot_radius, 253.0, np.where(d <= config.inflation_radius, decay, 0.0))


def dwa_control(
    pose: Sequence[float],
    velocity: Sequence[float],
    path: np.ndarray,
    grid: OccupancyGrid,
    robot_radius: float,
    others: MovingDiscs | None = None,
    config: DwaConfig | None = None,
    limits: VelocityLimits | None = None,
) -> DwaResult:
    """One DWA cycle (see module docstring).

    ``pose`` (x [m], y [m], θ [rad]); ``velocity`` the current (v [m/s], ω [rad/s]) — the last
    command, which bounds the dynamic window; ``path`` (M, 2) [m] the global path whose last
    vertex is the goal; ``grid`` the static layer; ``others`` the other robots; ``limits`` the
    coupling limits of this step (step 5), None or empty for none.

    a 5 Hz step of an LTL agent sits on the fleet's latency path, and on arrays of
    126 × 13 a numpy call costs more than its arithmetic. So the rollouts are coordinate arrays
    (no (…, 2) stacking), the path's geometry is plain floats, the grid lookup skips the
    off-grid test when every rollout stays a cell inside the grid, and other robots that cannot
    come within ``inflation_radius`` of any rollout are left out (they change no cost and no
    admissibility). The floating-point operations of what is computed are those of the plain
    array form, so the result is the same to the last bit (tests/nav/test_nav_dwa_reference.py).
    With ``config.native`` (the default where it was built) the whole cycle runs in C instead
    (``agent/nav/dwa_kernel.c``, the same operations; tests/nav/test_nav_dwa_native.py).
    """
    config = config or DwaConfig()
    others = others if others is not None else MovingDiscs.empty()
    if config.native:
        return _control_native(pose, velocity, path, grid, robot_radius, others, config, limits)
    v0, w0 = float(velocity[0]), float(velocity[1])
    px, py = float(pose[0]), float(pose[1])
    vertices = np.asarray(path, dtype=float).reshape(-1, 2).tolist()
    gx, gy = vertices[-1]
    dgx, dgy = gx - px, gy - py
    if math.sqrt(dgx * dgx + dgy * dgy) <= config.xy_goal_tolerance:
        v, w = braking_command(v0, w0, config)
        return DwaResult(v, w, 0.0, 0, True, np.zeros((0, 2)))

    vs, ws = _samples(v0, w0, config, limits)
    times = _times(config.sim_time, config.sim_dt)
    # Every rollout point lies within reach = max |v| · horizon of (px, py).
    horizon = float(times[-1])
    reach = float(np.abs(vs).max()) * horizon
    near = _near_discs(others, px, py, reach, horizon, config)
    current_static = grid.clearance_point(px, py)
    current_robots = _robots_gap(px, py, near)
    current = min(current_static, current_robots)
    required = min(robot_radius + config.collision_margin, current - 1e-6)

    x, y, cos_t, sin_t, min_clearance, least_static, least_robots = _clearances(
        pose, vs, ws, times, grid, near, reach)
    valid = _admissible(vs, ws, min_clearance >= required, limits, config)
    n_valid = int(np.count_nonzero(valid))
    if n_valid == 0:
        v, w = braking_command(v0, w0, config)
        return DwaResult(v, w, math.inf, 0, False, np.zeros((0, 2)))

    targets = _path_targets(px, py, vertices, config)
    cost = _costs(x, y, cos_t, sin_t, vs, least_static, least_robots, current_static,
                  current_robots, targets, robot_radius, config)
    cost[~valid] = np.inf
    best = int(np.argmin(cost))
    return DwaResult(
        float(vs[best]), float(ws[best]), float(cost[best]), n_valid, False,
        np.stack([x[best], y[best]], axis=-1),
    )


def _robots_gap(px: float, py: float, near: Sequence[tuple[float, ...]]) -> float:
    """The smallest gap [m] between the point ``(px, py)`` and the discs ``near`` (rows
    ``(x, y, vx, vy, radius)``), ``inf`` without any."""
    gap = math.inf
    for cx0, cy0, _, _, r in near:
        ex, ey = cx0 - px, cy0 - py
        gap = min(gap, math.sqrt(ex * ex + ey * ey) - r)
    return gap


def _admissible(vs: np.ndarray, ws: np.ndarray, clear: np.ndarray,
                limits: VelocityLimits | None, config: DwaConfig) -> np.ndarray:
    """Which samples ``(vs, ws)`` (N,) may be chosen among the ``clear`` ones (N,) (module
    docstring, steps 5-6): those within the coupling ``limits`` (or, when none is, those that
    exceed them least), then the moving ones unless none is."""
    valid = clear
    if limits and valid.any():
        excess = limits.excess(vs, ws)
        coupled = valid & (excess <= 1e-12)
        if not coupled.any():
            least = float(excess[valid].min())
            coupled = valid & (excess <= least + 1e-12)
        valid = coupled
    min_v, min_w = config.min_trans_vel, config.min_rot_vel
    if limits:  # a leader held to slow motions still turns and creeps (step 6)
        min_v, min_w = min(min_v, 0.5 * limits.v_max), min(min_w, 0.5 * limits.omega_max)
    moving = valid & ((np.abs(vs) >= min_v) | (np.abs(ws) >= min_w))
    if moving.any():  # standing still only when nothing else is admissible (step 6)
        return moving
    return valid


_PathTargets = tuple[list[list[float]], tuple[float, float], list[list[float]],
                     tuple[float, float]]


def _path_targets(px: float, py: float, vertices: list[list[float]], config: DwaConfig
                  ) -> _PathTargets:
    """What step 4 scores against: the path ahead of the robot, its look-ahead point, the path
    extended ``forward_point_distance`` past its end and the look-ahead point of the alignment
    point on it."""
    ahead = remaining_vertices(px, py, vertices)
    carrot = point_along_vertices(ahead, config.carrot_distance)
    # The alignment point runs forward_point_distance ahead of the robot, so it is scored against
    # the path extended by that much past the goal (else it would hold the robot short of it).
    fpd = config.forward_point_distance
    extended = _extend(ahead, (px, py), fpd)
    front_carrot = point_along_vertices(extended, config.carrot_distance + fpd)
    return ahead, carrot, extended, front_carrot


def _clearances(pose: Sequence[float], vs: np.ndarray, ws: np.ndarray, times: np.ndarray,
                grid: OccupancyGrid, near: list[tuple[float, float, float, float, float]],
                reach: float) -> tuple[np.ndarray, ...]:
    """Steps 2-3 in numpy: the rollouts x, y, cos θ, sin θ (S, T) and each rollout's least
    clearance (S,) [m] to the grid's obstacles and the ``near`` discs together, to the grid's
    obstacles alone and to the discs alone (``inf`` without any)."""
    px, py = float(pose[0]), float(pose[1])
    x, y, _, cos_t, sin_t = _arcs_with_trig(pose, vs, ws, times)  # (S, T) each
    static = grid.clearance_xy(x, y, within=(px, py, reach))  # (S, T)
    clearance = static
    robots = None
    for cx0, cy0, ux, uy, r in near:
        dx = x - (cx0 + times * ux)
        dy = y - (cy0 + times * uy)
        dx *= dx
        dy *= dy
        dx += dy
        gap = np.sqrt(dx, out=dx)
        gap -= r
        robots = gap if robots is None else np.minimum(robots, gap, out=robots)
    if robots is not None:
        clearance = np.minimum(static, robots)
        least_robots = robots.min(axis=1)
    else:
        least_robots = np.full(len(vs), np.inf)
    return x, y, cos_t, sin_t, clearance.min(axis=1), static.min(axis=1), least_robots


def _costs(x: np.ndarray, y: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray, vs: np.ndarray,
           least_static: np.ndarray, least_robots: np.ndarray, current_static: float,
           current_robots: float, targets: _PathTargets, robot_radius: float,
           config: DwaConfig) -> np.ndarray:
    """Step 4 in numpy: every sample's cost (S,), admissible or not."""
    ahead, (carrot_x, carrot_y), extended, (front_carrot_x, front_carrot_y) = targets
    end_x, end_y = x[:, -1], y[:, -1]
    cost = distance_to_polyline_xy(end_x, end_y, ahead)
    cost *= config.path_distance_bias
    dx, dy = end_x - carrot_x, end_y - carrot_y
    cost += config.goal_distance_bias * np.sqrt(dx * dx + dy * dy)
    fpd = config.forward_point_distance
    front_x = end_x + fpd * cos_t[:, -1]
    front_y = end_y + fpd * sin_t[:, -1]
    cost += config.path_distance_bias * distance_to_polyline_xy(front_x, front_y, extended)
    dx, dy = front_x - front_carrot_x, front_y - front_carrot_y
    cost += config.goal_distance_bias * np.sqrt(dx * dx + dy * dy)
    # As ROS, each occupancy term is the worst cost along the rollout including the start pose;
    # the inflation cost does not increase with the clearance, so the worst cost along a rollout
    # is the cost of its least clearance (the same value, on S instead of S·T clearances).
    worst = np.maximum(inflation_cost(least_static, robot_radius, config),
                       float(inflation_cost(np.float64(current_static), robot_radius, config)))
    cost += config.occdist_scale * worst
    worst = np.maximum(inflation_cost(least_robots, robot_radius, config),
                       float(inflation_cost(np.float64(current_robots), robot_radius, config)))
    cost += config.robot_occdist_scale * worst
    cost += config.speed_bias * (config.max_vel_x - vs) / config.max_vel_x
    return cost


def _control_native(pose: Sequence[float], velocity: Sequence[float], path: np.ndarray,
                    grid: OccupancyGrid, robot_radius: float, others: MovingDiscs,
                    config: DwaConfig, limits: VelocityLimits | None,
                    scores: dict | None = None) -> DwaResult:
    """``dwa_control`` in C (``tlfleet.agent.nav.dwa_native``); ``scores``, when given, receives
    every sample's least clearance, cost and excess over the coupling limits (tests)."""
    return DwaResult(*dwa_native.control(pose, velocity, path, grid, robot_radius, others, config,
                                         limits, _times(config.sim_time, config.sim_dt), scores))


def _near_discs(others: MovingDiscs, px: float, py: float, reach: float, horizon: float,
                config: DwaConfig) -> list[tuple[float, float, float, float, float]]:
    """The other robots (centre x, y [m], velocity x, y [m/s], radius [m]) that may come within
    ``inflation_radius`` of a rollout: a robot starting at distance D and moving at speed u can
    get no closer to a rollout point within ``horizon`` [s] than ``D − reach − u·horizon``. A
    robot left out would only raise clearances that are above ``inflation_radius`` (cost 0, and
    above what admissibility requires) to other values above it: the result is unchanged."""
    if not len(others):
        return []
    near = []
    for (cx0, cy0), (ux, uy), r in zip(others.centers.tolist(), others.velocities.tolist(),
                                       others.radii.tolist(), strict=True):
        ex, ey = cx0 - px, cy0 - py
        bound = (math.sqrt(ex * ex + ey * ey) - reach - math.sqrt(ux * ux + uy * uy) * horizon
                 - r)
        if bound <= config.inflation_radius + 1e-6:
            near.append((cx0, cy0, ux, uy, r))
    return near


@functools.lru_cache(maxsize=16)
def _times(sim_time: float, sim_dt: float) -> np.ndarray:
    """Rollout sample times t_k (T,) [s]: ⌈sim_time / sim_dt⌉ steps ending at sim_time (cached,
    read-only)."""
    n_steps = max(1, math.ceil(sim_time / sim_dt - 1e-9))
    times = np.arange(1, n_steps + 1) * (sim_time / n_steps)
    times.setflags(write=False)
    return times
