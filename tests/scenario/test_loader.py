"""Scenario loader: the paper's files load; each kind of bad input gets a pinned, specific error."""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path
from typing import Any

import pytest
from tlfleet.agent.model import Scenario
from tlfleet.agent.scenario import load_scenario, parse_scenario
from tlfleet.bus.errors import ScenarioError

BASE: dict[str, Any] = {
    "name": "mini",
    "duration": 10.0,
    "regions": [{"name": "a1", "center": [1.0, 1.0]}, {"name": "a2", "center": [-1.0, 1.0]}],
    "robots": [
        {"id": 1, "kind": "omni", "pose": [0.0, 0.0, 0.0],
         "stl": ["G[0,5] (dist(p1, [1,1]) <= 0.1)"]},
        {"id": 2, "kind": "omni", "pose": [1.0, -1.0, 0.0],
         "stl": ["G[0,5] (x2 >= 0)", "F[6,8] (y2 >= 0)"], "phase_start_times": [6.0]},
    ],
}


def mutated(path: str, value: Any) -> dict[str, Any]:
    """BASE with the value at a dotted path (``robots.1.kind``) replaced; DELETE removes it."""
    data = copy.deepcopy(BASE)
    *parents, last = path.split(".")
    node: Any = data
    for key in parents:
        node = node[int(key)] if isinstance(node, list) else node.setdefault(key, {})
    key_or_index: Any = int(last) if isinstance(node, list) else last
    if value is DELETE:
        del node[key_or_index]
    else:
        node[key_or_index] = value
    return data


DELETE = object()

