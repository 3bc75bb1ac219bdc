"""Suite-wide test configuration.

Hypothesis: the ``ci`` profile (selected when the CI environment variable is set, as it is for
``.ci/run``) derandomises example generation, so a CI run is reproducible; local runs use the
default profile and explore new examples every time.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci", derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("dev", deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def scenarios_dir() -> Path:
    return ROOT / "scenarios"
