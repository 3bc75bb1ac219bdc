"""Faults in a docker compose fleet: the coordinator's side of the handoff (fault-injection notes
§4.1).

In a compose fleet ``tlfleet supervise`` runs in a container: it sees the sim time, so it keeps
scheduling the faults (:class:`tlfleet.coordinator.faults.schedule.FaultScheduler`: the same
``fault_start`` / ``fault_end`` events, findings and report rows as everywhere else), but only
the host can run ``docker network disconnect``, ``docker pause`` or ``docker kill``. The two talk
through a **handoff directory**, the run directory's ``logs/faults`` (``/out/logs/faults`` inside
the coordinator's container, a bind mount of the host's run directory):

* the coordinator (:class:`ComposeActuator`) writes ``req-NNNN.json`` — ``{"id", "action":
  "start"|"end", "kind", "target", "spec", "wall"}`` — atomically (a temporary name, then
  ``os.replace``), and waits at most ``ack_timeout`` [s] wall for ``ack-NNNN.json``;
* the host's executor (:mod:`tlfleet.coordinator.faults.docker_executor`, started by
  ``docker/compose-run.sh`` for the run) writes ``executor.json`` when it starts, runs the docker
  commands of each request in order and answers ``{"id", "ok", "how", "error", "wall", "took"}`` the
  same way.

Why files and not the docker socket mounted into the coordinator: the socket is root on the
host (any container that holds it can start privileged containers), and the image has no docker
client; a bind-mounted directory gives the coordinator exactly one power — asking.

Targets map to compose services (:func:`service_of`): ``agent-3`` → ``robot3``, ``sim``,
``router``. What each fault does (:mod:`tlfleet.coordinator.faults.docker_executor`): cut → ``docker
network disconnect`` / ``connect --alias SERVICE`` of the fleet network; freeze → ``docker pause`` /
``unpause``; kill → ``docker kill``; restart → ``docker kill`` then, after the ack, ``docker
start`` (the same container, command and network alias: the agent starts again from the
beginning of its ``main``, declares its token, and the coordinator sends ``Control(start)``
again once it is back, as :class:`tlfleet.coordinator.faults.schedule.ProcessActuator` does).

While a container's network is cut or it is paused (its session misses its keep-alives, so the
router drops its link after the lease just as for a cut), and for ``CUT_GRACE`` seconds after
the restore, the loss of its liveliness token is a ``link_lost`` and its return a
``link_restored`` (``Supervisor.cut``), not a death. Partitions and namespace hosts are refused
before anything starts (:func:`check_compose_fault`).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tlfleet.agent.model.faults import Fault
from tlfleet.coordinator.faults.on_hosts import CUT_GRACE
from tlfleet.coordinator.faults.schedule import FaultError, StartAgain

HANDOFF_IN = "/out/logs/faults"  # the coordinator's handoff directory inside its container
EXECUTOR_NAME = "executor.json"
ACK_TIMEOUT = 15.0  # [s] wall: a docker command answers in well under a second (§4.1)
KINDS = frozenset({"cut", "freeze", "kill", "restart"})


def service_of(target: str) -> str:
    """The compose service of a fault target: ``agent-3`` → ``robot3``; ``sim``, ``router``."""
    if target in ("sim", "router"):
        return target
    if target.startswith("agent-") and target[6:].isdigit():
        return f"robot{int(target[6:])}"
    raise FaultError(f"{target!r} is not a process of a compose fleet (robot<N>, sim, router)")


def check_compose_fault(fault: Fault) -> None:
    """Reject, before anything starts, what a compose fleet cannot do (module docstring)."""
    spec = fault.text or fault.spec
    if fault.kind == "partition":
        raise FaultError(f"fault {spec}: partitions are not supported in compose: every service "
                         "reaches the others through the one router, so no docker network "
                         "command drops only the traffic between two of them (cut one of them "
                         "instead)")
    if fault.kind not in KINDS:
        raise FaultError(f"fault {spec}: {fault.kind!r} is not a fault of a compose fleet")
    for target in fault.targets:
        if target.startswith("host-"):
            raise FaultError(f"fault {spec}: a compose fleet has no namespace hosts; cut a "
                             "service (robot<N>, sim or router) instead")
        service_of(target)
    if fault.kind == "restart" and fault.target in ("router", "sim"):
        raise FaultError(f"fault {spec}: the run ends when its {fault.target} dies "
                         f"({fault.target}_died), so a restarted {fault.target} would join no "
                         f"run; use kill:{fault.target}")


# ---------------------------------------------------------------------- the file protocol


def write_json_atomically(path: Path, data: dict[str, Any]) -> None:
    """``data`` as ``path``, never half-written: a reader sees the old state or the whole file."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def request_path(directory: Path, number: int) -> Path:
    return Path(directory) / f"req-{number:04d}.json"


def ack_path(directory: Path, number: int) -> Path:
    return Path(directory) / f"ack-{number:04d}.json"