BAD = [
    ("name", DELETE, "name", "missing, expected a string"),
    ("name", "", "name", "expected a non-empty string"),
    ("fleet", "my fleet", "fleet", "'my fleet' is not usable in a key expression"),
    ("duration", -1, "duration", "expected a positive number, got -1"),
    ("duration", "90", "duration", "expected a number, got string '90'"),
    ("duration", True, "duration", "expected a number, got boolean True"),
    ("durationn", 3, "durationn", "unknown key 'durationn' \\(allowed here: .*duration"),
    ("arena.xmax", -4.0, "arena.xmax", "must exceed xmin = -3.5, got -4.0"),
    ("arena.obstacles", [{"shape": "triangle"}], "arena.obstacles[0].shape",
     "expected one of 'rect', 'disc', got 'triangle'"),
    ("arena.obstacles", [{"shape": "rect", "xmin": 1, "xmax": 0, "ymin": 0, "ymax": 1}],
     "arena.obstacles[0]", "empty rectangle"),
    ("arena.obstacles", [{"shape": "disc", "center": [0, 0]}], "arena.obstacles[0].radius",
     "missing, expected a number"),
    ("stl.r1", 0.8, "stl.r1", "must be below stl.r_sense = 0.7, got 0.8"),
    ("stl.eta", 0, "stl.eta", "expected a positive number, got 0"),
    ("stl.n_stage1", 2.5, "stl.n_stage1", "expected an integer, got number 2.5"),
    ("stl.gamma", 1.0, "stl.gamma", "unknown key 'gamma'"),
    ("stl.hold_f_above_r", 0, "stl.hold_f_above_r", "expected true or false, got integer 0"),
    ("ltl.stagger", "yes", "ltl.stagger", "expected true or false, got string 'yes'"),
    ("sim.seed", -1, "sim.seed", "expected a number ≥ 0, got -1"),
    ("sim.spread_frames", 1, "sim.spread_frames", "expected true or false, got integer 1"),
    ("sim.frame_slots", 0, "sim.frame_slots", "expected a positive number, got 0"),
    ("sim.frame_slots", 2.5, "sim.frame_slots", "expected an integer, got number 2.5"),
    ("sim.mocap_rate", "fast", "sim.mocap_rate", "expected a number, got string 'fast'"),
    ("regions.0.name", "A1", "regions[0].name", "'A1' is not a valid proposition name"),
    ("regions.0.name", "true", "regions[0].name", "'true' is not a valid proposition name"),
    ("regions.1.name", "a1", "regions[1]",
     "duplicate region name 'a1' \\(first at regions\\[0\\]"),
    ("regions.0.center", [9.0, 0.0], "regions[0].center", "lies outside the arena"),
    ("regions.0.center", [1.0, "x"], "regions[0].center", "expected a list of 2 numbers"),
    ("regions.0.radius", -0.1, "regions[0].radius", "expected a positive number, got -0.1"),
    ("regions.0.labels", ["a1", 3], "regions[0].labels[1]", "expected a string, got integer 3"),
    ("regions.0.shape", "disc", "regions[0].shape", "unknown key 'shape'"),
    ("regions", {"name": "a1"}, "regions", "expected an array of tables"),
    ("robots", [], "robots", "expected at least one \\[\\[robots\\]\\] table"),
    ("robots", DELETE, "robots", "missing, expected an array of tables"),
    ("robots.0.id", 0, "robots[0].id", "expected a positive integer, got 0"),
    ("robots.1.id", 1, "robots[1]",
     "duplicate robot id 1 \\(first at robots\\[0\\]: the 2nd \\[\\[robots\\]\\] table repeats "
     "the 1st"),
    ("robots.1.kind", "tank", "robots[id=2].kind",
     "expected one of 'unicycle', 'omni', got 'tank'"),
    ("robots.0.pose", [0.0, 0.0], "robots[id=1].pose", "expected a list of 3 numbers, got list"),
    ("robots.0.pose", [0.0, math.nan, 0.0], "robots[id=1].pose", "expected finite numbers"),
    ("robots.0.pose", [5.0, 0.0, 0.0], "robots[id=1].pose", r"position \(5.0, 0.0\) lies outside"),
    ("robots.1.pose", [0.3, 0.0, 0.0], "robots[id=2].pose",
     "robot 2 starts 0.300 m from robot 1, closer than their radii allow"),
    ("robots.0.stl", DELETE, "robots[id=1]", "expected a task"),
    ("robots.0.stl", ["  "], "robots[id=1].stl[0]", "expected a non-empty STL formula"),
    ("robots.0.stl", [1], "robots[id=1].stl[0]", "expected a string, got integer 1"),
    ("robots.0.ltl", "F a1", "robots[id=1].stl", "either an `ltl` or an `stl` task, not both"),
    ("robots.0.kind", "unicycle", "robots[id=1].stl", "STL tasks run on omni robots"),
    ("robots.1.phase_start_times", [6.0, 7.0], "robots[id=2].phase_start_times",
     "expected 1 times \\(one per sub-task after the first\\), got 2"),
    ("robots.1.rho_opt", [0.1], "robots[id=2].rho_opt",
     "expected one value per STL sub-task \\(2\\)"),
    ("robots.0.limits", {"max_v": 1.0}, "robots[id=1].limits.max_v", "unknown key 'max_v'"),
    ("robots.0.limits", {"max_lin": -1.0}, "robots[id=1].limits.max_lin", "expected a positive"),
    ("robots.0.colour", "red", "robots[id=1].colour", "unknown key 'colour'"),
]


@pytest.mark.parametrize(("path", "value", "field", "message"), BAD,
                         ids=[f"{b[0]}={b[1]!r}"[:50] for b in BAD])
def test_bad_scenarios_are_rejected_with_file_field_and_reason(path, value, field, message):
    with pytest.raises(ScenarioError, match=message) as info:
        parse_scenario(mutated(path, value), source="bad.toml")
    assert info.value.file == "bad.toml"
    assert info.value.field == field
    assert str(info.value).startswith(f"bad.toml: {field}")


def test_base_scenario_is_valid_and_typed():
    scenario = parse_scenario(copy.deepcopy(BASE), source="base.toml")
    assert scenario.fleet == "mini"
    assert scenario.robot(2).phase_start_times == (6.0,)
    assert scenario.robot(1).omni.max_lin == pytest.approx(0.2)
    assert scenario.region("a1").labels == frozenset({"a1"})
    assert scenario.propositions == frozenset({"a1", "a2"})
    with pytest.raises(KeyError, match=r"has no robot 7 \(robots: 1, 2\)"):
        scenario.robot(7)


