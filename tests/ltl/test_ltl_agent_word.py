"""The LTL agent knows its own word (docs/ltl-navigation.md §3): an entry its plan did not
schedule is an ``unplanned_region`` notice, the agent replans from the product state it is in,
and when the Büchi run has died it reports ``task_lost`` and stops — the progress it reports is
the word's. Poses are scripted (a robot pushed where its plan does not go), and the verdicts are
checked against the exact lasso evaluator, not against the agent's own automaton."""

from __future__ import annotations

import itertools
import math

import numpy as np
from tlfleet.agent.ltl.buchi import buchi_stutter_step
from tlfleet.agent.ltl.lasso import holds
from tlfleet.agent.model.scenario import Arena, Region, Robot, Scenario
from tlfleet.agent.policy.ltl import LtlAgent, LtlStepInput

NOBODY = np.zeros((0, 4))
REGIONS = (Region("a", (-2.5, 0.0), 0.3), Region("c", (0.0, 0.0), 0.5),
           Region("b", (2.5, 0.0), 0.3), Region("d", (0.0, -2.0), 0.4))


def _agent(task: str, regions=REGIONS) -> LtlAgent:
    robots = (Robot(1, "unicycle", (-2.5, 0.0, 0.0), ltl=task),)
    return LtlAgent(Scenario("word", "word", 60.0, Arena(), tuple(regions), robots), 1)


def _walk(agent: LtlAgent, points, state=None, t0=0.0):
    if state is None:
        state, _ = agent.initial_state(agent.plan())
    notices, outputs = [], []
    for k, (x, y) in enumerate(points):
        state, out = agent.step(state, LtlStepInput(t0 + 0.2 * k, (x, y, 0.0), NOBODY))
        notices += out.notices
        outputs.append(out)
    return state, notices, outputs


def _line(a, b, step=0.05):
    n = max(2, math.ceil(math.dist(a, b) / step) + 1)
    return [(a[0] + (b[0] - a[0]) * u, a[1] + (b[1] - a[1]) * u) for u in np.linspace(0, 1, n)]


def test_entering_a_forbidden_region_loses_the_task_and_the_agent_stops():
    agent = _agent("G F a & G F b & G !c")
    plan = agent.plan()
    assert "c" not in plan.prefix + plan.suffix  # the keep-out plan goes around c
    # pushed straight through c on the way to b
    state, notices, outputs = _walk(agent, _line((-2.5, 0.0), (2.5, 0.0)))
    kinds = [n.kind for n in notices]
    assert kinds.index("unplanned_region") < kinds.index("task_lost")
    unplanned = next(n for n in notices if n.kind == "unplanned_region")
    assert unplanned.data["region"] == "c" and unplanned.data["target"] == "b"
    assert unplanned.data["previous"] == "a"
    # independent: the word start-free a c ... violates the task whatever follows
    assert not holds("G F a & G F b & G !c", [frozenset({"a"}), frozenset({"c"})],
                     [frozenset({"a"}), frozenset({"b"})])
    lost = next(n for n in notices if n.kind == "task_lost")
    assert lost.data["region"] == "c"
    after = outputs[[n.kind for o in outputs for n in o.notices].index("task_lost"):]
    # from then on: no progress reported, no target, and the command ramps down to standstill
    assert "cycle_completed" not in kinds and "region_visited" not in kinds[
        kinds.index("task_lost"):]
    assert outputs[-1].progress.target is None and outputs[-1].progress.mode == "lost"
    assert outputs[-1].u == (0.0, 0.0)
    assert all(o.progress.rounds == 0 for o in after)
    assert state.lost


def test_an_unplanned_harmless_region_replans_from_the_product_state():
    agent = _agent("G F a & G F b")
    buchi = agent.buchi
    state, notices, _ = _walk(agent, [(-2.5, 0.0), *_line((-2.5, 0.0), (0.0, -2.0))])
    unplanned = [n for n in notices if n.kind == "unplanned_region"]
    assert [n.data["region"] for n in unplanned] == ["d"]
    # the states after d's entry: a's label read (once or more) from the initial states
    expected = buchi_stutter_step(buchi, frozenset(buchi.initial), {"a"})
    assert unplanned[0].data["buchi_before"] == sorted(buchi.initial)
    assert unplanned[0].data["buchi_after"] == sorted(expected)
    assert state.buchi_states == expected
    ready = [n for n in notices if n.kind == "plan_ready"]
    assert ready and ready[-1].data["reason"]["unplanned"] == "d"
    # the new plan starts where the robot is: d, then on to b
    assert (ready[-1].data["prefix"] or ready[-1].data["suffix"])[0] == "d"
    assert "task_lost" not in [n.kind for n in notices]
    # and it is followed: from d the robot's next target is b or a, never d again
    state, _, outputs = _walk(agent, [(0.0, -2.0)], state, t0=20.0)
    assert outputs[-1].progress.target in ("a", "b")


def test_cycles_are_counted_only_for_passes_the_word_made():
    """``G F a & G F b``: a b a b driven as planned completes cycles; a pass interrupted by an
    unplanned d starts a new plan whose cycles count from there, never more than the word
    holds (the report's count: the plan cycle b a b seen in the word). Without c, whose
    straight-line visits would be the cheapest way from a to b (the plan may pass through a
    region that the task does not name: its letter is in the plan's word)."""
    agent = _agent("G F a & G F b", [r for r in REGIONS if r.name != "c"])
    legs = [(-2.5, 0.0), (2.5, 0.0), (-2.5, 0.0), (2.5, 0.0)]
    around = []
    for p, q in itertools.pairwise(legs):
        around += _line(p, q)
    state, notices, _ = _walk(agent, around)
    done = [n for n in notices if n.kind == "cycle_completed"]
    word = [n.data["region"] for n in notices if n.kind == "region_visited"]
    assert word == ["a", "b", "a", "b"]
    assert len(done) == 1  # suffix b a b: one pass, b -> a -> b
    # now pushed through d on the way to a: the pass breaks, no cycle is reported for it
    state, notices, _ = _walk(agent, _line((2.5, 0.0), (0.0, -2.0)) + _line((0.0, -2.0),
                                                                            (-2.5, 0.0)),
                              state, t0=100.0)
    assert [n.kind for n in notices].count("cycle_completed") == 0
    assert "unplanned_region" in [n.kind for n in notices]
