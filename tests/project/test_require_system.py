"""TLFLEET_REQUIRE_SYSTEM=1 turns the skip of a ``needs_system`` test into a failure
(tests/conftest.py), so CI cannot pass by skipping the root / docker tests."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


@pytest.mark.needs_system
def test_probe():
    """Skips only when the outer test asks it to; passes otherwise."""
    if os.environ.get("TLFLEET_PROBE_SKIP") == "1":
        pytest.skip("probe: pretending root is missing")


@pytest.mark.parametrize(("require", "returncode", "seen"), [
    ("0", 0, "1 skipped"),
    ("1", 1, "TLFLEET_REQUIRE_SYSTEM=1, but this system test was skipped: "),
])
def test_a_system_skip_fails_under_tlfleet_require_system(repo_root, require, returncode, seen):
    env = dict(os.environ, TLFLEET_PROBE_SKIP="1", TLFLEET_REQUIRE_SYSTEM=require)
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "tests/project/test_require_system.py::test_probe"],
                          cwd=repo_root, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == returncode, done.stdout
    assert seen in done.stdout
    if require == "1":
        assert "probe: pretending root is missing" in done.stdout
