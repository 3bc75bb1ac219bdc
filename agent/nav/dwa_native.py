"""The DWA cycle in C: the bridge from ``tlfleet.agent.nav.dwa`` to ``tlfleet.agent.nav._dwa``.

``agent/nav/dwa_kernel.c`` runs a whole cycle of ``dwa.dwa_control`` with the numpy kernel's
floating-point operations in the same order (docs/performance.md, *the DWA in C*); cffi builds it
at install time where a C compiler is (``setup.py``, ``_dwa_build.py``). Without it
:func:`available` is False and ``dwa.py`` runs its numpy kernel. This module only hands the
arrays over and reads the result back.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

try:  # optional: the install builds it where a C compiler is
    from tlfleet.agent.nav import _dwa as _native
except ImportError:  # pragma: no cover - depends on the install
    _native = None

if TYPE_CHECKING:
    from tlfleet.agent.nav.coupling_limits import VelocityLimits
    from tlfleet.agent.nav.dwa import DwaConfig, MovingDiscs
    from tlfleet.agent.nav.grid import OccupancyGrid


def available() -> bool:
    """Whether the C kernel (``tlfleet.agent.nav._dwa``) was built at install time."""
    return _native is not None


@functools.lru_cache(maxsize=32)
def _params(config: DwaConfig, robot_radius: float):
    """The C kernel's ``tl_dwa_params`` of a configuration and robot radius (kept: the
    configuration is frozen)."""
    return _native.ffi.new("tl_dwa_params *", {
        "max_vel_x": config.max_vel_x, "min_vel_x": config.min_vel_x,
        "max_rot_vel": config.max_rot_vel, "acc_lim_x": config.acc_lim_x,
        "acc_lim_theta": config.acc_lim_theta, "controller_period": config.controller_period,
        "vx_samples": config.vx_samples, "vtheta_samples": config.vtheta_samples,
        "path_distance_bias": config.path_distance_bias,
        "goal_distance_bias": config.goal_distance_bias, "occdist_scale": config.occdist_scale,
        "xy_goal_tolerance": config.xy_goal_tolerance,
        "forward_point_distance": config.forward_point_distance,
        "inflation_radius": config.inflation_radius,
        "cost_scaling_factor": config.cost_scaling_factor,
        "collision_margin": config.collision_margin, "carrot_distance": config.carrot_distance,
        "speed_bias": config.speed_bias, "robot_occdist_scale": config.robot_occdist_scale,
        "min_trans_vel": config.min_trans_vel, "min_rot_vel": config.min_rot_vel,
        "robot_radius": float(robot_radius),
    })


def _doubles(values, shape: tuple[int, ...]) -> np.ndarray:
    """``values`` as a C-contiguous float64 array of ``shape`` (a copy only where needed)."""
    return np.ascontiguousarray(values, dtype=np.float64).reshape(shape)


def control(pose: Sequence[float], velocity: Sequence[float], path: np.ndarray,
            grid: OccupancyGrid, robot_radius: float, others: MovingDiscs, config: DwaConfig,
            limits: VelocityLimits | None, times: np.ndarray, scores: dict | None = None
            ) -> tuple[float, float, float, int, bool, np.ndarray]:
    """One DWA cycle in C: ``dwa.dwa_control``'s arguments and rollout ``times`` (T,) [s] in,
    ``DwaResult``'s fields out (v [m/s], ω [rad/s], cost, admissible samples, goal reached, the
    chosen rollout (T, 2) [m]). ``scores``, when given, receives every sample's least clearance
    [m], cost and excess over the coupling limits (tests)."""
    ffi, lib = _native.ffi, _native.lib
    vertices = _doubles(path, (-1, 2))
    if not len(vertices):
        raise IndexError("dwa_control: the path has no vertex")
    clearance = _doubles(grid.clearance, grid.clearance.shape)
    ny, nx = clearance.shape
    layer = ffi.new("tl_dwa_grid *", {
        "clearance": ffi.from_buffer("double[]", clearance), "nx": nx, "ny": ny,
        "ox": float(grid.origin[0]), "oy": float(grid.origin[1]), "res": float(grid.resolution)})
    k = len(others)
    centers = _doubles(others.centers, (k, 2))
    velocities = _doubles(others.velocities, (k, 2))
    radii = _doubles(others.radii, (k,))
    if limits:
        rows = _doubles([(c.a_v, c.a_omega, c.bound) for c in limits.constraints], (-1, 3))
        v_cap, w_cap = limits.v_max, limits.omega_max
    else:
        rows, v_cap, w_cap = np.zeros((0, 3)), math.inf, math.inf
    trajectory = np.empty((len(times), 2))
    result = ffi.new("tl_dwa_result *")
    most = config.vx_samples * (config.vtheta_samples + 1)
    min_clearance, cost, excess, count = (
        (np.empty(most), np.empty(most), np.empty(most), ffi.new("int *"))
        if scores is not None else (None, None, None, ffi.NULL))
    buffer = functools.partial(ffi.from_buffer, "double[]")
    status = lib.tl_dwa_control(
        _params(config, robot_radius), layer,
        float(pose[0]), float(pose[1]), float(pose[2]), float(velocity[0]), float(velocity[1]),
        len(vertices), buffer(vertices), k, buffer(centers), buffer(velocities), buffer(radii),
        len(rows), buffer(rows), v_cap, w_cap, len(times), buffer(times), result,
        buffer(trajectory),
        *((buffer(min_clearance), buffer(cost), buffer(excess)) if scores is not None
          else (ffi.NULL, ffi.NULL, ffi.NULL)), count)
    if status != 0:
        raise MemoryError("dwa_control: the C kernel could not allocate its samples")
    if scores is not None:
        n = count[0]
        scores.update(min_clearance=min_clearance[:n], cost=cost[:n], excess=excess[:n])
    if result.goal_reached:
        return result.v, result.omega, 0.0, 0, True, np.zeros((0, 2))
    if result.n_valid == 0:
        return result.v, result.omega, math.inf, 0, False, np.zeros((0, 2))
    return result.v, result.omega, result.cost, result.n_valid, False, trajectory