def test_a_single_stl_string_is_a_one_element_task_list():
    scenario = parse_scenario(mutated("robots.0.stl", "G[0,5] (x1 >= 0)"))
    assert scenario.robot(1).stl == ("G[0,5] (x1 >= 0)",)


@pytest.mark.parametrize("number", [1, 2, 3])
def test_the_paper_scenarios_load(scenarios_dir: Path, number: int):
    scenario = load_scenario(scenarios_dir / f"scenario{number}.toml")
    assert isinstance(scenario, Scenario)
    assert scenario.name == f"scenario{number}"
    assert all(r.radius == pytest.approx(0.2) for r in scenario.robots)
    assert (scenario.arena.xmin, scenario.arena.xmax) == (-3.5, 3.5)


def test_scenario1_matches_the_design_table(scenarios_dir: Path):
    s = load_scenario(scenarios_dir / "scenario1.toml")
    assert s.duration == 90.0
    assert [r.kind for r in s.robots] == ["unicycle"] * 2 + ["omni"] * 3
    assert s.robot(1).ltl == "G F a11 & G F a12"
    assert s.robot(3).stl[1] == "F[57,58] (dist(p3, [1.5,-1.5]) <= 0.1 & dist(p3, p4) <= 0.7)"
    assert s.robot(4).pose == (0.5, 0.0, 0.0)
    assert s.region("a12").center == (-2.0, 2.5)
    assert (s.stl.delta, s.stl.zeta_l, s.stl.r1, s.stl.r_sense, s.stl.beta) == (
        0.02, 0.2, 0.6, 0.7, 2.0)
    # the paper's Algorithm 2 through each F window, not the authors' code's F-hold
    assert (s.stl.hold_f_above_r, s.stl.complete_f_on_satisfaction) == (False, False)
    # the two LTL agents step at ticks 0 and 10 of every 20 (ltl.stagger default)
    assert s.ltl.stagger and [s.control_phase(r.id) for r in s.robots] == [0, 10, 0, 0, 0]


def test_missing_file(tmp_path: Path):
    with pytest.raises(ScenarioError, match=re.escape(f"{tmp_path / 'nope.toml'}: no such file")):
        load_scenario(tmp_path / "nope.toml")


def test_toml_syntax_error_names_file_and_line(tmp_path: Path):
    path = tmp_path / "broken.toml"
    path.write_text('name = "x"\nduration = \n')
    with pytest.raises(ScenarioError, match=r"broken.toml: not valid TOML: .*line 2"):
        load_scenario(path)


def test_ltl_task_errors_name_the_robot_field(tmp_path: Path):
    data = mutated("robots.0", {"id": 1, "kind": "unicycle", "pose": [0.0, 0.0, 0.0],
                                "ltl": "G F (a1 &"})
    with pytest.raises(ScenarioError, match=r"robots\[id=1\].ltl: LTL syntax error at column"):
        parse_scenario(data, source="s.toml")
    data["robots"][0]["ltl"] = "G F a1 & G F a13"
    with pytest.raises(ScenarioError,
                       match=r"robots\[id=1\].ltl: proposition 'a13' is carried by no region "
                             r"\(region labels: a1, a2\)"):
        parse_scenario(data, source="s.toml")
    data["robots"][0]["ltl"] = "G F a1 & G F a2"
    assert parse_scenario(data).robot(1).ltl == "G F a1 & G F a2"


def test_ltl_on_omni_robot_is_rejected():
    data = mutated("robots.0", {"id": 1, "kind": "omni", "pose": [0.0, 0.0, 0.0], "ltl": "F a1"})
    with pytest.raises(ScenarioError,
                       match=r"robots\[id=1\].ltl: LTL tasks run on unicycle robots"):
        parse_scenario(data, source="s.toml")


