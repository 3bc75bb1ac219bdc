"""Scenario checks of the STL tasks beyond syntax: what ``tlfleet run`` would only find
when an agent exits, and what runs but cannot mean what it says.

Rejections (``ScenarioError`` with the file, the field path and the reason), called by the
loader (``tlfleet.agent.scenario.loader.parse_scenario``):

* a sub-task whose ψ does not involve its own robot's state (stl-funnel.md §6.1: the control law
  uses ∂ρ/∂x_i, identically zero then);
* with ``[stl] rho_opt_from_arena = false`` only: a negated predicate whose robustness is
  unbounded above (``!(dist(p1, p2) <= 1)``: −h grows without bound) with no ``rho_opt`` override
  (the funnel needs ρ_opt = sup ρ^ψ; other unbounded predicates get a warning). By default ρ_opt is
  the supremum over the arena, bounded for every predicate (docs/stl-saturation.md §5);
* a predicate that asks two robots to be closer than their bodies allow (``dist(p2, p3) <= 0.3``
  between two 0.2 m bodies): its supremum with the bodies apart (‖z_i − z_j‖ ≥ r_i + r_j, each
  centre its radius from the walls) is ≤ 0 (docs/stl-saturation.md §7);
* sub-task windows that overlap (§9: sub-tasks run in sequence, b^(k) ≤ a^(k+1));
* ``phase_start_times`` entries that come before the previous window ends, or the wrong number
  of them (§9 item 4, §13 item 6);
* a window that ends after the scenario's ``duration`` (:func:`check_windows_in_run`).

Warnings (:func:`stl_warnings`, printed by ``tlfleet check``):

* a predicate whose robustness is unbounded above, with no ``rho_opt`` override (only with
  ``rho_opt_from_arena = false``);
* a predicate that two coupled robots can meet with their bodies apart but not outside each
  other's avoidance radius R_ij (docs/stl-saturation.md §7);
* a robot's sequence of sub-tasks that its speed limits cannot meet, by the minimal-time bound,
  naming the sub-tasks (docs/stl-saturation.md §6.3);
* a non-concave literal in the controlled states (paper Assumption 1);
* a G sub-task whose window opens at t = 0 while its predicate is violated at the start poses:
  ρ^φ ≤ ρ^ψ(x̄(0)) < 0 whatever the robots do (the funnel starts late, stl-funnel.md §5).
"""

from __future__ import annotations

from itertools import combinations

