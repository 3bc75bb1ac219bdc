"""The DWA's C kernel (``agent/nav/dwa_kernel.c``, built at install time as
``tlfleet.agent.nav._dwa``) against its numpy kernel, the checked reference of
test_nav_dwa_reference.py.

The C kernel does the numpy kernel's floating-point operations in the same order, with libm's
sin, cos and exp. Where numpy's own sin, cos and exp are libm's (this machine kind: x86-64
without AVX-512; checked below on every run) the two kernels agree to the last bit, on random
cycles and on Scenario 1's LTL agents replayed for a minute. Elsewhere numpy may use other
implementations a few ulp apart, and the test then allows that much.

The C kernel is an accelerator a user's install may lack (no C compiler): the tests that need it
skip without it, but fail under ``TLFLEET_REQUIRE_SYSTEM=1`` (CI), where it must have been built.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import tlfleet.agent.nav.dwa as dwa_module
import tlfleet.agent.nav.dwa_native as dwa_native
from dwa_cases import EXACT, GRID, PYTHON, ROBOT_RADIUS, random_cycle
from tlfleet.agent.nav.dwa import DwaConfig, MovingDiscs, dwa_control, native_kernel_available
from tlfleet.agent.nav.executor import Executor, ExecutorConfig

NATIVE = replace(PYTHON, kernel="native") if native_kernel_available() else None

c_kernel_built = pytest.mark.skipif(not native_kernel_available(),
                                    reason="the DWA's C kernel (tlfleet.agent.nav._dwa) was not "
                                           "built: no C compiler at install time")


def same(native, python) -> bool:
    """The two kernels' results agree: to the last bit where numpy's trig is libm's, else the
    same command and a cost and rollout within a few ulp."""
    if EXACT:
        return ((native.v, native.omega, native.cost, native.n_valid, native.goal_reached)
                == (python.v, python.omega, python.cost, python.n_valid, python.goal_reached)
                and native.trajectory.shape == python.trajectory.shape
                and bool(np.array_equal(native.trajectory, python.trajectory)))
    return ((native.v, native.omega, native.n_valid) == (python.v, python.omega, python.n_valid)
            and native.cost == pytest.approx(python.cost, rel=1e-12, abs=1e-12)
            and np.allclose(native.trajectory, python.trajectory, rtol=0.0, atol=1e-12))


@pytest.mark.needs_system
@c_kernel_built
@pytest.mark.parametrize("seed", range(6))
def test_c_kernel_equals_numpy_kernel_on_random_cycles(seed):
    """Poses inside the arena, at its edge and beyond it (the off-grid lookups), 0–6 other
    robots near and far (the pruned square roots), coupling limits, every outcome."""
    rng = np.random.default_rng(500 + seed)
    outcomes, disagree, limited = set(), 0, 0
    for _ in range(200):
        pose, velocity, path, others, limits = random_cycle(rng)
        args = (pose, velocity, path, GRID, ROBOT_RADIUS, others)
        scores = {}
        native = dwa_module._control_native(*args, NATIVE, limits, scores)
        python = dwa_control(*args, PYTHON, limits)
        disagree += not same(native, python)
        if limits and EXACT and not python.goal_reached:  # the samples' excess, every bit
            vs, ws = dwa_module._samples(*velocity, PYTHON, limits)
            assert scores["excess"].tolist() == limits.excess(vs, ws).tolist()
            limited += 1
        outcomes.add("reached" if python.goal_reached else
                     "braked" if python.n_valid == 0 else "moved")
    assert outcomes == {"reached", "braked", "moved"}  # every branch was compared
    assert disagree <= (0 if EXACT else 2)  # elsewhere a near-tie may flip on an ulp
    assert limited >= 40 or not EXACT


@pytest.mark.needs_system
@c_kernel_built
def test_c_kernel_equals_numpy_kernel_with_robots_at_the_clearance():
    """Other robots placed so that their gap to the rollouts crosses the clearance the grid
    gives, where the C kernel's skipped square roots must not change the least clearance."""
    rng = np.random.default_rng(11)
    pose = np.array([0.3, -0.2, 0.7])
    path = np.array([[1.0, 0.6], [2.0, 1.8]])
    checked = 0
    for distance in np.linspace(0.25, 1.6, 80):
        for heading in rng.uniform(-math.pi, math.pi, 4):
            center = pose[:2] + distance * np.array([math.cos(heading), math.sin(heading)])
            others = MovingDiscs(center[None], rng.normal(scale=0.1, size=(1, 2)),
                                 np.array([float(rng.choice([0.15, 0.2]))]))
            args = (pose, (0.25, 0.3), path, GRID, ROBOT_RADIUS, others)
            assert same(dwa_control(*args, NATIVE), dwa_control(*args, PYTHON))
            checked += 1
    assert checked == 320


