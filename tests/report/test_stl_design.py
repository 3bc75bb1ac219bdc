"""The run report says which STL design was in force (docs/stl-saturation.md §9): the F-task
semantics of each switch combination and the coupled pairs' avoidance radii."""

from __future__ import annotations

from pathlib import Path

import pytest
from tlfleet.agent.scenario import load_scenario, parse_scenario
from tlfleet.coordinator.record.run_record import Verdicts
from tlfleet.coordinator.report.task_verdicts import render_lines, stl_design

ROOT = Path(__file__).resolve().parents[2]


def _scenario(**stl):
    robots = [{"id": 2, "kind": "omni", "pose": [-2.0, 0.0, 0.0],
               "stl": ["F[5,25] (dist(p2, p3) <= 0.5)"]},
              {"id": 3, "kind": "omni", "pose": [1.0, 0.0, 0.0],
               "stl": ["F[0,2] (dist(p3, [1, 0]) <= 0.3)"]}]
    return parse_scenario({"name": "design", "duration": 25.0, "robots": robots, "stl": stl})


def test_each_switch_combination_names_its_f_semantics():
    assert stl_design(_scenario()).f_semantics.startswith("tlfleet's")
    authors = stl_design(_scenario(hold_f_above_r=True, complete_f_at_goal=False))
    assert authors.f_semantics.startswith("the authors' code")
    paper = stl_design(load_scenario(ROOT / "scenarios" / "scenario1.toml"))
    assert paper.f_semantics.startswith("the paper's Algorithm 2")
    assert not paper.saturation_aware and not paper.coupled_radii


def test_the_coupled_pair_and_its_radii_are_reported():
    design = stl_design(_scenario())
    assert design.coupled_radii == {"2-3": pytest.approx((0.43, 0.48))}
    (line,) = [x for x in render_lines(Verdicts(False, 0.9, True, {}, {}, (), design))
               if x.startswith("STL design")]
    assert "coupled pairs 2-3 0.43/0.48 m" in line and "R1/R 0.6/0.7 m" in line
    assert stl_design(_scenario(coupled_radii=False)).coupled_radii == {}
