"""What a user sees of the package itself: `tlfleet --version` and metadata that installs without
setuptools deprecation blocks."""

from __future__ import annotations

import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest
from tlfleet.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def test_version_flag_prints_the_installed_version(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"tlfleet {version('tlfleet')}"


def test_licence_is_an_spdx_string_and_networkx_is_for_tests_only():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert project["license"] == "Apache-2.0"  # a table makes setuptools print deprecations
    # SPDX strings need setuptools ≥ 77 in the isolated build environment
    assert "setuptools>=77" in config["build-system"]["requires"]
    assert not any(dep.startswith("networkx") for dep in project["dependencies"])
    assert any(dep.startswith("networkx") for dep in project["optional-dependencies"]["test"])
