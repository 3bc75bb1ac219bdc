"""The layering rule of architecture.md §4, checked on every import statement (nested ones too)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PURE_CORES = ("agent/ltl", "agent/stl", "agent/nav", "agent/control", "agent/protocol",
              "agent/scenario")
IO_LIBRARIES = {"zenoh", "pymunk", "rerun", "matplotlib"}

# package folder -> the I/O libraries it may import
ALLOWED = {
    "agent/runtime": {"zenoh"},
    "sim": {"zenoh", "pymunk"},
    "coordinator": {"zenoh", "rerun", "matplotlib"},
}


def imported_top_level_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def python_files(folder: str) -> list[Path]:
    return sorted((ROOT / folder).rglob("*.py"))


@pytest.mark.parametrize("folder", PURE_CORES)
def test_pure_cores_import_no_io_library(folder: str) -> None:
    offenders = {
        str(path.relative_to(ROOT)): sorted(imported_top_level_modules(path) & IO_LIBRARIES)
        for path in python_files(folder)
    }
    assert {k: v for k, v in offenders.items() if v} == {}


def test_io_libraries_stay_in_their_layer() -> None:
    offenders = {}
    for path in python_files("agent") + python_files("sim") + python_files("coordinator"):
        rel = path.relative_to(ROOT).as_posix()
        allowed = next((libs for prefix, libs in ALLOWED.items() if rel.startswith(prefix + "/")),
                       set())
        bad = (imported_top_level_modules(path) & IO_LIBRARIES) - allowed
        if bad:
            offenders[rel] = sorted(bad)
    assert offenders == {}


def test_pure_cores_do_not_import_upper_layers() -> None:
    offenders = {}
    for folder in PURE_CORES:
        for path in python_files(folder):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            for node in ast.walk(tree):
                module = node.module if isinstance(node, ast.ImportFrom) else None
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
                for name in [module, *names]:
                    if name and (name.startswith(("coordinator", "sim", "agent.runtime"))):
                        offenders[str(path.relative_to(ROOT))] = name
    assert offenders == {}


def test_the_checker_sees_a_violation(tmp_path: Path) -> None:
    """The scan itself must catch a nested import, or the tests above prove nothing."""
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    import zenoh.session\n    from pymunk import Body\n")
    assert imported_top_level_modules(bad) == {"zenoh", "pymunk"}
