"""The executor tracks the run's word (docs/ltl-navigation.md §1): region entries from its own
poses, planned visits, unplanned letters, stutters; and a replan with an empty prefix does not
send the robot back to the region it just left."""

from __future__ import annotations

import itertools
import math

import numpy as np
from nav_harness import ExecutorController, SimRobot, simulate
from tlfleet.agent.model.scenario import Arena, Region, Robot, Scenario
from tlfleet.agent.nav.events import PlanAccepted, RegionEntered, RegionVisited
from tlfleet.agent.nav.executor import Executor, ExecutorInputs

REGIONS = (Region("a", (-2.0, 0.0), 0.3), Region("d", (0.0, 0.0), 0.3),
           Region("b", (2.0, 0.0), 0.3), Region("s", (0.0, 1.2), 0.1))


def _executor(pose=(-2.0, 0.0, 0.0)) -> Executor:
    robots = (Robot(1, "unicycle", pose, ltl="G F a & G F b"),)
    return Executor.from_scenario(Scenario("w", "w", 60.0, Arena(), REGIONS, robots), 1)


def _walk(executor: Executor, state, points, t0: float = 0.0):
    """Scripted poses (the executor's commands are ignored): every event, the last state."""
    events = []
    for k, (x, y) in enumerate(points):
        state, out = executor.step(state, ExecutorInputs(t0 + 0.2 * k, (x, y, 0.0)))
        events += out.events
    return state, events


def _line(a, b, step):
    n = max(2, math.ceil(math.dist(a, b) / step) + 1)
    return [(a[0] + (b[0] - a[0]) * u, a[1] + (b[1] - a[1]) * u) for u in np.linspace(0, 1, n)]


def test_an_entry_the_plan_did_not_schedule_is_its_own_letter_and_the_plan_waits():
    executor = _executor()
    state = executor.initial_state(("a", "b"), ("b", "a", "b"))
    state, events = _walk(executor, state, _line((-2.0, 0.0), (2.0, 0.0), 0.06))
    kinds = [(type(e).__name__, getattr(e, "region", None)) for e in events]
    assert kinds[:3] == [("RegionVisited", "a"), ("RegionEntered", "d"), ("RegionVisited", "b")]
    entered = next(e for e in events if isinstance(e, RegionEntered))
    assert (entered.target, entered.previous, entered.visits) == ("b", "a", 1)
    assert dict(state.visits)["d"] == 1  # a real entry of the word
    assert state.last_region == "b" and state.target == "a"


def test_a_pass_between_two_frames_through_a_small_region_is_seen():
    executor = _executor(pose=(-0.6, 1.2, 0.0))
    state = executor.initial_state(("start", "b"), ("b", "a", "b"))
    # 0.5 m steps: no sample lies inside s (radius 0.1 m), the segment through it does
    state, events = _walk(executor, state, [(-0.6, 1.2), (-0.1, 1.2), (0.4, 1.2)])
    assert [e.region for e in events if isinstance(e, RegionEntered)] == ["s"]


def test_leaving_and_coming_back_into_the_last_letter_is_a_stutter():
    executor = _executor()
    state = executor.initial_state(("a", "b"), ("b", "a", "b"))
    # out of a by 0.2 m (beyond the 5 cm hysteresis) and back in: no new letter, no visit
    path = [(-2.0, 0.0), (-1.6, 0.0), (-1.4, 0.0), (-1.6, 0.0), (-1.9, 0.0), (-1.4, 0.0)]
    state, events = _walk(executor, state, path)
    assert [type(e) for e in events] == [RegionVisited]
    assert dict(state.visits)["a"] == 1 and state.target == "b"


def test_a_replan_with_an_empty_prefix_keeps_its_first_region_as_reached():
    """The planner's convention: with an empty prefix the suffix's first state is where the
    robot is (the word's last letter). Accepting (), (b, a, b) while the word ends in b must
    target a next — before the fix the executor drove back into b first."""
    executor = _executor(pose=(2.0, 0.0, math.pi))
    state = executor.initial_state(("b", "a"), ("a", "b", "a"))
    state, _ = _walk(executor, state, [(2.0, 0.0), (1.5, 0.0)])  # visited b, left it
    assert state.last_region == "b" and state.target == "a"
    rounds = state.rounds
    state, out = executor.step(state, ExecutorInputs(0.6, (1.45, 0.0, math.pi),
                                                     new_plan=((), ("b", "a", "b"))))
    assert isinstance(out.events[0], PlanAccepted)
    assert out.progress.target == "a"
    assert out.progress.rounds >= rounds


def test_closed_loop_after_an_empty_prefix_replan_the_robot_drives_on_not_back():
    """On the harness: b reached, then the empty-prefix plan () · (b a b)^ω arrives 3 s later,
    the robot 0.9 m out of b; the next region it enters is a (around d, a keep-out zone of the
    transition b → a), and rounds never drop."""
    executor = _executor(pose=(2.0, 0.0, math.pi))
    controller = ExecutorController(executor, executor.initial_state(("b", "a"),
                                                                     ("a", "b", "a")), [1])
    rounds = []

    def stop(t, poses):
        if controller.outputs:
            rounds.append(controller.outputs[-1].progress.rounds)
        if abs(t - 3.0) < 1e-9:
            controller.pending_plan = ((), ("b", "a", "b"))
        return any(isinstance(e, RegionVisited) and e.region == "a" for e in controller.events)

    result = simulate([SimRobot((2.0, 0.0, math.pi))], [controller], 40.0, Arena(), stop=stop)
    visits = [e.region for e in controller.events if isinstance(e, RegionVisited)]
    entered = [e.region for e in controller.events if isinstance(e, RegionEntered)]
    assert visits == ["b", "a"] and entered == []
    assert all(x <= y for x, y in itertools.pairwise(rounds))
    x = result.poses[:, 0, 0]
    assert np.all(np.diff(x[x < 1.6]) < 0.05)  # never back towards b once on the way
