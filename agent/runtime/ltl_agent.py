"""The LTL agent: an optimal prefix–suffix plan (paper Alg. 1) executed by the navigation stack.

:class:`LtlCore` is the pure part (style.md §3): built once per robot, it plans at start-up with
``plan_robot(scenario, id, distance=path_length_function(scenario))`` (ltl-planning.md §3–§5) and
then, per due frame (5 Hz, ``scenario.ltl.control_rate``), ``step(state, TickInput)``:

1. the plan executor's step (``agent.nav.executor.Executor.step``, ltl-planning.md §6) with the own
   pose of the frame and every other row as ``others`` → the command (v [m/s], ω [rad/s]);
   when the scenario's ``[navigation] coupling_aware`` is on (default) and STL tasks depend on
   this robot, the velocity limits those robots can track (``agent.nav.coupling_limits``,
   docs/coupling.md) bound the command;
2. the Büchi state set along the regions visited (``agent.ltl.buchi.buchi_step``): each time the
   executor advances from plan position k ≥ 1 to k + 1, the label of the region at position
   k − 1 (the one left) is read (the planner's convention, ``agent.ltl.planner``);
3. nav events → protocol events (``region_visited``, ``cycle_completed``, ``plan_finished``,
   ``stuck``, ``no_path``); a ``ReplanRequest`` → a new plan from the last region and the current
   Büchi states with the blocked edge penalised (``agent.ltl.planner.replan`` over
   ``with_penalised_edges``), handed to the executor at the next step, and ``plan_ready``;
4. an ``LtlStatus`` every due frame (≤ 10 Hz of sim time).

``main(args)`` is the process (``tlfleet agent SCENARIO --robot ID`` for an LTL robot).
"""

from __future__ import annotations

import argparse
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from agent.errors import UnsatisfiableTask
from agent.ltl.buchi import buchi_step, translate
from agent.ltl.planner import Plan, plan_robot, replan
from agent.ltl.transition_system import START, from_scenario
from agent.nav.coupling_limits import VelocityLimits
from agent.nav.events import NavEvent, RegionVisited, ReplanRequest
from agent.nav.executor import Executor, ExecutorInputs, ExecutorState, target_at
from agent.nav.grid_planner import path_length_function, with_penalised_edges
from agent.protocol.messages import Event, LtlStatus
from agent.runtime.loop import TickInput, TickOutput
from agent.scenario.model import Scenario
from agent.stl.coupling import CouplingModel

logger = logging.getLogger(__name__)

Point = tuple[float, float]
Distance = Callable[[Sequence[float], Sequence[float]], float]


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


