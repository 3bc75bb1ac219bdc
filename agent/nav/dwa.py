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
       + occdist_scale · max_t c(d)
       + speed_bias · (v_max − v_s) / v_max``
   where ``end`` is the rollout end point, ``front = end + forward_point_distance·(cos θ, sin θ)``
   (the alignment point), ``d_path`` the distance to the remaining global path, ``g`` the
   look-ahead point ``carrot_distance`` along the path, and ``c(d)`` the costmap_2d inflation
   cost ``252·exp(−cost_scaling_factor·(d − r_robot))`` for ``d ≤ inflation_radius`` (0 beyond).
   The ``front`` terms use the path extended by ``forward_point_distance`` past the goal and the
   look-ahead point that much further on (ROS instead drops them near the goal), so alignment
   never holds the robot short of its goal.
5. **Coupling limits** (optional, ``agent.nav.coupling_limits``, docs/coupling.md): the window
   is first clipped to the limits' largest admissible |v| and |ω|, and a sample whose
   ``a_v·|v| + a_ω·|ω|`` exceeds a constraint's bound is inadmissible. When no collision-free
   sample meets them (the robot still moves faster than the limits), the collision-free samples
   of least excess are kept: the robot slows down as fast as its accelerations allow.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from agent.nav.coupling_limits import VelocityLimits
from agent.nav.grid import OccupancyGrid
from agent.nav.polyline import distance_to_polyline, point_along, remaining_polyline


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
    occdist_scale: float = 0.5  # [1/cost]
    xy_goal_tolerance: float = 0.15  # [m]
    controller_period: float = 0.2  # [s] (5 Hz)
    forward_point_distance: float = 0.325  # [m] ROS default
    inflation_radius: float = 0.5  # [m] costmap inflation (turtlebot_navigation)
    cost_scaling_factor: float = 5.0  # [1/m] costmap inflation decay (turtlebot_navigation)
    collision_margin: float = 0.03  # [m] beyond the robot radius, rollouts closer are rejected
    carrot_distance: float = 0.8  # [m] look-ahead along the global path for the goal term
    speed_bias: float = 2.0  # weight of the speed term (ours; ROS has none)

    def __post_init__(self) -> None:
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
    x0, y0, th0 = float(pose[0]), float(pose[1]), float(pose[2])
    w = omega[:, None]
    t = times[None, :]
    theta = th0 + w * t
    turning = np.abs(w) > 1e-9
    w_safe = np.where(turning, w, 1.0)
    vv = v[:, None]
    radius = vv / w_safe
    x_arc = x0 + radius * (np.sin(theta) - math.sin(th0))
    y_arc = y0 - radius * (np.cos(theta) - math.cos(th0))
    vt = vv * t
    x_line = x0 + vt * math.cos(th0)
    y_line = y0 + vt * math.sin(th0)
    return np.where(turning, x_arc, x_line), np.where(turning, y_arc, y_line), theta


def _samples(v: float, omega: float, config: DwaConfig,
             limits: VelocityLimits | None = None) -> tuple[np.ndarray, np.ndarray]:
    v_lo, v_hi, w_lo, w_hi = velocity_window(v, omega, config)
    if limits:
        # clip the window to the box of the coupling limits, staying inside the dynamic window
        v_cap, w_cap = limits.v_max, limits.omega_max
        v_hi = max(v_lo, min(v_hi, v_cap))
        w_lo, w_hi = min(w_hi, max(w_lo, -w_cap)), max(w_lo, min(w_hi, w_cap))
    vs = np.linspace(v_lo, v_hi, config.vx_samples) if v_hi > v_lo else np.array([v_lo])
    ws = np.linspace(w_lo, w_hi, config.vtheta_samples) if w_hi > w_lo else np.array([w_lo])
    if w_lo < 0.0 < w_hi and not np.any(ws == 0.0):
        ws = np.sort(np.append(ws, 0.0))
    return np.repeat(vs, len(ws)), np.tile(ws, len(vs))  # the (v, ω) grid, v-major


