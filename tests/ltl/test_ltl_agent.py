"""The pure LTL agent (tlfleet.agent.policy.ltl): planning and stepping with no process, no
transport and no wire types — a unicycle integrated in the test closes the loop."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tlfleet.agent.ltl.buchi import translate
from tlfleet.agent.policy.ltl import LtlAgent, LtlStepInput, Notice
from tlfleet.agent.scenario import load_scenario

RATE = 5.0  # [Hz] the LTL loop


NOBODY = np.zeros((0, 4))  # no other robot in the arena


def _drive(agent: LtlAgent, seconds: float, others=NOBODY):
    """Unicycle kinematics x' = v cos θ, y' = v sin θ, θ' = ω, integrated at 5 Hz."""
    plan = agent.plan()
    state, ready = agent.initial_state(plan)
    x, y, th = agent.scenario.robot(agent.robot).pose
    notices: list[Notice] = [ready]
    history = []
    for k in range(round(seconds * RATE)):
        t = k / RATE
        state, out = agent.step(state, LtlStepInput(t, (x, y, th), others))
        notices += out.notices
        history.append((t, out.progress))
        v, w = out.u
        x, y, th = x + v * math.cos(th) / RATE, y + v * math.sin(th) / RATE, th + w / RATE
    return plan, state, notices, history


def test_one_translation_serves_the_check_planning_and_tracking(scenarios_dir, monkeypatch):
    """The loader's emptiness check translates the task; the agent plans, replans and tracks
    its Büchi states on that same automaton: no second translation in the process."""
    from tlfleet.agent.ltl import task as ltl_task

    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    calls = []
    real = ltl_task.translate

    def counting(formula):
        calls.append(formula)
        return real(formula)

    monkeypatch.setattr(ltl_task, "translate", counting)
    agent = LtlAgent(scenario, 1)
    plan = agent.plan()
    assert calls == []
    assert agent.buchi is ltl_task.text_automaton(scenario.robot(1).ltl)
    assert plan.buchi_states == agent.buchi.num_states
    assert plan.timings.translate == agent.translate_time >= 0.0
    # the same automaton a fresh translation gives: the planner's numbering is the agent's
    assert agent.buchi.num_states == translate(scenario.robot(1).ltl).num_states


def test_the_pure_agent_visits_its_regions_and_tracks_the_buchi_states(scenarios_dir):
    """Scenario 1's robot 1 (`G F a11 & G F a12`-style task) alone in the arena for 60 s."""
    scenario = load_scenario(scenarios_dir / "scenario1.toml")
    agent = LtlAgent(scenario, 1)
    plan, state, notices, history = _drive(agent, 60.0)
    visited = [n.data["region"] for n in notices if n.kind == "region_visited"]
    assert visited[:2] == list(plan.prefix)
    assert set(visited) >= set(plan.suffix) and len(visited) >= 4
    assert notices[0].kind == "plan_ready" and notices[0].data["suffix"] == list(plan.suffix)
    assert [t for t, _ in history] == [k / RATE for k in range(300)]
    assert all(progress.buchi_states for _, progress in history)  # never violated
    # an accepting state is passed on every completed cycle (Büchi acceptance along the run)
    assert any(set(p.buchi_states) & agent.buchi.accepting for _, p in history[-50:])
    assert state.replans == 0
    assert all(isinstance(v, int | float | str | list | dict | bool | type(None))
               for n in notices for v in n.data.values())


def test_a_robot_that_joins_away_from_its_start_plans_again_from_where_it_is(scenarios_dir):
    """A restarted agent: the first step finds Scenario 3's robot 1 at region a3,
    not at its start pose, so it plans Algorithm 1 again from there — the cheapest order of the
    other four regions, checked by brute force over Euclidean distances — from the automaton's
    initial states, and says so in a plan_ready notice."""
    import itertools

    scenario = load_scenario(scenarios_dir / "scenario3.toml")
    agent = LtlAgent(scenario, 1, distance=math.dist)
    state, _ready = agent.initial_state(agent.plan())
    centres = {r.name: tuple(r.center) for r in scenario.regions}
    here = centres["a3"]
    state, out = agent.step(state, LtlStepInput(42.0, (*here, 0.0), NOBODY))
    (joined,) = [n for n in out.notices if n.kind == "plan_ready"]
    assert joined.data["replan"] and joined.data["reason"]["joined"]
    assert joined.data["reason"]["away"] == pytest.approx(math.dist(here, (-2.0, -2.0)))
    others = sorted(set(centres) - {"a3"})

    def tour(order) -> float:
        points = [here, *(centres[n] for n in order)]
        return sum(math.dist(a, b) for a, b in itertools.pairwise(points))

    best = min(tour(order) for order in itertools.permutations(others))
    assert state.plan.prefix[0] == "a3"  # it is inside a3
    assert state.plan.cost == pytest.approx(best)
    assert state.buchi_states <= frozenset(range(agent.buchi.num_states))
    # a robot at its start pose keeps the plan it had
    fresh = LtlAgent(scenario, 1, distance=math.dist)
    plan = fresh.plan()
    state, _ = fresh.initial_state(plan)
    state, out = fresh.step(state, LtlStepInput(0.0, (-2.0, -2.0, 0.0), NOBODY))
    assert state.plan is plan and not [n for n in out.notices if n.kind == "plan_ready"]
