"""System tests: real router, simulator and agent processes on loopback.

Each test runs ``tlfleet run`` (``tlfleet.coordinator.run.run_fleet``) and asserts on the recorded
run directory; robustness is recomputed here with numpy (``system_helpers``), not with the monitor
the summary uses. Paper bounds: docs/scenarios.md.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from system_helpers import (
    HERE,
    ROOT,
    SCENARIOS,
    dist_to,
    entries,
    f_rob,
    formation_psi,
    g_rob,
    leftover_in_groups,
    load_trajectory,
    robot_robot_contacts,
    run,
)
from tlfleet.agent.scenario import load_scenario
from tlfleet.coordinator.record.rundir import RUN_INFO, read_json

pytestmark = pytest.mark.system
TWO = HERE / "two_robots.toml"


def regions(path):
    return {r.name: r for r in load_scenario(path).regions}


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_two_robot_fleet(tmp_path, mode):
    result = run(TWO, tmp_path / "run", mode=mode)
    assert result.clean, result.summary_text
    assert result.outcome.reason in ("sim_done", "duration")
    assert read_json(tmp_path / "run" / RUN_INFO)["links"] == "peer"  # both modes
    t, s = load_trajectory(tmp_path / "run")
    assert t[0] == 0.0 and t[-1] == pytest.approx(20.0)
    if mode == "lockstep":
        assert len(t) == 2001  # every frame of 100 Hz × 20 s
    else:
        assert len(t) > 1800  # realtime: a few frames may be lost on a busy machine
    assert np.all(np.diff(t) > 0)
    rho = g_rob(t, 0.8 - dist_to(s, 2, 1), 0, 20)
    assert result.summary.stl[2].robustness == pytest.approx(rho, abs=1e-9)
    assert rho > -0.5  # the omni follows the unicycle (0.2 m/s against 0.3 m/s)
    reg = regions(TWO)
    for name in ("a1", "a2"):
        assert entries(s[1][:, :2], reg[name].center, reg[name].radius) >= 1
    assert robot_robot_contacts(tmp_path / "run") == []
    assert leftover_in_groups(tmp_path / "run") == []


def test_lockstep_runs_with_the_same_seed_are_identical(tmp_path):
    first = run(TWO, tmp_path / "a", duration=8.0, seed=11)
    second = run(TWO, tmp_path / "b", duration=8.0, seed=11)
    assert first.clean and second.clean
    a = (tmp_path / "a" / "trajectory.csv").read_bytes()
    assert a == (tmp_path / "b" / "trajectory.csv").read_bytes()
    assert len(a.splitlines()) == 1 + 801


def test_lockstep_over_peer_links_is_the_run_through_the_router(tmp_path):
    """An unsecured lockstep run links the sim and the agents as zenoh peers; the
    trajectory is byte for byte the one of the same run with every sample through the
    router (``--via-router``)."""
    peer = run(TWO, tmp_path / "peer", duration=8.0, seed=11)
    routed = run(TWO, tmp_path / "routed", duration=8.0, seed=11, direct_links=False)
    assert peer.clean and routed.clean
    assert read_json(tmp_path / "peer" / RUN_INFO)["links"] == "peer"
    assert read_json(tmp_path / "routed" / RUN_INFO)["links"] == "router"
    a = (tmp_path / "peer" / "trajectory.csv").read_bytes()
    assert a == (tmp_path / "routed" / "trajectory.csv").read_bytes()
    assert len(a.splitlines()) == 1 + 801


@pytest.mark.slow
def test_scenario1_paper_bounds(scenario1_run):
    path = SCENARIOS / "scenario1.toml"
    result = scenario1_run  # one `tlfleet run` of Scenario 1 in lockstep (tests/system/conftest.py)
    assert result.clean, result.summary_text
    t, s = load_trajectory(result.run_dir)
    assert t[-1] == pytest.approx(90.0)
    measured = {
        "phi'3": g_rob(t, 0.1 - dist_to(s, 3, (0, -2)), 21, 30),
        "phi'4": g_rob(t, np.minimum(1 - dist_to(s, 4, 3), 1 - dist_to(s, 4, 5)), 5, 30),
        "phi'5": g_rob(t, 0.1 - dist_to(s, 5, (0, 2)), 21, 30),
        "phi''3": f_rob(t, np.minimum(0.1 - dist_to(s, 3, (1.5, -1.5)),
                                      0.7 - dist_to(s, 3, 4)), 57, 58),
        "phi''4": f_rob(t, 0.1 - dist_to(s, 4, (2, 2)), 83, 87),
        "phi''5": f_rob(t, 0.1 - dist_to(s, 5, (-1, 0.5)), 44, 47),
    }
    bounds = {"phi'3": -0.18, "phi'4": -1.11, "phi'5": -0.12, "phi''3": 0.02, "phi''4": -0.4,
              "phi''5": 0.05}
    failing = {k: v for k, v in measured.items() if not v >= bounds[k]}
    assert failing == {}, f"below the paper's bounds {bounds}: {failing}"
    # within 0.05 of the best achievable of scenarios.md (0.1 each), except φ′4, whose
    # −0.9 − 0.05 is jointly feasible with φ′3's and φ′5's goals only at one knife-edge point
    # (docs/coupling.md §3): φ′4 is held within 0.05 of its joint bound −0.9 − (ρ′3 + ρ′5)/2
    # and to 1e-3 of its bound given robots 3 and 5's trajectories, 1 − max ‖z3 − z5‖/2
    short = {k: v for k, v in measured.items() if k != "phi'4" and not v >= 0.1 - 0.05}
    assert short == {}, f"more than 0.05 below the best 0.1: {short}"
    joint = -0.9 - (measured["phi'3"] + measured["phi'5"]) / 2
    assert joint - 0.05 <= measured["phi'4"] <= joint + 1e-12
    given_z3_z5 = g_rob(t, 1 - np.hypot(*(s[3][:, :2] - s[5][:, :2]).T) / 2, 5, 30)
    assert measured["phi'4"] == pytest.approx(given_z3_z5, abs=1e-3)
    reg = regions(path)
    for robot, names in ((1, ("a11", "a12")), (2, ("a21", "a22"))):
        for name in names:
            assert entries(s[robot][:, :2], reg[name].center, reg[name].radius) >= 3, \
                (robot, name)
    assert robot_robot_contacts(result.run_dir) == []
    assert leftover_in_groups(result.run_dir) == []


def test_recovery_case_escort_back_within_10_s_of_the_leader_stop(tmp_path):
    """Issue 15's recovery goal on a real fleet (bench/recovery_case.toml): a reactive leader
    outruns its 0.2 m/s escort (stage-3 repairs lower r below 0), then parks; ρ^ψ = 1 − ‖z2 − z1‖,
    recomputed here, is ≥ 0 again within 10 s of the stop, and stays ≥ 0 to the end."""
    result = run(ROOT / "bench" / "recovery_case.toml", tmp_path / "run")
    assert result.clean, result.summary_text
    t, s = load_trajectory(tmp_path / "run")
    speed = np.hypot(*np.diff(s[1][:, :2], axis=0).T) / np.diff(t)
    t_stop = t[np.flatnonzero(speed > 0.005)[-1] + 1]
    assert 10.0 < t_stop < 30.0  # it drove, then parked in its region
    psi = 1.0 - dist_to(s, 2, 1)
    assert psi[t <= t_stop].min() < -1.0  # the escort had fallen far behind
    (sub,) = result.summary.stl[2].subtasks
    assert sub.r_least < -1.0 < sub.r_last  # repairs lowered r, recoveries raised it
    back = t[(t >= t_stop) & (psi >= 0.0)]
    assert back.size and back[0] - t_stop <= 10.0, (t_stop, back[:1])
    assert psi[t >= back[0]].min() >= 0.0
    assert robot_robot_contacts(tmp_path / "run") == []


@pytest.mark.slow
def test_scenario3_formation_and_all_regions(tmp_path):
    """Robot 1 visits the five regions; with its coupling-aware limits (docs/coupling.md) the
    three escorts hold their slots (ρ ≥ −0.1, predicate held ≥ 90 % of [10, 100])."""
    path = SCENARIOS / "scenario3.toml"
    result = run(path, tmp_path / "run")
    assert result.clean, result.summary_text
    _t, s = load_trajectory(tmp_path / "run")
    reg = regions(path)
    for name in ("a1", "a2", "a3", "a4", "a5"):
        assert entries(s[1][:, :2], reg[name].center, reg[name].radius) >= 1, name
    assert robot_robot_contacts(tmp_path / "run") == []
    for robot in (2, 3, 4):  # the summary's robustness is the trajectory's, and finite
        assert math.isfinite(result.summary.stl[robot].robustness)
    # goals (coupling-aware leader): every formation task ρ ≥ −0.1 and held ≥ 90 %
    t, s = load_trajectory(tmp_path / "run")
    window = (t >= 10.0) & (t <= 100.0)
    for robot, side in ((2, "right"), (3, "left"), (4, "behind")):
        psi = formation_psi(s, robot, 1, side)[window]
        assert psi.min() >= -0.1, (robot, psi.min())
        assert np.mean(psi >= 0.0) >= 0.9, (robot, np.mean(psi >= 0.0))
        assert result.summary.stl[robot].robustness == pytest.approx(psi.min(), abs=1e-9)
    assert leftover_in_groups(tmp_path / "run") == []
