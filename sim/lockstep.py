"""The tick logic of the simulator, free of sockets and threads (architecture.md §3, contract).

* **Due robots.** Robot r with control rate f_r is due at tick k when (k − φ_r) mod d_r = 0,
  with the divider d_r = round(mocap_rate / f_r) (STL at 100 Hz: every tick; LTL at 5 Hz: every
  20th) and the phase φ_r ∈ [0, d_r) (``Scenario.control_phase``: 0, or the LTL robots spread
  over the period), and only while its agent is alive (liveliness ``alive/agent/<r>``).
* **Lockstep collection** (:class:`LockstepCollector`). After publishing frame k the sim
  accepts exactly one ``Command(robot=r, seq=k)`` from each due robot r. Commands with another
  seq, from robots not due, for unknown robots or repeated are ignored and counted. The tick may
  advance when every due robot has answered, when an agent died (it is dropped from ``due`` at
  once), or at the wall timeout, when every robot still missing is recorded as a deadline miss.
* **Realtime collection** (:class:`LatestCommands`): the newest command of each robot wins.
* **Early answers.** Before the sim has processed ``Control(start)`` it republishes the initial
  frame (t = 0, seq = 0). An agent that got the start first may answer such a frame; its
  command is then exactly its answer to tick 0 (same t, same poses), so a ``seq = 0`` command
  that arrives before the start is held for tick 0 instead of being dropped (otherwise the
  agent, having answered seq 0 already, would miss tick 0 and make the run depend on the race).
  Any other command before the start is ignored.

Every class here is single-threaded; the process loop feeds it from its own thread.
"""

from __future__ import annotations

import enum
from collections import Counter
from collections.abc import Iterable, Mapping

from tlfleet.agent.model.scenario import Scenario
from tlfleet.bus.protocol.messages import Command


def control_dividers(scenario: Scenario) -> dict[int, int]:
    """Robot id → d_r = round(mocap_rate / f_r) ≥ 1, f_r the robot's control rate [Hz]."""
    return {robot.id: scenario.control_divider(robot.id) for robot in scenario.robots}


def control_phases(scenario: Scenario) -> dict[int, int]:
    """Robot id → φ_r ∈ [0, d_r), the tick of its control period at which it is due."""
    return {robot.id: scenario.control_phase(robot.id) for robot in scenario.robots}


def due_robots(tick: int, dividers: Mapping[int, int], alive: Iterable[int],
               phases: Mapping[int, int]) -> tuple[int, ...]:
    """The robots due at ``tick``: alive, and ``tick % divider == phase`` (phase 0 when
    ``phases`` does not list the robot); ids ascending."""
    alive = set(alive)
    return tuple(sorted(r for r, d in dividers.items()
                        if r in alive and tick % d == phases.get(r, 0)))


class Offer(enum.Enum):
    """What happened to one command offered to a collector."""

    ACCEPTED = "accepted"
    WRONG_SEQ = "wrong_seq"  # stale (late for an earlier tick) or from the future
    NOT_DUE = "not_due"  # the robot is not due this tick (or its agent was dropped)
    DUPLICATE = "duplicate"  # a second command for the same robot and seq
    UNKNOWN_ROBOT = "unknown_robot"  # no such robot in the scenario
    BEFORE_START = "before_start"  # no tick is open yet (and not an early answer to tick 0)
    EARLY = "early"  # a seq-0 answer before the start: held for tick 0


class LockstepCollector:
    """Collects the due robots' commands of one lockstep tick (see the module docstring).

    ``counts`` tallies every :class:`Offer` outcome over the whole run; ``misses`` counts
    deadline misses per robot.
    """

    def __init__(self, robots: Iterable[int]):
        self.robots = frozenset(robots)
        self.seq: int | None = None
        self.due: tuple[int, ...] = ()
        self._waiting: set[int] = set()
        self._received: dict[int, Command] = {}
        self._early: dict[int, Command] = {}
        self.counts: Counter[Offer] = Counter()
        self.misses: Counter[int] = Counter()

    def begin(self, seq: int, due: Iterable[int]) -> tuple[int, ...]:
        """Open tick ``seq`` (the previous tick's commands must have been taken); returns the
        due robots whose early answer was accepted for it (tick 0 only)."""
        self.seq = seq
        self.due = tuple(sorted(due))
        self._waiting = set(self.due)
        self._received = {}
        early, self._early = self._early, {}
        for robot in sorted(early):
            self.offer(early[robot])
        return tuple(sorted(r for r in early if r in self._received))

    def offer(self, command: Command) -> Offer:
        if command.robot not in self.robots:
            outcome = Offer.UNKNOWN_ROBOT
        elif self.seq is None and command.seq == 0 and command.robot not in self._early:
            self._early[command.robot] = command
            outcome = Offer.EARLY
        elif self.seq is None:
            outcome = Offer.BEFORE_START
        elif command.seq != self.seq:
            outcome = Offer.WRONG_SEQ
        elif command.robot in self._received:
            outcome = Offer.DUPLICATE
        elif command.robot not in self._waiting:
            outcome = Offer.NOT_DUE
        else:
            self._waiting.discard(command.robot)
            self._received[command.robot] = command
            outcome = Offer.ACCEPTED
        self.counts[outcome] += 1
        return outcome

    def drop(self, robot: int) -> None:
        """The agent of ``robot`` died: stop waiting for it."""
        self._waiting.discard(robot)

    @property
    def complete(self) -> bool:
        """Every due robot still alive has answered."""
        return not self._waiting

    def missing(self) -> tuple[int, ...]:
        return tuple(sorted(self._waiting))

    def expire(self) -> tuple[int, ...]:
        """The wall timeout elapsed: record and return the robots that missed this tick."""
        late = self.missing()
        for robot in late:
            self.misses[robot] += 1
        self._waiting.clear()
        return late

    def take(self) -> list[Command]:
        """The accepted commands of this tick, robot ids ascending (a deterministic order)."""
        commands = [self._received[r] for r in sorted(self._received)]
        self._received = {}
        return commands


class LatestCommands:
    """Realtime mode: the newest command of each robot, applied at the next tick."""

    def __init__(self, robots: Iterable[int]):
        self.robots = frozenset(robots)
        self._pending: dict[int, Command] = {}
        self.started = False
        self.counts: Counter[Offer] = Counter()

    def offer(self, command: Command) -> Offer:
        if command.robot not in self.robots:
            outcome = Offer.UNKNOWN_ROBOT
        elif not self.started and command.seq == 0:
            self._pending[command.robot] = command
            outcome = Offer.EARLY
        elif not self.started:
            outcome = Offer.BEFORE_START
        else:
            self._pending[command.robot] = command
            outcome = Offer.ACCEPTED
        self.counts[outcome] += 1
        return outcome

    def take(self) -> list[Command]:
        commands = [self._pending[r] for r in sorted(self._pending)]
        self._pending = {}
        return commands