def test_each_task_text_is_parsed_once_per_process(scenarios_dir, monkeypatch):
    """The loader's parse of every task is the process's only one: building the agents and
    planning parse nothing again, and a replaced task text is parsed anew, never served the old
    text's tree."""
    import dataclasses

    import tlfleet.agent.ltl.parser as ltl_parser
    import tlfleet.agent.ltl.task as ltl_task
    import tlfleet.agent.stl.parser as stl_parser
    from tlfleet.agent.policy.ltl import LtlAgent
    from tlfleet.agent.policy.stl import build_agents

    ltl_task.task_formula.cache_clear()
    stl_parser.parsed_task.cache_clear()
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    ltl_robot = next(r for r in scenario.robots if r.is_ltl)
    stl_robot = next(r for r in scenario.robots if r.is_stl)

    def refuse(*args, **kwargs):
        raise AssertionError("parsed twice")

    import tlfleet.agent.ltl.planner as planner
    import tlfleet.agent.stl.sequencer as sequencer
    import tlfleet.agent.stl.task as task

    for module, name in ((ltl_parser, "parse"), (ltl_task, "parse"), (planner, "parse"),
                         (stl_parser, "parse_task"), (sequencer, "parse_task"),
                         (task, "parse_task")):
        if hasattr(module, name):
            monkeypatch.setattr(module, name, refuse)
    assert ltl_task.robot_formula(ltl_robot) is ltl_task.robot_formula(ltl_robot)
    assert len(stl_parser.robot_subtasks(stl_robot)) == len(stl_robot.stl)
    build_agents(scenario)
    LtlAgent(scenario, ltl_robot.id).plan()
    monkeypatch.undo()

    changed = dataclasses.replace(ltl_robot, ltl="F a12")
    assert ltl_parser.parse("F a12") == ltl_task.robot_formula(changed)
    assert ltl_task.robot_formula(changed) != ltl_task.robot_formula(ltl_robot)


def test_loading_and_building_the_agents_parse_and_translate_each_ltl_task_once(monkeypatch):
    """Loading Scenario 1 and building both LTL agents as `tlfleet check` and `run` do (plan
    included): each formula parsed once and translated once — the emptiness check's automaton
    is the one the agent plans with (three parses a formula a load before)."""
    from tlfleet.agent.ltl import buchi, task
    from tlfleet.agent.policy.preflight import check_launch
    from tlfleet.agent.scenario import validation

    parses: list[str] = []
    translations: list[object] = []
    real_parse, real_translate = task.parse, buchi.translate

    def counting_parse(text, *args, **kwargs):
        parses.append(text)
        return real_parse(text, *args, **kwargs)

    def counting_translate(formula, *args, **kwargs):
        translations.append(formula)
        return real_translate(formula, *args, **kwargs)

    monkeypatch.setattr(task, "parse", counting_parse)
    monkeypatch.setattr(buchi, "parse", counting_parse)
    monkeypatch.setattr(task, "translate", counting_translate)
    for cached in (task.task_formula, task.text_automaton, validation._ltl_empty):
        cached.cache_clear()
    scenario = load_scenario(Path(__file__).resolve().parents[2] / "scenarios" /
                             "scenario1.toml")
    check_launch(scenario)
    texts = sorted(r.ltl for r in scenario.robots if r.ltl is not None)
    assert sorted(parses) == texts
    assert len(translations) == len(texts)


def test_loading_and_building_the_agents_parse_each_stl_sub_task_once(monkeypatch):
    """The loader's checks and every agent share one tree a sub-task (two parses a sub-task a
    load before: the syntax check and the window check)."""
    from tlfleet.agent.policy.preflight import check_launch
    from tlfleet.agent.stl import parser

    parsed: list[str] = []
    real = parser._Parser.task

    def counting(self):
        parsed.append(self.text)
        return real(self)

    monkeypatch.setattr(parser._Parser, "task", counting)
    parser.parsed_task.cache_clear()
    scenario = load_scenario(Path(__file__).resolve().parents[2] / "scenarios" /
                             "scenario1.toml")
    check_launch(scenario)
    assert sorted(parsed) == sorted(t for r in scenario.robots for t in r.stl)
