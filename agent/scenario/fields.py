"""How error messages name the places of a scenario file (``ScenarioError.field``)."""

from __future__ import annotations


def robot_field(index: int, robot_id: int | None = None) -> str:
    """The field path of the ``index``-th ``[[robots]]`` table (0-based)."""
    return f"robots[{index}]"
