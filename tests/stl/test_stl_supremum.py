"""ρ_opt from the arena (docs/stl-saturation.md §5): the projected ascent against a grid search, and
`tlfleet check` agreeing with the agents."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from tlfleet.agent.model.scenario import Arena, DiscObstacle, RectObstacle
from tlfleet.agent.nav.grid import arena_clearance
from tlfleet.agent.policy.stl import build_agents
from tlfleet.agent.scenario import parse_scenario
from tlfleet.agent.scenario.stl_setup import stl_sequences
from tlfleet.agent.stl.evaluate import evaluate_array
from tlfleet.agent.stl.parser import parse_task
from tlfleet.agent.stl.robustness import participants, smooth_and_array
from tlfleet.agent.stl.supremum import Workspace, psi_supremum
from tlfleet.agent.stl.syntax import Not, literals, predicate_function, to_text

CLEARANCE = 0.3


def grid_sup(text: str, arena: Arena, clearance: float, step: float = 0.01) -> float:
    """max of the smooth ρ^ψ (η = 10) by brute force (numpy, no ascent): the conjuncts over a
    grid of robot 1's positions with clearance; heading conjuncts, which do not involve the
    position, over a 0.001 rad grid of headings, combined through the LSE's monotonicity
    (max LSE(a(z), b(θ)) = LSE(max a, max b))."""
    phi = parse_task(text)
    xs = np.arange(arena.xmin, arena.xmax + 1e-9, step)
    x, y = np.meshgrid(xs, xs)
    ok = arena_clearance(arena, np.stack([x, y], axis=-1)) >= clearance - 1e-12
    x, y = x[ok], y[ok]
    positions = {1: np.column_stack([x, y, np.zeros(len(x))])}
    th = np.arange(-math.pi, math.pi, 0.001)
    headings = {1: np.column_stack([np.zeros(len(th)), np.zeros(len(th)), th])}
    position_values, heading_values = [], []
    for lit in literals(phi.body):
        pred = lit.pred if isinstance(lit, Not) else lit
        sign = -1.0 if isinstance(lit, Not) else 1.0
        if "th1" in to_text(pred):
            heading_values.append(sign * evaluate_array(predicate_function(pred), headings))
        else:
            v = np.broadcast_to(evaluate_array(predicate_function(pred), positions), x.shape)
            position_values.append(sign * v)
    best = float(smooth_and_array(position_values, 10.0).max())
    if heading_values:
        best = float(smooth_and_array([np.array([best]),
                                       np.array([smooth_and_array(heading_values, 10.0).max()])],
                                      10.0)[0])
    return best


ARENAS = {
    "empty": Arena(),
    "wall": Arena(obstacles=(RectObstacle(-0.1, -3.5, 0.1, 1.5, "wall"),)),
    "pillar": Arena(obstacles=(DiscObstacle((1.0, 1.0), 0.5, "pillar"),)),
}


@pytest.mark.parametrize("arena", ARENAS)
@pytest.mark.parametrize("text", [
    "F[0,1] (dist(p1, [2, -1]) <= 0.2)",
    "F[0,1] (dist(p1, [1, 1]) <= 0.6)",  # around the pillar: at best on its rim
    "F[0,1] (dist(p1, [0, 0]) <= 0.3)",  # inside the wall: negative
    "F[0,1] (x1 >= 1.5 & y1 >= 0.5)",  # half-planes: bounded by the arena
    "F[0,1] (x1 <= -1 & x1 >= -2 & y1 <= 0.5 & y1 >= -0.5)",  # a box
    "F[0,1] (!(dist(p1, [0, 0]) <= 1))",  # a negation, unbounded in the plane
    "F[0,1] (dist(p1, [2, 2]) <= 0.3 & angdist(th1, 1.57) <= 0.1)",
])
def test_supremum_matches_a_grid_search(arena, text):
    workspace = Workspace(ARENAS[arena], default_clearance=CLEARANCE)
    phi = parse_task(text)
    sup = psi_supremum(phi.body, participants(phi.body), 10.0, workspace,
                       ((1, (-2.0, -2.0, 0.0)),))
    brute = grid_sup(text, ARENAS[arena], CLEARANCE)
    # the grid is 0.01 m coarse (a 1-Lipschitz ρ loses ≤ 0.0071 m on it), the ascent stops at
    # 1e-5: equal within 0.01
    assert sup.value == pytest.approx(brute, abs=0.01)
    assert sup.value >= brute - 0.01
    # the state it reports attains it
    compiled = parse_task(text)
    state = {1: np.array([sup.state])}
    values = [(-1 if isinstance(lit, Not) else 1)
              * evaluate_array(predicate_function(lit.pred if isinstance(lit, Not) else lit),
                               state) for lit in literals(compiled.body)]
    assert float(smooth_and_array(values, 10.0)[0]) == pytest.approx(sup.value, abs=1e-9)
    assert arena_clearance(ARENAS[arena], np.array(sup.state[:2])) >= CLEARANCE - 1e-6


@settings(max_examples=examples(40), deadline=None)
@given(c=st.floats(0.45, 1.5), sep=st.floats(0.3, 0.8), gx=st.floats(-2.5, 2.5),
       gy=st.floats(-2.5, 2.5), radius=st.floats(0.1, 0.4))
def test_two_robot_supremum_keeps_the_pair_apart(c, sep, gx, gy, radius):
    """dist(p2, p3) <= c & dist(p2, [gx, gy]) <= r with robots 2 and 3 at least ``sep`` apart:
    the supremum is found with the pair separated, and it equals the grid search over robot 2's
    position with robot 3 anywhere on the circle of radius max(sep, ...) around it."""
    text = f"F[0,1] (dist(p2, p3) <= {c:.4f} & dist(p2, [{gx:.4f}, {gy:.4f}]) <= {radius:.4f})"
    phi = parse_task(text)
    workspace = Workspace(Arena(), default_clearance=CLEARANCE, separation=((2, 3, sep),))
    sup = psi_supremum(phi.body, (2, 3), 10.0, workspace, ((2, (0.0, 0.0, 0.0)),
                                                           (3, (1.0, 1.0, 0.0))))
    z2, z3 = np.array(sup.state[0:2]), np.array(sup.state[3:5])
    assert np.linalg.norm(z2 - z3) >= sep - 1e-6
    # brute force: the best is robot 2 at the goal, robot 3 at exactly ``sep`` from it (any
    # direction that stays in the arena), so ρ = LSE(c − sep, r)
    best = float(smooth_and_array([np.array([c - sep]), np.array([radius])], 10.0)[0])
    assert sup.value == pytest.approx(best, abs=2e-3)


def _scenario(tasks: list[str], **extra) -> dict:
    robot = {"id": 20, "kind": "omni", "pose": [-2.0, -2.0, 0.0], "stl": tasks}
    return {"name": "half", "duration": 40.0, "robots": [robot], **extra}


def test_half_plane_and_box_tasks_run_without_rho_opt_and_check_agrees():
    """The issue's case: F[0,30] (x20 >= 1.5 & y20 >= 0.5) without rho_opt no longer needs one;
    the agents and `tlfleet check` resolve the same ρ_opt (one function), and the box's is its
    true supremum 0.5 − ln(4)/10, not the literal bound."""
    from tlfleet.agent.scenario.stl_checks import stl_warnings

    data = _scenario(["F[0,30] (x20 >= 1.5 & y20 >= 0.5)",
                      "G[32,40] (x20 <= -1 & x20 >= -2 & y20 <= 0.5 & y20 >= -0.5)"])
    scenario = parse_scenario(data)
    assert not [w for w in stl_warnings(scenario) if "rho_opt" in w or "unbounded" in w]
    agent = build_agents(scenario)[20]
    checked = stl_sequences(scenario)[20]
    assert [t.rho_opt for t in agent.cfg.subtasks] == [t.rho_opt for t in checked]
    assert agent.cfg.subtasks[1].rho_opt == pytest.approx(0.5 - math.log(4) / 10, abs=1e-4)
    # the half-plane corner: x ≤ 3.5 − 0.2 − 0.1 (the body and the wall term's margin)
    assert agent.cfg.subtasks[0].rho_opt == pytest.approx(
        float(smooth_and_array([np.array([3.2 - 1.5]), np.array([3.2 - 0.5])], 10.0)[0]),
        abs=1e-3)


def test_the_literal_bound_is_kept_behind_its_switch():
    data = _scenario(["F[0,30] (dist(p20, [1, 1]) <= 0.3 & dist(p20, [1.2, 1]) <= 0.3)"],
                     stl={"rho_opt_from_arena": False})
    (task,) = stl_sequences(parse_scenario(data))[20]
    assert task.rho_opt == pytest.approx(0.3 - math.log(2) / 10)  # LSE(0.3, 0.3)
    data.pop("stl")
    (task,) = stl_sequences(parse_scenario(data))[20]
    # both discs peak 0.2 m apart: the best point is between them
    assert task.rho_opt == pytest.approx(0.2 - math.log(2) / 10, abs=1e-3)
