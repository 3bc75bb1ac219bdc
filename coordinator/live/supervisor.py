"""Supervision of a running fleet: readiness, start, deaths, end of run.

Protocol (architecture.md §1–§3, the runtime contract):

1. :meth:`Supervisor.wait_ready` — wait until the liveliness tokens ``alive/sim/0`` and
   ``alive/agent/<id>`` of every robot exist; a child that exits first, or a token still missing
   after ``ready_timeout``, raises :class:`~tlfleet.coordinator.launch.processes.LaunchError` naming
   who did not come up, with the tail of its log.
2. :meth:`Supervisor.start` — publish ``Control(start)`` (mission clock t = 0).
3. :meth:`Supervisor.supervise` — every ``poll_period`` drain the recorder tap, and report a child
   whose token disappears or whose process has exited: printed and recorded as
   ``Event(kind="process_died")`` within one poll period (≪ 1 s); the run goes on without it
   unless it was the simulator or the router. The run ends at ``Event(kind="sim_done")``, at sim
   time ≥ ``duration``, after ``wall_timeout`` or when ``stop`` is set (Ctrl-C).
4. :meth:`Supervisor.finish` — publish ``Control(stop)`` and give the children ``stop_grace`` to
   exit by themselves (the launcher then terminates what is left).

Deaths are detected twice (token DELETE, ``Popen.poll()``) and reported once per process. The
simulator exits by itself after ``sim_done``: its end counts as a death only when ``sim_done`` has
not arrived ``end_grace`` later, and its lost token not at all when it comes back within that
grace while the process runs (``Event(kind="token_blip")``: the link blinked).

a ``sim_done`` ends the run only when it is plausible (:attr:`Supervisor.sim_done`: the
simulator has ended, the frames reached the end of the run, or no newer frame followed it for
``end_grace``); one followed by newer frames is reported and recorded as ``flagged_event``.
When the router is gone, the other processes' lost tokens are its consequence: reported as one
router loss, not as deaths of everybody. An agent whose token comes back while its process still
runs (a partition longer than the lease) is reported as recovered (``Event(process_recovered)``)
and is no longer counted as dead.
"""

from __future__ import annotations

import logging
import queue
import signal
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol

from tlfleet.agent.model import Scenario
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Control, Event
from tlfleet.bus.transport import Closeable, Transport
from tlfleet.coordinator.launch.processes import LaunchError
from tlfleet.coordinator.record.recorder import COORDINATOR_SOURCE, RecorderTap
from tlfleet.coordinator.record.trust import FLAGGED, sim_done_plausible

logger = logging.getLogger(__name__)


class ChildLike(Protocol):
    """What the supervisor needs from a child process (``launcher.Child`` and test doubles)."""

    name: str

    @property
    def returncode(self) -> int | None: ...

    def log_tail(self, lines: int = 15) -> str: ...


@dataclass(frozen=True)
class SupervisorConfig:
    ready_timeout: float = 60.0  # [s] wall, for every token to appear
    wall_timeout: float = 600.0  # [s] wall, safety limit of the supervised phase
    poll_period: float = 0.05  # [s] wall, death detection and tap draining
    stop_grace: float = 5.0  # [s] wall, for children to exit after Control(stop)
    end_grace: float = 0.5  # [s] wall, for sim_done to arrive after the simulator exits
    sim_exit_grace: float = 10.0  # [s] wall, for the simulator to exit after its sim_done
    waiting_period: float = 1.0  # [s] wall, between "still waiting for …" reports


@dataclass
class Death:
    process: str
    how: str
    t: float  # [s] sim time when it was noticed
    wall: float  # [s] time.time() when it was noticed
    returncode: int | None = None


@dataclass
class Outcome:
    """How the supervised phase ended."""

    # sim_done | duration | sim_ended (exited 0, its sim_done not received) | wall_timeout |
    # interrupted | sim_died | router_lost
    reason: str
    t_end: float  # [s] sim time
    deaths: list[Death] = field(default_factory=list)
    sim_reached: float | None = None  # [s] where the simulator says it ended, once it ended


FINISHERS = frozenset({"sim"})  # processes that end by themselves at the end of the mission


def expected_tokens(scenario: Scenario) -> dict[str, str]:
    """{liveliness key: process name} of the processes a run waits for."""
    fleet = scenario.fleet
    tokens = {keys.alive(fleet, "sim", 0): "sim"}
    for robot in sorted(scenario.robots, key=lambda r: r.id):
        tokens[keys.alive(fleet, "agent", robot.id)] = f"agent-{robot.id}"
    return tokens


