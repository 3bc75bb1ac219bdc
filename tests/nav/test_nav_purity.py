"""agent/nav is a pure core (style.md §1): stdlib, numpy and agent.* only; no I/O frameworks."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ALLOWED_THIRD_PARTY = {"numpy"}


def _imported_roots(path: Path) -> set[str]:
    roots = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            roots.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
    return roots


def test_nav_imports_only_stdlib_numpy_and_agent(repo_root):
    files = sorted((repo_root / "agent" / "nav").glob("*.py"))
    assert files
    offenders = {}
    for path in files:
        bad = {
            root
            for root in _imported_roots(path)
            if root not in sys.stdlib_module_names
            and root not in ALLOWED_THIRD_PARTY
            and root != "agent"
        }
        if bad:
            offenders[path.name] = sorted(bad)
    assert offenders == {}


def test_nav_does_not_depend_on_other_agent_cores(repo_root):
    """Navigation takes plans as region names; it needs no planner, STL or runtime code."""
    for path in sorted((repo_root / "agent" / "nav").glob("*.py")):
        for root in _imported_agent_modules(path):
            assert root in {"agent.errors", "agent.scenario", "agent.nav"}, (path.name, root)


def _imported_agent_modules(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        found.update(".".join(n.split(".")[:2]) for n in names if n.startswith("agent."))
    return found
