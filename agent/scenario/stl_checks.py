"""Scenario checks of the STL tasks beyond syntax: what ``tlfleet run`` would only find
when an agent exits, and what runs but cannot mean what it says.

Rejections (``ScenarioError`` with the file, the field path and the reason), called by the
loader (``tlfleet.agent.scenario.loader.parse_scenario``):

* a sub-task whose ψ does not involve its own robot's state (stl-funnel.md §6.1: the control law
  uses ∂ρ/∂x_i, identically zero then);
* a negated predicate whose robustness is unbounded above (``!(dist(p1, p2) <= 1)``: −h grows
  without bound) with no ``rho_opt`` override: the funnel needs ρ_opt = sup ρ^ψ (stl-funnel.md
  §3, §5) — other unbounded predicates (``x2 >= 0``) get a warning, as the agent needs the
  override too;
* sub-task windows that overlap (§9: sub-tasks run in sequence, b^(k) ≤ a^(k+1));
* ``phase_start_times`` entries that come before the previous window ends, or the wrong number
  of them (§9 item 4, §13 item 6);
* a window that ends after the scenario's ``duration`` (:func:`check_windows_in_run`);
* a conjunct that asks two robots' bodies to overlap (:func:`check_bodies_apart`).

Warnings (:func:`stl_warnings`, printed by ``tlfleet check``):

* a non-concave literal in the controlled states (paper Assumption 1);
* a G sub-task whose window opens at t = 0 while its predicate is violated at the start poses:
  ρ^φ ≤ ρ^ψ(x̄(0)) < 0 whatever the robots do (the funnel starts late, stl-funnel.md §5).
"""

from __future__ import annotations

from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.scenario.fields import robot_field
from tlfleet.agent.stl.analysis import literal_sup, non_concave_literals
from tlfleet.agent.stl.parser import robot_subtasks
from tlfleet.agent.stl.syntax import (
    And,
    BinOp,
    Call,
    Const,
    Not,
    Position,
    Predicate,
    Temporal,
    literals,
    robots_of,
    to_text,
)
from tlfleet.bus.errors import ScenarioError

# The loader runs these checks in every process that loads a scenario: they use the syntax tree
# and the analysis only (no numpy), and mirror tlfleet.agent.stl.sequencer's rules (§9): consecutive
# G sub-tasks with the same window merge; otherwise b(k) <= a(k+1); phase_start_times[k] >= b(k).


def _merged_windows(formulas: list[Temporal]) -> tuple[list[tuple[float, float]], int | None]:
    """Windows after the same-window G merge, and the index of the first overlapping sub-task."""
    windows: list[tuple[str, float, float]] = []
    for k, phi in enumerate(formulas):
        if windows:
            op, a, b = windows[-1]
            if phi.op == op == "G" and (phi.a, phi.b) == (a, b):
                continue
            if b > phi.a:
                return [(a, b) for _, a, b in windows], k
        windows.append((phi.op, phi.a, phi.b))
    return [(a, b) for _, a, b in windows], None


def _formulas(scenario: Scenario, index: int) -> list[Temporal]:
    robot = scenario.robots[index]
    return list(robot_subtasks(robot))


def check_stl_tasks(scenario: Scenario, source: str) -> None:
    """Raise ``ScenarioError`` for the rejections of the module docstring."""
    for index, robot in enumerate(scenario.robots):
        if not robot.is_stl:
            continue
        where = robot_field(index, robot.id)
        formulas = _formulas(scenario, index)
        for k, phi in enumerate(formulas):
            field = f"{where}.stl[{k}]"
            if robot.id not in robots_of(phi.body):
                raise ScenarioError(
                    source, field,
                    f"{to_text(phi)!r} does not involve robot {robot.id}'s own state "
                    f"(p{robot.id}, x{robot.id}, y{robot.id} or th{robot.id}): its gradient "
                    f"w.r.t. robot {robot.id} is zero, so robot {robot.id} cannot act on it")
            override = robot.rho_opt[k] if k < len(robot.rho_opt) else None
            if override is None:
                for literal in literals(phi.body):
                    if isinstance(literal, Not) and literal_sup(literal) == float("inf"):
                        raise ScenarioError(
                            source, field,
                            f"the robustness of {to_text(literal)!r} is unbounded above, so the "
                            f"funnel has no rho_opt (sup of the robustness); give "
                            f"{where}.rho_opt[{k}] or use a bounded predicate")
        windows, overlap = _merged_windows(formulas)
        if overlap is not None:
            phi, (_, b_prev) = formulas[overlap], windows[-1]
            raise ScenarioError(
                source, f"{where}.stl[{overlap}]",
                f"window [{phi.a:g}, {phi.b:g}] starts before the previous one ends "
                f"(b = {b_prev:g}); sub-tasks run in sequence and need b(k) <= a(k+1) "
                f"(stl-funnel.md §9)")
        times = robot.phase_start_times
        if times is not None:
            if len(times) != len(windows) - 1:
                raise ScenarioError(
                    source, f"{where}.phase_start_times",
                    f"has {len(times)} entries, expected {len(windows) - 1} (one per sub-task "
                    f"after the first)")
            for k, t in enumerate(times):
                if t < windows[k][1]:
                    raise ScenarioError(
                        source, f"{where}.phase_start_times[{k}]",
                        f"{t:g} precedes the end b = {windows[k][1]:g} of sub-task {k + 1} "
                        f"(stl-funnel.md §9: a forced start needs the previous window closed)")
    check_windows_in_run(scenario, source)
    check_bodies_apart(scenario, source)