from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.scenario import stl_setup
from tlfleet.agent.scenario.fields import robot_field
from tlfleet.agent.stl.analysis import literal_sup, non_concave_literals
from tlfleet.agent.stl.parser import robot_subtasks
from tlfleet.agent.stl.robustness import participants
from tlfleet.agent.stl.supremum import Workspace, psi_supremum
from tlfleet.agent.stl.syntax import (
    Not,
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
            for literal, sup, pair in _pair_literals(scenario, phi, separated="bodies"):
                if sup <= 0.0:
                    i, j = pair
                    bodies = scenario.robot(i).radius + scenario.robot(j).radius
                    raise ScenarioError(
                        source, field,
                        f"predicate {to_text(literal)!r} asks robots {i} and {j} to be closer "
                        f"than their bodies allow ({bodies:g} m between centres): its "
                        f"robustness is at most {sup:+.3f} with the bodies apart, so it can "
                        f"never hold")
            if override is None and not scenario.stl.rho_opt_from_arena:
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
            override = robot.rho_opt[k] if k < len(robot.rho_opt) else None
            unbounded = [lit for lit in literals(phi.body) if literal_sup(lit) == float("inf")]
            if unbounded and override is None and not scenario.stl.rho_opt_from_arena:
                out.append(f"{field}: the robustness of {to_text(unbounded[0])!r} is unbounded "
                           f"above: the agent needs {robot_field(index, robot.id)}.rho_opt[{k}]")
            for literal in non_concave_literals(phi.body, ltl_ids):
                out.append(f"{field}: predicate {to_text(literal)!r} is not concave in the "
                           f"controlled states (paper Assumption 1): the funnel guarantees do "
                           f"not apply to it")
            if scenario.stl.coupled_radii:
                for literal, sup, (i, j) in _pair_literals(scenario, phi, separated="radii"):
                    if sup <= 0.0:
                        _, big_r = stl_setup.pair_radii(scenario, i, j)
                        out.append(f"{field}: predicate {to_text(literal)!r} needs robots {i} and "
                                   f"{j} closer than their mutual avoidance radius "
                                   f"R = {big_r:g} m (bodies + [stl] coupled_r_margin): its "
                                   f"robustness is at most {sup:+.3f} outside it")
            if k == 0 and phi.op == "G" and phi.a <= 0.0:
                # the agent's own first sub-task (ρ_opt resolved as the agent resolves it: a
                # half-plane's from the arena), so a warning never fails where the run would not
                task = stl_setup.stl_sequences(scenario, only=frozenset({robot.id}))[robot.id][0]
                rho0 = task.compiled.value_min(task.stacked_state(poses))
                if rho0 < 0.0:
                    out.append(f"{field}: {text!r} is violated at the start poses "
                               f"(ρ^ψ(x̄(0)) = {rho0:+.3f}), and its window opens at t = 0, so "
                               f"ρ^φ ≤ {rho0:+.3f} whatever the robots do")
    out.extend(speed_limit_warnings(scenario))
    return out


def _pair_literals(scenario: Scenario, phi: Temporal, separated: str):
    """(literal, sup, (i, j)) for every literal of ``phi`` in which the positions of two or more
    robots enter: its supremum over the arena with the centres of every such pair ≥ r_i + r_j
    apart (``separated="bodies"``) or ≥ their avoidance radius R_ij (``"radii"``), each centre its
    radius from the walls and obstacles; (i, j) the first such pair."""
    for literal in literals(phi.body):
        movers = sorted(stl_setup.positions_of(literal))
        if len(movers) < 2:
            continue
        pairs = list(combinations(movers, 2))
        if separated == "bodies":
            sep = tuple((i, j, scenario.robot(i).radius + scenario.robot(j).radius)
                        for i, j in pairs)
        else:
            sep = tuple((i, j, stl_setup.pair_radii(scenario, i, j)[1]) for i, j in pairs)
        workspace = Workspace(scenario.arena, tuple((r.id, r.radius) for r in scenario.robots),
                              sep)
        robots = participants(literal)
        sup = psi_supremum(literal, robots, scenario.stl.eta, workspace,
                           tuple(p for p in stl_setup.start_poses(scenario) if p[0] in robots))
        yield literal, sup.value, pairs[0]


def speed_limit_warnings(scenario: Scenario) -> list[str]:
    """A warning for every STL robot whose sequence of sub-tasks its speed limits cannot meet
    (``tlfleet.agent.stl.timing.sequence_infeasibilities``, docs/stl-saturation.md §6.3): from
    the start pose, or from where sub-task k can end to sub-task k+1, naming both."""
    from tlfleet.agent.scenario.stl_timing import position_grid, sequence_infeasibilities

    poses = {r.id: r.pose for r in scenario.robots}
    sequences = stl_setup.stl_sequences(scenario)
    out: list[str] = []
    for index, robot in enumerate(scenario.robots):
        if not robot.is_stl:
            continue
        tasks = sequences[robot.id]
        grid = position_grid(scenario.arena, robot.radius)
        for bad in sequence_infeasibilities(tasks, robot.id, poses, grid, robot.omni.max_lin,
                                            robot.omni.max_ang, robot.phase_start_times):
            where = f"{robot_field(index, robot.id)}.stl[{bad.to}]"
            target = f"{tasks[bad.to].text!r} by t = {bad.due:g} s"
            if bad.source < 0:
                out.append(f"{where}: at its speed limit ({robot.omni.max_lin:g} m/s) robot "
                           f"{robot.id} needs at least {bad.needed:.1f} s from its start pose "
                           f"to meet {target}: infeasible (minimal-time bound)")
            else:
                out.append(f"{robot_field(index, robot.id)}.stl[{bad.source}] -> stl[{bad.to}]: at "
                           f"its speed "
                           f"limit ({robot.omni.max_lin:g} m/s) robot {robot.id} needs at least "
                           f"{bad.needed:.1f} s from where stl[{bad.source}] "
                           f"({tasks[bad.source].text!r}) can end (t >= {bad.t_from:g} s) to "
                           f"meet {target}: the sequence is infeasible (minimal-time bound)")
    return out
