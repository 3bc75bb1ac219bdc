"""Suite-wide test configuration.

Hypothesis: the ``ci`` profile (selected when the CI environment variable is set, as it is for
``.ci/run``) derandomises example generation, so a CI run is reproducible; local runs use the
``dev`` profile and explore new examples every time. Either runs a quarter of each property's
budget (``tests/hypothesis_budget.py``); ``TLFLEET_HYPOTHESIS=full`` runs all of it.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings
from hypothesis_budget import examples

DEFAULT_BUDGET = 100  # Hypothesis's own default number of examples
settings.register_profile(
    "ci", derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow],
    max_examples=examples(DEFAULT_BUDGET),
)
settings.register_profile("dev", deadline=None, max_examples=examples(DEFAULT_BUDGET))
settings.load_profile("ci" if os.environ.get("CI") else "dev")

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def scenarios_dir() -> Path:
    return ROOT / "scenarios"


# ----------------------------------------------------------------- system requirements
# Tests marked ``needs_system`` need root, network namespaces or docker. Where those are missing
# they skip with the reason; with TLFLEET_REQUIRE_SYSTEM=1 (set by .ci/run) such a skip is turned
# into a failure, so CI can never pass by skipping them. So are the ``ros`` tests (the tlfleet[ros2]
# extra: rclpy, mcap), which `make test` installs.
REQUIRE_SYSTEM = os.environ.get("TLFLEET_REQUIRE_SYSTEM") == "1"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if REQUIRE_SYSTEM and report.skipped and (item.get_closest_marker("needs_system")
                                              or item.get_closest_marker("ros")):
        reason = report.longrepr[-1] if isinstance(report.longrepr, tuple) else report.longrepr
        report.outcome = "failed"
        report.longrepr = (f"TLFLEET_REQUIRE_SYSTEM=1, but this system test was skipped: "
                           f"{reason}")
