"""Fixtures of the system tests shared across files.

``scenario1_run``: one ``tlfleet run`` of Scenario 1 in lockstep with the scenario's seed, made
once per session (about 50 s on 2 cores) and shared by the paper-bounds test and the
byte-identity tests of issue 12 (by hand + ``supervise``, namespace hosts, compose), which compare
their ``trajectory.csv`` to its bytes.
"""

from __future__ import annotations

import pytest
from system_helpers import SCENARIOS, run


@pytest.fixture(scope="session")
def scenario1_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("scenario1-run") / "run"
    result = run(SCENARIOS / "scenario1.toml", out)
    return result
