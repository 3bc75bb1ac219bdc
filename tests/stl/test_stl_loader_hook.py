"""The scenario loader checks every STL sub-task with the STL parser (``_check_stl_task``)."""

from __future__ import annotations

import pytest
from tlfleet.agent.scenario.loader import load_scenario
from tlfleet.bus.errors import ScenarioError


@pytest.mark.parametrize(("old", "new", "message"), [
    ("dist(p3, p4) <= 0.7", "dist(p3, p9) <= 0.7",
     r"robots\[id=3\]\.stl\[1\]: STL task error at column 50: robot 9 is not in the scenario "
     r"\(robots: 1, 2, 3, 4, 5\)"),
    ("G[5,30] (dist(p4, p3) <= 1 &", "G[5,30] (dist(p4, p3) <= 1 |",
     r"robots\[id=4\]\.stl\[0\]: STL task error at column 28: '\|' \(disjunction\) is not in the "
     r"STL fragment"),
    ("F[44,47] (dist(p5", "F[44 47] (dist(p5",
     r"robots\[id=5\]\.stl\[1\]: STL task error at column 6: expected ',' between the window "
     r"bounds"),
])
def test_bad_stl_task_is_a_scenario_error(tmp_path, scenarios_dir, old, new, message):
    text = (scenarios_dir / "scenario1.toml").read_text()
    assert old in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(path)
    assert info.value.file == str(path)


@pytest.mark.parametrize("name", ["scenario1.toml", "scenario2.toml", "scenario3.toml"])
def test_shipped_scenarios_pass(scenarios_dir, name):
    assert load_scenario(scenarios_dir / name).robots