def _pair_bound(literal: object) -> tuple[int, int, float] | None:
    """``(i, j, d)`` when ``literal`` is ``dist(pi, pj) <= d`` (or ``< d``, ``d >= dist(…)``,
    ``norm(pi - pj)``) with two different robots and a constant d [m]; None otherwise."""
    if not isinstance(literal, Predicate):
        return None
    if literal.cmp in ("<=", "<"):
        distance, bound = literal.lhs, literal.rhs
    else:
        distance, bound = literal.rhs, literal.lhs
    if not isinstance(bound, Const) or not isinstance(distance, Call):
        return None
    args = distance.args
    if distance.func == "norm" and len(args) == 1 and isinstance(args[0], BinOp) \
            and args[0].op == "-":
        args = (args[0].left, args[0].right)
    elif distance.func != "dist":
        return None
    if len(args) != 2 or not all(isinstance(a, Position) for a in args):
        return None
    i, j = args[0].robot, args[1].robot  # type: ignore[union-attr]
    return (i, j, float(bound.value)) if i != j else None


def check_bodies_apart(scenario: Scenario, source: str) -> None:
    """A sub-task whose every satisfying state puts two robots' centres closer than their radii
    allow — a conjunct ``dist(pi, pj) <= d`` with d < r_i + r_j — asks their bodies to overlap:
    no run meets it (the simulator keeps bodies apart) and the funnel would push them into
    contact."""
    radius = {r.id: r.radius for r in scenario.robots}
    for index, robot in enumerate(scenario.robots):
        for k, phi in enumerate(_formulas(scenario, index)):
            body = phi.body
            conjuncts = body.children if isinstance(body, And) else (body,)
            for literal in conjuncts:
                pair = _pair_bound(literal)
                if pair is None or pair[0] not in radius or pair[1] not in radius:
                    continue
                i, j, d = pair
                if d < radius[i] + radius[j]:
                    raise ScenarioError(
                        source, f"{robot_field(index, robot.id)}.stl[{k}]",
                        f"{to_text(literal)!r} asks the bodies of robots {i} and {j} to overlap: "
                        f"their centres can come no closer than the sum of their radii, "
                        f"{radius[i]:g} + {radius[j]:g} = {radius[i] + radius[j]:g} m > {d:g} m")


def check_windows_in_run(scenario: Scenario, source: str) -> None:
    """Every sub-task's window closes by the scenario's ``duration``: a window the run never
    closes has no verdict, so its task cannot be met (``tlfleet run --duration`` may still cut a
    run shorter: its tally then says ``not evaluated``)."""
    for index, robot in enumerate(scenario.robots):
        for k, phi in enumerate(_formulas(scenario, index)):
            if phi.b > scenario.duration:
                raise ScenarioError(
                    source, f"{robot_field(index, robot.id)}.stl[{k}]",
                    f"window [{phi.a:g}, {phi.b:g}] ends after the run (duration = "
                    f"{scenario.duration:g} s): the run could never tell whether it was met; "
                    f"raise duration or end the window by {scenario.duration:g} s")


def stl_warnings(scenario: Scenario) -> list[str]:
    """The warnings of the module docstring, each naming the field path."""
    out: list[str] = []
    ltl_ids = frozenset(r.id for r in scenario.robots if r.is_ltl)
    poses = {r.id: r.pose for r in scenario.robots}
    for index, robot in enumerate(scenario.robots):
        if not robot.is_stl:
            continue
        for k, phi in enumerate(_formulas(scenario, index)):
            field = f"{robot_field(index, robot.id)}.stl[{k}]"
            text = to_text(phi)
            for literal in non_concave_literals(phi.body, ltl_ids):
                out.append(f"{field}: predicate {to_text(literal)!r} is not concave in the "
                           f"controlled states (paper Assumption 1): the funnel guarantees do "
                           f"not apply to it")
            if k == 0 and phi.op == "G" and phi.a <= 0.0:
                from tlfleet.agent.stl.sequencer import build_sequence  # numpy: only for warnings

                task = build_sequence(robot.id, [phi], robot_ids=scenario.robot_ids,
                                      warn=False, eta=scenario.stl.eta,
                                      rho_opt=robot.rho_opt[:1])[0]
                rho0 = task.compiled.value_min(task.stacked_state(poses))
                if rho0 < 0.0:
                    out.append(f"{field}: {text!r} is violated at the start poses "
                               f"(ρ^ψ(x̄(0)) = {rho0:+.3f}), and its window opens at t = 0, so "
                               f"ρ^φ ≤ {rho0:+.3f} whatever the robots do")
    return out
