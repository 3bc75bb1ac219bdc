"""Errors of the navigation stack (ltl-planning.md §6); all derive from ``TlfleetError``."""

from __future__ import annotations

from tlfleet.bus.errors import TlfleetError


class NoPathError(TlfleetError):
    """The global planner found no collision-free path between two points.

    ``start`` and ``goal`` are the requested world points (x, y) [m]; ``reason`` says why (e.g. the
    goal lies in a part of the free space that the start cannot reach).
    """

    def __init__(self, start: tuple[float, float], goal: tuple[float, float], reason: str):
        self.start = (float(start[0]), float(start[1]))
        self.goal = (float(goal[0]), float(goal[1]))
        self.reason = reason
        super().__init__(
            f"no path from ({self.start[0]:.3f}, {self.start[1]:.3f}) "
            f"to ({self.goal[0]:.3f}, {self.goal[1]:.3f}): {reason}"
        )


class InvalidPlanError(TlfleetError, ValueError):
    """A region plan the executor cannot follow (empty, or naming an unknown region)."""

    def __init__(self, plan: tuple[tuple[str, ...], tuple[str, ...]], reason: str):
        self.plan = plan
        self.reason = reason
        super().__init__(f"invalid plan prefix={plan[0]!r} suffix={plan[1]!r}: {reason}")