def _extend(path: np.ndarray, position: np.ndarray, length: float) -> np.ndarray:
    """The path (M, 2) with one more vertex ``length`` [m] past its end, along its last leg."""
    direction = path[-1] - (path[-2] if len(path) >= 2 else position)
    norm = float(np.linalg.norm(direction))
    if norm < 1e-9:
        return path
    return np.vstack([path, path[-1] + direction * (length / norm)])


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
    """
    config = config or DwaConfig()
    others = others if others is not None else MovingDiscs.empty()
    v0, w0 = float(velocity[0]), float(velocity[1])
    position = np.asarray(pose[:2], dtype=float)
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    goal = path[-1]
    goal_distance = float(np.linalg.norm(goal - position))
    if goal_distance <= config.xy_goal_tolerance:
        v, w = braking_command(v0, w0, config)
        return DwaResult(v, w, 0.0, 0, True, np.zeros((0, 2)))

    vs, ws = _samples(v0, w0, config, limits)
    times = _times(config.sim_time, config.sim_dt)
    x, y, theta = _arcs(pose, vs, ws, times)  # (S, T) each

    # Issue 17: the same arithmetic as the plain (…, 2) form, on coordinate arrays, with fewer
    # numpy calls (a 5 Hz step of an LTL agent sits on the fleet's latency path).
    clearance = grid.clearance_xy(x, y)  # (S, T)
    px, py = float(position[0]), float(position[1])
    current = grid.clearance_point(px, py)
    if len(others):
        centers, velocities, radii = others.centers, others.velocities, others.radii
        cx = centers[:, 0][None, :] + times[:, None] * velocities[:, 0][None, :]  # (T, K)
        cy = centers[:, 1][None, :] + times[:, None] * velocities[:, 1][None, :]
        dx = x[:, :, None] - cx[None]  # (S, T, K)
        dy = y[:, :, None] - cy[None]
        gaps = np.sqrt(dx * dx + dy * dy)
        clearance = np.minimum(clearance, (gaps - radii).min(axis=2))
        ex, ey = centers[:, 0] - px, centers[:, 1] - py
        current = min(current, float((np.sqrt(ex * ex + ey * ey) - radii).min()))
    required = min(robot_radius + config.collision_margin, current - 1e-6)
    min_clearance = clearance.min(axis=1)
    valid = min_clearance >= required
    if limits and valid.any():
        excess = limits.excess(vs, ws)
        coupled = valid & (excess <= 1e-12)
        if not coupled.any():
            least = float(excess[valid].min())
            coupled = valid & (excess <= least + 1e-12)
        valid = coupled
    n_valid = int(np.count_nonzero(valid))
    if n_valid == 0:
        v, w = braking_command(v0, w0, config)
        return DwaResult(v, w, math.inf, 0, False, np.zeros((0, 2)))

    ahead = remaining_polyline(position, path)
    carrot = point_along(ahead, config.carrot_distance)
    end_x, end_y = x[:, -1], y[:, -1]
    end = np.stack([end_x, end_y], axis=1)
    cost = config.path_distance_bias * distance_to_polyline(end, ahead)
    gx, gy = end_x - carrot[0], end_y - carrot[1]
    cost += config.goal_distance_bias * np.sqrt(gx * gx + gy * gy)
    # The alignment point runs forward_point_distance ahead of the robot, so it is scored against
    # the path extended by that much past the goal (else it would hold the robot short of it).
    extended = _extend(ahead, position, config.forward_point_distance)
    front_carrot = point_along(extended, config.carrot_distance + config.forward_point_distance)
    heading = theta[:, -1]
    front_x = end_x + config.forward_point_distance * np.cos(heading)
    front_y = end_y + config.forward_point_distance * np.sin(heading)
    cost += config.path_distance_bias * distance_to_polyline(
        np.stack([front_x, front_y], axis=1), extended)
    fx, fy = front_x - front_carrot[0], front_y - front_carrot[1]
    cost += config.goal_distance_bias * np.sqrt(fx * fx + fy * fy)
    # As ROS, the occupancy term is the worst cost along the rollout including the start pose;
    # the inflation cost does not increase with the clearance, so the worst cost along a rollout
    # is the cost of its least clearance (the same value, on S instead of S·T clearances).
    worst = np.maximum(
        inflation_cost(min_clearance, robot_radius, config),
        float(inflation_cost(np.array(current), robot_radius, config)),
    )
    cost += config.occdist_scale * worst
    cost += config.speed_bias * (config.max_vel_x - vs) / config.max_vel_x
    cost = np.where(valid, cost, np.inf)
    best = int(np.argmin(cost))
    return DwaResult(
        float(vs[best]), float(ws[best]), float(cost[best]), n_valid, False,
        np.stack([x[best], y[best]], axis=-1),
    )


@functools.lru_cache(maxsize=16)
def _times(sim_time: float, sim_dt: float) -> np.ndarray:
    """Rollout sample times t_k (T,) [s]: ⌈sim_time / sim_dt⌉ steps ending at sim_time (cached,
    read-only)."""
    n_steps = max(1, math.ceil(sim_time / sim_dt - 1e-9))
    times = np.arange(1, n_steps + 1) * (sim_time / n_steps)
    times.setflags(write=False)
    return times