@pytest.mark.needs_system
@c_kernel_built
def test_skipped_square_roots_never_change_the_least_clearance():
    """The C kernel skips a robot's square root where its gap must exceed both the least
    clearance found so far and the inflation radius (near a wall, the least clearance). A
    standing robot is placed so that its gap to one rollout point is that
    point's grid clearance d times 1 + δ, for δ from −1e-4 to 1e-4 down to 1e-15: every
    sample's least clearance must stay equal to the numpy kernel's, and the robot must set the
    minimum for δ < 0."""
    pose, velocity = (2.9, -0.3, 0.4), (0.2, 0.3)  # heading for the wall at x = 3.5
    path = np.array([[3.0, 0.8], [2.5, 2.0]])
    vs, ws = dwa_module._samples(*velocity, PYTHON)
    times = dwa_module._times(PYTHON.sim_time, PYTHON.sim_dt)
    reach = float(np.abs(vs).max()) * float(times[-1])
    x, y, _, _, base, _, _ = dwa_module._clearances(pose, vs, ws, times, GRID, [], reach)
    radius = 0.2
    lowered = 0
    clearance = GRID.clearance_xy(x, y)
    points = np.argwhere((clearance > 0.05) & (clearance < 0.3))  # free, near the wall
    assert len(points) >= 10
    for i, k in points[[0, len(points) // 2, -1]].tolist():
        d = float(clearance[i, k])
        for delta in (-1e-4, -1e-6, -1e-8, -1e-10, -1e-12, -1e-15, 0.0, 1e-15, 1e-12, 1e-8,
                      1e-4):
            disc = (float(x[i, k]) + d * (1.0 + delta) + radius, float(y[i, k]), 0.0, 0.0,
                    radius)
            others = MovingDiscs(np.array([disc[:2]]), np.zeros((1, 2)), np.array([radius]))
            near = dwa_module._near_discs(others, pose[0], pose[1], reach, float(times[-1]),
                                          PYTHON)
            assert near == [disc]
            python = dwa_module._clearances(pose, vs, ws, times, GRID, near, reach)[4]
            scores = {}
            dwa_module._control_native(pose, velocity, path, GRID, ROBOT_RADIUS, others, NATIVE,
                                       None, scores)
            assert scores["min_clearance"].tolist() == python.tolist(), (i, k, delta)
            lowered += python[i] < base[i]
    assert lowered >= 3 * 5  # the robot was the nearest obstacle in the δ < 0 placements


@pytest.mark.needs_system
@c_kernel_built
def test_c_kernel_gives_scenario1_ltl_agents_the_same_commands(scenarios_dir):
    """Scenario 1's two LTL agents stepped as their processes step them (every 20th frame, the
    deferred re-plan after the command) over 40 s of a kinematic replay, once per kernel: the
    same commands, to the last bit where numpy's trig is libm's."""
    from tlfleet.agent.runtime.loop import TickInput
    from tlfleet.agent.runtime.ltl_agent import LtlCore
    from tlfleet.agent.scenario import load_scenario
    from tlfleet.bus.protocol.messages import MocapFrame

    scenario = load_scenario(scenarios_dir / "scenario1.toml")

    def replay(kernel: str) -> list[tuple[float, float]]:
        config = ExecutorConfig(dwa=DwaConfig(kernel=kernel))
        cores = {r.id: LtlCore(scenario, r.id,
                               executor=Executor.from_scenario(scenario, r.id, config))
                 for r in scenario.robots if r.kind == "unicycle"}
        assert {core.agent.executor.config.dwa.kernel for core in cores.values()} == {kernel}
        states = {j: core.initial_state(core.plan())[0] for j, core in cores.items()}
        poses = {r.id: tuple(map(float, r.pose)) for r in scenario.robots}
        commands = []
        for k in range(0, 4000, 20):
            frame = MocapFrame(k / 100, k, tuple((i, *p) for i, p in sorted(poses.items())))
            for j, core in cores.items():
                states[j], out = core.step(states[j], TickInput(frame))
                states[j] = core.after_command(states[j])
                commands.append(out.u)
                v, w = out.u
                x, y, th = poses[j]
                for _ in range(20):
                    x, y, th = (x + 0.01 * v * math.cos(th), y + 0.01 * v * math.sin(th),
                                th + 0.01 * w)
                poses[j] = (x, y, th)
        return commands

    native, python = replay("native"), replay("python")
    assert sum(v != 0.0 for v, _ in python) > 100  # the robots drove
    if EXACT:
        assert native == python
    else:
        assert np.allclose(native, python, rtol=0.0, atol=1e-9)


def test_the_kernel_setting_is_checked(monkeypatch):
    with pytest.raises(ValueError, match=r"DwaConfig.kernel .*TLFLEET_DWA.*auto, native, "
                                         r"python.*'fast'"):
        DwaConfig(kernel="fast")
    monkeypatch.setenv("TLFLEET_DWA", "python")
    assert DwaConfig().kernel == "python" and not DwaConfig().native
    monkeypatch.setenv("TLFLEET_DWA", "turbo")
    with pytest.raises(ValueError, match="'turbo'"):
        DwaConfig()


def test_without_the_c_kernel_auto_runs_numpy_and_native_is_refused(monkeypatch):
    monkeypatch.delenv("TLFLEET_DWA", raising=False)
    monkeypatch.setattr(dwa_native, "_native", None)
    assert not native_kernel_available()
    with pytest.raises(ValueError, match="not built"):
        DwaConfig(kernel="native")
    config = DwaConfig()
    assert config.kernel == "auto" and not config.native
    path = np.array([[1.0, 0.0], [2.0, 0.5]])
    result = dwa_control((0.0, 0.0, 0.0), (0.1, 0.0), path, GRID, ROBOT_RADIUS, None, config)
    assert result.v > 0.0 and result.n_valid > 0  # the numpy kernel drove it