class LtlCore:
    """Pure LTL agent of robot ``robot`` in ``scenario`` (see the module docstring)."""

    def __init__(self, scenario: Scenario, robot: int, *, distance: Distance | None = None,
                 executor: Executor | None = None):
        spec = scenario.robot(robot)
        if spec.ltl is None:
            raise ValueError(f"robot {robot} has no LTL task")
        self.scenario = scenario
        self.robot = robot
        self.zero = (0.0, 0.0)
        self.source = f"agent/{robot}"
        self.formula = spec.ltl
        self.start_point: Point = (float(spec.pose[0]), float(spec.pose[1]))
        self.distance = distance or path_length_function(scenario)
        self.executor = executor or Executor.from_scenario(scenario, robot)
        self.buchi = translate(spec.ltl)  # deterministic: the planner's numbering
        ts = from_scenario(scenario, robot, self.distance)
        self.labels = dict(zip(ts.names, ts.labels, strict=True))
        self.initial_region = ts.names[ts.initial]
        self.coupling = (CouplingModel.from_scenario(scenario, robot)
                         if scenario.navigation.coupling_aware else None)

    # start-up -------------------------------------------------------------------------------

    def plan(self) -> Plan:
        """Algorithm 1; raises :class:`agent.errors.UnsatisfiableTask`."""
        return plan_robot(self.scenario, self.robot, distance=self.distance)

    def initial_state(self, plan: Plan) -> tuple[LtlState, Event]:
        """State before the first frame and the ``plan_ready`` event."""
        executor = self.executor.initial_state(plan.prefix, plan.suffix, 0.0)
        state = LtlState(executor, frozenset(self.buchi.initial), plan)
        return state, self._plan_event(0.0, plan, replanned=False)

    def coupling_event(self) -> Event:
        """``coupling_limits`` at start-up: whether the limits are on and the coupled predicates."""
        terms = [term.source for term in self.coupling.terms] if self.coupling else []
        return Event(0.0, self.source, "coupling_limits",
                     {"coupling_aware": self.coupling is not None,
                      "share": self.scenario.navigation.coupling_share, "predicates": terms})

    def _plan_event(self, t: float, plan: Plan, replanned: bool,
                    reason: dict | None = None) -> Event:
        data = {"prefix": list(plan.prefix), "suffix": list(plan.suffix), "cost": plan.cost,
                "prefix_cost": plan.prefix_cost, "suffix_cost": plan.suffix_cost,
                "timings": {"parse": plan.timings.parse, "translate": plan.timings.translate,
                            "product": plan.timings.product, "search": plan.timings.search,
                            "total": plan.timings.total},
                "buchi_states": plan.buchi_states, "product_states": plan.product_states,
                "replan": replanned}
        if reason:
            data["reason"] = reason
        return Event(t, self.source, "plan_ready", data)

    # the step -------------------------------------------------------------------------------

    def step(self, state: LtlState, inputs: TickInput) -> tuple[LtlState, TickOutput]:
        frame = inputs.frame
        t = frame.t
        pose = frame.pose(self.robot)
        if pose is None:
            raise ValueError(f"frame {frame.seq} has no pose of robot {self.robot}")
        others = np.array([row for row in frame.poses if row[0] != self.robot],
                          dtype=float).reshape(-1, 4)
        prev = state.executor
        new_plan = state.pending_plan
        limits = None
        if self.coupling:
            limits = VelocityLimits.of(
                self.coupling.limits(t, {int(row[0]): row[1:4] for row in frame.poses}))
        ex_state, ex_out = self.executor.step(prev, ExecutorInputs(t, pose, others, new_plan,
                                                                   limits))
        if new_plan is not None:
            first = 1 if new_plan[0] and new_plan[0][0] == prev.last_region else 0
        else:
            first = prev.step
        buchi = self._track(state.buchi_states, ex_state, first)
        state = replace(state, executor=ex_state, buchi_states=buchi, pending_plan=None)
        events: list[Event] = []
        for nav_event in ex_out.events:
            if isinstance(nav_event, ReplanRequest):
                state, event = self._replan(state, nav_event, t)
            else:
                event = self._event(nav_event)
            if event is not None:
                events.append(event)
        progress = ex_out.progress
        status = LtlStatus(self.robot, t, ex_state.prefix, ex_state.suffix, progress.target,
                           tuple(sorted(buchi)), progress.visits, progress.rounds, progress.mode)
        return state, TickOutput((ex_out.v, ex_out.omega), status, tuple(events))

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

    def _event(self, nav_event: NavEvent) -> Event:
        if isinstance(nav_event, RegionVisited):
            data: dict[str, object] = {"region": nav_event.region, "visits": nav_event.visits}
        else:
            data = {name: _plain(value) for name, value in vars(nav_event).items() if name != "t"}
        return Event(nav_event.t, self.source, nav_event.kind, data)

    def _centre(self, region: str | None) -> Point:
        if region is None or region not in self.labels or region == START:
            return self.start_point
        centre = self.scenario.region(region).center
        return (float(centre[0]), float(centre[1]))

    def _replan(self, state: LtlState, request: ReplanRequest, t: float
                ) -> tuple[LtlState, Event]:
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
                    Event(t, self.source, "replan_failed", {**reason, "error": str(exc)}))
        logger.info("robot %d: replanned at t=%.2f: %s · (%s)^ω", self.robot, t, plan.prefix,
                    plan.suffix)
        state = replace(state, plan=plan, pending_plan=(plan.prefix, plan.suffix),
                        penalties=penalties, replans=state.replans + 1)
        return state, self._plan_event(t, plan, replanned=True, reason=reason)


def _plain(value: object) -> object:
    """Event data must be msgpack-plain: tuples → lists, numpy scalars → floats."""
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if hasattr(value, "item"):
        return value.item()
    return value


# --------------------------------------------------------------------------- process


def main(args: argparse.Namespace, scenario: Scenario, *, transport=None, stop=None) -> int:
    """The LTL agent process of ``args.robot`` (see ``coordinator.commands.agent``);
    ``transport`` and ``stop`` are for tests (see ``agent.runtime.process.run_agent``)."""
    from agent.runtime.process import run_agent

    def build(_transport, _malformed, _publish):
        core = LtlCore(scenario, args.robot)
        plan = core.plan()  # UnsatisfiableTask → fault event, exit code 1 (run_agent)
        state, event = core.initial_state(plan)
        events = (event, core.coupling_event()) if core.coupling else (event,)
        logger.info("robot %d: plan %s · (%s)^ω, cost %.3f, %.1f ms", args.robot, plan.prefix,
                    plan.suffix, plan.cost, 1e3 * plan.timings.total)
        return core, state, events, None

    divider = max(1, round(scenario.sim.mocap_rate / scenario.ltl.control_rate))
    return run_agent(args, scenario, divider, build, transport=transport, stop=stop)
