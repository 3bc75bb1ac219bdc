"""No product module writes into a frozen dataclass with ``object.__setattr__``: a value derived
from the fields is a ``functools.cached_property`` (or a field built by a ``default_factory``),
so "frozen" means what it says and equality never depends on a cache."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PRODUCT = ("agent", "bus", "sim", "coordinator", "cli")


def frozen_writes(source: str) -> list[int]:
    """Line numbers of the calls ``object.__setattr__(…)`` in ``source``."""
    return [node.lineno for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
            and node.func.attr == "__setattr__" and isinstance(node.func.value, ast.Name)
            and node.func.value.id == "object"]


def test_the_check_sees_a_write_and_not_a_mention():
    written = ('@dataclass(frozen=True)\nclass A:\n    x: int\n'
               '    def __post_init__(self):\n        object.__setattr__(self, "y", 1)\n')
    assert frozen_writes(written) == [5]
    assert frozen_writes('"""sets fields through ``object.__setattr__``"""\n') == []


def test_no_product_module_writes_into_a_frozen_dataclass():
    found = [f"{path.relative_to(ROOT)}:{line}"
             for top in PRODUCT for path in sorted((ROOT / top).rglob("*.py"))
             for line in frozen_writes(path.read_text(encoding="utf-8"))]
    assert not found, "object.__setattr__ in " + ", ".join(found)
