"""System test of Scenario 2 (issue 5 §5): STL robots 3 and 4 keep within 0.6 m of the LTL robots
1 and 2 while those cycle their regions, all over Zenoh with real processes.

What is asserted is what the method guarantees on this run: each STL task's robustness,
recomputed here with numpy from trajectory.csv, is at least the bound r̄ its agent ended with
(paper Alg. 2, ρ^φ ≥ r̄); both LTL robots keep cycling; nobody collides.

Not asserted: the paper's ρ(φ3) ≥ −0.45, ρ(φ4) ≥ −0.47. With the scenario's limits
(scenarios.md: unicycles at DWA's 0.3 m/s, omni escorts saturated at 0.2 m/s) an escort falls
0.1 m/s behind on every 4.5–5 m leg, so ≈ −1.4 / −0.9 is what any controller reaches; the
pure harness with ideal kinematics, fed the same LTL motion, gives the same values. Meeting the
paper's figures needs slower leaders, which would break the ≥ 3 GF rounds in 90 s — a scenario
decision left open on the issue.
"""

from __future__ import annotations

import json

import pytest
from system_helpers import (
    SCENARIOS,
    dist_to,
    entries,
    g_rob,
    load_trajectory,
    robot_robot_contacts,
    run,
)

from agent.scenario import load_scenario

pytestmark = [pytest.mark.system, pytest.mark.slow]


def test_scenario2_escorts_keep_their_guarantee_and_leaders_keep_cycling(tmp_path):
    path = SCENARIOS / "scenario2.toml"
    run_dir = tmp_path / "run"
    result = run(path, run_dir)
    assert result.clean, result.summary_text
    t, states = load_trajectory(run_dir)
    summary = json.loads((run_dir / "summary.json").read_text())
    for escort, leader in ((3, 1), (4, 2)):
        rho = g_rob(t, 0.6 - dist_to(states, escort, leader), 0.0, 90.0)
        (subtask,) = summary["stl"][str(escort)]["subtasks"]
        assert subtask["robustness"] == pytest.approx(rho, abs=1e-9)
        assert rho >= subtask["r_last"], (escort, rho, subtask["r_last"])
        assert rho > -2.0  # the escort follows: parked, it would end at −4.4 (3) / −3.4 (4)
    regions = {r.name: r for r in load_scenario(path).regions}
    for robot, names in ((1, ("a11", "a12")), (2, ("a21", "a22"))):
        for name in names:
            assert entries(states[robot][:, :2], regions[name].center,
                           regions[name].radius) >= 2, (robot, name)
    assert robot_robot_contacts(run_dir) == []
