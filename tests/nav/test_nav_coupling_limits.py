"""Coupling-aware limits of LTL robots (docs/coupling.md): derivation, DWA filter, scenario key."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.agent.model.scenario import Arena
from tlfleet.agent.nav.coupling_limits import CouplingConstraint, VelocityLimits
from tlfleet.agent.nav.dwa import DwaConfig, dwa_control
from tlfleet.agent.nav.grid import grid_from_arena
from tlfleet.agent.policy.coupling import CouplingModel
from tlfleet.agent.scenario import load_scenario, parse_scenario
from tlfleet.agent.stl.evaluate import compile_expr
from tlfleet.agent.stl.parser import parse_task
from tlfleet.agent.stl.syntax import BinOp
from tlfleet.bus.errors import ScenarioError

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"


def _poses(scenario):
    return {r.id: r.pose for r in scenario.robots}


def _limits(scenario, leader, t, poses=None):
    model = CouplingModel.from_scenario(scenario, leader)
    return VelocityLimits.of(model.limits(t, poses or _poses(scenario)))


def _mini(offset: float, u_lin: float = 0.2, share: float | None = None) -> dict:
    data = {
        "name": "mini", "duration": 20.0,
        "regions": [{"name": "a1", "center": [1.0, 1.0]}],
        "robots": [
            {"id": 1, "kind": "unicycle", "pose": [0.0, 0.0, 0.0], "ltl": "F a1"},
            {"id": 2, "kind": "omni", "pose": [0.0, -offset, 0.0],
             "stl": [f"G[0,10] (dist(p2 - p1, [{offset} * sin(th1), -{offset} * cos(th1)]) "
                     f"<= 0.1)"],
             "limits": {"max_lin": u_lin}},
        ],
    }
    if share is not None:
        data["navigation"] = {"coupling_share": share}
    return data


def test_paper_scenarios_limits_follow_from_the_predicates():
    s1, s2, s3 = (load_scenario(SCENARIOS / f"scenario{n}.toml") for n in (1, 2, 3))
    for leader in (1, 2):  # Scenario 1: no STL task involves an LTL robot
        assert not CouplingModel.from_scenario(s1, leader)
    for leader in (1, 2):  # Scenario 2: ‖z_esc − z_L‖, only v is bounded: 0.9 · 0.2 m/s
        limits = _limits(s2, leader, 0.0)
        assert limits.v_max == pytest.approx(0.18)
        assert limits.omega_max == math.inf
    # Scenario 3: slots 1 m from robot 1: |v| + 1 m · |ω| ≤ 0.18 m/s; heading term 0.9 · 6.28
    limits = _limits(s3, 1, 0.0)
    assert limits.v_max == pytest.approx(0.18)
    assert limits.omega_max == pytest.approx(0.18)
    slots = [c for c in limits.constraints if c.a_v > 0]
    assert len(slots) == 3 and all(c.a_omega == pytest.approx(1.0) for c in slots)
    angles = [c for c in limits.constraints if c.a_v == 0]
    assert [c.bound for c in angles] == pytest.approx([0.9 * 6.28] * 3)


@pytest.mark.parametrize("offset,u_lin,share", [(0.5, 0.2, None), (2.0, 0.3, 0.5)])
def test_the_slot_distance_and_the_dependants_limit_set_the_bounds(offset, u_lin, share):
    scenario = parse_scenario(_mini(offset, u_lin, share))
    kappa = 0.9 if share is None else share
    limits = _limits(scenario, 1, 0.0)
    assert limits.v_max == pytest.approx(kappa * u_lin)
    assert limits.omega_max == pytest.approx(kappa * u_lin / offset)
    # the window of G[0,10] is over after t = 10 s: no constraint any more
    assert not _limits(scenario, 1, 10.5)


@settings(max_examples=examples(60), deadline=None)
@given(x=st.floats(-2, 2), y=st.floats(-2, 2), th=st.floats(-math.pi, math.pi),
       ex=st.floats(-1, 1), ey=st.floats(-1, 1), frac=st.floats(0, 1),
       sign=st.sampled_from([-1, 1]))
def test_a_command_on_the_limit_moves_the_slot_no_faster_than_the_bound(x, y, th, ex, ey, frac,
                                                                         sign):
    """Finite differences of the predicate's argument F along the leader's unicycle motion: a
    command with a_v|v| + a_ω|ω| = bound changes F at most at the bound (up to O(dt))."""
    scenario = parse_scenario(_mini(1.0))
    model = CouplingModel.from_scenario(scenario, 1)
    poses = {1: (x, y, th), 2: (x + math.sin(th) + ex, y - math.cos(th) + ey, 0.0)}
    (c,) = [c for c in VelocityLimits.of(model.limits(0.0, poses)).constraints if c.a_v > 0]
    v = frac * c.bound / c.a_v
    w = sign * (c.bound - c.a_v * v) / c.a_omega
    phi = parse_task("G[0,10] (dist(p2 - p1, [sin(th1), -cos(th1)]) <= 0.1)")
    inner = phi.body.lhs
    f = compile_expr(BinOp("-", inner.args[0], inner.args[1]), (1, 2))
    dt = 1e-5
    moved = {1: (x + v * dt * math.cos(th), y + v * dt * math.sin(th), th + w * dt), 2: poses[2]}
    f0 = np.array(f([*poses[1], *poses[2]])[0])
    f1 = np.array(f([*moved[1], *moved[2]])[0])
    assert np.linalg.norm(f1 - f0) / dt <= c.bound * (1 + 1e-3) + 1e-6


GRID = grid_from_arena(Arena(), inflation=0.25)
PATH = np.array([[0.0, 0.0], [3.0, 0.0]])


def test_dwa_keeps_the_command_inside_the_coupling_limits():
    limits = VelocityLimits((CouplingConstraint(1.0, 1.0, 0.1, "test"),))
    free = dwa_control((0.0, 0.0, 0.0), (0.0, 0.0), PATH, GRID, 0.2, None, DwaConfig())
    assert free.v > 0.15  # unconstrained, the first step accelerates to 0.2 m/s
    command = (0.0, 0.0)
    for _ in range(10):
        result = dwa_control((0.0, 0.0, 0.0), command, PATH, GRID, 0.2, None, DwaConfig(), limits)
        command = (result.v, result.omega)
        assert abs(result.v) + abs(result.omega) <= 0.1 + 1e-9
    assert result.v > 0.05  # still driving towards the goal


@pytest.mark.parametrize("kernel", ["python", "native"])
def test_a_leader_held_to_slow_motions_turns_towards_its_path_instead_of_driving_off(kernel):
    """Facing away from the path (it goes north, the robot faces east) under a limit
    |v| + 1 m·|ω| ≤ 0.18 (Scenario 3's formation): turning at 0.4 rad/s would break the limit, so
    the rule against standing still must not force the only fast-enough samples — driving
    east at 0.1 m/s — on the robot; it turns in place (slowly) and drives off only once it
    faces the path."""
    if kernel == "native" and not DwaConfig().native:
        pytest.skip("the C kernel was not built")
    config = DwaConfig(kernel=kernel)
    limits = VelocityLimits((CouplingConstraint(1.0, 1.0, 0.18, "formation"),))
    north = np.array([[0.0, 0.0], [0.0, 2.0]])
    pose, command = [0.0, 0.0, 0.0], (0.0, 0.0)
    for _ in range(100):  # 20 s at 5 Hz, integrated with Euler steps
        result = dwa_control(pose, command, north, GRID, 0.2, None, config, limits)
        command = (result.v, result.omega)
        assert abs(result.v) + abs(result.omega) <= 0.18 + 1e-9
        pose = [pose[0] + 0.2 * result.v * math.cos(pose[2]),
                pose[1] + 0.2 * result.v * math.sin(pose[2]), pose[2] + 0.2 * result.omega]
        if pose[2] < 1.0:  # still turning towards the path: in place, not off to the east
            assert abs(pose[0]) < 0.02 and abs(pose[1]) < 0.02
    assert pose[1] > 0.3 and abs(pose[2] - math.pi / 2) < 0.5  # it turned and went north


def test_dwa_slows_down_as_fast_as_it_can_when_above_the_limits():
    limits = VelocityLimits((CouplingConstraint(1.0, 0.0, 0.05, "test"),))
    config = DwaConfig()
    result = dwa_control((0.0, 0.0, 0.0), (0.3, 0.0), PATH, GRID, 0.2, None, config, limits)
    assert result.v == pytest.approx(0.3 - config.acc_lim_x * config.controller_period)


def test_navigation_key_switches_and_bad_values_are_rejected():
    data = _mini(1.0)
    assert parse_scenario(data).navigation.coupling_aware is True
    off = copy.deepcopy(data)
    off["navigation"] = {"coupling_aware": False}
    assert parse_scenario(off).navigation.coupling_aware is False
    for bad, field, reason in (({"coupling_share": 1.5}, "navigation.coupling_share", "(0, 1]"),
                               ({"coupling_share": 0.0}, "navigation.coupling_share", "positive"),
                               ({"coupling_aware": 1}, "navigation.coupling_aware", "true or"),
                               ({"speed": 1}, "navigation.speed", "")):
        broken = copy.deepcopy(data)
        broken["navigation"] = bad
        with pytest.raises(ScenarioError) as info:
            parse_scenario(broken)
        assert field in str(info.value) and reason in str(info.value)


def test_ltl_core_uses_the_limits_only_when_coupling_aware():
    from tlfleet.agent.runtime.ltl_agent import LtlCore

    scenario = load_scenario(SCENARIOS / "scenario3.toml")
    assert LtlCore(scenario, 1).coupling
    off = parse_scenario({**_mini(1.0), "navigation": {"coupling_aware": False}})
    assert LtlCore(off, 1).coupling is None
    event = LtlCore(off, 1).coupling_event()
    assert event.kind == "coupling_limits" and event.data["coupling_aware"] is False
