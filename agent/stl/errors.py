"""Errors and warnings specific to the STL core (style.md §7)."""

from __future__ import annotations

from tlfleet.bus.errors import TlfleetError


class StlTaskError(TlfleetError, ValueError):
    """An STL task that parses but cannot be executed (e.g. overlapping sub-task windows, an
    unbounded ρ_opt without override). The message names the robot and the sub-task."""


class FunnelInvariantError(TlfleetError, RuntimeError):
    """Internal error: a funnel computed by §5 or by a repair (§7.3) violates its invariants
    (−1 < ζ(t_r) < 0, 0 < γ_∞ ≤ γ_0, γ_∞ < ρ_max − r, 0 ≤ l < ∞). Never expected; it means a bug."""


class StlConcavityWarning(UserWarning):
    """A predicate whose robustness is not certified concave (paper Assumption 1), so the funnel
    guarantees do not apply to it (see ``tlfleet.agent.stl.analysis`` for the rule)."""
