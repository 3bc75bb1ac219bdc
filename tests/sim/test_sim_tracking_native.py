"""The C tracking law (``sim/tracking.c``, built at install time as ``tlfleet.sim._tracking``)
against the Python law (``SimRobot.track``), its fallback: the same trajectories to the last bit, on
the paper's scenarios and on robots pushing each other and the walls, and the same velocity after
one physics step from random states around the acceleration limits.

The C law is an accelerator a user's install may lack (no C compiler): the tests that need it
skip without it, but fail under ``TLFLEET_REQUIRE_SYSTEM=1`` (CI), where it must have been built.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import tlfleet.sim.world as world_module
from sim_helpers import omni, scenario, unicycle
from tlfleet.agent.model.scenario import Arena, DiscObstacle
from tlfleet.agent.scenario import load_scenario
from tlfleet.sim.world import World, WorldConfig, native_tracking_available

c_law_built = pytest.mark.skipif(not native_tracking_available(),
                                 reason="the C tracking law (tlfleet.sim._tracking) was not "
                                        "built: no C compiler at install time")


def trace(scn, tracking: str, ticks: int, seed: int = 3) -> list:
    """Random commands (some far beyond the limits, so the acceleration limits and the command
    clipping act) every few ticks; the true poses, velocities and contacts after every tick."""
    w = World.from_scenario(scn, np.random.default_rng(seed), WorldConfig(tracking=tracking))
    assert w.config.native_tracking is (tracking == "native")
    rng = np.random.default_rng(seed + 100)
    out = []
    for k in range(ticks):
        if k % 7 == 0:
            for rid, robot in w.robots.items():
                size = 3 if robot.kind == "omni" else 2
                w.set_command(rid, tuple(rng.uniform(-2.0, 2.0, size).tolist()), k * 0.01)
        w.step(0.01)
        out.append((w.poses(), w.velocities(), tuple(w.drain_contacts())))
    return out


@pytest.mark.needs_system
@c_law_built
@pytest.mark.parametrize("name", ["scenario1", "scenario2", "scenario3"])
def test_c_law_equals_python_law_on_the_paper_scenarios(name, scenarios_dir):
    scn = load_scenario(scenarios_dir / f"{name}.toml")
    assert trace(scn, "native", 1500) == trace(scn, "python", 1500)


@pytest.mark.needs_system
@c_law_built
def test_c_law_equals_python_law_through_collisions_walls_and_disturbance():
    """Omni and unicycle robots driven into each other, an obstacle and the walls of a small
    arena, under disturbance and mocap noise."""
    arena = Arena(xmin=-1.5, xmax=1.5, ymin=-1.5, ymax=1.5,
                  obstacles=(DiscObstacle(center=(0.0, 0.9), radius=0.3),))
    scn = scenario(omni(1, -1.0, 0.0), omni(2, 1.0, 0.05), unicycle(3, 0.0, -1.0, math.pi / 2),
                   unicycle(4, 0.8, 0.8, 2.0), omni(5, -0.8, -0.9, 0.3), arena=arena,
                   disturbance=0.05, mocap_noise=0.01)
    python, native = trace(scn, "python", 1500, seed=11), trace(scn, "native", 1500, seed=11)
    assert sum(len(contacts) for _, _, contacts in python) > 10  # they did collide
    assert native == python


@pytest.mark.needs_system
@c_law_built
def test_c_law_equals_python_law_from_random_states_at_the_limits():
    """2 000 random states, one physics step each: velocities, headings, commands and
    disturbances drawn so that the velocity change lies near the acceleration limit (where the
    norm's last bit decides whether it is scaled), on both kinds."""
    rng = np.random.default_rng(2026)
    robots = (omni(1, -1.0, -1.0, acc_lin=2.0, acc_ang=5.0, max_lin=5.0, max_ang=5.0),
              unicycle(2, 1.0, 1.0, acc_v=1.0, acc_omega=3.0, max_v=5.0, max_omega=5.0))
    worlds = {mode: World.from_scenario(scenario(*robots), np.random.default_rng(0),
                                        WorldConfig(tracking=mode))
              for mode in ("python", "native")}
    dv_limit = {1: 2.0 * 0.001, 2: 1.0 * 0.001}  # acc · dt [m/s] per physics step
    gain = 0.001 / WorldConfig().tracking_tau
    scaled = 0
    for _ in range(2000):
        velocity = {rid: rng.uniform(-1.0, 1.0, 3).tolist() for rid in (1, 2)}
        angle = {rid: float(rng.uniform(-math.pi, math.pi)) for rid in (1, 2)}
        disturbance = {rid: tuple(rng.uniform(-0.05, 0.05, 3).tolist()) for rid in (1, 2)}
        # omni: |u − v| · gain within 0.1 % of dv_max, the norm's last bit decides the scaling
        direction = rng.normal(size=2)
        direction *= dv_limit[1] / gain * float(rng.uniform(0.999, 1.001)) / np.hypot(*direction)
        vx, vy, w = velocity[1]
        commands = {1: (vx + float(direction[0]), vy + float(direction[1]),
                        w + float(rng.uniform(-0.2, 0.2))),
                    2: (float(rng.uniform(-1.0, 1.0)), float(rng.uniform(-1.0, 1.0)))}
        scaled += float(np.hypot(*direction)) * gain > dv_limit[1]
        after = {}
        for mode, world in worlds.items():
            for rid in (1, 2):
                robot = world.robots[rid]
                robot.body.velocity = tuple(velocity[rid][:2])
                robot.body.angular_velocity = velocity[rid][2]
                robot.body.angle = angle[rid]
                robot.disturbance = disturbance[rid]
                world.set_command(rid, commands[rid], 0.0)
            world.step(0.001)
            after[mode] = (world.velocities(), world.poses())
        assert after["native"] == after["python"]
    assert 500 < scaled < 1500  # both sides of the limit were exercised


def test_the_tracking_setting_is_checked(monkeypatch):
    with pytest.raises(ValueError, match=r"WorldConfig.tracking .*TLFLEET_TRACKING.*auto, "
                                         r"native, python.*'fast'"):
        WorldConfig(tracking="fast")
    monkeypatch.setenv("TLFLEET_TRACKING", "python")
    assert WorldConfig().tracking == "python" and not WorldConfig().native_tracking
    monkeypatch.setenv("TLFLEET_TRACKING", "turbo")
    with pytest.raises(ValueError, match="'turbo'"):
        WorldConfig()


def test_without_the_c_law_auto_runs_the_python_law_and_native_is_refused(monkeypatch):
    monkeypatch.delenv("TLFLEET_TRACKING", raising=False)
    monkeypatch.setattr(world_module, "_native", None)
    assert not native_tracking_available()
    with pytest.raises(ValueError, match="not built"):
        WorldConfig(tracking="native")
    config = WorldConfig()
    assert config.tracking == "auto" and not config.native_tracking
    w = World.from_scenario(scenario(omni(1, 0.0, 0.0)), np.random.default_rng(0), config)
    w.set_command(1, (0.2, 0.0, 0.0), 0.0)
    w.step(0.5)
    assert w.robots[1]._native is None
    assert w.velocities()[1][0] == pytest.approx(0.2, abs=1e-9)  # the Python law tracked it


def bits(poses) -> tuple:
    """Poses with every float as its exact bits (``==`` takes −0.0 for 0.0)."""
    return tuple((rid, *(v.hex() for v in values)) for rid, *values in poses)


@pytest.mark.needs_system
@c_law_built
def test_c_pose_read_out_equals_python_from_random_states():
    """``tl_read_poses`` (``World.poses`` and ``World.mocap_poses`` with the C law) against the
    Python read-out: 500 random states of 6 robots, headings anywhere (many turns, exactly ±π,
    next to ±π) and mocap noise on and off; the same values to the last bit and the same random
    stream afterwards."""
    rng = np.random.default_rng(7)
    robots = tuple(omni(i, -2.0 + 0.7 * i, 0.0) for i in range(1, 4)) + tuple(
        unicycle(i, -2.0 + 0.7 * i, 1.0, 0.5) for i in range(4, 7))
    specials = (math.pi, -math.pi, math.nextafter(math.pi, 0.0),
                math.nextafter(-math.pi, 0.0), 3 * math.pi, 0.0, -0.0)
    for noise in (0.0, 0.05):
        scn = scenario(*robots, mocap_noise=noise)
        worlds = {mode: World.from_scenario(scn, np.random.default_rng(5),
                                            WorldConfig(tracking=mode))
                  for mode in ("python", "native")}
        assert worlds["native"]._native_cp is not None and worlds["python"]._native_cp is None
        for k in range(500):
            angles = rng.uniform(-40.0, 40.0, len(robots)).tolist()
            if k % 5 == 0:
                angles[k % len(robots)] = specials[k % len(specials)]
            positions = rng.uniform(-2.5, 2.5, (len(robots), 2)).tolist()
            for w in worlds.values():
                for robot, angle, (x, y) in zip(w.robots.values(), angles, positions,
                                                strict=True):
                    robot.body.angle = angle
                    robot.body.position = (x, y)
            python, native = worlds["python"], worlds["native"]
            assert bits(native.poses()) == bits(python.poses())
            got, expected = native.mocap_poses(), python.mocap_poses()
            assert bits(got) == bits(expected)
            assert all(-math.pi < th <= math.pi for _, _, _, th in got)
        assert worlds["native"].rng.random() == worlds["python"].rng.random()
