"""The simulator's cores stay pure: only ``sim/process.py`` touches the transport, and only
``sim/world.py`` imports pymunk (architecture.md §4; issue 5 §3)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SIM = Path(__file__).resolve().parents[2] / "sim"


def imports(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


@pytest.mark.parametrize("module", ["world", "lockstep", "clock", "stats"])
def test_cores_import_no_transport(module):
    names = imports(SIM / f"{module}.py")
    assert not {n for n in names if n.split(".")[0] == "zenoh" or n.startswith("agent.runtime")}


def test_only_the_world_imports_pymunk():
    users = sorted(p.name for p in SIM.glob("*.py")
                   if any(n.split(".")[0] == "pymunk" for n in imports(p)))
    assert users == ["world.py"]
