"""The straight-line ψ (tlfleet.agent.stl.compiled) against the generic evaluator, its checked
reference.

Property (issue 17 item 2): compiled = generic to 1e-12 on random states, for random expression
trees and conjunctions with negations, and for every sub-task of Scenarios 1–3. Non-zero entries
are even bit-identical (the generated code keeps the generic order of operations), which is what
keeps the lockstep trajectories byte-identical.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis_budget import examples
from stl_strategies import ROBOTS, coords, numbers, predicate_expressions, states
from tlfleet.agent.policy.stl import build_agents
from tlfleet.agent.scenario.loader import load_scenario
from tlfleet.agent.stl.compiled import StraightLinePsi, generate_source
from tlfleet.agent.stl.parser import parse_psi
from tlfleet.agent.stl.robustness import CompiledPsi
from tlfleet.agent.stl.syntax import And, Const, Not, Predicate

ROOT = Path(__file__).resolve().parents[2]
expressions = predicate_expressions(max_leaves=6)
predicates = st.builds(Predicate, expressions, st.sampled_from(["<=", "<", ">=", ">"]),
                       numbers.map(Const))
literal_ = st.one_of(predicates, st.builds(Not, predicates))
psis = st.one_of(literal_, st.lists(literal_, min_size=2, max_size=4).map(
    lambda xs: And(tuple(xs))))


def assert_same(reference, compiled, s):
    v_ref, g_ref = reference.value_grad(s)
    v_new, g_new = compiled.value_grad(s)
    assume(math.isfinite(v_ref))
    assert v_new == pytest.approx(v_ref, rel=1e-12, abs=1e-12)
    if v_ref != 0.0:
        assert v_new == v_ref  # bit-identical
    ref = [0.0] * len(s) if g_ref is None else g_ref
    new = [0.0] * len(s) if g_new is None else g_new
    assert len(new) == len(s)
    for a, b in zip(ref, new, strict=True):
        assume(math.isfinite(a))
        assert b == pytest.approx(a, rel=1e-12, abs=1e-12)
        if a != 0.0:
            assert b == a  # bit-identical where non-zero


@settings(max_examples=examples(400), deadline=None)
@given(psi=psis, s=states, eta=st.sampled_from([1.0, 10.0, 50.0]))
def test_compiled_equals_generic_on_random_trees_and_states(psi, s, eta):
    reference = CompiledPsi(psi, ROBOTS, eta)
    compiled = StraightLinePsi(psi, ROBOTS, eta)
    assert_same(reference, compiled, s)


def _scenario_tasks():
    for n in (1, 2, 3):
        scenario = load_scenario(ROOT / "scenarios" / f"scenario{n}.toml")
        for agent in build_agents(scenario, warn=False).values():
            yield from agent.cfg.subtasks


SCENARIO_TASKS = list(_scenario_tasks())


@settings(max_examples=examples(300), deadline=None)
@given(k=st.integers(0, len(SCENARIO_TASKS) - 1), s=st.lists(coords, min_size=15, max_size=15))
def test_compiled_equals_generic_on_every_scenario_subtask(k, s):
    task = SCENARIO_TASKS[k]
    assert isinstance(task.compiled, StraightLinePsi)  # what the agent's step evaluates
    state = s[:3 * len(task.participants)]
    assert_same(task.compiled.reference, task.compiled, state)


def test_gradient_is_zero_at_non_differentiable_points_like_the_generic():
    psi = parse_psi("dist(p1, p2) <= 1 & angdist(th1, th2) <= 1 & abs(x1 - x2) <= 2")
    compiled = StraightLinePsi(psi, (1, 2), 10.0)
    s = [1.0, 1.0, 0.5, 1.0, 1.0, 0.5 + 2 * math.pi]
    rho, grad = compiled.value_grad(s)
    ref_rho, ref_grad = CompiledPsi(psi, (1, 2), 10.0).value_grad(s)
    assert rho == ref_rho
    assert ref_grad is None and grad == [0.0] * 6


def test_generated_source_is_straight_line_over_the_state():
    source = generate_source(parse_psi("dist(p4, p3) <= 1 & dist(p4, p5) <= 1"), (3, 4, 5), 10.0)
    assert source.startswith("def value_grad(s):")
    assert "for " not in source and "lambda" not in source
    compiled = StraightLinePsi(parse_psi("dist(p4, [2, 2]) <= 0.1"), (4,), 10.0)
    assert compiled.value([2.0, 2.0, 0.0]) == pytest.approx(0.1)
    assert compiled.value_min([2.0, 3.0, 0.0]) == pytest.approx(-0.9)
