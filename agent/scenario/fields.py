"""How error messages name the places of a scenario file (``ScenarioError.field``).

A robot is named by its id, as the file's author knows it — ``robots[id=6].stl[0]`` — not by
the position of its ``[[robots]]`` table (``robots[5]``, 0-based, read as "robot 5" by half the
people who see it). Only a table whose id cannot be read is named by its position, and the
reason then says which table it is in words (:func:`ordinal_table`).
"""

from __future__ import annotations


def robot_field(index: int, robot_id: int | None = None) -> str:
    """The field path of the robot with id ``robot_id`` (``robots[id=6]``), or of the
    ``index``-th ``[[robots]]`` table (0-based, ``robots[5]``) when its id is not known."""
    return f"robots[{index}]" if robot_id is None else f"robots[id={robot_id}]"


def ordinal_table(index: int, name: str = "robots") -> str:
    """``the 6th [[robots]] table`` for the 0-based ``index``."""
    n = index + 1
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"the {n}{suffix} [[{name}]] table"
