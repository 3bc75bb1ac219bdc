"""One LTL agent as a pure step function: an optimal prefix–suffix plan (paper Alg. 1) executed by
the navigation stack (ltl-planning.md §3–§6), beside the STL one of ``tlfleet.agent.policy.stl``.

    agent = LtlAgent(scenario, robot)
    plan = agent.plan()                       # Algorithm 1; UnsatisfiableTask if none
    state, ready = agent.initial_state(plan)  # ready: the plan_ready notice
    state, out = agent.step(state, LtlStepInput(t, pose, others))

The robot's task is translated **once**, here (the scenario carries the parsed formula): the same
automaton plans (``plan_robot(..., buchi=agent.buchi)``), replans and tracks the Büchi states, so
no two translations have to number states alike. One step (5 Hz, ``scenario.ltl.control_rate``):

1. the plan executor's step (``tlfleet.agent.nav.executor.Executor.step``, ltl-planning.md §6) with
   the own pose and every other robot as ``others`` → the command (v [m/s], ω [rad/s]); when the
   scenario's ``[navigation] coupling_aware`` is on (default) and STL tasks depend on this robot,
   the velocity limits those robots can track (``tlfleet.agent.policy.coupling``,
   ``tlfleet.agent.nav.coupling_limits``, docs/coupling.md) bound the command;
2. the Büchi state set along the regions visited (``tlfleet.agent.ltl.buchi.buchi_step``): each time
   the executor advances from plan position k ≥ 1 to k + 1, the label of the region at position
   k − 1 (the one left) is read (the planner's convention, ``tlfleet.agent.ltl.planner``);
3. navigation events → :class:`Notice` records (``region_visited``, ``cycle_completed``,
   ``plan_finished``, ``stuck``, ``no_path``, …); a ``ReplanRequest`` → a new plan from the last
   region and the current Büchi states with the blocked edge penalised
   (``tlfleet.agent.ltl.planner.replan`` over ``with_penalised_edges``), handed to the executor at
   the next step, and a ``plan_ready`` notice;
4. an :class:`LtlProgress` every step.

A robot whose first step finds it more than ``JOIN_DISTANCE`` from the scenario's start pose (a
restarted agent process, or one joining a running fleet) first plans again from
where it is (:meth:`LtlAgent.plan_from`): Algorithm 1 over a transition system whose start is
the current position, from the automaton's initial states. A new process does not know what the
robot did before, so it satisfies the whole task from now on — a suffix of the trajectory that
satisfies φ, which for the recurrence and reachability tasks of the scenarios asks no less than
the run as a whole; a ``plan_ready`` notice with ``reason.joined`` says so.

No I/O, no clock, no wire types: the runtime (``tlfleet.agent.runtime.ltl_agent``) turns notices
into events and the progress into the status message.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from tlfleet.agent.evolve import evolve
from tlfleet.agent.ltl.buchi import Buchi, buchi_step
from tlfleet.agent.ltl.planner import Plan, plan_robot, replan
from tlfleet.agent.ltl.task import robot_formula, task_automaton
from tlfleet.agent.ltl.transition_system import START, from_regions, from_scenario
from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.nav.coupling_limits import VelocityLimits
from tlfleet.agent.nav.events import NavEvent, RegionVisited, ReplanRequest
from tlfleet.agent.nav.executor import Executor, ExecutorInputs, ExecutorState, target_at
from tlfleet.agent.nav.grid_planner import path_length_function, with_penalised_edges
from tlfleet.agent.policy.coupling import CouplingModel
from tlfleet.bus.errors import UnsatisfiableTask

logger = logging.getLogger(__name__)

Point = tuple[float, float]
Distance = Callable[[Sequence[float], Sequence[float]], float]
JOIN_DISTANCE = 0.1  # [m] a first pose farther than this from the start pose: plan from it


@dataclass(frozen=True, eq=False)
class LtlState:
    """Executor state, Büchi states consistent with the regions visited, the plan being followed,
    a new plan waiting for the next step, and the penalised edges ((p, q) [m], penalty [m])."""

    executor: ExecutorState
    buchi_states: frozenset[int]
    plan: Plan
    pending_plan: tuple[tuple[str, ...], tuple[str, ...]] | None = None
    penalties: tuple[tuple[Point, Point, float], ...] = ()
    replans: int = 0
    stepped: bool = False  # a step has run (the first one checks where the robot is)


@dataclass(frozen=True, slots=True)
class LtlStepInput:
    """One due frame as the agent sees it: sim time [s], the own pose (x [m], y [m], θ [rad])
    and every other robot's row (id, x, y, θ), shape (n, 4)."""

    t: float
    pose: tuple[float, float, float]
    others: np.ndarray

    def poses(self, robot: int) -> dict[int, Sequence[float]]:
        """Every robot's (x, y, θ), the own one as ``robot``."""
        out: dict[int, Sequence[float]] = {
            int(row[0]): (float(row[1]), float(row[2]), float(row[3])) for row in self.others}
        out[robot] = tuple(self.pose)
        return out


