"""``tlfleet monitor SCENARIO TRAJECTORY.csv [--json]`` end to end (in process)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from stl_harness import ScriptedRobot, run_closed_loop
from tlfleet.agent.policy.stl import build_agents
from tlfleet.agent.scenario.loader import load_scenario
from tlfleet.agent.stl.monitor import Trajectory, task_robustness, write_trajectory_csv
from tlfleet.cli.main import main


@pytest.fixture(scope="module")
def scenario1_csv(tmp_path_factory, scenarios_dir):
    """Scenario 1 for 31 s: STL robots on the harness, LTL robots 1 and 2 standing still."""
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    agents = build_agents(scenario, robots=[3, 4, 5])
    poses = {j: scenario.robot(j).pose for j in (3, 4, 5)}
    exo = [ScriptedRobot(j, scenario.robot(j).pose) for j in (1, 2)]
    result = run_closed_loop(list(agents.values()), poses, 31.0, exogenous=exo)
    path = tmp_path_factory.mktemp("monitor") / "trajectory.csv"
    write_trajectory_csv(path, result.trajectory)
    return scenario, agents, result.trajectory, path


def test_json_output_matches_offline_monitor(scenario1_csv, scenarios_dir, capsys):
    _, agents, traj, path = scenario1_csv
    assert main(["monitor", str(scenarios_dir / "scenario1.toml"), str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["semantics"] == "standard"
    assert set(report["robots"]) == {"3", "4", "5"}
    for j in (3, 4, 5):
        entry = report["robots"][str(j)]
        first = entry["subtasks"][0]
        assert first["robustness"] == pytest.approx(
            task_robustness(agents[j].cfg.subtasks[0], traj), abs=1e-12)
        assert entry["subtasks"][1]["robustness"] == "-inf"  # F windows after t = 31 s
        assert entry["robustness"] == "-inf"
        task = agents[j].cfg.subtasks[0]
        assert first["window"] == [task.a, task.b]


def test_table_output(scenario1_csv, scenarios_dir, capsys):
    _, _, _, path = scenario1_csv
    assert main(["monitor", str(scenarios_dir / "scenario1.toml"), str(path)]) == 0
    out = capsys.readouterr().out
    assert "standard semantics" in out and "robot 4:" in out
    assert "G[5,30] ((dist(p4, p3) <= 1) & (dist(p4, p5) <= 1))" in out


def test_bad_csv_is_a_clear_error(tmp_path, scenarios_dir, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x1,y1,th1\n0,0,0,0\n0.01,0,oops,0\n")
    assert main(["monitor", str(scenarios_dir / "scenario1.toml"), str(bad)]) == 1
    err = capsys.readouterr().err
    assert f"{bad}:3:3: y1 is not a number: 'oops'" in err


def test_missing_robot_columns_is_a_clear_error(tmp_path, scenarios_dir, capsys):
    path = tmp_path / "only1.csv"
    write_trajectory_csv(path, Trajectory(np.arange(3.0), {1: np.zeros((3, 3))}))
    assert main(["monitor", str(scenarios_dir / "scenario1.toml"), str(path)]) == 1
    assert "no columns for robot 3" in capsys.readouterr().err
