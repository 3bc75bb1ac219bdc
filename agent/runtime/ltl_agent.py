"""The LTL agent process: the pure :class:`tlfleet.agent.policy.ltl.LtlAgent` inside the agent loop.

:class:`LtlCore` adapts it to the loop's :class:`~tlfleet.agent.runtime.loop.Core` interface: a due
mocap frame → :class:`~tlfleet.agent.policy.ltl.LtlStepInput` (own pose, every other row), the
step's notices →
``Event`` messages from ``agent/<id>``, its progress → an ``LtlStatus`` every due frame (≤ 10 Hz
of sim time). All decisions are the pure agent's (style.md §3).

``main(config, scenario)`` is the process (``tlfleet agent SCENARIO --robot ID`` for an LTL robot).
"""

from __future__ import annotations

import logging

import numpy as np
from tlfleet.agent.ltl.planner import Plan
from tlfleet.agent.model.scenario import Scenario
from tlfleet.agent.nav.dwa import DwaConfig, native_kernel_available
from tlfleet.agent.nav.events import ReplanRequest
from tlfleet.agent.nav.executor import Executor
from tlfleet.agent.policy.ltl import Distance, LtlAgent, LtlState, LtlStepInput, Notice
from tlfleet.agent.runtime.config import AgentConfig
from tlfleet.agent.runtime.loop import TickInput, TickOutput
from tlfleet.bus.protocol.messages import Event, LtlStatus

logger = logging.getLogger(__name__)

__all__ = ["LtlCore", "LtlState", "main"]


class LtlCore:
    """The loop's core of LTL robot ``robot``: :class:`LtlAgent` with wire types around it."""

    def __init__(self, scenario: Scenario, robot: int, *, distance: Distance | None = None,
                 executor: Executor | None = None):
        self.agent = LtlAgent(scenario, robot, distance=distance, executor=executor)
        self.robot = robot
        self.zero = (0.0, 0.0)
        self.source = f"agent/{robot}"

    @property
    def buchi(self):  # the agent's one automaton (tests read its numbering)
        return self.agent.buchi

    @property
    def coupling(self):  # the coupling-aware limits (None: off, or nobody depends on us)
        return self.agent.coupling

    def coupling_event(self) -> Event:
        return self._event(self.agent.coupling_notice())

    def plan(self) -> Plan:
        """Algorithm 1; raises :class:`tlfleet.bus.errors.UnsatisfiableTask`."""
        return self.agent.plan()

    def initial_state(self, plan: Plan) -> tuple[LtlState, Event]:
        """State before the first frame and the ``plan_ready`` event."""
        state, notice = self.agent.initial_state(plan)
        return state, self._event(notice)

    def step(self, state: LtlState, inputs: TickInput) -> tuple[LtlState, TickOutput]:
        frame = inputs.frame
        pose = frame.pose(self.robot)
        if pose is None:
            raise ValueError(f"frame {frame.seq} has no pose of robot {self.robot}")
        others = np.array([row for row in frame.poses if row[0] != self.robot],
                          dtype=float).reshape(-1, 4)
        state, out = self.agent.step(state, LtlStepInput(frame.t, pose, others))
        p = out.progress
        status = LtlStatus(self.robot, p.t, p.prefix, p.suffix, p.target, p.buchi_states,
                           p.visits, p.rounds, p.mode)
        return state, TickOutput(out.u, status, tuple(self._event(n) for n in out.notices))

    def after_command(self, state: LtlState) -> LtlState:
        """Deferred work of the last step, run by the loop once the command is published."""
        return self.agent.after_command(state)

    def _replan(self, state: LtlState, request: ReplanRequest, t: float
                ) -> tuple[LtlState, Event]:
        state, notice = self.agent.replan(state, request, t)
        return state, self._event(notice)

    def _event(self, notice: Notice) -> Event:
        return Event(notice.t, self.source, notice.kind, notice.data)


# --------------------------------------------------------------------------- process


def main(config: AgentConfig, scenario: Scenario, *, transport=None, stop=None) -> int:
    """The LTL agent process of ``config.robot`` (see ``tlfleet.cli.commands.agent``);
    ``transport`` and ``stop`` are for tests (see ``tlfleet.agent.runtime.process.run_agent``)."""
    from tlfleet.agent.runtime.process import run_agent

    def build(_transport, _malformed, _publish):
        core = LtlCore(scenario, config.robot)
        plan = core.plan()  # UnsatisfiableTask → fault event, exit code 1 (run_agent)
        state, event = core.initial_state(plan)
        events = (event, core.coupling_event()) if core.coupling else (event,)
        logger.info("robot %d: plan %s · (%s)^ω, cost %.3f, %.1f ms", config.robot, plan.prefix,
                    plan.suffix, plan.cost, 1e3 * plan.timings.total)
        _log_dwa_kernel(config.robot, core.agent.executor.config.dwa)
        return core, state, events, None

    return run_agent(config, scenario, build, transport=transport, stop=stop)


def _log_dwa_kernel(robot: int, dwa: DwaConfig) -> None:
    if dwa.native:
        logger.info("robot %d: DWA kernel: C (tlfleet.agent.nav._dwa)", robot)
    elif native_kernel_available():
        logger.info("robot %d: DWA kernel: numpy (kernel = %r)", robot, dwa.kernel)
    else:
        logger.warning("robot %d: the DWA's C kernel (tlfleet.agent.nav._dwa) was not built at "
                       "install time (no C compiler?): running its numpy form, the same "
                       "commands, a slower step", robot)
