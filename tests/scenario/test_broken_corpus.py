"""Every file of the broken-scenario corpus is rejected by what ``tlfleet check`` and
``tlfleet run`` both run — the loader, then every agent built as its process would
(:func:`tlfleet.agent.policy.preflight.check_launch`) — with a specific error: the file, the
field path and the reason; never a traceback, never accepted."""

from __future__ import annotations

import re

import pytest
from broken_corpus import CASES
from tlfleet.agent.policy.preflight import check_launch
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.errors import ScenarioError


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_broken_file_gets_a_specific_error(case, tmp_path):
    path = case.make(tmp_path)
    with pytest.raises(ScenarioError) as info:
        check_launch(load_scenario(path))
    error = info.value
    assert error.file == str(path)
    assert error.field == case.field, str(error)
    assert re.search(case.reason, error.reason), str(error)


def test_the_corpus_base_file_is_valid(tmp_path):
    from broken_corpus import BASE

    path = tmp_path / "base.toml"
    path.write_text(BASE, encoding="utf-8")
    scenario = load_scenario(path)
    check_launch(scenario)
    assert scenario.robot_ids == (1, 2, 3)


def test_the_corpus_is_large():
    assert len(CASES) >= 70
