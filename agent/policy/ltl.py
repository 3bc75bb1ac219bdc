"""One LTL agent as a pure step function: an optimal prefix–suffix plan (paper Alg. 1) executed by
the navigation stack (docs/ltl-navigation.md), beside the STL one of ``tlfleet.agent.policy.stl``.

    agent = LtlAgent(scenario, robot)
    plan = agent.plan()                       # Algorithm 1; UnsatisfiableTask if none
    state, ready = agent.initial_state(plan)  # ready: the plan_ready notice
    state, out = agent.step(state, LtlStepInput(t, pose, others))

The robot's task is translated **once**, here (the scenario carries the parsed formula): the same
automaton plans (``plan_robot(..., buchi=agent.buchi)``), replans and tracks the Büchi states, so
no two translations have to number states alike. The transition system's weights are the
keep-out path lengths of ``tlfleet.agent.nav.keep_out.RegionPaths`` (docs/ltl-navigation.md §2):
an edge ``π_m → π_n`` exists when a path enters no third region, so the plan's word is the word
the robot's run can produce. One step (5 Hz, ``scenario.ltl.control_rate``):

1. the plan executor's step (``tlfleet.agent.nav.executor.Executor.step``) with the own pose and
   every other robot as ``others`` → the command (v [m/s], ω [rad/s]); when the scenario's
   ``[navigation] coupling_aware`` is on (default) and STL tasks depend on this robot, the
   velocity limits those robots can track (``tlfleet.agent.policy.coupling``,
   ``tlfleet.agent.nav.coupling_limits``, docs/coupling.md) bound the command;
2. **the run's word** (docs/ltl-navigation.md §1): the executor reports every region the
   robot's centre enters; each entry reads the label of the word's previous letter, once or more
   (``buchi_stutter_step``: the product reads the *source* region's label). An entry the plan did
   not schedule is an ``unplanned_region`` notice (region, target, Büchi states before and after);
   then the agent plans again from the current product state (the entered region and the Büchi
   states), or, when no Büchi state is left — now, or once the entered region's own label is
   read — reports ``task_lost`` and stops: it never reports progress the word does not make;
3. navigation events → :class:`Notice` records (``region_visited``, ``cycle_completed``,
   ``plan_finished``, ``stuck``, ``recovered``, ``yield``, ``no_path``, …); a ``ReplanRequest``
   (a target out of reach after the recoveries) → a new plan from the word's last letter and
   the current Büchi states with the blocked edge penalised, handed to the executor at the next
   step, and a ``plan_ready`` notice;
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

import itertools
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from tlfleet.agent.evolve import evolve
from tlfleet.agent.ltl.buchi import Buchi, buchi_stutter_step
from tlfleet.agent.ltl.planner import Plan, plan_robot, replan
from tlfleet.agent.ltl.task import robot_automaton
from tlfleet.agent.ltl.transition_system import START, EdgeLength, from_regions, from_scenario
from tlfleet.agent.model.scenario import Region, Scenario
from tlfleet.agent.nav.coupling_limits import VelocityLimits
from tlfleet.agent.nav.events import NavEvent, RegionEntered, RegionVisited, ReplanRequest
from tlfleet.agent.nav.executor import Executor, ExecutorInputs, ExecutorState
from tlfleet.agent.nav.grid_planner import path_length_function
from tlfleet.agent.nav.keep_out import RegionPaths
from tlfleet.agent.policy.coupling import CouplingModel
from tlfleet.agent.scenario.stl_setup import naming
from tlfleet.bus.errors import UnsatisfiableTask

logger = logging.getLogger(__name__)

Point = tuple[float, float]
Distance = Callable[[Sequence[float], Sequence[float]], float]
JOIN_DISTANCE = 0.1  # [m] a first pose farther than this from the start pose: plan from it


@dataclass(frozen=True, eq=False)
class LtlState:
    """Executor state, Büchi states consistent with the run's word (its last letter not read
    yet), the plan being followed, a new plan waiting for the next step, the penalised edges
    ((source, target) region names, penalty [m]), the word's last letter (None before the first
    step, ``"start"`` for a robot that started in no region) and whether the task is lost."""

    executor: ExecutorState
    buchi_states: frozenset[int]
    plan: Plan
    pending_plan: tuple[tuple[str, ...], tuple[str, ...]] | None = None
    penalties: tuple[tuple[str, str, float], ...] = ()
    replans: int = 0
    stepped: bool = False  # a step has run (the first one checks where the robot is)
    word_last: str | None = None
    lost: bool = False


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


def penalised(edge_length: EdgeLength, penalties: Sequence[tuple[str, str, float]]
              ) -> EdgeLength:
    """``edge_length`` with ``penalty`` [m] added on the directed edges ``(source, target)``
    given by region name (``"start"`` for the start point): how a ``ReplanRequest`` (a blocked
    edge) becomes weights for the replanning (docs/ltl-navigation.md §5)."""
    extra: dict[tuple[str, str], float] = {}
    for source, target, penalty in penalties:
        extra[(source, target)] = extra.get((source, target), 0.0) + float(penalty)

    def weight(source: Region | Sequence[float], target: Region) -> float | None:
        w = edge_length(source, target)
        name = source.name if isinstance(source, Region) else START
        return None if w is None else w + extra.get((name, target.name), 0.0)

    return weight


def plan_on_map(scenario: Scenario, robot_id: int, *, buchi: Buchi | None = None,
                paths: RegionPaths | None = None) -> Plan:
    """Algorithm 1 for LTL robot ``robot_id`` with the agent's own map and rules: the keep-out
    transition system of docs/ltl-navigation.md §2 (what ``tlfleet run``'s agent, ``tlfleet
    plan`` and ``tlfleet check`` plan with). Raises :class:`UnsatisfiableTask`; when only the
    keep-out rule leaves no plan, its message names the region in the way
    (:func:`keep_out_reason`)."""
    paths = paths or RegionPaths.from_scenario(scenario, robot_id)
    try:
        return plan_robot(scenario, robot_id, buchi=buchi, edge_length=paths.edge_length)
    except UnsatisfiableTask as exc:
        reason = keep_out_reason(scenario, robot_id, paths, buchi)
        if reason is None:
            raise
        raise UnsatisfiableTask(robot_id, scenario.robot(robot_id).ltl or exc.formula,
                                reason) from None


def keep_out_reason(scenario: Scenario, robot_id: int, paths: RegionPaths,
                    buchi: Buchi | None = None) -> str | None:
    """Why no plan keeps out of the other regions, in one sentence naming the region in the way,
    when a plan exists on the map without the keep-out rule; None otherwise."""
    robot = scenario.robot(robot_id)
    try:
        free = plan_robot(scenario, robot_id, buchi=buchi,
                          distance=path_length_function(scenario, robot.radius))
    except UnsatisfiableTask:
        return None
    names = [*free.prefix, *free.suffix, *free.suffix[:1]]
    start = (float(robot.pose[0]), float(robot.pose[1]))
    for source, target in itertools.pairwise(names):
        if source == target or target == START:
            continue
        origin = start if source == START else source
        if math.isfinite(paths.length(origin, target)):
            continue
        frm = "the start" if source == START else source
        blockers = paths.blockers(origin, target)
        margin = paths.grid.inflation
        if blockers:
            names_in_way = " or ".join(f"region {b!r}" for b in blockers)
            return (f"every way from {frm} to {target} enters {names_in_way} (a region the "
                    f"transition must keep out of, by the robot's radius and margin, "
                    f"{margin:.2f} m)")
        return (f"every way from {frm} to {target} enters another region (kept out by the "
                f"robot's radius and margin, {margin:.2f} m)")
    return None


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
        executor = executor or Executor.from_scenario(scenario, robot)
        if not executor.followers:  # escorts and formations: the right-of-way rule skips them
            followers = naming(scenario, frozenset({robot})) - {robot}
            executor = replace(executor, followers=frozenset(followers))
        self.executor = executor
        self.paths = self.executor.paths
        # ``distance`` (over centre points) replaces the keep-out weights: tests and benches
        # that compare with the plain map's weights
        self.distance = distance
        self.edge_length: EdgeLength = (self.paths.edge_length if distance is None
                                        else lambda p, q: distance(_centre(p), _centre(q)))
        t0 = time.perf_counter()
        self.buchi: Buchi = robot_automaton(spec)  # the one translation of this task
        self.translate_time = time.perf_counter() - t0  # [s]
        ts = from_scenario(scenario, robot)
        self.labels = dict(zip(ts.names, ts.labels, strict=True))
        self.initial_region = ts.names[ts.initial]
        self.coupling = (CouplingModel.from_scenario(scenario, robot)
                         if scenario.navigation.coupling_aware else None)

    # start-up -------------------------------------------------------------------------------

    def plan(self) -> Plan:
        """Algorithm 1 with this agent's automaton; raises :class:`UnsatisfiableTask` (naming the
        region in the way when only the keep-out rule leaves no plan). The plan's timings
        include this agent's translation."""
        if self.distance is None:
            plan = plan_on_map(self.scenario, self.robot, buchi=self.buchi, paths=self.paths)
        else:
            plan = plan_robot(self.scenario, self.robot, buchi=self.buchi,
                              edge_length=self.edge_length)
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
        initial states, over the agent's keep-out weights (see the module docstring)."""
        ts = from_regions(self.scenario.regions, point, edge_length=self.edge_length)
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
        first_step = not state.stepped
        if first_step:
            state, joined = self._joined(state, inputs)
        t = inputs.t
        limits = None
        if self.coupling and not state.lost:
            limits = VelocityLimits.of(self.coupling.limits(t, inputs.poses(self.robot)))
        ex_state, ex_out = self.executor.step(
            state.executor, ExecutorInputs(t, inputs.pose, inputs.others, state.pending_plan,
                                           limits))
        state = evolve(state, executor=ex_state, pending_plan=None)
        notices: list[Notice] = [] if joined is None else [joined]
        entered = False
        for nav_event in ex_out.events:
            if isinstance(nav_event, RegionVisited | RegionEntered):
                entered = True
                state, more = self._read_entry(state, nav_event, t)
                notices.extend(more)
            elif isinstance(nav_event, ReplanRequest):
                if not state.lost:
                    state, notice = self.replan(state, nav_event, t)
                    notices.append(notice)
            else:
                notices.append(_notice(nav_event))
        if first_step and not entered and state.word_last is None:
            state = evolve(state, word_last=START)  # started in no region: the letter ∅
        ex_state = state.executor
        progress = ex_out.progress
        if progress.mode != ex_state.mode:  # the agent stopped it this step (task lost)
            progress = self.executor.progress(ex_state)
        report = LtlProgress(t, ex_state.prefix, ex_state.suffix, progress.target,
                             tuple(sorted(state.buchi_states)), progress.visits,
                             progress.rounds, progress.mode)
        return state, LtlStepOutput((ex_out.v, ex_out.omega), report, tuple(notices))

    def _label(self, name: str | None) -> frozenset[str]:
        return self.labels.get(name, frozenset()) if name is not None else frozenset()

    def _read_entry(self, state: LtlState, event: RegionVisited | RegionEntered, t: float
                    ) -> tuple[LtlState, list[Notice]]:
        """One letter of the run's word (module docstring, step 2)."""
        before = state.buchi_states
        after = before
        if state.word_last is not None:
            after = buchi_stutter_step(self.buchi, before, self._label(state.word_last))
        state = evolve(state, buchi_states=after, word_last=event.region)
        notices: list[Notice] = []
        if isinstance(event, RegionVisited):
            notices.append(_notice(event))
        else:
            notices.append(Notice(t, "unplanned_region", {
                "region": event.region, "target": event.target, "previous": event.previous,
                "visits": event.visits, "buchi_before": sorted(before),
                "buchi_after": sorted(after)}))
            logger.warning("robot %d: entered %s on the way to %s (not in the plan)",
                           self.robot, event.region, event.target)
        if state.lost:
            return state, notices
        ahead = buchi_stutter_step(self.buchi, after, self._label(event.region)) if after else after
        if not ahead:
            logger.error("robot %d: the run's word violates %s (entered %s)", self.robot,
                         self.formula, event.region)
            notices.append(Notice(t, "task_lost", {
                "region": event.region, "buchi_before": sorted(before),
                "buchi_after": sorted(after), "formula": self.formula}))
            return evolve(state, lost=True,
                          executor=self.executor.lose(state.executor, t)), notices
        if isinstance(event, RegionEntered):
            state, notice = self._replan_from_word(state, t, {
                "unplanned": event.region, "target": event.target})
            notices.append(notice)
        return state, notices

    def _replan_from_word(self, state: LtlState, t: float, reason: dict
                          ) -> tuple[LtlState, Notice]:
        """A new plan from the current product state: the word's last letter and the Büchi
        states, with the penalised edges."""
        ts = from_scenario(self.scenario, self.robot,
                           edge_length=penalised(self.edge_length, state.penalties))
        current = state.word_last if state.word_last not in (None, START) else \
            self.initial_region
        try:
            plan = replan(self.buchi, ts, current, state.buchi_states,
                          self.scenario.ltl.suffix_weight, robot=self.robot)
        except UnsatisfiableTask as exc:
            logger.warning("robot %d: replanning failed: %s", self.robot, exc)
            return state, Notice(t, "replan_failed", {**reason, "error": str(exc)})
        logger.info("robot %d: replanned at t=%.2f: %s · (%s)^ω", self.robot, t, plan.prefix,
                    plan.suffix)
        state = evolve(state, plan=plan, pending_plan=(plan.prefix, plan.suffix),
                       replans=state.replans + 1)
        return state, self.plan_notice(t, plan, replanned=True, reason=reason)

    def after_command(self, state: LtlState) -> LtlState:
        """The work a step deferred until its command is sent: the executor's periodic global
        re-plan (``Executor.refresh``). Pure; skipping it changes nothing but when the
        work runs (the next step runs it first)."""
        if state.executor.pending is None:
            return state
        return evolve(state, executor=self.executor.refresh(state.executor))

    def replan(self, state: LtlState, request: ReplanRequest, t: float
               ) -> tuple[LtlState, Notice]:
        """A new plan with the edge ``from_region → to_region`` penalised: the target stayed out
        of reach through the executor's recoveries (docs/ltl-navigation.md §5)."""
        source = request.from_region if request.from_region is not None else START
        penalties = (*state.penalties, (source, request.to_region, float(request.penalty)))
        state = evolve(state, penalties=penalties)
        reason = {"from": request.from_region, "to": request.to_region,
                  "penalty": request.penalty}
        return self._replan_from_word(state, t, reason)


def _centre(point: Region | Sequence[float]) -> Point:
    if isinstance(point, Region):
        return float(point.center[0]), float(point.center[1])
    return float(point[0]), float(point[1])


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
