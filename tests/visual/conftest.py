"""Fixtures of the visual tests (no fleet is launched: run directories are synthetic)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from visual_helpers import write_run


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    path = tmp_path / "run"
    write_run(path)
    return path


@pytest.fixture
def copy_run(run_dir: Path, tmp_path: Path):
    """A fresh copy of the run directory to break."""
    def make(name: str) -> Path:
        target = tmp_path / name
        shutil.copytree(run_dir, target)
        return target
    return make
