"""The intended layering of the tree as data (docs/architecture.md §Layers), checked on every import
statement of every module, nested and lazy ones included.

``ALLOWED`` lists, for each package, the packages of the project it may import; any other project
import is a violation. ``NEVER`` spells out the arrows that must never exist (each is also absent
from ``ALLOWED``; listing them makes the intent readable and guards against a later edit of
``ALLOWED`` that would let one in). ``LIBRARIES`` says which package alone may import each I/O
library. This one test replaces the per-package purity scanners that each checked a part of it.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TOP_LEVEL = ("agent", "bus", "sim", "coordinator", "cli")

PURE = ("agent.ltl", "agent.stl", "agent.nav", "agent.control", "agent.scenario")

# package -> project packages it may import (besides itself). Bottom to top.
ALLOWED: dict[str, frozenset[str]] = {
    "agent.errors": frozenset(),
    "agent.evolve": frozenset(),  # dataclasses.replace for the per-tick states, stdlib only
    "agent.protocol": frozenset({"agent.errors"}),
    "bus": frozenset({"agent.errors", "agent.protocol"}),
    # the pure cores: numbers in, numbers out; the scenario model is their shared data
    **{core: frozenset({"agent.errors", "agent.evolve", *PURE}) - {core} for core in PURE},
    "agent.runtime": frozenset({"agent.errors", "agent.evolve", "agent.protocol", "bus", *PURE}),
    "sim": frozenset({"agent.errors", "agent.protocol", "bus", "agent.scenario"}),
    "coordinator": frozenset({"agent.errors", "agent.protocol", "bus", "agent.scenario",
                              "agent.ltl", "agent.stl"}),
    "cli": frozenset({"agent.errors", "agent.evolve", "agent.protocol", "bus", *PURE,
                      "agent.runtime", "sim", "coordinator"}),
}

# (importer, imported, why): arrows that must never appear.
NEVER: tuple[tuple[str, str, str], ...] = (
    ("sim", "agent.runtime", "the simulator and the agents share only the bus and the protocol"),
    ("agent.runtime", "sim", "the simulator and the agents share only the bus and the protocol"),
    ("sim", "coordinator", "the simulator runs without a coordinator"),
    ("agent.runtime", "coordinator", "agents run without a coordinator"),
    *((core, "bus", "pure cores never touch the bus") for core in PURE),
    *((core, "agent.protocol", "pure cores know no wire format") for core in PURE),
    *((core, "agent.runtime", "pure cores never import the runtime") for core in PURE),
    ("bus", "agent.runtime", "the bus is the bottom layer"),
    ("bus", "sim", "the bus is the bottom layer"),
    ("bus", "coordinator", "the bus is the bottom layer"),
    ("agent.protocol", "bus", "the protocol sits below the bus"),
    ("coordinator", "agent.runtime", "the coordinator starts agents as processes"),
    ("coordinator", "sim", "the coordinator starts the simulator as a process"),
    *((pkg, "cli", "nothing imports the command line") for pkg in ALLOWED if pkg != "cli"),
)

# I/O library -> the only modules (prefixes) that may import it
LIBRARIES: dict[str, tuple[str, ...]] = {
    "zenoh": ("bus.zenoh_transport",),
    "pymunk": ("sim.world",),
    "rerun": ("coordinator.visual",),
    "matplotlib": ("coordinator.figures",),
}

# project module -> the only packages that may import it
RESTRICTED_MODULES: dict[str, tuple[str, ...]] = {
    "coordinator.visual": ("coordinator", "cli"),
    "coordinator.figures": ("coordinator", "cli"),
}


@dataclass(frozen=True)
class Import:
    importer: str  # dotted module name
    imported: str  # dotted module name (for `from a import b`: both `a` and `a.b`)
    line: int


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(path: Path, root: Path) -> list[Import]:
    """Every absolute import in the file, however deeply nested (functions, ``if`` blocks)."""
    importer = module_name(path, root)
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [Import(importer, alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append(Import(importer, node.module, node.lineno))
            found += [Import(importer, f"{node.module}.{alias.name}", node.lineno)
                      for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level > 0:
            found.append(Import(importer, "<relative>", node.lineno))
    return found


def package_of(module: str) -> str | None:
    """The layering package a project module belongs to (longest matching prefix)."""
    for package in sorted(ALLOWED, key=len, reverse=True):
        if module == package or module.startswith(package + "."):
            return package
    return None


def _within(module: str, prefixes: Iterable[str]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in prefixes)


def violations(root: Path) -> list[str]:
    """Every import of the tree under ``root`` that breaks ``ALLOWED``, ``NEVER``, ``LIBRARIES``
    or ``RESTRICTED_MODULES``, as ``file:line: importer -> imported (rule)``."""
    never = {(a, b): why for a, b, why in NEVER}
    out = []
    for top in TOP_LEVEL:
        for path in sorted((root / top).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            for imp in imports_of(path, root):
                where = f"{rel}:{imp.line}: {imp.importer} -> {imp.imported}"
                if imp.imported == "<relative>":
                    out.append(f"{where} (relative imports hide the layer; use absolute ones)")
                    continue
                src = package_of(imp.importer)
                library = imp.imported.split(".")[0]
                if library in LIBRARIES:
                    if not _within(imp.importer, LIBRARIES[library]):
                        out.append(f"{where} (only {', '.join(LIBRARIES[library])} may import "
                                   f"{library})")
                    continue
                dst = package_of(imp.imported)
                if src is None:
                    out.append(f"{where} (module outside every layer)")
                    continue
                if dst is None or dst == src:
                    continue
                if (src, dst) in never:
                    out.append(f"{where} (never: {never[(src, dst)]})")
                elif dst not in ALLOWED[src]:
                    out.append(f"{where} ({src} may import only {sorted(ALLOWED[src])})")
                for module, users in RESTRICTED_MODULES.items():
                    if _within(imp.imported, (module,)) and src not in users:
                        out.append(f"{where} (only {', '.join(users)} may import {module})")
    # `from a import b` yields `a` and `a.b`: one message per file, line and rule
    unique: dict[tuple[str, str], str] = {}
    for message in out:
        place, _, rest = message.partition(": ")
        unique.setdefault((place, rest[rest.index(" ("):]), message)
    return list(unique.values())


def test_the_tree_follows_the_layering() -> None:
    assert violations(ROOT) == []


def test_never_arrows_are_not_allowed_anywhere() -> None:
    """The data is consistent: no arrow is both forbidden and allowed."""
    assert [(a, b) for a, b, _ in NEVER if b in ALLOWED.get(a, ())] == []
    assert all(b in ALLOWED or b == "cli" for _, b, _ in NEVER)


def test_every_project_package_has_a_layer() -> None:
    packages = {module_name(p.parent, ROOT) for top in TOP_LEVEL
                for p in (ROOT / top).rglob("__init__.py")}
    assert {p for p in packages if package_of(p) is None} == {"agent"}  # agent/ only groups


def test_pure_cores_import_only_the_standard_library_and_numpy() -> None:
    """A C accelerator's cffi builder (``_*_build.py``, e.g. agent/nav/_dwa_build.py) runs at
    install time only (setup.py) and is never imported by the core, so it may import cffi."""
    allowed_roots = set(sys.stdlib_module_names) | {"numpy", "agent"}
    offenders = {}
    for core in PURE:
        for path in sorted((ROOT / core.replace(".", "/")).rglob("*.py")):
            if path.name.startswith("_") and path.name.endswith("_build.py"):
                continue
            imported = [i.imported for i in imports_of(path, ROOT)]
            bad = {name.split(".")[0] for name in imported} - allowed_roots
            bad |= {name for name in imported if name.endswith("_build")}  # builders: never
            if bad:
                offenders[path.relative_to(ROOT).as_posix()] = sorted(bad)
    assert offenders == {}


def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = tmp_path / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    for top in TOP_LEVEL:
        (tmp_path / top).mkdir(exist_ok=True)
    return tmp_path


@pytest.mark.parametrize(("files", "expected"), [
    ({"sim/process.py": "from agent.runtime.loop import AgentLoop\n"},
     "sim.process -> agent.runtime.loop (never: the simulator and the agents share only"),
    ({"agent/stl/x.py": "def f():\n    import zenoh\n"},
     "only bus.zenoh_transport may import zenoh"),
    ({"bus/transport.py": "import zenoh\n"}, "only bus.zenoh_transport may import zenoh"),
    ({"agent/nav/x.py": "from bus.transport import Transport\n"},
     "never: pure cores never touch the bus"),
    ({"sim/x.py": "from agent.stl.funnel import Funnel\n"}, "sim may import only"),
    ({"coordinator/report.py": "import rerun as rr\n"}, "only coordinator.visual may import rerun"),
    ({"coordinator/report.py": "from matplotlib.figure import Figure\n"},
     "only coordinator.figures may import matplotlib"),
    ({"agent/runtime/x.py": "from cli.main import main\n"}, "nothing imports the command line"),
    ({"sim/x.py": "from coordinator.visual import FleetLog\n"}, "never: the simulator runs"),
    ({"agent/ltl/x.py": "from . import y\n"}, "relative imports hide the layer"),
    ({"agent/runtime/x.py": "from coordinator import visual\n"},
     "only coordinator, cli may import coordinator.visual"),
])
def test_the_checker_catches_a_deliberate_violation(tmp_path: Path, files, expected) -> None:
    """Each rule fails on a tree that breaks it, or the test above proves nothing."""
    found = violations(_tree(tmp_path, files))
    assert len(found) >= 1 and any(expected in v for v in found), found


def test_the_checker_passes_an_allowed_tree(tmp_path: Path) -> None:
    root = _tree(tmp_path, {
        "sim/process.py": "from bus.transport import Transport\nfrom agent.protocol import keys\n",
        "bus/zenoh_transport.py": "import zenoh\n",
        "cli/main.py": "def f():\n    from coordinator.visual import FleetLog\n",
    })
    assert violations(root) == []
