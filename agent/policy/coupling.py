"""What an LTL robot may do so that the STL robots coupled to it can track it (docs/coupling.md).

Beyond the paper: a robot L under an LTL task moves as its navigation stack likes
(paper §III-A), while STL robots j track it through predicates μ = (h(x̄) ≥ 0) whose x̄ contains
x_L = [z_Lᵀ, θ_L]ᵀ (Scenario 2: ``dist(p3, p1) <= 0.6``; Scenario 3: a slot 1 m beside robot 1
that turns with θ_1). Robot j can change h at most at the rate its saturated input allows
(paper §III-B: ‖u_j‖ ≤ u_max,j); when L changes h faster, no funnel can hold ρ and the repair
scheme (Alg. 2) can only lower r. This module turns each coupled predicate into a constraint on
L's unicycle command (v [m/s], ω [rad/s]); ``tlfleet.agent.nav.coupling_limits`` applies them in the
DWA.

For a predicate of the form ``c − ‖F(x̄)‖`` (``dist(a, b)`` → F = a − b, ``norm(F)``, ``abs(F)``,
``angdist(a, b)`` → F = a − b wrapped), with J_k = ∂F/∂x_k the Jacobian blocks at the current
stacked state:

* L moves F at the rate J_{z_L} ż_L + J_{θ_L} θ̇_L with ‖ż_L‖ = |v|, θ̇_L = ω, so
  ‖Ḟ_L‖ ≤ a_v·|v| + a_ω·|ω| with a_v = σ_max(J_{z_L}), a_ω = ‖J_{θ_L}‖ (for a slot at distance d
  from L: a_v = 1, a_ω = d — the slot moves at |v| + |ω|·d);
* j, saturated at u_lin (planar) and u_ang (|ω_j|), can move F in every direction at least at
  the rate ``capacity = σ_min(J_{z_j})·u_lin`` (2-vector F) or ``‖J_{z_j}‖·u_lin + |J_{θ_j}|·u_ang``
  (scalar F);
* the constraint is a_v·|v| + a_ω·|ω| ≤ κ·capacity, with the share κ < 1
  (``NavParams.coupling_share``, one constant for every scenario) leaving j the rest of its
  input to close the error it already has.

Any other predicate shape falls back to the gradient of h itself (|∂h/∂x_L| against
|∂h/∂x_j|·u_max,j), which bounds the rate of h instead of the rate of its argument. The limits of
one step are the intersection over every sub-task whose window has not ended (t ≤ b) and every
literal that involves both L and the sub-task's owner.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.scenario.stl_setup import naming, stl_sequences
from tlfleet.agent.stl.evaluate import compile_expr
from tlfleet.agent.stl.syntax import (
    BinOp,
    Call,
    Const,
    Not,
    Predicate,
    literals,
    predicate_function,
    to_text,
)
from tlfleet.agent.stl.task import Task

NORM_FUNCTIONS = ("dist", "norm", "abs", "angdist")


@dataclass(frozen=True, eq=False)
class _Term:
    task: Task
    literal_index: int
    rows: object  # closure s -> (value, grad) of F (scalar or 2-vector) or of h (fallback)
    vector: bool
    u_lin: float  # [m/s] owner's planar saturation
    u_ang: float  # [rad/s] owner's angular saturation
    source: str


def _argument(literal: Predicate | Not):
    """(F, is_norm_form): the argument of ``c − ‖F‖`` when the literal has that form, else h."""
    if isinstance(literal, Predicate) and literal.cmp in ("<=", "<"):
        lhs, rhs = literal.lhs, literal.rhs
        if isinstance(rhs, Const) and isinstance(lhs, Call) and lhs.func in NORM_FUNCTIONS:
            if lhs.func in ("dist", "angdist"):
                return BinOp("-", lhs.args[0], lhs.args[1]), True
            return lhs.args[0], True
    pred = literal.pred if isinstance(literal, Not) else literal
    h = predicate_function(pred)
    return (h if isinstance(literal, Predicate) else BinOp("-", Const(0.0), h)), False


class CouplingModel:
    """The coupled predicates of LTL robot ``leader`` in a scenario, ready to give limits."""

    def __init__(self, leader: int, terms: Sequence[_Term], share: float):
        self.leader = leader
        self.terms = tuple(terms)
        self.share = share

    @staticmethod
    def from_scenario(scenario: Scenario, leader: int) -> CouplingModel:
        """Every literal of every STL sub-task that involves ``leader`` and its owner's state."""
        params = scenario.navigation
        terms: list[_Term] = []
        # only the tasks that name the leader: another robot's task, however broken, is that
        # robot's agent's to report, never a reason for this one to fail
        sequences = stl_sequences(scenario, only=naming(scenario, frozenset({leader})))
        for robot in scenario.robots:
            if robot.id not in sequences:
                continue
            for task in sequences[robot.id]:
                if leader not in task.participants:
                    continue
                for k, literal in enumerate(literals(task.psi)):
                    expr, _ = _argument(literal)
                    fn = compile_expr(expr, task.participants)
                    probe = fn([0.0] * (3 * len(task.participants)))
                    vector = isinstance(probe[0], tuple)
                    terms.append(_Term(task, k, fn, vector, robot.omni.max_lin,
                                       robot.omni.max_ang,
                                       f"robot {robot.id} sub-task {task.index + 1}: "
                                       f"{to_text(literal)}"))
        return CouplingModel(leader, terms, params.coupling_share)

    def __bool__(self) -> bool:
        return bool(self.terms)

    def limits(self, t: float, poses: Mapping[int, Sequence[float]]
               ) -> tuple[tuple[float, float, float, str], ...]:
        """Rows ``(a_v, a_ω, bound, source)`` (a_v·|v| + a_ω·|ω| ≤ bound) at time ``t`` [s] for
        the poses ``{id: (x, y, θ)}`` of the frame (``tlfleet.agent.nav.coupling_limits``)."""
        out: list[tuple[float, float, float, str]] = []
        for term in self.terms:
            task = term.task
            if t > task.b or any(j not in poses for j in task.participants):
                continue
            s = task.stacked_state(poses)
            _, grads = term.rows(s)
            rows = grads if term.vector else (grads,)
            jac = np.array([g if g is not None else [0.0] * len(s) for g in rows], dtype=float)
            lead = task.block(self.leader)
            own = task.block(task.owner)
            j_zl, j_thl = jac[:, lead:lead + 2], jac[:, lead + 2]
            j_zo, j_tho = jac[:, own:own + 2], jac[:, own + 2]
            a_v = float(np.linalg.norm(j_zl, 2))
            a_w = float(np.linalg.norm(j_thl))
            if a_v == 0.0 and a_w == 0.0:
                continue
            if len(jac) == 1:
                capacity = (float(np.linalg.norm(j_zo)) * term.u_lin
                            + abs(float(j_tho[0])) * term.u_ang)
            else:
                capacity = float(np.linalg.svd(j_zo, compute_uv=False)[-1]) * term.u_lin
            if capacity <= 0.0:
                continue
            out.append((a_v, a_w, self.share * capacity, term.source))
        return tuple(out)
