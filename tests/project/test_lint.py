"""The tree passes its own linter (``make lint``: ruff with the rules of ``pyproject.toml``), so
a rule broken in one change is seen in ``make test`` and CI, not at the next manual lint."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_ruff_finds_nothing():
    ruff = Path(sys.executable).with_name("ruff")  # installed with the test extras
    done = subprocess.run([str(ruff), "check", "--no-cache", "."], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
