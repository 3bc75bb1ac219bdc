"""Scheduled faults, driven by the sim time the coordinator sees.

:class:`FaultScheduler` is polled once per supervision step (every ``poll_period``, 50 ms) with
the newest frame time; a fault starts at the first poll where sim time ≥ its ``at`` and, when it
has a duration, ends at the first poll ``duration`` seconds of **wall** time later (a cut or a
freeze lasts wall time: in lockstep the fleet's sim time may stand still meanwhile). Each start
and end is recorded as ``Event(fault_start)`` / ``Event(fault_end)`` in ``events.jsonl`` with the
sim time and the wall time (``time.time()``); :meth:`FaultScheduler.close` ends every fault
still active (a run that ends mid-fault is restored before anything is stopped), and
:meth:`FaultScheduler.findings` words each fault for the verdict and the report.

What a fault does is an :class:`Actuator`'s business: :class:`ProcessActuator` signals the
process groups of the children a :class:`tlfleet.coordinator.launch.processes.Launcher` started
(freeze: SIGSTOP / SIGCONT of the group; kill: SIGKILL; restart: SIGKILL, wait until the group is
gone, start the same argv again and hand the new child to the supervisor); link cuts need namespace
hosts (:mod:`tlfleet.coordinator.faults.on_hosts`).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import signal
import time
from collections.abc import Callable, Iterable, MutableMapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from tlfleet.agent.model.faults import Fault
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Control, Event
from tlfleet.coordinator.launch.processes import Child, Launcher, group_alive

logger = logging.getLogger(__name__)

SOURCE = "coordinator"


class FaultError(TlfleetError, RuntimeError):
    """A fault that cannot be injected in this run (wrong target, no namespaces, …)."""


class Actuator(Protocol):
    """Does and undoes faults; ``check`` rejects, before the run, what it cannot do."""

    def check(self, fault: Fault) -> None: ...

    def start(self, fault: Fault) -> dict[str, Any]: ...

    def end(self, fault: Fault) -> dict[str, Any]: ...


@dataclass
class _Active:
    fault: Fault
    wall: float  # [s] monotonic clock at the start
    record: dict[str, Any] = field(default_factory=dict)


class FaultScheduler:
    """Starts and ends ``faults`` as sim time and wall time go (see the module docstring)."""

    def __init__(self, faults: Iterable[Fault], actuator: Actuator,
                 record: Callable[[Event], None], report: Callable[[str], None] | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 wall: Callable[[], float] = time.time):
        self.pending = sorted(faults, key=lambda f: f.at)
        self.actuator = actuator
        self._record = record
        self._report = report or (lambda text: logger.warning("%s", text))
        self._clock = clock
        self._wall = wall
        self.active: list[_Active] = []
        self.log: list[dict[str, Any]] = []  # one per fault, in start order
        self.sim_time = 0.0
        for fault in self.pending:
            actuator.check(fault)

    def progress(self, inner: Callable[[float, float], None] | None
                 ) -> Callable[[float, float], None]:
        """A supervision progress callback that polls this scheduler, then calls ``inner``."""

        def step(t: float, duration: float) -> None:
            self.poll(t)
            if inner is not None:
                inner(t, duration)

        return step

    def poll(self, sim_time: float) -> None:
        self.sim_time = max(self.sim_time, sim_time)
        if hasattr(self.actuator, "poll"):
            self.actuator.poll()
        now = self._clock()
        for active in list(self.active):
            if now - active.wall >= (active.fault.duration or 0.0):
                self._end(active)
        while self.pending and self.pending[0].at <= self.sim_time:
            self._start(self.pending.pop(0))

    def close(self) -> None:
        """End every active fault now (the run is over); pending ones never start, each
        recorded as ``Event(fault_skipped)`` with the reason (the report's fault table lists
        it)."""
        for active in list(self.active):
            self._end(active, early=True)
        for fault in self.pending:
            reason = (f"the run ended at t = {self.sim_time:.2f} s, before the fault's time "
                      f"t = {fault.at:g} s")
            self.log.append({**fault.as_dict(), "started": False, "reason": reason})
            self._event("fault_skipped", fault, {"reason": reason})
        self.pending.clear()

    def findings(self) -> list[str]:
        """One line per fault for the verdict (a run with faults is never *clean*)."""
        out = []
        for entry in self.log:
            if not entry.get("started"):
                out.append(f"fault {entry['spec']} skipped: {entry.get('reason', 'never due')}")
                continue
            end = entry.get("end_t")
            lasted = entry.get("lasted")
            tail = (f", ended at t = {end:.2f} s after {lasted:.2f} s wall"
                    if end is not None and lasted is not None else "")
            error = f" ({entry['error']})" if entry.get("error") else ""
            out.append(f"fault {entry['spec']} injected at t = {entry['start_t']:.2f} s{tail}"
                       f"{error}")
        return out

    # ------------------------------------------------------------------ internals

    def _event(self, event_kind: str, fault: Fault, data: dict[str, Any]) -> None:
        payload = {**fault.as_dict(), "wall": self._wall(), **data}
        self._record(Event(self.sim_time, SOURCE, event_kind, payload))

    def _start(self, fault: Fault) -> None:
        entry: dict[str, Any] = {**fault.as_dict(), "started": True, "start_t": self.sim_time,
                                 "start_wall": self._wall()}
        self.log.append(entry)
        try:
            entry.update(self.actuator.start(fault))
        except Exception as exc:  # a fault that fails is reported, the run goes on
            logger.exception("fault %s failed", fault.spec)
            entry["error"] = str(exc)
        self._report(f"fault {entry['spec']} at t = {self.sim_time:.2f} s"
                     + (f" FAILED: {entry['error']}" if "error" in entry else ""))
        # stamped with the wall time it began: a kill's death is recorded while the actuator
        # works, before this event, and its detection delay is measured from here
        self._event("fault_start", fault, {**{k: v for k, v in entry.items()
                                              if k not in ("started", "start_t", "start_wall")},
                                           "wall": entry["start_wall"]})
        active = _Active(fault, self._clock(), entry)
        if fault.duration is None or "error" in entry:  # kill / restart: over once done
            self._finish(active, {})
        else:
            self.active.append(active)

    def _end(self, active: _Active, early: bool = False) -> None:
        self.active.remove(active)
        try:
            done = self.actuator.end(active.fault)
        except Exception as exc:
            logger.exception("ending fault %s failed", active.fault.spec)
            done = {"error": f"ending it failed: {exc}"}
        if early:
            done["early"] = True
        self._finish(active, done)
        self._report(f"fault {active.record['spec']} ended at t = {self.sim_time:.2f} s")

    def _finish(self, active: _Active, done: dict[str, Any]) -> None:
        lasted = self._clock() - active.wall
        active.record.update(done, end_t=self.sim_time, end_wall=self._wall(), lasted=lasted)
        self._event("fault_end", active.fault,
                    {"lasted": lasted, "start_t": active.record["start_t"], **done})


# ---------------------------------------------------------------------- process faults


PROCESS_KINDS = frozenset({"freeze", "kill", "restart"})


def check_restartable(fault: Fault, router: bool = False) -> None:
    """Agents can be restarted, and (``router``: where the actuator started the router itself)
    the router; not the simulator: the run ends when it dies."""
    if fault.kind != "restart":
        return
    if fault.target == "sim" or (fault.target == "router" and not router):
        where = "" if fault.target == "sim" else " here (only a fleet on loopback that tlfleet " \
            "run started restarts its router)"
        raise FaultError(f"fault {fault.text or fault.spec}: the run ends when its "
                         f"{fault.target} dies ({fault.target}_died), so a restarted "
                         f"{fault.target} would join no run{where}; use kill:{fault.target}")


ROUTER_RESTART_GRACE = 5.0  # [s] wall after a router restart during which every lost token is
#                             a link loss (the clients reconnect within zenoh's retry period)


class StartAgain:
    """A restarted agent waits for ``Control(start)`` (realtime frames list nobody as due): once
    its token is back at ``supervisor`` (a :class:`tlfleet.coordinator.live.supervisor.Supervisor`),
    the start goes out again (agents already started ignore it)."""

    def __init__(self, supervisor: Any = None):
        self.supervisor = supervisor
        self.awaiting: set[str] = set()  # restarted agents whose token is not back yet

    def add(self, name: str) -> None:
        if name.startswith("agent-"):
            self.awaiting.add(name)

    def poll(self) -> set[str]:
        """Send ``Control(start)`` again if an awaited agent's token is back → those agents
        (they leave ``awaiting``)."""
        supervisor = self.supervisor
        if supervisor is None or not self.awaiting:
            return set()
        back = {name for name in self.awaiting if name in supervisor.alive}
        if back:
            self.awaiting -= back
            supervisor.transport.publish(keys.control(supervisor.fleet),
                                         encode(Control(cmd="start", t0=0.0)))
            logger.info("Control(start) again for the restarted %s", ", ".join(sorted(back)))
        return back


def kill_group(pid: int, wait: float, poll: Callable[[], bool] | None = None) -> None:
    """SIGKILL process group ``pid`` (a stopped, frozen group dies too) and wait up to ``wait``
    [s] wall until none of it is left (and ``poll()``, when given, says the leader is reaped);
    :class:`FaultError` when it is not gone by then."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(pid, signal.SIGKILL)
    deadline = time.monotonic() + wait
    while (group_alive(pid) or (poll is not None and not poll())) \
            and time.monotonic() < deadline:
        time.sleep(0.005)
    if group_alive(pid) or (poll is not None and not poll()):
        raise FaultError(f"pid {pid} did not die within {wait:g} s")


