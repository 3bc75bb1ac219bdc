"""The bundled scenarios (found by name from any directory) and ``tlfleet init``'s starter."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from tlfleet.agent.ltl.planner import plan_robot
from tlfleet.agent.scenario import load_scenario
from tlfleet.agent.scenario.bundled import bundled_scenarios, resolve_scenario
from tlfleet.agent.scenario.stl_checks import stl_warnings
from tlfleet.agent.stl.parser import parse_task
from tlfleet.agent.stl.syntax import robots_of
from tlfleet.bus.errors import TlfleetError
from tlfleet.cli.arg_types import scenario_file
from tlfleet.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def test_the_papers_scenarios_are_bundled() -> None:
    bundled = bundled_scenarios()
    assert sorted(bundled) == sorted(p.stem for p in (ROOT / "scenarios").glob("*.toml"))
    assert {"scenario1", "scenario2", "scenario3"} <= set(bundled)
    for name, path in bundled.items():
        assert path.read_bytes() == (ROOT / "scenarios" / f"{name}.toml").read_bytes()


def test_names_resolve_from_any_directory(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    bundled = bundled_scenarios()["scenario2"]
    assert resolve_scenario("scenario2") == bundled
    assert resolve_scenario("scenario2.toml") == bundled
    assert resolve_scenario("sub/scenario2.toml") == Path("sub/scenario2.toml")  # a path: as is
    assert resolve_scenario("nothing") == Path("nothing")
    (tmp_path / "scenario2.toml").write_text("# mine\n")
    assert resolve_scenario("scenario2.toml") == Path("scenario2.toml")  # a file always wins
    assert scenario_file("scenario3") == bundled_scenarios()["scenario3"]
    with pytest.raises(argparse.ArgumentTypeError, match=r"no bundled scenario .*scenario1"):
        scenario_file("scenari01")
    assert scenario_file("missing.toml") == Path("missing.toml")  # the loader names it


def test_init_writes_a_starter_that_passes_check(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["init", "lab"]) == 0
    path = tmp_path / "lab.toml"
    text = path.read_text()
    scenario = load_scenario(path)
    assert scenario.name == "lab" and scenario.fleet == "lab"
    assert {r.kind for r in scenario.robots} == {"unicycle", "omni"}
    # one STL task couples two robots (paper eq. (2))
    assert any(len(robots_of(parse_task(task))) > 1 for r in scenario.robots if r.ltl is None
               for task in r.stl)
    assert stl_warnings(scenario) == []
    for robot in scenario.robots:
        if robot.ltl is not None:
            assert plan_robot(scenario, robot.id).suffix  # satisfiable on the map
    # every section is explained
    for section in ("[arena]", "[sim]", "[ltl]", "[stl]", "[[regions]]", "[[robots]]"):
        line = next(i for i, s in enumerate(text.splitlines()) if s.startswith(section))
        around = text.splitlines()[max(line - 2, 0):line + 2]
        assert any("#" in s for s in around), section
    capsys.readouterr()
    assert main(["check", "lab.toml"]) == 0
    assert "lab: valid" in capsys.readouterr().out


def test_init_refuses_to_overwrite_and_bad_names(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["init", "a", "-o", "sub/x.toml"]) == 0
    assert (tmp_path / "sub" / "x.toml").is_file()
    before = (tmp_path / "sub" / "x.toml").read_text()
    assert main(["init", "b", "-o", "sub/x.toml"]) == 1
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "sub" / "x.toml").read_text() == before
    assert main(["init", "b", "-o", "sub/x.toml", "--force"]) == 0
    assert 'name = "b"' in (tmp_path / "sub" / "x.toml").read_text()
    assert main(["init", "no/slash"]) == 1
    assert "letters, digits" in capsys.readouterr().err
    with pytest.raises(TlfleetError):
        from tlfleet.cli.commands.init import starter
        starter("bad name", "x.toml")
