"""Frozen or partitioned agents: noticed from their silence, and their recovery.

A process that is stopped (SIGSTOP), wedged or cut off keeps its liveliness token until the
zenoh lease expires (10 s by default) — or forever, if the process is only frozen — so the
supervisor's death detection does not see it. Every agent publishes its status several times a
second of mission time (LTL: each control period, STL: ≤ 10 Hz), so :class:`Health` watches the
statuses instead: agent r is **silent** when no status of r arrived for ``silence`` [s] wall
*and* the fleet went on without it — the frames advanced more than ``sim_lag`` [s] of sim time
since r's last status (realtime), or the simulator reported a missed deadline of r since then
(lockstep, where the whole fleet waits for r). It is reported once per episode
(``Event(agent_silent)``, printed) and when its statuses come back (``Event(agent_back)``, with
the length of the silence). Both make the run *degraded* (:mod:`tlfleet.coordinator.live.verdict`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from tlfleet.bus.protocol.messages import Event, LtlStatus, StlStatus

logger = logging.getLogger(__name__)

SOURCE = "coordinator"


@dataclass
class _Agent:
    wall: float  # [s] wall time of the last status (or of the mission start)
    t: float  # [s] sim time of the last status
    silent_since: float | None = None  # [s] wall
    missed_after_status: bool = False


class Health:
    """Silence detection of the agents of ``robots`` (see the module docstring)."""

    def __init__(self, robots: Iterable[int], record: Callable[[Event], None],
                 report: Callable[[str], None], *, silence: float = 2.0, sim_lag: float = 0.5,
                 clock: Callable[[], float] = time.monotonic):
        self.robots = tuple(sorted(robots))
        self.silence = silence
        self.sim_lag = sim_lag
        self._record = record
        self._report = report
        self._clock = clock
        self._agents: dict[int, _Agent] = {}
        self.sim_t = 0.0  # [s] newest frame time seen
        self.episodes: list[dict[str, Any]] = []  # {robot, t, wall_silence, back_t}

    def start(self) -> None:
        """Mission start: every agent's silence counts from now."""
        now = self._clock()
        self._agents = {r: _Agent(now, 0.0) for r in self.robots}

    def on_message(self, what: str, message: Any) -> None:
        """Recorder tap hook (decoded, trusted messages)."""
        if what == "mocap":
            self.sim_t = max(self.sim_t, message.t)
        elif what == "status" and isinstance(message, (LtlStatus, StlStatus)):
            agent = self._agents.get(message.robot)
            if agent is None:
                return
            now = self._clock()
            if agent.silent_since is not None:
                quiet = now - agent.silent_since + self.silence
                self._report(f"agent-{message.robot} is back at t = {message.t:.2f} s after "
                             f"{quiet:.1f} s of silence")
                self._record(Event(message.t, SOURCE, "agent_back",
                                   {"robot": message.robot, "silence": quiet}))
                self._close(message.robot, message.t)
                agent.silent_since = None
            agent.wall, agent.t, agent.missed_after_status = now, message.t, False
        elif what == "event" and getattr(message, "kind", "") == "deadline_miss":
            robot = message.data.get("robot") if isinstance(message.data, dict) else None
            agent = self._agents.get(robot) if isinstance(robot, int) else None
            if agent is not None:
                agent.missed_after_status = True

    def _close(self, robot: int, t: float) -> None:
        for episode in reversed(self.episodes):
            if episode["robot"] == robot and episode["back_t"] is None:
                episode["back_t"] = t
                return

    def poll(self) -> None:
        """Report agents that became silent (call every supervision step)."""
        now = self._clock()
        for robot, agent in self._agents.items():
            if agent.silent_since is not None or now - agent.wall < self.silence:
                continue
            if not (self.sim_t - agent.t > self.sim_lag or agent.missed_after_status):
                continue  # the whole fleet is waiting (lockstep stall): not this agent's fault
            agent.silent_since = now
            quiet = now - agent.wall
            self.episodes.append({"robot": robot, "t": self.sim_t, "wall_silence": quiet,
                                  "back_t": None})
            self._report(f"agent-{robot} silent for {quiet:.1f} s (last status at "
                         f"t = {agent.t:.2f} s, fleet at t = {self.sim_t:.2f} s): frozen or "
                         "partitioned?")
            self._record(Event(self.sim_t, SOURCE, "agent_silent",
                               {"robot": robot, "last_status_t": agent.t, "silence": quiet}))

    def findings(self) -> list[str]:
        """Worded degradations for the verdict (episodes still open at the end included)."""
        out = []
        for e in self.episodes:
            end = "never came back" if e["back_t"] is None else f"back at t = {e['back_t']:.2f} s"
            out.append(f"agent-{e['robot']} silent from t = {e['t']:.2f} s ({end})")
        return out