class Supervisor:
    """Watches the fleet's liveliness and child processes; sends start and stop."""

    def __init__(self, transport: Transport, scenario: Scenario, tap: RecorderTap,
                 children: Mapping[str, ChildLike], *, duration: float,
                 config: SupervisorConfig = SupervisorConfig(),
                 report: Callable[[str], None] | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.transport = transport
        self.scenario = scenario
        self.fleet = scenario.fleet
        self.tap = tap
        self.children = dict(children)
        self.duration = duration  # [s] sim time
        self.config = config
        self._report = report or (lambda text: logger.warning("%s", text))
        self._clock = clock
        self.tokens = expected_tokens(scenario)
        self.alive: set[str] = set()
        self.deaths: dict[str, Death] = {}
        # finishers whose end may still be the mission's: name -> (wall [s monotonic] since,
        # how, exit code, sim time [s] of the first sign)
        self._suspects: dict[str, tuple[float, str, int | None, float]] = {}
        self.recovered: list[Death] = []  # deaths that came back (token declared again)
        self._sim_done_count = 0  # sim_done events judged so far
        self._sim_done_pending: tuple[float, float] | None = None  # (wall, sim time) of the last
        self.sim_reached: float | None = None  # [s] the sim time of a sim_done from an ended sim
        self.stopping = False
        # processes whose link a fault cuts → until when [s monotonic] (inf: still
        # cut) a lost token of theirs is a link loss, not a death; and the losses now open
        self.cut: dict[str, float] = {}
        self.link_lost: dict[str, float] = {}  # process -> wall time (time.time()) of the loss
        # children whose token is gone while their process runs -> (sim time, wall) it went
        self.unreachable: dict[str, tuple[float, float]] = {}
        self.sim_exited = False  # the simulator exited 0 without a sim_done received
        # processes known by pid, not started here (namespace hosts): name -> "still runs?"
        self.probes: dict[str, Callable[[], bool]] = {}
        self._alive_queue: queue.SimpleQueue[tuple[str, bool]] = queue.SimpleQueue()
        self._handles: list[Closeable] = [
            transport.watch_alive(keys.all_alive(self.fleet),
                                  lambda key, alive: self._alive_queue.put((key, alive)))]

    # ----------------------------------------------------------------- helpers

    @property
    def sim_time(self) -> float:
        return self.tap.recorder.last_t

    @property
    def sim_done(self) -> bool:
        """True once a plausible ``Event(kind="sim_done")`` has been recorded.

        A ``sim_done`` counts at once when the simulator has ended or the frames reached the end
        of the run (:func:`tlfleet.coordinator.record.trust.sim_done_plausible`): the simulator
        exits right after its own. One followed by newer frames is flagged and ignored: the
        fleet is still running. One while the simulator still runs and publishes nothing (a
        pause: a forged ``sim_done`` during a withheld lockstep command) waits for the simulator
        to end; after ``sim_exit_grace`` without a frame it counts, and the verdict, which
        compares the end with the duration, says the run ended early.
        """
        seen = self.tap.recorder.event_kinds["sim_done"]
        if seen > self._sim_done_count:  # a new one: judge it from now
            self._sim_done_count = seen
            self._sim_done_pending = (self._clock(), self.sim_time)
        if self._sim_done_pending is None:
            return False
        since, t_then = self._sim_done_pending
        sim = self.children.get("sim")
        ended = (sim is not None and sim.returncode is not None) or "sim" not in self.alive
        if sim_done_plausible(self.sim_time, self.duration, ended):
            if ended:  # the simulator's own end: how far it says it got can be believed
                self.sim_reached = self.tap.recorder.sim_done_t
            return True
        if self.sim_time > t_then + 1e-9:
            self._sim_done_pending = None
            reason = (f"sim_done at t = {t_then:.2f} s of {self.duration:g} s, followed by "
                      f"newer frames (now t = {self.sim_time:.2f} s): the simulator still runs")
            self._report(f"ignored a sim_done: {reason} (spoofed?)")
            self.tap.recorder.on_event(Event(t=t_then, source=COORDINATOR_SOURCE, kind=FLAGGED,
                                             data={"claimed_kind": "sim_done",
                                                   "reason": reason}))
            return False
        return self._clock() - since >= self.config.sim_exit_grace

    def _process_alive_queue(self) -> None:
        while True:
            try:
                key, alive = self._alive_queue.get_nowait()
            except queue.Empty:
                return
            name = self.tokens.get(key)
            if name is None:
                continue
            if alive:
                self.alive.add(name)
                if name in self.link_lost:
                    self._link_event("link_restored", name)
                self._lift_suspicion(name)
                self._reachable_again(name)
                self._maybe_recovered(name)
            else:
                self.alive.discard(name)
                if (self._clock() <= self.cut.get(name, -1.0) and not self.stopping
                        and not self.tap.recorder.event_kinds["sim_done"]):
                    self._link_event("link_lost", name)
                elif not self.stopping:
                    self._token_lost(name)

    def _token_lost(self, name: str) -> None:
        """A token gone is a death only when the process is gone too: a child of ours that
        still runs (frozen, starved, cut off past the lease) is *unreachable* until it exits or
        comes back. The simulator's lost token waits ``end_grace`` first (its own end: its
        ``sim_done`` may still be in flight). Without a handle on the process (``tlfleet
        supervise``) the token is all there is: a token back within ``end_grace`` was a blip
        of a link (a compose run whose coordinator's session lapsed lost every token at once
        and had them back 0.05 s later: five deaths and recoveries twice over), one that stays
        away is a death, recovered if the token returns."""
        runs = self._runs(name)
        if self._router_lost():  # everybody's token went with it: one router loss
            self._died(name, "liveliness token lost", None)
        elif name in FINISHERS:
            self._suspect(name, "liveliness token lost", None)
        elif runs:
            self._unreachable(name)
        elif runs is None:
            self._suspect(name, "liveliness token lost", None, grace=True)
        else:
            self._suspect(name, "liveliness token lost", None)

    def _runs(self, name: str) -> bool | None:
        """Whether process ``name`` still runs: a child's exit code, a probe's answer (a
        process this coordinator knows by pid), or None (unknown)."""
        child = self.children.get(name)
        if child is not None:
            return child.returncode is None
        probe = self.probes.get(name)
        return probe() if probe is not None else None

    def process_killed(self, name: str, how: str) -> None:
        """A fault killed ``name`` (``kill:``, or ``restart:`` before its new process starts):
        a death now, whatever its token does next (a restart's new token is a recovery)."""
        self.unreachable.pop(name, None)
        self._suspects.pop(name, None)
        self._died(name, how, -signal.SIGKILL)

    def _unreachable(self, name: str) -> None:
        if name in self.unreachable or name in self.deaths:
            return
        wall = time.time()
        self.unreachable[name] = (self.sim_time, wall)
        self._report(f"{name} unreachable at t = {self.sim_time:.2f} s: its liveliness token is "
                     "gone and its process still runs (frozen, starved or cut off?)")
        self.tap.recorder.on_event(Event(t=self.sim_time, source=COORDINATOR_SOURCE,
                                         kind="process_unreachable",
                                         data={"process": name, "wall": wall}))

    def _reachable_again(self, name: str) -> None:
        episode = self.unreachable.pop(name, None)
        if episode is None:
            return
        t, wall = episode
        lost_for = time.time() - wall
        self._report(f"{name} reachable again at t = {self.sim_time:.2f} s after {lost_for:.2f} s")
        self.tap.recorder.on_event(Event(t=self.sim_time, source=COORDINATOR_SOURCE,
                                         kind="process_reachable",
                                         data={"process": name, "lost_at": t,
                                               "lost_for": lost_for, "wall": time.time()}))

    def _poll_children(self) -> None:
        for name, child in self.children.items():
            code = child.returncode
            if code is not None and name not in self.deaths and not self.stopping:
                self.unreachable.pop(name, None)  # it is not unreachable: it is gone
                self._suspect(name, f"exited with code {code}", code)
        for name in [n for n in self.unreachable if n in self.probes]:
            if not self.probes[name]() and not self.stopping:
                del self.unreachable[name]
                self._suspect(name, "its process exited", None)
        now = self._clock()
        for name, (since, how, code, _t) in list(self._suspects.items()):
            if self.sim_done:
                del self._suspects[name]  # the simulator ended the mission: not a death
            elif now - since >= self.config.end_grace:
                del self._suspects[name]
                if code is None and self._runs(name):
                    self._unreachable(name)  # its token only: the process still runs
                elif code == 0 and name == "sim":
                    self._sim_ended()
                else:
                    self._died(name, how, code)

    def _sim_ended(self) -> None:
        """The simulator exited 0 without a ``sim_done`` the coordinator received (a starved
        or cut link lost it, and its last frames): it ended by itself, it did not die."""
        if self.sim_exited:
            return
        self.sim_exited = True
        self._report(f"sim exited 0 at t = {self.sim_time:.2f} s (the frames recorded end "
                     "there): its end and its last frames never reached the coordinator")
        self.tap.recorder.on_event(Event(t=self.sim_time, source=COORDINATOR_SOURCE,
                                         kind="process_exited",
                                         data={"process": "sim", "returncode": 0,
                                               "wall": time.time()}))

    def _suspect(self, name: str, how: str, returncode: int | None,
                 grace: bool = False) -> None:
        """The simulator exits by itself right after ``sim_done``, which may still be in flight:
        its end is a death only if ``sim_done`` has not arrived within ``end_grace``. ``grace``:
        any other process whose token is all there is to go by waits ``end_grace`` too."""
        if name in self.deaths:
            return
        if name not in FINISHERS and not grace:
            self._died(name, how, returncode)
        elif not self.sim_done:
            since, first_how, code, t = self._suspects.get(
                name, (self._clock(), how, returncode, self.sim_time))
            if code is None and returncode is not None:  # prefer the exit code to the token
                first_how, code = how, returncode
            self._suspects[name] = (since, first_how, code, t)

    def _lift_suspicion(self, name: str) -> None:
        """A finisher's token came back within ``end_grace`` while its process still runs: the
        link blinked, nobody died. Seen when the coordinator's own session lapsed (a machine
        starved past a short lease: every token goes and comes back at once); before, the
        simulator was declared dead ``end_grace`` later and the run ended. Reported and
        recorded as ``Event(kind="token_blip")``; an exit code seen meanwhile keeps it a
        suspect."""
        suspect = self._suspects.get(name)
        child = self.children.get(name)
        if (suspect is None or suspect[2] is not None
                or (child is not None and child.returncode is not None)):
            return
        del self._suspects[name]
        since, _how, _code, t = suspect
        gone = self._clock() - since
        self._report(f"{name}'s liveliness token went at t = {t:.2f} s and came back "
                     f"{gone:.2f} s later, its process running: a link blip, not a death")
        self.tap.recorder.on_event(Event(t=self.sim_time, source=COORDINATOR_SOURCE,
                                         kind="token_blip",
                                         data={"process": name, "lost_at": t, "lost_for": gone}))

    def _maybe_recovered(self, name: str) -> None:
        death = self.deaths.get(name)
        child = self.children.get(name)  # None under `tlfleet supervise`: the token is all
        #                                  there is to go by (a restart on hosts, a partition)
        if (death is None or name in ("sim", "router") or self.stopping
                or (child is not None and child.returncode is not None)):
            return
        del self.deaths[name]
        self.recovered.append(death)
        self._report(f"{name} is back at t = {self.sim_time:.2f} s (liveliness token declared "
                     f"again; lost at t = {death.t:.2f} s)")
        event = Event(t=self.sim_time, source=COORDINATOR_SOURCE, kind="process_recovered",
                      data={"process": name, "lost_at": death.t, "how": death.how})
        self.tap.recorder.on_event(event)

    def _link_event(self, kind: str, name: str) -> None:
        """``link_lost`` (a cut process's token went) or ``link_restored``."""
        wall = time.time()
        data: dict[str, object] = {"process": name, "wall": wall}
        if kind == "link_lost":
            self.link_lost[name] = wall
        else:
            data["lost_for"] = wall - self.link_lost.pop(name)
        self._report(f"{kind} {name} at t = {self.sim_time:.2f} s"
                     + (f" (after {data['lost_for']:.2f} s)" if "lost_for" in data else ""))
        self.tap.recorder.on_event(Event(t=self.sim_time, source=COORDINATOR_SOURCE, kind=kind,
                                         data=data))

    def _router_lost(self) -> bool:
        router = self.children.get("router")
        return router is not None and router.returncode is not None

    def _died(self, name: str, how: str, returncode: int | None) -> None:
        if name in self.deaths:
            return
        if name != "router" and self._router_lost():
            # everybody's token goes with the router: one router loss, not N deaths
            router = self.children["router"]
            self._died("router", f"exited with code {router.returncode}", router.returncode)
            return
        death = Death(name, how, self.sim_time, time.time(), returncode)
        self.deaths[name] = death
        fatal = name in ("sim", "router")
        self._report(f"{name} died ({how}) at t = {death.t:.2f} s; "
                     + ("the run cannot go on" if fatal else "the run goes on without it"))
        event = Event(t=death.t, source=COORDINATOR_SOURCE, kind="process_died",
                      data={"process": name, "how": how, "returncode": returncode,
                            "wall": death.wall})
        self.tap.recorder.on_event(event)
        try:
            self.transport.publish(keys.event(self.fleet, "coordinator", 0), encode(event))
        except Exception:  # the router may be gone: recording matters, publishing does not
            logger.exception("cannot publish the process_died event")

    def check(self) -> None:
        """One supervision step: drain messages, process liveliness changes, poll children."""
        self.tap.drain()
        self._process_alive_queue()
        self._poll_children()

    # ----------------------------------------------------------------- phases

    def wait_ready(self, stop: threading.Event | None = None,
                   waiting: Callable[[list[str]], None] | None = None) -> float:
        """Block until every expected token is alive; returns the wall time it took [s].

        ``waiting(missing)`` is called at once and then every ``waiting_period`` while some
        token is missing (``tlfleet supervise`` prints who it still waits for)."""
        started = self._clock()
        deadline = started + self.config.ready_timeout
        next_say = started
        while True:
            self.tap.drain()
            self._process_alive_queue()
            missing = [name for name in self.tokens.values() if name not in self.alive]
            if not missing:
                return self._clock() - started
            if waiting is not None and self._clock() >= next_say:
                waiting(missing)
                next_say += self.config.waiting_period
            for name, child in self.children.items():
                if child.returncode is not None:
                    raise LaunchError(f"{name} exited with code {child.returncode} before the "
                                      f"fleet was ready\n{child.log_tail()}")
            if stop is not None and stop.is_set():
                raise KeyboardInterrupt
            if self._clock() > deadline:
                tails = "\n".join(self.children[n].log_tail() for n in missing
                                  if n in self.children)
                raise LaunchError(f"not up after {self.config.ready_timeout:g} s (no liveliness "
                                  f"token): {', '.join(missing)}" + (f"\n{tails}" if tails else ""))
            time.sleep(0.02)

    def start(self) -> None:
        """Mission start: the recorder starts writing rows, then ``Control(start)`` goes out."""
        self.tap.recorder.start()
        self.transport.publish(keys.control(self.fleet), encode(Control(cmd="start", t0=0.0)))

    def supervise(self, stop: threading.Event | None = None,
                  progress: Callable[[float, float], None] | None = None) -> Outcome:
        """Run until the end of the mission (see the module docstring)."""
        deadline = self._clock() + self.config.wall_timeout
        reason = ""
        while not reason:
            self.check()
            if progress is not None:
                progress(self.sim_time, self.duration)
            if "sim" in self.deaths:
                reason = "sim_died"
            elif self.sim_exited:
                reason = "sim_ended"
            elif "router" in self.deaths:
                reason = "router_lost"
            elif self.sim_done:
                reason = "sim_done"
                # The sim publishes its last frame before sim_done, and zenoh keeps their order,
                # but they come through separate channels: a drain that read the frames' channel
                # just before both arrived saw the event only. Read once more so that the frame
                # (and with it sim_time, the outcome's t_end) is recorded.
                self.tap.drain()
            elif self.sim_time >= self.duration:
                reason = "duration"
            elif stop is not None and stop.is_set():
                reason = "interrupted"
            elif self._clock() > deadline:
                reason = "wall_timeout"
                self._report(f"wall-clock safety timeout ({self.config.wall_timeout:g} s) at "
                             f"t = {self.sim_time:.2f} s: stopping the run")
            else:
                time.sleep(self.config.poll_period)
        return Outcome(reason, self.sim_time, list(self.deaths.values()), self.sim_reached)

    def finish(self, wait_for: Mapping[str, ChildLike] | None = None) -> dict[str, int | None]:
        """Publish ``Control(stop)`` and wait up to ``stop_grace`` for ``wait_for`` (default:
        every child but the router) to exit; returns their exit codes (``None``: still running).
        """
        self.check()
        self.stopping = True
        try:
            self.transport.publish(keys.control(self.fleet),
                                   encode(Control(cmd="stop", t0=self.sim_time)))
        except Exception:
            logger.exception("cannot publish Control(stop)")
        waiting = dict(wait_for) if wait_for is not None else {
            n: c for n, c in self.children.items() if n != "router"}
        deadline = self._clock() + self.config.stop_grace
        while self._clock() < deadline and any(c.returncode is None for c in waiting.values()):
            self.tap.drain()
            time.sleep(0.02)
        self.tap.drain()
        self._process_alive_queue()
        return {n: c.returncode for n, c in waiting.items()}

    def findings(self) -> list[str]:
        """The processes still unreachable when the run ended (the verdict's degradations)."""
        return [f"{name} unreachable from t = {t:.2f} s to the end of the run (token gone, "
                "process running)" for name, (t, _wall) in sorted(self.unreachable.items())]

    def close(self) -> None:
        for handle in self._handles:
            handle.close()
        self._handles.clear()
