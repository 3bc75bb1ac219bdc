"""One STL sub-task ready to run: window, ψ, participants, V_ctrl, ρ_opt and compiled ψ.

stl-funnel.md §2 (participants vs. V_ctrl), §3 (ρ_opt: an override, else the supremum over the
arena's workspace (``tlfleet.agent.stl.supremum``, docs/stl-saturation.md §5), else the LSE_η of
the conjunct suprema), paper Assumption 1 (concavity warning, rule in
``tlfleet.agent.stl.analysis``).
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Literal

from tlfleet.agent.stl.analysis import literal_sup, non_concave_literals
from tlfleet.agent.stl.compiled import StraightLinePsi
from tlfleet.agent.stl.errors import StlConcavityWarning, StlTaskError
from tlfleet.agent.stl.parser import parse_task
from tlfleet.agent.stl.robustness import CompiledPsi, participants, smooth_and
from tlfleet.agent.stl.supremum import Workspace, psi_supremum
from tlfleet.agent.stl.syntax import Psi, Temporal, Top, literals, to_text

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Task:
    """Sub-task ``index`` (0-based) of robot ``owner``: φ = G_[a,b] ψ or F_[a,b] ψ.

    ``participants``: every robot whose state enters ψ (ascending; the layout of the stacked state
    x̄ = [x_j1, y_j1, θ_j1, …]); ``v_ctrl``: the STL-controlled ones (V_i of §7);
    ``rho_opt``: sup ρ^ψ used by the funnel (§5), resolved (override or default); ``goal``: a
    stacked state that attains it when it was computed over a workspace (else empty).
    """

    owner: int
    index: int
    kind: Literal["G", "F"]
    a: float  # [s]
    b: float  # [s]
    psi: Psi
    participants: tuple[int, ...]
    v_ctrl: tuple[int, ...]
    rho_opt: float
    eta: float
    compiled: CompiledPsi | StraightLinePsi = field(compare=False, repr=False)
    goal: tuple[float, ...] = field(default=(), compare=False, repr=False)

    @property
    def text(self) -> str:
        return to_text(Temporal(self.kind, self.a, self.b, self.psi))

    @property
    def relevant_deadline(self) -> float:
        """b for F, a for G: the time that matters to the stage-2 enabling rule (§7.4)."""
        return self.b if self.kind == "F" else self.a

    def stacked_state(self, poses: Mapping[int, object]) -> list[float]:
        """x̄ as a flat list [x_j1, y_j1, θ_j1, …] from ``poses[j] = (x, y, θ)`` (array or tuple)."""
        s: list[float] = []
        for robot in self.participants:
            pose = poses[robot]
            s.extend(pose.tolist() if hasattr(pose, "tolist") else pose)
        return s

    def block(self, robot: int) -> int:
        """Offset of ``robot``'s 3-state block in the stacked state."""
        return 3 * self.participants.index(robot)


def default_rho_opt(psi: Psi, eta: float) -> float:
    """ρ_opt := LSE_η of the conjunct suprema (stl-funnel.md §3), ``math.inf`` if unbounded."""
    sups = [literal_sup(lit) for lit in literals(psi)]
    if not sups or any(math.isinf(s) for s in sups):
        return math.inf
    return smooth_and(sups, eta)


def build_task(
    formula: str | Temporal,
    owner: int,
    index: int = 0,
    *,
    robot_ids: Iterable[int] | None = None,
    stl_ids: Iterable[int] | None = None,
    rho_opt: float | None = None,
    eta: float = 10.0,
    warn: bool = True,
    workspace: Workspace | None = None,
    poses: tuple[tuple[int, tuple[float, float, float]], ...] = (),
) -> Task:
    """Parse (if needed), analyse and compile one sub-task of robot ``owner``.

    ``stl_ids``: the STL robots of the scenario (default: every participant); the others are
    exogenous signals, not in V_ctrl, and treated as parameters by the concavity rule.
    Without ``rho_opt``, ρ_opt is the supremum of ρ^ψ over ``workspace`` (the ascent starting
    from ``poses``: (robot, (x, y, θ)) pairs), or without a workspace the LSE of the literal
    suprema (stl-funnel.md §3).
    Raises ``FormulaSyntaxError`` (parse), ``StlTaskError`` (owner absent from ψ, ψ = ⊤, unbounded
    ρ_opt without override or workspace); warns ``StlConcavityWarning`` for non-concave
    conjuncts.
    """
    phi = formula if isinstance(formula, Temporal) else parse_task(formula, robot_ids)
    where = f"robot {owner} sub-task {index + 1} ({to_text(phi)!r})"
    if isinstance(phi.body, Top) or not literals(phi.body):
        raise StlTaskError(f"{where}: ψ = true leaves nothing to control")
    robots = participants(phi.body)
    if owner not in robots:
        raise StlTaskError(f"{where}: the task does not involve robot {owner}'s own state")
    stl = set(robots) if stl_ids is None else set(stl_ids) | {owner}
    v_ctrl = tuple(r for r in robots if r in stl)
    exogenous = frozenset(robots) - stl
    if warn:
        for literal in non_concave_literals(phi.body, exogenous):
            warnings.warn(StlConcavityWarning(
                f"{where}: predicate {to_text(literal)!r} is not concave in the controlled states "
                f"(paper Assumption 1); the funnel guarantees do not apply to it"), stacklevel=2)
    goal: tuple[float, ...] = ()
    if rho_opt is not None:
        resolved = float(rho_opt)
    elif workspace is not None:
        sup = psi_supremum(phi.body, robots, eta, workspace,
                           tuple(p for p in poses if p[0] in robots))
        resolved, goal = sup.value, sup.state
    else:
        resolved = default_rho_opt(phi.body, eta)
    if not math.isfinite(resolved):
        raise StlTaskError(f"{where}: sup of the robustness is unbounded; give rho_opt explicitly")
    return Task(owner=owner, index=index, kind=phi.op, a=phi.a, b=phi.b, psi=phi.body,
                participants=robots, v_ctrl=v_ctrl, rho_opt=resolved, eta=eta,
                compiled=StraightLinePsi(phi.body, robots, eta), goal=goal)
