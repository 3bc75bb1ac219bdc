"""agent/stl and agent/control import only the standard library, numpy and agent.* (issue 3)."""

from __future__ import annotations

import ast
import sys

import pytest

ALLOWED = set(sys.stdlib_module_names) | {"numpy", "agent"}


@pytest.mark.parametrize("folder", ["agent/stl", "agent/control"])
def test_only_stdlib_numpy_and_agent_imports(repo_root, folder):
    offenders = {}
    for path in sorted((repo_root / folder).rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
        if names - ALLOWED:
            offenders[path.name] = sorted(names - ALLOWED)
    assert offenders == {}
    # and within agent.*, nothing above the pure cores (runtime, coordinator) or beside them
    for path in sorted((repo_root / folder).rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        for layer in ("agent.runtime", "agent.ltl", "agent.nav", "coordinator", "sim"):
            assert f"from {layer}" not in text and f"import {layer}" not in text, (path, layer)
