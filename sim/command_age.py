"""Commands have an age: a command is stamped with the sim time ``t`` of the frame it
answers (``Command.t``, tlfleet.agent.runtime.loop), and the simulator applies it only while it is
fresh.

At tick k (sim time t_k) a command of robot r is *stale* when t_k − ``Command.t`` exceeds r's
bound: ``max_age`` [s] when given, else ``periods`` control periods of r (d_r / mocap_rate each,
``tlfleet.sim.lockstep.control_dividers``), and never less than ``floor`` [s]. A stale command is
not applied and does not re-arm the command watchdog, so a robot whose agent froze, or whose link
was cut, stops after ``SimParams.watchdog`` instead of replaying commands computed from old poses
when the backlog arrives. In lockstep every accepted command answers the current tick (age 0),
so this never triggers there.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

from tlfleet.bus.protocol.messages import Command

DEFAULT_PERIODS = 5.0  # control periods
FLOOR = 0.05  # [s]


class CommandAge:
    """Filters the commands of a tick by their age (see the module docstring)."""

    def __init__(self, dividers: Mapping[int, int], mocap_rate: float, *,
                 max_age: float | None = None, periods: float = DEFAULT_PERIODS,
                 floor: float = FLOOR):
        self.bound = {r: max_age if max_age is not None else max(floor, periods * d / mocap_rate)
                      for r, d in dividers.items()}
        self.stale: Counter[int] = Counter()  # per robot, over the run
        self.episodes: Counter[int] = Counter()  # stale episodes per robot (event each)
        self._in_episode: set[int] = set()

    def fresh(self, commands: Iterable[Command], t: float) -> tuple[list[Command], list[Command]]:
        """(fresh, newly stale episode starts) of ``commands`` at sim time ``t`` [s]; counts."""
        fresh: list[Command] = []
        started: list[Command] = []
        for command in commands:
            bound = self.bound.get(command.robot)
            if bound is None or t - command.t <= bound + 1e-9:
                fresh.append(command)
                self._in_episode.discard(command.robot)
                continue
            self.stale[command.robot] += 1
            if command.robot not in self._in_episode:
                self._in_episode.add(command.robot)
                self.episodes[command.robot] += 1
                started.append(command)
        return fresh, started