@dataclass(frozen=True, slots=True)
class Notice:
    """Something the agent reports once (an event on the wire): sim time [s], kind, plain data
    (msgpack-plain values only: lists, numbers, strings)."""

    t: float
    kind: str
    data: dict[str, Any]


@dataclass(frozen=True, slots=True)
class LtlProgress:
    """Where the agent is in its plan (its status on the wire)."""

    t: float  # [s]
    prefix: tuple[str, ...]
    suffix: tuple[str, ...]
    target: str | None
    buchi_states: tuple[int, ...]
    visits: tuple[tuple[str, int], ...]
    rounds: int
    mode: str


@dataclass(frozen=True, slots=True)
class LtlStepOutput:
    """The command (v [m/s], ω [rad/s]), the progress and the notices of one step."""

    u: tuple[float, float]
    progress: LtlProgress
    notices: tuple[Notice, ...] = ()


class LtlAgent:
    """Pure LTL agent of robot ``robot`` in ``scenario`` (see the module docstring)."""

    def __init__(self, scenario: Scenario, robot: int, *, distance: Distance | None = None,
                 executor: Executor | None = None):
        spec = scenario.robot(robot)
        if spec.ltl is None:
            raise ValueError(f"robot {robot} has no LTL task")
        self.scenario = scenario
        self.robot = robot
        self.formula = spec.ltl
        self.start_point: Point = (float(spec.pose[0]), float(spec.pose[1]))
        self.distance = distance or path_length_function(scenario)
        self.executor = executor or Executor.from_scenario(scenario, robot)
        t0 = time.perf_counter()
        self.buchi: Buchi = task_automaton(robot_formula(spec))  # the one translation of this task
        self.translate_time = time.perf_counter() - t0  # [s]
        ts = from_scenario(scenario, robot, self.distance)
        self.labels = dict(zip(ts.names, ts.labels, strict=True))
        self.initial_region = ts.names[ts.initial]
        self.coupling = (CouplingModel.from_scenario(scenario, robot)
                         if scenario.navigation.coupling_aware else None)

    # start-up -------------------------------------------------------------------------------

    def plan(self) -> Plan:
        """Algorithm 1 with this agent's automaton; raises :class:`UnsatisfiableTask`. The plan's
        timings include this agent's translation."""
        plan = plan_robot(self.scenario, self.robot, distance=self.distance, buchi=self.buchi)
        return replace(plan, timings=replace(plan.timings, translate=self.translate_time))

    def initial_state(self, plan: Plan) -> tuple[LtlState, Notice]:
        """State before the first frame and the ``plan_ready`` notice."""
        executor = self.executor.initial_state(plan.prefix, plan.suffix, 0.0)
        state = LtlState(executor, frozenset(self.buchi.initial), plan)
        return state, self.plan_notice(0.0, plan, replanned=False)

    def plan_notice(self, t: float, plan: Plan, replanned: bool,
                    reason: dict | None = None) -> Notice:
        data = {"prefix": list(plan.prefix), "suffix": list(plan.suffix), "cost": plan.cost,
                "prefix_cost": plan.prefix_cost, "suffix_cost": plan.suffix_cost,
                "timings": {"parse": plan.timings.parse, "translate": plan.timings.translate,
                            "product": plan.timings.product, "search": plan.timings.search,
                            "total": plan.timings.total},
                "buchi_states": plan.buchi_states, "product_states": plan.product_states,
                "replan": replanned}
        if reason:
            data["reason"] = reason
        return Notice(t, "plan_ready", data)

    def coupling_notice(self) -> Notice:
        """``coupling_limits`` at start-up: whether the limits are on and the coupled
        predicates."""
        terms = [term.source for term in self.coupling.terms] if self.coupling else []
        return Notice(0.0, "coupling_limits",
                      {"coupling_aware": self.coupling is not None,
                       "share": self.scenario.navigation.coupling_share, "predicates": terms})

    # the step -------------------------------------------------------------------------------

    def plan_from(self, point: Point) -> Plan:
        """Algorithm 1 from ``point`` [m] (instead of the start pose) and the automaton's
        initial states, over the agent's map distances (see the module docstring)."""
        ts = from_regions(self.scenario.regions, point, self.distance)
        plan = replan(self.buchi, ts, ts.names[ts.initial], self.buchi.initial,
                      self.scenario.ltl.suffix_weight, robot=self.robot)
        return replace(plan, timings=replace(plan.timings, translate=0.0))

    def _joined(self, state: LtlState, inputs: LtlStepInput
                ) -> tuple[LtlState, Notice | None]:
        """The first step of a robot away from its start pose: a plan from where it is."""
        point = (float(inputs.pose[0]), float(inputs.pose[1]))
        away = float(np.hypot(point[0] - self.start_point[0], point[1] - self.start_point[1]))
        state = evolve(state, stepped=True)
        if away <= JOIN_DISTANCE:
            return state, None
        try:
            plan = self.plan_from(point)
        except UnsatisfiableTask as exc:
            logger.warning("robot %d: no plan from (%.2f, %.2f): %s", self.robot, *point, exc)
            return state, Notice(inputs.t, "replan_failed", {"joined": True, "error": str(exc)})
        logger.info("robot %d: joined %.2f m from its start pose at t=%.2f: %s · (%s)^ω",
                    self.robot, away, inputs.t, plan.prefix, plan.suffix)
        state = evolve(state, plan=plan, pending_plan=(plan.prefix, plan.suffix),
                        buchi_states=frozenset(self.buchi.initial), replans=state.replans + 1)
        return state, self.plan_notice(inputs.t, plan, replanned=True,
                                       reason={"joined": True, "from": list(point),
                                               "away": away})

    def step(self, state: LtlState, inputs: LtlStepInput) -> tuple[LtlState, LtlStepOutput]:
        joined = None
        if not state.stepped:
            state, joined = self._joined(state, inputs)
        t = inputs.t
        prev = state.executor
        new_plan = state.pending_plan
        limits = None
        if self.coupling:
            limits = VelocityLimits.of(self.coupling.limits(t, inputs.poses(self.robot)))
        ex_state, ex_out = self.executor.step(prev, ExecutorInputs(t, inputs.pose, inputs.others,
                                                                   new_plan, limits))
        if new_plan is not None:
            first = 1 if new_plan[0] and new_plan[0][0] == prev.last_region else 0
        else:
            first = prev.step
        buchi = self._track(state.buchi_states, ex_state, first)
        state = evolve(state, executor=ex_state, buchi_states=buchi, pending_plan=None)
        notices: list[Notice] = [] if joined is None else [joined]
        for nav_event in ex_out.events:
            if isinstance(nav_event, ReplanRequest):
                state, notice = self.replan(state, nav_event, t)
            else:
                notice = _notice(nav_event)
            notices.append(notice)
        progress = ex_out.progress
        report = LtlProgress(t, ex_state.prefix, ex_state.suffix, progress.target,
                             tuple(sorted(buchi)), progress.visits, progress.rounds, progress.mode)
        return state, LtlStepOutput((ex_out.v, ex_out.omega), report, tuple(notices))

    def after_command(self, state: LtlState) -> LtlState:
        """The work a step deferred until its command is sent: the executor's periodic global
        re-plan (``Executor.refresh``). Pure; skipping it changes nothing but when the
        work runs (the next step runs it first)."""
        if state.executor.pending is None:
            return state
        return evolve(state, executor=self.executor.refresh(state.executor))

    def _track(self, states: frozenset[int], ex_state: ExecutorState, first: int
               ) -> frozenset[int]:
        """Read the label of every region left between plan positions ``first`` and the
        executor's new position (the planner's convention: the source label is read)."""
        for k in range(max(first, 1), ex_state.step):
            left = target_at(ex_state.prefix, ex_state.suffix, k - 1)
            states = buchi_step(self.buchi, states, self.labels.get(left, frozenset()))
            if not states:
                logger.error("robot %d: the regions visited violate %s", self.robot,
                             self.formula)
        return states

    def _centre(self, region: str | None) -> Point:
        if region is None or region not in self.labels or region == START:
            return self.start_point
        centre = self.scenario.region(region).center
        return (float(centre[0]), float(centre[1]))

    def replan(self, state: LtlState, request: ReplanRequest, t: float
               ) -> tuple[LtlState, Notice]:
        """A new plan with the edge ``from_region → to_region`` penalised (ltl-planning.md §5)."""
        edge = (self._centre(request.from_region), self._centre(request.to_region))
        penalties = (*state.penalties, (*edge, float(request.penalty)))
        distance = self.distance
        for p, q, penalty in penalties:
            distance = with_penalised_edges(distance, [(p, q)], penalty)
        ts = from_scenario(self.scenario, self.robot, distance)
        current = state.executor.last_region or self.initial_region
        reason = {"from": request.from_region, "to": request.to_region,
                  "penalty": request.penalty}
        try:
            plan = replan(self.buchi, ts, current, state.buchi_states,
                          self.scenario.ltl.suffix_weight, robot=self.robot)
        except UnsatisfiableTask as exc:
            logger.warning("robot %d: replanning failed: %s", self.robot, exc)
            return (replace(state, penalties=penalties),
                    Notice(t, "replan_failed", {**reason, "error": str(exc)}))
        logger.info("robot %d: replanned at t=%.2f: %s · (%s)^ω", self.robot, t, plan.prefix,
                    plan.suffix)
        state = evolve(state, plan=plan, pending_plan=(plan.prefix, plan.suffix),
                        penalties=penalties, replans=state.replans + 1)
        return state, self.plan_notice(t, plan, replanned=True, reason=reason)


def _notice(nav_event: NavEvent) -> Notice:
    if isinstance(nav_event, RegionVisited):
        data: dict[str, object] = {"region": nav_event.region, "visits": nav_event.visits}
    else:
        data = {name: _plain(value) for name, value in vars(nav_event).items() if name != "t"}
    return Notice(nav_event.t, nav_event.kind, data)


def _plain(value: object) -> object:
    """Notice data must be msgpack-plain: tuples → lists, numpy scalars → floats."""
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if hasattr(value, "item"):
        return value.item()
    return value