def read_json(path: Path) -> dict[str, Any] | None:
    """The file's object, or None when it is not there (yet)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    if not isinstance(data, dict):
        raise FaultError(f"{path}: not a JSON object")
    return data


def wait_for_executor(directory: Path, timeout: float, sleep: Callable[[float], None] = time.sleep
                      ) -> dict[str, Any]:
    """The executor's ``executor.json``, waited for up to ``timeout`` [s] wall; FaultError
    saying how to start one otherwise."""
    path = Path(directory) / EXECUTOR_NAME
    deadline = time.monotonic() + timeout
    while True:
        found = read_json(path)
        if found is not None:
            return found
        if time.monotonic() >= deadline:
            raise FaultError(f"faults in compose need the host's fault executor, and none "
                             f"announced itself in {directory} within {timeout:g} s: run the "
                             "fleet with docker/compose-run.sh (it starts the executor, "
                             "`tlfleet compose-faults`), not with a bare `docker compose up`")
        sleep(0.05)


class ComposeActuator:
    """A :class:`tlfleet.coordinator.faults.schedule.Actuator` that hands every action to the host's
    executor through ``directory`` (see the module docstring); ``supervisor`` (a
    :class:`tlfleet.coordinator.live.supervisor.Supervisor`) gets the ``cut`` marks, the placeholder
    of a restarted agent and the repeated ``Control(start)``."""

    def __init__(self, directory: Path, supervisor: Any = None,
                 ack_timeout: float = ACK_TIMEOUT, poll: float = 0.01,
                 clock: Callable[[], float] = time.monotonic):
        self.directory = Path(directory)
        self.supervisor = supervisor
        self.ack_timeout = ack_timeout  # [s] wall
        self._poll = poll  # [s] wall between looks for the ack
        self._clock = clock
        self.number = 0
        self.start_again = StartAgain(supervisor)  # re-sends the start to restarted agents

    check = staticmethod(check_compose_fault)

    def _names(self, target: str) -> list[str]:
        """The processes whose token goes when ``target``'s link goes (the router: everyone)."""
        if target == "router" and self.supervisor is not None:
            return [n for n in self.supervisor.tokens.values() if n != "router"]
        return [target]

    def _mark(self, target: str, until: float) -> None:
        if self.supervisor is not None:
            for name in self._names(target):
                self.supervisor.cut[name] = until

    def ask(self, action: str, fault: Fault) -> dict[str, Any]:
        """Write one request, wait for its ack → the ack; FaultError when the executor says it
        failed or does not answer within ``ack_timeout``."""
        self.number += 1
        number = self.number
        self.directory.mkdir(parents=True, exist_ok=True)
        write_json_atomically(request_path(self.directory, number), {
            "id": number, "action": action, "kind": fault.kind, "target": fault.target,
            "service": service_of(fault.target), "spec": fault.text or fault.spec,
            "wall": time.time()})
        deadline = self._clock() + self.ack_timeout
        while True:
            ack = read_json(ack_path(self.directory, number))
            if ack is not None:
                break
            if self._clock() >= deadline:
                raise FaultError(f"the host's fault executor did not answer request {number} "
                                 f"({action} {fault.text or fault.spec}) within "
                                 f"{self.ack_timeout:g} s ({self.directory})")
            time.sleep(self._poll)
        if not ack.get("ok"):
            raise FaultError(f"{action} of {fault.text or fault.spec} failed on the host: "
                             f"{ack.get('error')}")
        return ack

    @staticmethod
    def _record(ack: dict[str, Any]) -> dict[str, Any]:
        record = {"how": ack.get("how"), "docker_wall": ack.get("wall"),
                  "docker_s": ack.get("took")}
        return {**record, "then": ack["then"]} if ack.get("then") else record

    def start(self, fault: Fault) -> dict[str, Any]:
        if fault.kind in ("cut", "freeze"):
            self._mark(fault.target, math.inf)  # before the link goes
        try:
            ack = self.ask("start", fault)
        except FaultError:
            self._mark(fault.target, -1.0)  # nothing was cut: a lost token is a death again
            raise
        if (fault.kind in ("kill", "restart") and self.supervisor is not None
                and fault.target != "router"):
            # the host killed the container and waited for it: a death now, whatever its token
            # does meanwhile (without this the stand-in below made it "unreachable", and the
            # restarted agent's token a return from silence instead of a recovery)
            self.supervisor.process_killed(fault.target,
                                           f"killed by fault {fault.text or fault.spec}")
        if fault.kind == "restart" and self.supervisor is not None:
            self.supervisor.children[fault.target] = RestartedContainer(fault.target)
            self.start_again.add(fault.target)
        return self._record(ack)

    def end(self, fault: Fault) -> dict[str, Any]:
        if fault.kind not in ("cut", "freeze"):
            return {}
        try:
            ack = self.ask("end", fault)
        finally:
            self._mark(fault.target, self._clock() + CUT_GRACE)
        return {"restore": self._record(ack)}

    def poll(self) -> None:
        """A restarted agent waits for ``Control(start)``: once its token is back (the supervisor
        has recorded its recovery), it goes out again (agents already started ignore it) and
        its stand-in leaves the supervisor's children (whose exit it would wait for at the end)."""
        if self.supervisor is None:
            return
        for name in self.start_again.poll():
            if isinstance(self.supervisor.children.get(name), RestartedContainer):
                del self.supervisor.children[name]


class RestartedContainer:
    """The supervisor's stand-in for a container the host restarted: a ``ChildLike`` whose return
    makes the token's return a ``process_recovered``. Its exit code is unknown from inside the
    fleet (``None``), as for every other compose service."""

    def __init__(self, name: str):
        self.name = name

    @property
    def returncode(self) -> int | None:
        return None

    def log_tail(self, lines: int = 15) -> str:
        return f"({self.name} runs in its own container: see logs/{self.name}.log)"