class ProcessActuator:
    """Freeze, kill and restart the children of ``launcher``; ``children`` is the supervisor's
    map (a restarted child replaces the old one there, so its token's return is a recovery).
    Link cuts and partitions are rejected: they need namespace hosts. ``restart:router`` kills
    the router and starts it again on the same endpoint; every process's token goes and comes
    back with it, which the supervisor reports as link losses and restorations
    (``ROUTER_RESTART_GRACE``), not deaths."""

    def __init__(self, launcher: Launcher, children: MutableMapping[str, Any],
                 kill_wait: float = 5.0, supervisor: Any = None):
        self.launcher = launcher
        self.children = children
        self.kill_wait = kill_wait  # [s] wall, for a killed group to be gone
        # tlfleet.coordinator.live.supervisor.Supervisor (None in unit tests)
        self.supervisor = supervisor
        self.start_again = StartAgain(supervisor)  # re-sends the start to restarted agents

    def poll(self) -> None:
        self.start_again.poll()

    @staticmethod
    def check_all(faults: Iterable[Fault]) -> None:
        for fault in faults:
            ProcessActuator.check(fault)

    @staticmethod
    def check(fault: Fault) -> None:
        if fault.kind not in PROCESS_KINDS:
            raise FaultError(f"fault {fault.text or fault.spec}: {fault.kind} drops links, which "
                             "needs namespace hosts (--hosts N, root, iproute2 and nftables)")
        check_restartable(fault, router=True)

    def _child(self, name: str) -> Child:
        for child in reversed(self.launcher.children):
            if child.name == name:
                return child
        raise FaultError(f"no child process {name!r} in this run")

    def _signal(self, name: str, sig: signal.Signals) -> int:
        child = self._child(name)
        os.killpg(child.pid, sig)
        return child.pid

    def start(self, fault: Fault) -> dict[str, Any]:
        name = fault.target
        if fault.kind == "freeze":
            return {"pid": self._signal(name, signal.SIGSTOP)}
        if fault.kind == "restart" and name == "router":
            self._mark_everyone(math.inf)
        pid = self._kill(name)
        if self.supervisor is not None and name != "router":
            self.supervisor.process_killed(name, f"killed by fault {fault.text or fault.spec}")
        if fault.kind == "kill":
            return {"pid": pid}
        child = self.launcher.restart(name)
        if name == "router":
            self._mark_everyone(time.monotonic() + ROUTER_RESTART_GRACE)
        self.children[name] = child
        self.start_again.add(name)
        return {"pid": pid, "new_pid": child.pid}

    def _mark_everyone(self, until: float) -> None:
        """While the router restarts, a lost token is a link loss (``Supervisor.cut``)."""
        if self.supervisor is not None:
            for name in self.supervisor.tokens.values():
                self.supervisor.cut[name] = until

    def end(self, fault: Fault) -> dict[str, Any]:
        if fault.kind == "freeze":
            with contextlib.suppress(ProcessLookupError):
                self._signal(fault.target, signal.SIGCONT)
        return {}

    def _kill(self, name: str) -> int:
        child = self._child(name)
        try:
            kill_group(child.pid, self.kill_wait, lambda: child.process.poll() is not None)
        except FaultError:
            raise FaultError(f"{name} (pid {child.pid}) did not die within "
                             f"{self.kill_wait:g} s") from None
        return child.pid
