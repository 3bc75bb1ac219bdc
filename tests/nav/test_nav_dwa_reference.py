"""The DWA and the polyline helpers against their plain array form, to the last bit.

``tlfleet.agent.nav.dwa.dwa_control`` and ``tlfleet.agent.nav.polyline`` compute in plain floats and
on coordinate arrays, and leave out other robots that cannot matter; the reference below is the
straightforward numpy form of ltl-planning.md §6 (rollouts (S, T, 2), every robot, every
polyline as one (P, M−1) array) that they replaced. Equality is exact (``==``), not approximate:
the lockstep trajectories depend on every bit of the chosen command — where numpy's sin, cos and
exp are libm's (``dwa_cases.EXACT``, checked on every run). Where numpy uses its own SIMD forms
(x86-64 with AVX-512) the kernel's plain-float trigonometry and the reference's numpy arrays are
a few ulp apart: the command must then be the same (a near-tie may flip in at most 2 of 150
random cycles), the cost and the rollout within 1e-12.

These tests pin the DWA's numpy kernel (``DwaConfig(kernel="python")``); its C kernel is compared
with this one in test_nav_dwa_native.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from dwa_cases import EXACT, GRID, PYTHON, ROBOT_RADIUS, random_cycle, random_path
from tlfleet.agent.nav import polyline
from tlfleet.agent.nav.coupling_limits import VelocityLimits
from tlfleet.agent.nav.dwa import (
    DwaConfig,
    MovingDiscs,
    braking_command,
    dwa_control,
    inflation_cost,
    velocity_window,
)

# ----------------------------------------------------------------------- the reference forms

def ref_distance_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    if len(poly) == 1:
        return np.linalg.norm(points - poly[0], axis=1)
    a = poly[:-1]
    ab = poly[1:] - a
    len2 = np.maximum(np.sum(ab * ab, axis=1), 1e-12)
    ap = points[:, None, :] - a[None, :, :]
    s = np.clip(np.sum(ap * ab[None], axis=2) / len2[None], 0.0, 1.0)
    diff = ap - s[..., None] * ab[None]
    return np.sqrt(np.min(np.sum(diff * diff, axis=2), axis=1))


def ref_project(point: np.ndarray, poly: np.ndarray) -> tuple[int, np.ndarray]:
    if len(poly) == 1:
        return 0, poly[0].copy()
    a = poly[:-1]
    ab = poly[1:] - a
    len2 = np.maximum(np.sum(ab * ab, axis=1), 1e-12)
    s = np.clip(np.sum((point - a) * ab, axis=1) / len2, 0.0, 1.0)
    proj = a + s[:, None] * ab
    k = int(np.argmin(np.sum((proj - point) ** 2, axis=1)))
    return k, proj[k]


def ref_remaining(point: np.ndarray, poly: np.ndarray) -> np.ndarray:
    k, proj = ref_project(point, poly)
    return np.vstack([proj[None, :], poly[k + 1:]])


def ref_point_along(poly: np.ndarray, distance: float) -> np.ndarray:
    if len(poly) == 1 or distance <= 0.0:
        return poly[0].copy()
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if distance >= cum[-1]:
        return poly[-1].copy()
    k = int(np.searchsorted(cum, distance, side="right") - 1)
    s = (distance - cum[k]) / max(seg[k], 1e-12)
    return poly[k] + s * (poly[k + 1] - poly[k])


def ref_length(poly: np.ndarray) -> float:
    if len(poly) < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.diff(poly, axis=0), axis=1)))


def ref_dwa(pose, velocity, path, others: MovingDiscs, config: DwaConfig,
            limits: VelocityLimits | None):
    v0, w0 = float(velocity[0]), float(velocity[1])
    position = np.asarray(pose[:2], dtype=float)
    goal = path[-1]
    if float(np.linalg.norm(goal - position)) <= config.xy_goal_tolerance:
        return (*braking_command(v0, w0, config), 0.0, 0, True, np.zeros((0, 2)))
    v_lo, v_hi, w_lo, w_hi = velocity_window(v0, w0, config)
    if limits:
        v_hi = max(v_lo, min(v_hi, limits.v_max))
        w_lo, w_hi = (min(w_hi, max(w_lo, -limits.omega_max)),
                      max(w_lo, min(w_hi, limits.omega_max)))
    vs = np.linspace(v_lo, v_hi, config.vx_samples) if v_hi > v_lo else np.array([v_lo])
    ws = np.linspace(w_lo, w_hi, config.vtheta_samples) if w_hi > w_lo else np.array([w_lo])
    if w_lo < 0.0 < w_hi and not np.any(ws == 0.0):
        ws = np.sort(np.append(ws, 0.0))
    vs, ws = np.repeat(vs, len(ws)), np.tile(ws, len(vs))
    n_steps = max(1, math.ceil(config.sim_time / config.sim_dt - 1e-9))
    times = np.arange(1, n_steps + 1) * (config.sim_time / n_steps)
    x0, y0, th0 = (float(c) for c in pose[:3])
    w, t, vv = ws[:, None], times[None, :], vs[:, None]
    theta = th0 + w * t
    turning = np.abs(w) > 1e-9
    radius = vv / np.where(turning, w, 1.0)
    x = np.where(turning, x0 + radius * (np.sin(theta) - math.sin(th0)),
                 x0 + vv * t * math.cos(th0))
    y = np.where(turning, y0 - radius * (np.cos(theta) - math.cos(th0)),
                 y0 + vv * t * math.sin(th0))
    points = np.stack([x, y], axis=-1)  # (S, T, 2)
    static = GRID.clearance_at(points)
    clearance = static
    current_static = float(GRID.clearance_at(position))
    current, current_robots = current_static, math.inf
    robots = np.full(static.shape, np.inf)
    if len(others):
        moving = others.centers[None] + times[:, None, None] * others.velocities[None]  # (T, K, 2)
        gaps = np.linalg.norm(points[:, :, None, :] - moving[None], axis=-1) - others.radii
        robots = gaps.min(axis=2)
        clearance = np.minimum(clearance, robots)
        current_robots = float(
            (np.linalg.norm(others.centers - position, axis=1) - others.radii).min())
        current = min(current, current_robots)
    required = min(ROBOT_RADIUS + config.collision_margin, current - 1e-6)
    valid = clearance.min(axis=1) >= required
    if limits and valid.any():
        excess = limits.excess(vs, ws)
        coupled = valid & (excess <= 1e-12)
        if not coupled.any():
            coupled = valid & (excess <= float(excess[valid].min()) + 1e-12)
        valid = coupled
    min_v, min_w = config.min_trans_vel, config.min_rot_vel
    if limits:
        min_v, min_w = min(min_v, 0.5 * limits.v_max), min(min_w, 0.5 * limits.omega_max)
    moving = valid & ((np.abs(vs) >= min_v) | (np.abs(ws) >= min_w))
    if moving.any():
        valid = moving
    if not valid.any():
        return (*braking_command(v0, w0, config), math.inf, 0, False, np.zeros((0, 2)))
    ahead = ref_remaining(position, path)
    carrot = ref_point_along(ahead, config.carrot_distance)
    end = points[:, -1]
    cost = config.path_distance_bias * ref_distance_to_polyline(end, ahead)
    cost += config.goal_distance_bias * np.linalg.norm(end - carrot, axis=1)
    direction = ahead[-1] - (ahead[-2] if len(ahead) >= 2 else position)
    fpd = config.forward_point_distance
    norm = float(np.linalg.norm(direction))
    extended = ahead if norm < 1e-9 else np.vstack([ahead, ahead[-1] + direction * (fpd / norm)])
    front_carrot = ref_point_along(extended, config.carrot_distance + fpd)
    heading = theta[:, -1]
    front = end + fpd * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    cost += config.path_distance_bias * ref_distance_to_polyline(front, extended)
    cost += config.goal_distance_bias * np.linalg.norm(front - front_carrot, axis=1)
    worst = np.maximum(inflation_cost(static, ROBOT_RADIUS, config).max(axis=1),
                       float(inflation_cost(np.array(current_static), ROBOT_RADIUS, config)))
    cost += config.occdist_scale * worst
    worst = np.maximum(inflation_cost(robots, ROBOT_RADIUS, config).max(axis=1),
                       float(inflation_cost(np.array(current_robots), ROBOT_RADIUS, config)))
    cost += config.robot_occdist_scale * worst
    cost += config.speed_bias * (config.max_vel_x - vs) / config.max_vel_x
    cost = np.where(valid, cost, np.inf)
    best = int(np.argmin(cost))
    return (float(vs[best]), float(ws[best]), float(cost[best]), int(valid.sum()), False,
            points[best])


def agrees(result, reference) -> bool:
    """Every bit the same where numpy's trigonometry is libm's (``EXACT``); elsewhere the same
    command, and the cost and the rollout within 1e-12."""
    v, omega, cost, n_valid, reached, trajectory = reference
    if (result.v, result.omega, result.n_valid, result.goal_reached) != (v, omega, n_valid,
                                                                         reached):
        return False
    if result.trajectory.shape != trajectory.shape:
        return False
    if EXACT:
        return result.cost == cost and bool(np.array_equal(result.trajectory, trajectory))
    return (result.cost == pytest.approx(cost, rel=1e-12, abs=1e-12)
            and bool(np.allclose(result.trajectory, trajectory, rtol=0.0, atol=1e-12)))


def assert_same_result(result, reference) -> None:
    assert agrees(result, reference), (result, reference[:5])


@pytest.mark.parametrize("seed", range(8))
def test_dwa_equals_the_array_form_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    config = PYTHON
    outcomes, disagree = set(), 0
    for _ in range(150):
        pose, velocity, path, others, limits = random_cycle(rng)
        result = dwa_control(pose, velocity, path, GRID, ROBOT_RADIUS, others, config, limits)
        disagree += not agrees(result, ref_dwa(pose, velocity, path, others, config, limits))
        outcomes.add("reached" if result.goal_reached else
                     "braked" if result.n_valid == 0 else "moved")
    assert outcomes == {"reached", "braked", "moved"}  # every branch was compared
    assert disagree <= (0 if EXACT else 2)  # elsewhere a near-tie may flip on an ulp


def test_dwa_equals_the_array_form_with_a_robot_just_outside_the_pruning_bound():
    """Other robots placed around the distance where ``_near_discs`` starts leaving them out."""
    config = PYTHON
    pose = np.array([0.0, 0.0, 0.3])
    path = np.array([[1.5, 0.5], [2.5, 2.0]])
    reach = config.max_vel_x * config.sim_time
    for distance in np.linspace(0.3, reach + config.inflation_radius + 0.6, 60):
        for heading in (0.0, 1.0, 2.5):
            others = MovingDiscs(np.array([[distance * math.cos(heading),
                                            distance * math.sin(heading)]]),
                                 np.array([[-0.1, 0.05]]), np.array([0.2]))
            result = dwa_control(pose, (0.3, 0.2), path, GRID, ROBOT_RADIUS, others, config)
            assert_same_result(result, ref_dwa(pose, (0.3, 0.2), path, others, config, None))


@pytest.mark.parametrize("seed", range(4))
def test_polyline_helpers_equal_the_array_form_bit_for_bit(seed):
    rng = np.random.default_rng(100 + seed)
    for _ in range(300):
        start = rng.uniform(-3, 3, size=2)
        poly = random_path(rng, start)
        point = start + rng.normal(size=2)
        points = rng.uniform(-4, 4, size=(int(rng.integers(1, 20)), 2))
        assert np.array_equal(polyline.distance_to_polyline(points, poly),
                              ref_distance_to_polyline(points, poly))
        k, proj = polyline.project_on_polyline(point, poly)
        k_ref, proj_ref = ref_project(point, poly)
        assert k == k_ref and np.array_equal(proj, proj_ref)
        assert np.array_equal(polyline.remaining_polyline(point, poly), ref_remaining(point, poly))
        distance = float(rng.choice([0.0, -1.0, rng.uniform(0, 3), ref_length(poly)]))
        assert np.array_equal(polyline.point_along(poly, distance), ref_point_along(poly, distance))
        assert polyline.polyline_length(poly) == ref_length(poly)
