"""The LTL agent loop on the fake network: plan at start, 5 Hz commands within the unicycle's
limits, region visits with Büchi tracking, status, replanning and unsatisfiable tasks."""

from __future__ import annotations

import math
import threading
from dataclasses import replace

import numpy as np
import pytest
from runtime_helpers import FakeSim
from tlfleet.agent.ltl.buchi import buchi_step, buchi_stutter_step
from tlfleet.agent.nav.events import ReplanRequest
from tlfleet.agent.runtime import ltl_agent
from tlfleet.agent.runtime.config import AgentConfig
from tlfleet.agent.runtime.loop import AgentLoop, LoopConfig, TickInput
from tlfleet.agent.runtime.ltl_agent import LtlCore
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.protocol.messages import LtlStatus, MocapFrame

RATE = 100.0
DT = 1.0 / RATE
DIVIDER = 20  # 100 Hz mocap / 5 Hz LTL control


@pytest.fixture(scope="module")
def scenario1():
    return load_scenario("scenarios/scenario1.toml")


def ltl_loop(network, scenario, robot):
    core = LtlCore(scenario, robot)
    state, event = core.initial_state(core.plan())
    transport = network.transport(f"agent{robot}")
    loop = AgentLoop(transport, LoopConfig(scenario.fleet, robot, DIVIDER), core, state)
    loop.open()
    loop.ready()
    loop.publish_event(event)
    return loop


def test_ltl_agents_plan_drive_visit_and_report(scenario1):
    """Both LTL robots of Scenario 1 in lockstep on a kinematic unicycle loop driven here
    (ẋ = v cos θ, ẏ = v sin θ, θ̇ = ω, zero-order hold): plans published, every command within
    the DWA limits, both GF regions visited repeatedly, Büchi states tracked, status at 5 Hz."""
    network = FakeNetwork()
    sim = FakeSim(network, scenario1.fleet)
    ltl_ids = [r.id for r in scenario1.robots if r.is_ltl]
    loops = {j: ltl_loop(network, scenario1, j) for j in ltl_ids}
    poses = {r.id: np.array(r.pose, dtype=float) for r in scenario1.robots}
    held = {j: (0.0, 0.0) for j in ltl_ids}
    commands = {j: [] for j in ltl_ids}
    sim.control("start")
    seconds = 75.0
    for k in range(round(seconds * RATE)):
        due = ltl_ids if k % DIVIDER == 0 else []
        sim.frame(k / RATE, k, poses, due=due)
        for j in ltl_ids:
            assert loops[j].run_once(0.0)
        for j in due:
            held[j] = sim.command(j, k).u
            commands[j].append(held[j])
        for j in ltl_ids:
            v, w = held[j]
            x, y, th = poses[j]
            poses[j] = np.array([x + DT * v * math.cos(th), y + DT * v * math.sin(th),
                                 th + DT * w])

    plans = [e for e in sim.events if e.kind == "plan_ready"]
    assert sorted(e.source for e in plans) == ["agent/1", "agent/2"]
    assert all(e.data["cost"] > 0 and e.data["timings"]["total"] > 0 for e in plans)
    for j in ltl_ids:
        limits = scenario1.robot(j).unicycle
        u = np.array(commands[j])
        assert len(u) == seconds * RATE / DIVIDER
        assert np.all(np.abs(u[:, 0]) <= limits.max_v + 1e-9)
        assert np.all(np.abs(u[:, 1]) <= limits.max_omega + 1e-9)
        period = DIVIDER / RATE
        assert np.all(np.abs(np.diff(u[:, 0])) <= limits.acc_v * period + 1e-9)
        assert np.all(np.abs(np.diff(u[:, 1])) <= limits.acc_omega * period + 1e-9)
        visits = [e for e in sim.events if e.kind == "region_visited"
                  and e.source == f"agent/{j}"]
        regions = {e.data["region"] for e in visits}
        assert len(regions) == 2 and len(visits) >= 4, visits
        statuses = [s for s in sim.statuses if isinstance(s, LtlStatus) and s.robot == j]
        assert len(statuses) == len(u)
        last = statuses[-1]
        assert last.rounds >= 2 and dict(last.visits) == {
            r: sum(e.data["region"] == r for e in visits) for r in regions}
        assert last.buchi_states  # the visited regions never violated the task
        assert last.mode == "navigate" and last.target in regions
        # the periodic global re-plans ran after the commands (LtlCore.after_command),
        # none is left for the next step
        assert loops[j].state.executor.pending is None
        assert loops[j].summary()["mean_after_command_ms"] > 0.0
    # the Büchi tracking went through an accepting state on the way
    core = loops[1].core
    assert any(set(s.buchi_states) & core.buchi.accepting
               for s in sim.statuses if isinstance(s, LtlStatus) and s.robot == 1)


