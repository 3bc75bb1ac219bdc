"""The pymunk world: velocity tracking, limits, no lateral slip, walls, obstacles, contacts,
disturbance, mocap noise, watchdog and determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sim_helpers import distance, omni, scenario, unicycle
from tlfleet.agent.model.scenario import Arena, DiscObstacle, RectObstacle
from tlfleet.sim.world import WALL, Contact, World, native_tracking_available, wrap_angle

DT = 0.001  # [s] one physics step at the default 1 kHz


def world(*robots, seed: int = 0, **kw) -> World:
    return World.from_scenario(scenario(*robots, **kw), np.random.default_rng(seed))


def run(w: World, seconds: float, tick: float = 0.01) -> list[tuple]:
    """Step ``seconds`` of sim time, returning the true poses after every tick."""
    out = []
    for _ in range(round(seconds / tick)):
        w.step(tick)
        out.append(w.poses())
    return out


@pytest.mark.parametrize(("theta", "expected"), [
    (0.0, 0.0), (math.pi, math.pi), (-math.pi, math.pi), (3 * math.pi, math.pi),
    (-3 * math.pi / 2, math.pi / 2), (2 * math.pi + 0.5, 0.5), (-0.5, -0.5),
])
def test_wrap_angle_to_half_open_interval(theta, expected):
    assert wrap_angle(theta) == pytest.approx(expected, abs=1e-12)
    assert -math.pi < wrap_angle(theta) <= math.pi


def test_omni_tracks_world_frame_command_within_acceleration_limits():
    # Heading 90°: a world-frame command must move along world x, not along the heading.
    w = world(omni(1, 0, 0, math.pi / 2, max_lin=0.5, max_ang=3.0, acc_lin=2.0, acc_ang=20.0))
    w.set_command(1, (0.3, -0.4, 1.0), t=0.0)
    prev = w.velocities()[1]
    for _ in range(600):  # 0.6 s, one physics step at a time
        w.step(DT)
        vx, vy, om = w.velocities()[1]
        assert math.hypot(vx - prev[0], vy - prev[1]) <= 2.0 * DT + 1e-12
        assert abs(om - prev[2]) <= 20.0 * DT + 1e-12
        prev = (vx, vy, om)
    assert prev == pytest.approx((0.3, -0.4, 1.0), abs=1e-6)
    # The acceleration limit, not the time constant, is what bounds the start: 0.5 m/s at
    # 2 m/s² takes 0.25 s, so after 0.1 s the speed is at most 0.2 m/s.
    w2 = world(omni(1, 0, 0, max_lin=0.5, acc_lin=2.0))
    w2.set_command(1, (0.5, 0.0, 0.0), t=0.0)
    w2.step(0.1)
    assert w2.velocities()[1][0] == pytest.approx(0.2, abs=2.0 * DT)


@pytest.mark.parametrize(("robot", "u", "expected"), [
    (omni(1, 0, 0, max_lin=0.2, max_ang=1.0), (3.0, 4.0, -5.0), (0.12, 0.16, -1.0)),
    (omni(1, 0, 0, max_lin=0.2, max_ang=1.0), (0.1, 0.0, 0.5), (0.1, 0.0, 0.5)),
    (unicycle(1, 0, 0, max_v=0.3, max_omega=1.0), (-2.0, 3.0), (-0.3, 1.0)),
])
def test_commands_are_clipped_to_the_velocity_limits(robot, u, expected):
    w = world(robot)
    w.set_command(1, u, t=0.0)
    assert w.robots[1].target == pytest.approx(expected)
    w.step(2.0)
    vx, vy, om = w.velocities()[1]
    if robot.kind == "omni":
        assert (vx, vy, om) == pytest.approx(expected, abs=1e-6)
    else:
        # While turning, the heading moves on after each velocity update: an O(v·ω²·dt·τ) lag.
        assert (math.hypot(vx, vy), om) == pytest.approx((abs(expected[0]), expected[1]),
                                                         abs=1e-5)


@pytest.mark.parametrize("u", [(0.1, 0.2), (0.1, math.nan, 0.0), (0.1, 0.0, math.inf)])
def test_malformed_omni_command_is_rejected_and_the_previous_one_kept(u):
    w = world(omni(1, 0, 0))
    w.set_command(1, (0.1, 0.0, 0.0), t=0.0)
    with pytest.raises(ValueError, match="robot 1"):
        w.set_command(1, u, t=0.1)
    assert w.robots[1].target == (0.1, 0.0, 0.0)
    assert w.robots[1].last_command_t == 0.0
    with pytest.raises(KeyError):
        w.set_command(7, (0.0, 0.0, 0.0), t=0.0)


def test_unicycle_has_no_lateral_slip_and_drives_a_circle():
    v, om = 0.3, 1.0  # radius v/ω = 0.3 m
    w = world(unicycle(1, 0.5, -0.5, 0.3, max_v=0.3, max_omega=1.0, acc_v=1.0, acc_omega=2.0))
    w.set_command(1, (v, om), t=0.0)
    w.step(1.0)  # past the acceleration transient
    body = w.robots[1].body
    x0, y0, th0 = w.poses()[0][1:]
    center = (x0 - v / om * math.sin(th0), y0 + v / om * math.cos(th0))
    for _ in range(700):  # more than one full turn (2π s)
        w.step(0.01)
        c, s = math.cos(body.angle), math.sin(body.angle)
        lateral = -body.velocity.x * s + body.velocity.y * c
        assert abs(lateral) < 1e-9
        x, y, _ = w.poses()[0][1:]
        assert math.hypot(x - center[0], y - center[1]) == pytest.approx(v / om, abs=2e-3)


def test_unicycle_forward_acceleration_is_limited():
    w = world(unicycle(1, 0, 0, max_v=0.3, acc_v=0.5))
    w.set_command(1, (0.3, 0.0), t=0.0)
    speeds = []
    for _ in range(700):
        w.step(DT)
        speeds.append(math.hypot(*w.velocities()[1][:2]))
    assert max(np.diff([0.0, *speeds])) <= 0.5 * DT + 1e-12
    assert speeds[299] == pytest.approx(0.15, abs=1e-3)  # 0.5 m/s² for 0.3 s
    assert speeds[-1] == pytest.approx(0.3, abs=1e-4)  # 5 τ after the ramp


@pytest.mark.parametrize("robot", [omni(1, 2.5, 0.3, max_lin=1.0),
                                   unicycle(1, 2.5, 0.3, 0.0, max_v=1.0)])
def test_robot_driven_into_the_wall_stops_there_with_one_contact(robot):
    w = world(robot)
    w.set_command(1, (1.0, 0.0, 0.0) if robot.kind == "omni" else (1.0, 0.0), t=0.0)
    trajectory = run(w, 3.0)
    xs = [p[0][1] for p in trajectory]
    assert max(xs) <= 3.5 - robot.radius + 0.005  # never through the wall
    assert xs[-1] == pytest.approx(3.5 - robot.radius, abs=0.005)
    assert w.drain_contacts() == [Contact(1, WALL, "arena")]
    assert w.drain_contacts() == []  # drained


def test_head_on_robots_do_not_pass_through_each_other():
    w = world(omni(1, -1.0, 0.0, max_lin=1.0), omni(2, 1.0, 0.0, max_lin=1.0))
    w.set_command(1, (1.0, 0.0, 0.0), t=0.0)
    w.set_command(2, (-1.0, 0.0, 0.0), t=0.0)
    gaps = [distance(p[0][1:], p[1][1:]) for p in run(w, 3.0)]
    assert min(gaps) >= 0.4 - 0.005  # 2 R, up to the collision slop and one step
    (_, x1, _, _), (_, x2, _, _) = w.poses()
    assert x1 < x2  # still in their original order
    assert w.drain_contacts() == [Contact(1, 2)]


def test_head_on_unicycles_collide_once_and_stay_apart():
    w = world(unicycle(3, -1.0, 0.0, 0.0, max_v=0.3), unicycle(1, 1.0, 0.0, math.pi, max_v=0.3))
    w.set_command(1, (0.3, 0.0), t=0.0)
    w.set_command(3, (0.3, 0.0), t=0.0)
    gaps = [distance(p[0][1:], p[1][1:]) for p in run(w, 6.0)]
    assert min(gaps) >= 0.4 - 0.005
    assert w.drain_contacts() == [Contact(1, 3)]  # a < b whatever the order of the shapes


def test_static_obstacles_block_robots_and_are_named_in_contacts():
    arena = Arena(obstacles=(RectObstacle(1.0, -0.5, 2.0, 0.5, name="box"),
                             DiscObstacle((0.0, 2.0), 0.5, name="pillar")))
    w = world(omni(1, 0.0, 0.0, max_lin=1.0), omni(2, 0.0, 0.5, max_lin=1.0), arena=arena)
    w.set_command(1, (1.0, 0.0, 0.0), t=0.0)  # into the box's left face at x = 1
    w.set_command(2, (0.0, 1.0, 0.0), t=0.0)  # into the pillar from below
    run(w, 2.0)
    (_, x1, y1, _), (_, _, y2, _) = w.poses()
    assert x1 == pytest.approx(1.0 - 0.2, abs=0.005) and y1 == pytest.approx(0.0, abs=1e-6)
    assert y2 == pytest.approx(2.0 - 0.5 - 0.2, abs=0.005)
    assert sorted(w.drain_contacts(), key=lambda c: c.a) == [
        Contact(1, WALL, "obstacle:box"), Contact(2, WALL, "obstacle:pillar")]


def test_disturbance_is_bounded_and_moves_a_resting_robot():
    bound = 0.05  # [m/s]
    w = world(omni(1, 0, 0), unicycle(2, 1, 1), seed=4, disturbance=bound)
    before = w.poses()
    norms, speeds = [], []
    for _ in range(300):
        w.step(0.01)
        after = w.poses()
        for rid in (1, 2):
            norms.append(math.hypot(*w.robots[rid].disturbance))
        for b, a in zip(before, after, strict=True):
            speeds.append(distance(b[1:], a[1:]) / 0.01)
        before = after
    assert max(norms) <= bound * (1 + 1e-12)
    assert max(norms) > 0.9 * bound  # uniform in the ball: the bound is nearly reached
    assert max(speeds) <= bound * (1 + 1e-9)  # the robots have a zero command: w_i only
    assert np.mean(speeds) > 0.3 * bound


def test_mocap_noise_statistics_and_wrapped_heading():
    sigma = 0.01
    w = world(omni(1, 0.5, -0.25, math.pi), seed=11, mocap_noise=sigma)
    samples = np.array([w.mocap_poses()[0][1:] for _ in range(4000)])
    true = np.array([0.5, -0.25])
    assert np.all(np.abs(samples[:, :2].mean(axis=0) - true) < 4 * sigma / math.sqrt(4000))
    assert samples[:, 0].std() == pytest.approx(sigma, rel=0.1)
    assert samples[:, 1].std() == pytest.approx(sigma, rel=0.1)
    headings = samples[:, 2]
    assert np.all((headings > -math.pi) & (headings <= math.pi))
    assert (headings < 0).any() and (headings > 0).any()  # noise around π wraps to both ends
    offsets = np.angle(np.exp(1j * (headings - math.pi)))
    assert offsets.std() == pytest.approx(sigma, rel=0.1)
    assert w.poses()[0][1:3] == (0.5, -0.25)  # noise is not in the physics


def test_without_noise_mocap_is_the_true_pose_and_draws_nothing():
    w = world(omni(1, 0.5, -0.25), seed=1)
    state = w.rng.bit_generator.state
    assert w.mocap_poses() == w.poses()
    w.step(0.01)
    assert w.rng.bit_generator.state == state


def test_watchdog_stops_a_silent_robot_once_until_commanded_again():
    w = world(omni(1, 0, 0, max_lin=0.2), omni(2, 1, 1))  # robot 2 is never commanded
    w.set_command(1, (0.2, 0.0, 0.0), t=0.0)
    assert w.check_watchdog(0.5) == []  # exactly the watchdog period: still fresh
    w.step(0.5)
    assert w.check_watchdog(0.51) == [1]
    assert w.check_watchdog(0.6) == []  # reported once
    w.step(0.5)
    assert w.velocities()[1] == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
    x = w.poses()[0][1]
    w.step(0.5)
    assert w.poses()[0][1] == pytest.approx(x, abs=1e-9)
    w.set_command(1, (0.1, 0.0, 0.0), t=1.5)
    assert w.check_watchdog(1.9) == []
    assert w.check_watchdog(2.1) == [1]


def test_same_seed_same_world_different_seed_different_world():
    def trace(seed: int) -> list:
        w = world(omni(1, 0, 0), unicycle(2, -1, 0), omni(3, 0.45, 0.05), seed=seed,
                  disturbance=0.05, mocap_noise=0.01)
        w.set_command(1, (0.2, 0.0, 0.0), t=0.0)
        w.set_command(2, (0.3, 0.5), t=0.0)
        w.set_command(3, (-0.2, 0.0, 0.0), t=0.0)
        out = []
        for _ in range(200):
            w.step(0.01)
            out.append((w.mocap_poses(), tuple(w.drain_contacts())))
        return out

    first = trace(5)
    assert first == trace(5)
    assert first != trace(6)
    assert any(contacts for _, contacts in first)


def _reference_track(robot, body, _gravity, _damping, dt):
    """The tracking law through pymunk's public ``Body`` API (as ``body.velocity_func``): the
    definition the fast Chipmunk callback of ``SimRobot`` must reproduce bit for bit."""
    old_wx, old_wy, old_ww = robot._applied
    vel = body.velocity
    vx, vy = vel.x - old_wx, vel.y - old_wy
    omega = body.angular_velocity - old_ww
    gain = dt / max(robot._tau, dt)
    dv_max, dw_max = robot.acc_lin * dt, robot.acc_ang * dt
    if robot.kind == "omni":
        ux, uy, uw = robot.target
        dvx, dvy = (ux - vx) * gain, (uy - vy) * gain
        norm = math.sqrt(dvx * dvx + dvy * dvy)  # not hypot: the C law's correctly rounded norm
        if norm > dv_max:
            scale = dv_max / norm
            while True:
                xs, ys = dvx * scale, dvy * scale
                if not math.sqrt(xs * xs + ys * ys) > dv_max:
                    break
                scale = math.nextafter(scale, 0.0)
            dvx, dvy = dvx * scale, dvy * scale
        vx, vy = vx + dvx, vy + dvy
    else:
        u_lin, uw = robot.target
        c, s = math.cos(body.angle), math.sin(body.angle)
        v = vx * c + vy * s
        v += min(dv_max, max(-dv_max, (u_lin - v) * gain))
        vx, vy = v * c, v * s
    omega += min(dw_max, max(-dw_max, (uw - omega) * gain))
    wx, wy, ww = robot._applied = robot.disturbance
    body.velocity = (vx + wx, vy + wy)
    body.angular_velocity = omega + ww


@pytest.mark.parametrize("tracking", [
    "python", pytest.param("native", marks=pytest.mark.skipif(
        not native_tracking_available(), reason="the C tracking law was not built"))])
def test_the_chipmunk_velocity_callback_equals_the_public_api_law(tracking, monkeypatch):
    """Robots crossing, pushing each other and a wall, both kinds, with disturbance: the same
    poses to the last bit as with the law written against ``body.velocity_func`` (the Python
    law and the C law, tests/sim/test_sim_tracking_native.py)."""
    monkeypatch.setenv("TLFLEET_TRACKING", tracking)
    robots = (omni(1, -1.0, 0.0), omni(2, 1.0, 0.05), unicycle(3, 0.0, -1.0, math.pi / 2),
              unicycle(4, 3.0, 2.0))
    commands = {1: (1.0, 0.0, 0.5), 2: (-1.0, 0.0, -0.3), 3: (0.8, 0.2), 4: (0.5, 0.0)}
    trajectories = []
    for reference in (False, True):
        w = world(*robots, seed=7, disturbance=0.05)
        if reference:
            for robot in w.robots.values():
                robot.body.velocity_func = (
                    lambda body, g, d, dt, robot=robot: _reference_track(robot, body, g, d, dt))
        for rid, u in commands.items():
            w.set_command(rid, u, 0.0)
        trajectories.append(run(w, 3.0))
        assert w.drain_contacts()  # they did collide
    assert trajectories[0] == trajectories[1]
