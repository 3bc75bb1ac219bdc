"""The layers of the ``tlfleet`` package as data (docs/architecture.md §4), checked on every import
statement of every module, nested and lazy ones included.

``LAYERS`` lists the layers from the ground up, one line each; a layer is a set of *units*
(packages, or single modules such as ``tlfleet.bus.errors``), and a module belongs to the unit
with the longest matching name. A unit may import its own modules and the units of the layers
below it; anything else — an import up, or sideways into another unit of its own layer — is a
violation. ``NEVER`` adds arrows that point down but must not exist (each one names why).
``LIBRARIES`` says which module alone may import each I/O library. Finally no two packages may
import each other, directly or around a circle (:func:`package_cycles`), at any depth: two
sub-packages of one unit included, which the layers alone would not catch.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = "tlfleet"  # the repository's root is the package's folder (setup.py)
FOLDERS = ("agent", "bus", "sim", "coordinator", "cli")

# The layers, bottom to top.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("tlfleet.bus.errors",),  # the error hierarchy every layer raises
    ("tlfleet.bus.protocol", "tlfleet.bus"),  # the wire protocol; the transport interface, fake
    ("tlfleet.bus.zenoh",),  # the zenoh transport
    ("tlfleet.agent.evolve", "tlfleet.agent.model"),  # state updates; the scenario model
    ("tlfleet.agent.ltl", "tlfleet.agent.stl", "tlfleet.agent.nav", "tlfleet.agent.control"),
    ("tlfleet.agent.scenario",),  # scenario files: parsing and checking tasks needs the cores
    ("tlfleet.agent.policy",),  # one robot's decision per tick, from the cores
    ("tlfleet.agent.runtime", "tlfleet.sim", "tlfleet.sim.router"),  # the processes
    ("tlfleet.coordinator.launch", "tlfleet.coordinator.record", "tlfleet.coordinator.security"),
    ("tlfleet.coordinator.faults", "tlfleet.coordinator.live"),
    ("tlfleet.coordinator.report",),
    ("tlfleet.coordinator",),  # the entry points: run, run_hosts, supervise, compose
    ("tlfleet.cli",),
    ("tlfleet",),  # the package's root
)

# Below the bus: what knows no wire format and no transport.
PURE = ("tlfleet.agent.evolve", "tlfleet.agent.model", "tlfleet.agent.ltl", "tlfleet.agent.stl",
        "tlfleet.agent.nav", "tlfleet.agent.control", "tlfleet.agent.scenario",
        "tlfleet.agent.policy")
TRANSPORT = ("tlfleet.bus.protocol", "tlfleet.bus", "tlfleet.bus.zenoh")
PROCESSES = ("tlfleet.agent.runtime", "tlfleet.sim", "tlfleet.sim.router")
COORDINATOR = tuple(unit for layer in LAYERS for unit in layer
                    if unit == "tlfleet.coordinator" or unit.startswith("tlfleet.coordinator."))

# (importer, imported, why): arrows that point down but must never appear.
NEVER: tuple[tuple[str, str, str], ...] = (
    *((pure, transport, "the cores, the model and the policies know no wire format and no "
                        "transport") for pure in PURE for transport in TRANSPORT),
    *((unit, process, "the coordinator starts the processes; it never imports them")
      for unit in COORDINATOR for process in PROCESSES),
    *(("tlfleet.sim", unit, "the simulator emulates hardware: it knows no task or policy")
      for unit in ("tlfleet.agent.ltl", "tlfleet.agent.stl", "tlfleet.agent.nav",
                   "tlfleet.agent.control", "tlfleet.agent.policy")),
    *(("tlfleet.sim.router", unit, "the router knows only the bus")
      for unit in ("tlfleet.agent.model", "tlfleet.agent.scenario", *PURE)),
)

# I/O library -> the only modules (prefixes) that may import it
LIBRARIES: dict[str, tuple[str, ...]] = {
    "zenoh": ("tlfleet.bus.zenoh.transport",),
    "pymunk": ("tlfleet.sim.world",),
    "rerun": ("tlfleet.coordinator.report.viewer",),
    "matplotlib": ("tlfleet.coordinator.report.figures",),
    "rclpy": ("tlfleet.sim.hardware.ros_link", "tlfleet.coordinator.report.ros_mirror"),
}

UNITS = tuple(unit for layer in LAYERS for unit in layer)
RANK = {unit: rank for rank, layer in enumerate(LAYERS) for unit in layer}


@dataclass(frozen=True)
class Import:
    importer: str  # dotted module name
    imported: str  # dotted module name (for `from a import b`: both `a` and `a.b`)
    line: int


def module_name(path: Path, root: Path) -> str:
    parts = [PACKAGE, *path.relative_to(root).with_suffix("").parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def source_files(root: Path) -> list[Path]:
    """The package's modules: the root's ``__init__.py`` and every module of the layer folders."""
    init = root / "__init__.py"
    return ([init] if init.is_file() else []) + sorted(
        path for folder in FOLDERS for path in (root / folder).rglob("*.py"))


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


def _within(module: str, prefixes: Iterable[str]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in prefixes)


def unit_of(module: str) -> str | None:
    """The layer unit a project module belongs to (longest matching name; the package's root
    unit is its ``__init__`` alone)."""
    if module == PACKAGE:
        return PACKAGE
    for unit in sorted(UNITS, key=len, reverse=True):
        if unit != PACKAGE and _within(module, (unit,)):
            return unit
    return None


def violations(root: Path) -> list[str]:
    """Every import of the tree under ``root`` that breaks ``LAYERS``, ``NEVER`` or
    ``LIBRARIES``, as ``file:line: importer -> imported (rule)``."""
    never = {(a, b): why for a, b, why in NEVER}
    out = []
    for path in source_files(root):
        rel = path.relative_to(root).as_posix()
        for imp in imports_of(path, root):
            where = f"{rel}:{imp.line}: {imp.importer} -> {imp.imported}"
            if imp.imported == "<relative>":
                out.append(f"{where} (relative imports hide the layer; use absolute ones)")
                continue
            library = imp.imported.split(".")[0]
            if library in LIBRARIES:
                if not _within(imp.importer, LIBRARIES[library]):
                    allowed = ", ".join(LIBRARIES[library]) or "no module"
                    out.append(f"{where} (only {allowed} may import {library})")
                continue
            if library in FOLDERS:
                out.append(f"{where} (the layers are installed under {PACKAGE}: import "
                           f"{PACKAGE}.{imp.imported})")
                continue
            if library != PACKAGE:
                continue
            src, dst = unit_of(imp.importer), unit_of(imp.imported)
            if src is None:
                out.append(f"{where} (module outside every layer)")
            elif dst is None or dst == src:
                continue
            elif (src, dst) in never:
                out.append(f"{where} (never: {never[(src, dst)]})")
            elif RANK[dst] > RANK[src]:
                out.append(f"{where} (upward: {src} is below {dst})")
            elif RANK[dst] == RANK[src]:
                out.append(f"{where} (sideways: {src} and {dst} share a layer)")
    # `from a import b` yields `a` and `a.b`: one message per file, line and rule
    unique: dict[tuple[str, str], str] = {}
    for message in out:
        place, _, rest = message.partition(": ")
        unique.setdefault((place, rest[rest.index(" ("):]), message)
    return list(unique.values())


def package_cycles(root: Path) -> list[list[str]]:
    """Circles of packages that import each other. An import from a module of package A of a
    module of package B (A ≠ B, neither inside the other) is an arrow between the two children of
    their deepest common package that hold them; each package's children must form no circle."""
    modules = {module_name(path, root): path for path in source_files(root)}
    packages = {name for name, path in modules.items() if path.name == "__init__.py"}

    def package(module: str) -> str:
        return module if module in packages else module.rpartition(".")[0]

    arrows: dict[str, set[str]] = {}
    for path in source_files(root):
        importer = module_name(path, root)
        for imp in imports_of(path, root):
            target = imp.imported
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if not target:
                continue
            a, b = package(importer).split("."), package(target).split(".")
            common = 0
            while common < min(len(a), len(b)) and a[common] == b[common]:
                common += 1
            if common == len(a) or common == len(b):
                continue  # one package inside the other: its own parts
            arrows.setdefault(".".join(a[:common + 1]), set()).add(".".join(b[:common + 1]))
    cycles: list[list[str]] = []
    state: dict[str, int] = {}  # 1 on the current path, 2 done

    def visit(node: str, trail: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(arrows.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append([*trail[trail.index(nxt):], nxt])
            elif nxt not in state:
                visit(nxt, [*trail, nxt])
        state[node] = 2

    for node in sorted(arrows):
        if node not in state:
            visit(node, [node])
    return cycles


def test_the_tree_follows_the_layers() -> None:
    assert violations(ROOT) == []


def test_no_packages_import_each_other() -> None:
    assert package_cycles(ROOT) == []


def test_the_rules_are_consistent() -> None:
    """Every ``NEVER`` arrow points down (an upward one is caught anyway and would hide a typo);
    every unit is a folder or a module of the tree; no unit is listed twice."""
    assert [(a, b) for a, b, _ in NEVER if RANK[b] >= RANK[a]] == []
    assert len(UNITS) == len(set(UNITS))
    for unit in UNITS[:-1]:
        relative = Path(*unit.split(".")[1:])
        assert (ROOT / relative).is_dir() or (ROOT / relative.with_suffix(".py")).is_file(), unit


def test_every_package_belongs_to_a_layer() -> None:
    packages = {module_name(path, ROOT) for path in source_files(ROOT)
                if path.name == "__init__.py"}
    assert {p for p in packages if unit_of(p) is None} == {"tlfleet.agent"}  # it only groups


def test_pure_code_imports_only_the_standard_library_and_numpy() -> None:
    """A C accelerator's cffi builder (``_*_build.py``, e.g. agent/nav/_dwa_build.py) runs at
    install time only (setup.py) and is never imported by the core, so it may import cffi."""
    allowed_roots = set(sys.stdlib_module_names) | {"numpy", PACKAGE}
    offenders = {}
    for path in source_files(ROOT):
        if not _within(module_name(path, ROOT), PURE):
            continue
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
    for folder in FOLDERS:
        (tmp_path / folder).mkdir(exist_ok=True)
    return tmp_path


BROKEN_TREES = [
    ({"bus/transport.py": "from tlfleet.agent.model import Scenario\n"},
     "upward: tlfleet.bus is below tlfleet.agent.model"),
    ({"bus/errors.py": "from tlfleet.bus.protocol import keys\n"},
     "upward: tlfleet.bus.errors is below tlfleet.bus.protocol"),
    ({"agent/ltl/x.py": "from tlfleet.agent.stl.syntax import Temporal\n"},
     "sideways: tlfleet.agent.ltl and tlfleet.agent.stl share a layer"),
    ({"coordinator/live/x.py": "from tlfleet.coordinator.report import summary\n"},
     "upward: tlfleet.coordinator.live is below tlfleet.coordinator.report"),
    ({"agent/nav/x.py": "from tlfleet.bus.transport import Transport\n"},
     "never: the cores, the model and the policies know no wire format"),
    ({"agent/policy/x.py": "from tlfleet.bus.protocol.messages import Event\n"},
     "never: the cores, the model and the policies know no wire format"),
    ({"coordinator/run.py": "from tlfleet.sim.process import SimProcess\n"},
     "never: the coordinator starts the processes"),
    ({"sim/world.py": "from tlfleet.agent.stl.funnel import Funnel\n"},
     "never: the simulator emulates hardware"),
    ({"sim/process.py": "from tlfleet.agent.runtime.loop import AgentLoop\n"},
     "sideways: tlfleet.sim and tlfleet.agent.runtime share a layer"),
    ({"sim/router/process.py": "from tlfleet.agent.scenario import load_scenario\n"},
     "never: the router knows only the bus"),
    ({"agent/runtime/x.py": "from tlfleet.cli.main import main\n"},
     "upward: tlfleet.agent.runtime is below tlfleet.cli"),
    ({"agent/stl/x.py": "def f():\n    import zenoh\n"},
     "only tlfleet.bus.zenoh.transport may import zenoh"),
    ({"bus/transport.py": "import zenoh\n"}, "only tlfleet.bus.zenoh.transport may import zenoh"),
    ({"coordinator/report/run_report.py": "import rerun as rr\n"},
     "only tlfleet.coordinator.report.viewer may import rerun"),
    ({"coordinator/report/run_report.py": "from matplotlib.figure import Figure\n"},
     "only tlfleet.coordinator.report.figures may import matplotlib"),
    ({"sim/process.py": "import rclpy\n"},
     "only tlfleet.sim.hardware.ros_link, tlfleet.coordinator.report.ros_mirror may import rclpy"),
    ({"agent/ltl/x.py": "from . import y\n"}, "relative imports hide the layer"),
    ({"sim/x.py": "from bus.transport import Transport\n"},
     "the layers are installed under tlfleet"),
    ({"extra/x.py": "", "cli/x.py": "from tlfleet.nowhere import y\n", "agent/stray.py":
      "from tlfleet.bus.errors import TlfleetError\n"}, "module outside every layer"),
]


@pytest.mark.parametrize(("files", "expected"), BROKEN_TREES)
def test_the_checker_catches_a_deliberate_violation(tmp_path: Path, files, expected) -> None:
    """Each rule fails on a tree that breaks it, or the test above proves nothing."""
    found = violations(_tree(tmp_path, files))
    assert len(found) >= 1 and any(expected in v for v in found), found


def test_the_cycle_checker_catches_two_packages_of_one_unit_importing_each_other(
        tmp_path: Path) -> None:
    root = _tree(tmp_path, {
        "cli/__init__.py": "", "cli/a/__init__.py": "", "cli/b/__init__.py": "",
        "cli/a/x.py": "from tlfleet.cli.b.y import g\n",
        "cli/b/y.py": "def g():\n    from tlfleet.cli.a.x import f\n",
    })
    assert violations(root) == []  # one unit: the layers alone would let it through
    assert package_cycles(root) == [["tlfleet.cli.a", "tlfleet.cli.b", "tlfleet.cli.a"]]


def test_the_checker_passes_an_allowed_tree(tmp_path: Path) -> None:
    root = _tree(tmp_path, {
        "__init__.py": '"""the root"""\n',
        "sim/__init__.py": "", "bus/__init__.py": "", "cli/__init__.py": "",
        "sim/process.py": "from tlfleet.bus.transport import Transport\n"
                          "from tlfleet.bus.protocol import keys\n",
        "bus/zenoh/transport.py": "import zenoh\nfrom tlfleet.bus.errors import TlfleetError\n",
        "agent/ltl/planner.py": "from tlfleet.agent.model import Scenario\n"
                                "from tlfleet.bus.errors import LtlError\n",
        "cli/main.py": "def f():\n    from tlfleet.coordinator.report.viewer import FleetLog\n",
    })
    assert violations(root) == []
    assert package_cycles(root) == []
