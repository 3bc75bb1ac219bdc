"""`tlfleet check`: rejections and warnings of STL tasks (tlfleet.agent.scenario.stl_checks, issue
15)."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
from tlfleet.agent.scenario import load_scenario, parse_scenario
from tlfleet.agent.scenario.stl_checks import stl_warnings
from tlfleet.bus.errors import ScenarioError
from tlfleet.cli.main import main

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"

BASE = {
    "name": "mini", "duration": 60.0,
    "regions": [{"name": "a1", "center": [1.0, 1.0]}],
    "robots": [
        {"id": 1, "kind": "unicycle", "pose": [-2.0, -2.5, 0.0], "ltl": "F a1"},
        {"id": 2, "kind": "omni", "pose": [0.0, 0.0, 0.0],
         "stl": ["G[0,10] (dist(p2, [0.5, 0]) <= 0.1)", "F[20,30] (dist(p2, [0, 0.5]) <= 0.1)"]},
        {"id": 3, "kind": "omni", "pose": [1.0, -1.0, 0.0],
         "stl": ["F[5,10] (dist(p3, p2) <= 1)"]},
    ],
}


def _with(robot: int, **fields) -> dict:
    data = copy.deepcopy(BASE)
    data["robots"][robot].update(fields)
    return data


@pytest.mark.parametrize("data,field,reason", [
    (_with(2, stl=["G[0,10] (dist(p2, [0.5, 0]) <= 0.1)"]), "robots[id=3].stl[0]",
     "does not involve robot 3's own state"),
    # with the literal bound only (the default bounds it by the arena: test_stl_supremum.py)
    ({**_with(2, stl=["G[0,10] (!(dist(p3, p2) <= 1))"]), "stl": {"rho_opt_from_arena": False}},
     "robots[id=3].stl[0]", "unbounded above"),
    (_with(1, phase_start_times=[15.0]), None, None),  # valid: 15 ≥ b = 10
    (_with(1, phase_start_times=[5.0]), "robots[id=2].phase_start_times[0]",
     "precedes the end b = 10"),
    # overlapping windows: the loader's window-order check (tlfleet.agent.scenario.validation) names
    # it
    (_with(1, stl=["G[0,10] (x2 >= 0)", "F[5,12] (y2 >= 0)"]), "robots[id=2].stl[1]",
     "window [5, 12] overlaps the window [0, 10] of stl[0]"),
])
def test_broken_stl_tasks_are_rejected_with_field_and_reason(data, field, reason):
    if field is None:
        parse_scenario(data)
        return
    with pytest.raises(ScenarioError) as info:
        parse_scenario(data, source="mini.toml")
    text = str(info.value)
    assert "mini.toml" in text and field in text and reason in text, text


def test_unbounded_negation_is_accepted_with_an_explicit_rho_opt():
    parse_scenario(_with(2, stl=["G[0,10] (!(dist(p3, p2) <= 1))"], rho_opt=[0.5]))


def test_warnings_nonconcave_and_violated_from_start():
    # 6th robot: 4.6 m from robot 1 at t = 0
    data = _with(2, stl=["G[0,50] (dist(p3, p1) <= 0.6)"], pose=[1.0, 1.0, 0.0])
    data["duration"] = 50.0
    data["robots"][1]["stl"] = ["G[0,10] (dist(p2, [0.5, 0]) <= 0.1)",
                                "F[20,30] (dist(p2, [0, 0.5]) >= 0.1)"]
    warnings = stl_warnings(parse_scenario(data))
    assert any("robots[id=2].stl[1]" in w and "not concave" in w for w in warnings)
    assert any("robots[id=3].stl[0]" in w and "violated at the start poses" in w
               and "-4.0" in w for w in warnings)


def test_paper_scenarios_have_no_warning():
    for n in (1, 2, 3):
        assert stl_warnings(load_scenario(SCENARIOS / f"scenario{n}.toml")) == []


@pytest.mark.parametrize("data,field,reason", [
    # a window the run never closes: no verdict, so never met
    (_with(2, stl=["F[50,70] (dist(p3, p2) <= 1)"]), "robots[id=3].stl[0]",
     r"window \[50, 70\] ends after the run \(duration = 60 s\)"),
    # bodies asked to overlap: radii 0.2 + 0.2 > 0.3, in any spelling of the distance
    (_with(2, stl=["F[5,10] (dist(p3, p2) <= 0.3)"]), "robots[id=3].stl[0]",
     "closer than their bodies allow"),
    (_with(2, stl=["G[5,10] (x3 >= 0 & 0.35 > norm(p2 - p3))"]), "robots[id=3].stl[0]",
     "closer than their bodies allow"),
    (_with(2, stl=["F[5,10] (dist(p3, p2) <= 0.5)"], radius=0.35), "robots[id=3].stl[0]",
     r"closer than their bodies allow \(0.55 m between centres\)"),
])
def test_tasks_no_run_can_meet_are_rejected(data, field, reason):
    import re

    with pytest.raises(ScenarioError) as info:
        parse_scenario(data, source="mini.toml")
    assert info.value.field == field and re.search(reason, info.value.reason), str(info.value)


def test_bodies_kept_apart_and_disjunctions_are_not_overlaps():
    parse_scenario(_with(2, stl=["F[5,10] (dist(p3, p2) <= 0.45)"]))  # 0.45 > 0.2 + 0.2
    parse_scenario(_with(2, stl=["F[5,10] (!(dist(p3, p2) <= 0.1))"], rho_opt=[1.0]))


def test_a_robot_overlapping_the_wall_at_its_start_is_rejected():
    with pytest.raises(ScenarioError) as info:
        parse_scenario(_with(2, pose=[3.4, 0.0, 0.0]), source="mini.toml")
    assert info.value.field == "robots[id=3].pose" and "arena's wall" in info.value.reason
    parse_scenario(_with(2, pose=[3.3, 0.0, 0.0]))  # 0.2 m from the wall: touching, allowed


def test_check_command_prints_warnings_and_rejects(tmp_path, capsys):
    good = tmp_path / "good.toml"
    good.write_text((SCENARIOS / "scenario2.toml").read_text().replace(
        "pose = [-1.5, -2.5, 0.0]", "pose = [1.0, 1.0, 0.0]"))  # G[0,90] violated at t = 0
    assert main(["check", str(good)]) == 0
    out = capsys.readouterr().out
    assert "warning:" in out and "robots[id=3].stl[0]" in out and "coupling-aware leaders on" in out
    bad = tmp_path / "bad.toml"
    bad.write_text((SCENARIOS / "scenario2.toml").read_text().replace(
        'stl = ["G[0,90] (dist(p3, p1) <= 0.6)"]', 'stl = ["G[0,90] (dist(p4, p1) <= 0.6)"]'))
    assert main(["check", str(bad)]) == 1
    err = capsys.readouterr().err
    assert str(bad) in err and "robots[id=3].stl[0]" in err and "own state" in err
