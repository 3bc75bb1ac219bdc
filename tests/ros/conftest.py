"""The ROS tests' schedule: Scenario 1's 90 s acceptance mission over the bridge
(test_ros_acceptance.py) is started in the background when the first ROS test runs, the other
ROS tests run meanwhile, and the acceptance test, moved behind them, collects the mission's
result and checks it as before. The mission runs in its own namespace and ROS domain, as every
case does (ros_harness); it only shares the machine's cores with the case running beside it.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from ros_harness import CaseRun, missing_for_ros, start_case, unique_domain

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
ACCEPTANCE = "test_scenario1_over_the_bridge_has_the_simulators_verdicts"
MISSION_TIMEOUT = 480.0  # [s] wall: the 90 s mission, its start and its report, on a loaded machine


def _is_acceptance(item: pytest.Item) -> bool:
    return item.name == ACCEPTANCE and Path(str(item.path)).parent == HERE


def pytest_collection_modifyitems(session: pytest.Session, config: pytest.Config,
                                  items: list[pytest.Item]) -> None:
    """Move the acceptance test behind the last of the other ROS tests."""
    acceptance = [item for item in items if _is_acceptance(item)]
    if not acceptance:
        return
    rest = [item for item in items if not _is_acceptance(item)]
    ros = [i for i, item in enumerate(rest) if Path(str(item.path)).parent == HERE]
    at = ros[-1] + 1 if ros else len(rest)
    items[:] = rest[:at] + acceptance + rest[at:]


@pytest.fixture(scope="session")
def acceptance_mission(tmp_path_factory: pytest.TempPathFactory):
    """Scenario 1 through ``tlfleet run --hardware`` against fake robots, started now; stopped
    at the end of the session if nobody collected it."""
    mission: CaseRun = start_case(
        {"kind": "run", "scenario": str(ROOT / "scenarios" / "scenario1.toml"),
         "domain_id": unique_domain(), "timeout": 400},
        tmp_path_factory.mktemp("acceptance"), timeout=MISSION_TIMEOUT)
    yield mission
    mission.stop()


@pytest.fixture(scope="session", autouse=True)
def _acceptance_in_the_background(request: pytest.FixtureRequest) -> None:
    """Start the acceptance mission with the first ROS test when it is to run at all."""
    if missing_for_ros() is None and any(_is_acceptance(i) for i in request.session.items):
        request.getfixturevalue("acceptance_mission")
