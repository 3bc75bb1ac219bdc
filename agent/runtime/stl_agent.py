"""The STL agent: the pure funnel agent of ``tlfleet.agent.policy.stl`` behind the runtime loop.

:class:`StlCore` wraps one :class:`~tlfleet.agent.policy.stl.StlAgent` (built with
``build_agents(scenario, robots=[id])[id]``; stl-funnel.md §6–§9, §12, paper Alg. 2) into the
loop's ``step(state, TickInput) -> (state, TickOutput)``, adding no decision of its own:

* inputs: the frame's poses of *every* robot (LTL robots included, for collision avoidance,
  eq. (6)) as ``{id: (x, y, θ)}``, the collaboration messages delivered for this tick and
  the peers the runtime cannot reach (``StepInput.unreachable``);
* outputs: the world-frame command (v_x, v_y [m/s], ω [rad/s]), the step's messages as
  ``CollabMessage`` stamped with the frame's time (the loop sends them by query before the
  command), an ``StlStatus`` at most every ``status_period`` [s] of sim time (≤ 10 Hz), and
  events read off the step's ``LogRecord`` and messages: ``critical_event`` and ``repair``
  (data: stage, r, …), ``recovery`` (a robustness recovery raised r: r, r_before, ρ, …;
  ``tlfleet.agent.stl.recovery``), ``collab_request``, ``collab_release``, ``collab_follow`` (the
  agent starts or stops following a requester), ``subtask_done`` and ``peers_unreachable`` (the set
  of peers the runtime cannot reach changed: ``peers``, ``lost``, ``back``).

``main(config, scenario)`` is the process (``tlfleet agent SCENARIO --robot ID`` for an STL
robot); its
:class:`~tlfleet.agent.runtime.peers.CollabLink` serves ``robot/<id>/collab``, and its agent
announces its status only to the robots that read it (``tlfleet.agent.policy.stl.status_readers``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.policy.stl import AgentState, LogRecord, StepInput, StlAgent, build_agents
from tlfleet.agent.runtime.collab import to_wire
from tlfleet.agent.runtime.config import AgentConfig
from tlfleet.agent.runtime.loop import TickInput, TickOutput
from tlfleet.agent.runtime.peers import CollabLink
from tlfleet.agent.stl.messages import CollabRelease, CollabRequest
from tlfleet.bus.protocol.fast_paths import pose_map
from tlfleet.bus.protocol.messages import Event, StlStatus

STATUS_PERIOD = 0.1  # [s] sim time: StlStatus at ≤ 10 Hz (architecture.md §2)
_EPS = 1e-9  # [s] so that frames at exactly k·0.1 s count as due despite float sums


@dataclass(frozen=True, eq=False)
class StlRuntimeState:
    """The pure agent's state, when the last status went out [s] and the peers it was last
    told it cannot reach."""

    agent: AgentState
    last_status: float = -math.inf
    unreachable: frozenset[int] = frozenset()


class StlCore:
    """One STL agent as a loop :class:`~tlfleet.agent.runtime.loop.Core`."""

    def __init__(self, agent: StlAgent, status_period: float = STATUS_PERIOD):
        self.agent = agent
        self.robot = agent.robot_id
        self.zero = (0.0, 0.0, 0.0)
        self.source = f"agent/{self.robot}"
        self.status_period = status_period

    def initial_state(self) -> StlRuntimeState:
        return StlRuntimeState(self.agent.initial_state())

    def step(self, state: StlRuntimeState, inputs: TickInput
             ) -> tuple[StlRuntimeState, TickOutput]:
        frame = inputs.frame
        t = frame.t
        # (x, y, θ) tuples as decoded: the pure step reads them as it reads arrays (it would
        # turn arrays back into lists), and 30 small arrays per tick cost more than the step;
        # the dict is built in C where the codec is (a 30-row comprehension from cold caches
        # was ≈ 8 % of an agent's tick)
        poses = pose_map(frame.poses)
        before = state.agent
        after, out = self.agent.step(before, StepInput(t, poses, inputs.inbox,
                                                       inputs.unreachable, tuples=True))
        messages = tuple(to_wire(m, t) for m in out.messages) if out.messages else ()
        events = self._events(t, before, after, out.log, out.messages)
        unreachable = inputs.unreachable
        if unreachable is not state.unreachable and unreachable != state.unreachable:
            events += (_reach_event(t, self.source, state.unreachable, unreachable),)
        status = None
        last = state.last_status
        if t - last >= self.status_period - _EPS:
            status = _status(self.robot, out.log, after)
            last = t
        return (StlRuntimeState(after, last, unreachable),
                TickOutput(out.u, status, events, messages))

    def _events(self, t: float, before: AgentState, after: AgentState, log: LogRecord,
                sent) -> tuple[Event, ...]:
        if not (log.repair or log.recovered or sent or after.follow != before.follow
                or after.outcomes is not before.outcomes):
            return ()  # the common tick: none of _all_events' cases (fewer lines from cold caches)
        return self._all_events(t, before, after, log, sent)

    def _all_events(self, t: float, before: AgentState, after: AgentState, log: LogRecord,
                    sent) -> tuple[Event, ...]:
        src = self.source
        events = []
        if log.repair:
            events.append(Event(t, src, "critical_event",
                                {"stage": log.repair, "ce": log.ce, "rho": log.rho,
                                 "subtask": log.subtask, "follow": _follow(log.follow)}))
            events.append(Event(t, src, "repair",
                                {"stage": log.repair, "r": log.r, "rho_max": log.rho_max,
                                 "lower": log.lower, "subtask": log.subtask}))
        if log.recovered:
            events.append(Event(t, src, "recovery",
                                {"r": log.r, "r_before": before.funnel.r if before.funnel else None,
                                 "rho": log.rho, "rho_max": log.rho_max, "lower": log.lower,
                                 "subtask": log.subtask}))
        requests = [m for m in sent if isinstance(m, CollabRequest)]
        if requests:
            events.append(Event(t, src, "collab_request",
                                {"subtask": requests[0].subtask,
                                 "receivers": [m.receiver for m in requests]}))
        releases = [m for m in sent if isinstance(m, CollabRelease)]
        if releases:
            events.append(Event(t, src, "collab_release",
                                {"subtask": releases[0].subtask,
                                 "receivers": [m.receiver for m in releases]}))
        if after.follow != before.follow:
            events.append(Event(t, src, "collab_follow",
                                {"requester": _follow(after.follow),
                                 "previous": _follow(before.follow),
                                 "subtask": after.follow_subtask}))
        for outcome in after.outcomes[len(before.outcomes):]:
            events.append(Event(t, src, "subtask_done",
                                {"subtask": outcome.index, "satisfied": outcome.satisfied,
                                 "r": outcome.final_r, "rho_phi": outcome.rho_phi,
                                 "events": list(outcome.events), "ended_by": outcome.ended_by,
                                 "recoveries": outcome.recoveries}))
        return tuple(events)


def _reach_event(t: float, source: str, before: frozenset[int], now: frozenset[int]) -> Event:
    """``peers_unreachable``: the peers this agent cannot reach changed (their liveliness token
    went or came back, or a query to one failed or its retry wait ended; ``CollabLink``)."""
    return Event(t, source, "peers_unreachable",
                 {"peers": sorted(now), "lost": sorted(now - before),
                  "back": sorted(before - now)})


def _follow(follow: int | None) -> int:
    return -1 if follow is None else int(follow)


def _status(robot: int, log: LogRecord, state: AgentState) -> StlStatus:
    return StlStatus(robot, log.t, log.subtask, log.rho, log.rho_max, log.lower, log.r,
                     log.stage, log.ce, log.c, _follow(log.follow), tuple(state.events))


# --------------------------------------------------------------------------- process


def main(config: AgentConfig, scenario: Scenario, *, transport=None, stop=None) -> int:
    """The STL agent process of ``config.robot`` (see ``tlfleet.cli.commands.agent``);
    ``transport`` and ``stop`` are for tests (see ``tlfleet.agent.runtime.process.run_agent``)."""
    from tlfleet.agent.runtime.process import run_agent

    def build(transport, malformed, _publish_fault):
        agent = build_agents(scenario, robots=[config.robot])[config.robot]
        link = CollabLink(transport, scenario.fleet, config.robot, agent.cfg.peers, malformed,
                          timeout=config.collab_timeout, check=agent.collab_problem)
        core = StlCore(agent)
        return core, core.initial_state(), (), link

    return run_agent(config, scenario, build, transport=transport, stop=stop)
