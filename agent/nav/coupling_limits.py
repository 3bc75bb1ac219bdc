"""Coupling-aware velocity limits of an LTL robot: the DWA's constraints (docs/coupling.md).

Beyond the paper. Each :class:`CouplingConstraint` bounds the unicycle command
(v [m/s], ω [rad/s]) of an LTL robot that an STL task of another robot depends on:
``a_v·|v| + a_ω·|ω| ≤ bound``. The constraints of one control step are derived from the coupled
predicates' gradients by ``tlfleet.agent.policy.coupling`` (navigation does not depend on the STL
core) and applied to the DWA's admissible set by ``tlfleet.agent.nav.dwa.dwa_control`` (its step 5)
and to the executor's recovery rotations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CouplingConstraint:
    """a_v·|v| + a_ω·|ω| ≤ bound (v [m/s], ω [rad/s]; a_v, a_ω per metre and per radian of the
    predicate's argument, bound in its units per second); ``source`` names the predicate."""

    a_v: float
    a_omega: float
    bound: float
    source: str

    def excess(self, v: np.ndarray, omega: np.ndarray) -> np.ndarray:
        return self.a_v * np.abs(v) + self.a_omega * np.abs(omega) - self.bound


@dataclass(frozen=True)
class VelocityLimits:
    """The coupling constraints of one control step (empty: no limit)."""

    constraints: tuple[CouplingConstraint, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.constraints)

    def excess(self, v: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """max over the constraints of a_v|v| + a_ω|ω| − bound (≤ 0: admissible)."""
        v = np.asarray(v, dtype=float)
        omega = np.asarray(omega, dtype=float)
        if not self.constraints:
            return np.zeros(np.broadcast(v, omega).shape)
        return np.max([c.excess(v, omega) for c in self.constraints], axis=0)

    @property
    def v_max(self) -> float:
        """Largest admissible |v| [m/s] (at ω = 0)."""
        return min((c.bound / c.a_v for c in self.constraints if c.a_v > 0), default=math.inf)

    @property
    def omega_max(self) -> float:
        """Largest admissible |ω| [rad/s] (at v = 0)."""
        return min((c.bound / c.a_omega for c in self.constraints if c.a_omega > 0),
                   default=math.inf)



    @staticmethod
    def of(rows) -> VelocityLimits:
        """From ``(a_v, a_ω, bound, source)`` rows
        (``tlfleet.agent.policy.coupling.CouplingModel.limits``)."""
        return VelocityLimits(tuple(CouplingConstraint(*row) for row in rows))