def test_buchi_tracking_reads_the_label_of_each_region_left(scenario1):
    """Unit check of the convention on Scenario 1's robot 1 (starts in a11; plan a11 a12 ·
    (a12 a11 a12)^ω; docs/ltl-navigation.md §1): entering a region reads the label of the word's
    previous letter, once or more (a robot may stay), so arriving in a12 the states are those
    after a11's label, back in a11 after a12's; each time they contain the plan's own state."""
    core = LtlCore(scenario1, 1)
    plan = core.plan()
    assert plan.prefix == ("a11", "a12") and plan.suffix == ("a12", "a11", "a12")
    state, _ = core.initial_state(plan)
    a11 = scenario1.region("a11").center
    a12 = scenario1.region("a12").center
    others = ((2, 2.5, -2.0, 0.0),)

    def frame(t, x, y):
        return TickInput(MocapFrame(t, round(t * RATE), ((1, x, y, math.pi / 2), *others)))

    state, out = core.step(state, frame(0.0, *a11))
    assert out.events[0].kind == "region_visited" and out.events[0].data["region"] == "a11"
    assert state.buchi_states == frozenset(core.buchi.initial)
    state, out = core.step(state, frame(0.2, *a12))
    expected = buchi_stutter_step(core.buchi, frozenset(core.buchi.initial), {"a11"})
    assert plan.prefix_run[1] == ("a12", next(iter(expected & {plan.prefix_run[1][1]})))
    assert [e.data["region"] for e in out.events if e.kind == "region_visited"] == ["a12"]
    assert state.buchi_states == expected
    assert out.status.buchi_states == tuple(sorted(expected))
    # an independent check of the closure: reading a11 once, twice, three times
    once = buchi_step(core.buchi, frozenset(core.buchi.initial), {"a11"})
    thrice = buchi_step(core.buchi, buchi_step(core.buchi, once, {"a11"}), {"a11"})
    assert once <= expected and thrice <= expected
    state, out = core.step(state, frame(0.4, *a11))
    back = buchi_stutter_step(core.buchi, expected, {"a12"})
    assert [e.data["region"] for e in out.events if e.kind == "region_visited"] == ["a11"]
    assert state.buchi_states == back
    assert plan.suffix_run[1] == ("a11", next(iter(back & {plan.suffix_run[1][1]})))
    assert back & core.buchi.accepting  # the cycle's accepting state was passed


def test_a_replan_request_yields_a_new_plan_for_the_executor(scenario1):
    core = LtlCore(scenario1, 1)
    state, _ = core.initial_state(core.plan())
    a11 = scenario1.region("a11").center
    tick = TickInput(MocapFrame(0.0, 0, ((1, a11[0], a11[1], 0.0),)))
    state, _ = core.step(state, tick)
    request = ReplanRequest(0.0, "a11", "a12", 10.0, a11)
    state, event = core._replan(state, request, 0.0)
    assert event.kind == "plan_ready" and event.data["replan"]
    assert event.data["reason"] == {"from": "a11", "to": "a12", "penalty": 10.0}
    assert state.pending_plan is not None and state.pending_plan[0][0] == "a11"
    assert state.plan.cost > 0 and state.replans == 1
    # the executor takes it at the next step (PlanAccepted → plan_accepted event)
    tick = TickInput(MocapFrame(0.2, 20, ((1, a11[0], a11[1], 0.0),)))
    state, out = core.step(state, tick)
    assert "plan_accepted" in [e.kind for e in out.events]
    assert state.pending_plan is None


def test_an_unsatisfiable_task_is_a_fault_with_exit_code_1(scenario1):
    robots = tuple(replace(r, ltl="F a11 & G !a11") if r.id == 1 else r
                   for r in scenario1.robots)
    scenario = replace(scenario1, robots=robots)
    network = FakeNetwork()
    sim = FakeSim(network, scenario.fleet)
    config = AgentConfig(robot=1, stale_after=0.5)
    code = ltl_agent.main(config, scenario, transport=network.transport("a1"),
                                      stop=threading.Event())
    assert code == 1
    (fault,) = [e for e in sim.events if e.kind == "fault"]
    assert fault.source == "agent/1" and "cannot be satisfied" in fault.data["error"]
    assert not network.alive_keys()  # never declared alive
