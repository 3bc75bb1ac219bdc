"""The error hierarchy shared by every tlfleet layer (style.md §7).

Each error is specific, carries the offending value and where it was found, and derives from the
builtin that a caller would naturally catch (``ValueError`` for bad input).
"""

from __future__ import annotations


class TlfleetError(Exception):
    """Base class of every error tlfleet raises on purpose."""


class FormulaSyntaxError(TlfleetError, ValueError):
    """A formula (LTL or STL) that does not parse.

    ``column`` is 1-based and points at the first offending character of ``text``.
    """

    def __init__(self, text: str, column: int, message: str):
        self.text = text
        self.column = column
        self.reason = message
        pointer = " " * (column - 1) + "^"
        super().__init__(f"column {column}: {message}\n  {text}\n  {pointer}")


class LtlSyntaxError(FormulaSyntaxError):
    """An LTL formula that does not parse; the message is one line: formula, column, reason."""

    def __init__(self, text: str, column: int, message: str):
        super().__init__(text, column, message)
        shown = text if len(text) <= 72 else (
            ("…" if column > 36 else "") + text[max(0, column - 36): column + 36]
            + ("…" if column + 36 < len(text) else ""))
        self.args = (f"LTL formula {shown!r}, column {column}: {message}",)

    def __str__(self) -> str:
        return self.args[0]


class LtlError(TlfleetError, ValueError):
    """Any other LTL failure (an automaton file that does not parse, a formula too large …)."""


class ScenarioError(TlfleetError, ValueError):
    """A scenario file that is not valid: names the file, the field path and what was expected."""

    def __init__(self, file: str, field: str, reason: str):
        self.file = file
        self.field = field
        self.reason = reason
        where = f"{file}: {field}" if field else file
        super().__init__(f"{where}: {reason}")


class UnsatisfiableTask(TlfleetError):
    """A task that has no satisfying execution on the robot's transition system.

    The message names the robot, the formula, and what is missing.
    """

    def __init__(self, robot: int | None, formula: str, missing: str):
        self.robot = robot
        self.formula = formula
        self.missing = missing
        who = f"robot {robot}: " if robot is not None else ""
        super().__init__(f"{who}task {formula!r} cannot be satisfied: {missing}")
