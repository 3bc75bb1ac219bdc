"""The host's side of faults in a compose fleet: the executor that runs the docker commands the
coordinator asks for (fault-injection notes §4.1; the handoff protocol
is :mod:`tlfleet.coordinator.faults.handoff`).

``tlfleet compose-faults --dir RUN/logs/faults --project P`` (started in the background by
``docker/compose-run.sh`` when the compose file carries faults, stopped by its clean-up) writes
``executor.json``, then every ``POLL`` seconds handles the new ``req-NNNN.json`` in order and
answers each with ``ack-NNNN.json``. The containers are found by compose's own labels
(``com.docker.compose.project`` / ``.service``, the same for Compose v1 and v2), the fleet network
by ``com.docker.compose.network=fleet``:

=======  ======================================  ===========================================
fault    start                                   end
=======  ======================================  ===========================================
cut      ``docker network disconnect NET C``     ``docker network connect --alias S
                                                 [--ip A] NET C``
freeze   ``docker pause C``                      ``docker unpause C``
kill     ``docker kill C`` (SIGKILL)             —
restart  ``docker kill C``, ``docker wait C``;   —
         after the ack ``docker start C``
=======  ======================================  ===========================================

A restart is acknowledged once the container is dead, and started again after the ack: the
coordinator waits for the ack in its supervision loop, and ``docker start`` took 1.8 s at load 11
(that long the loop would not notice the death).

(``--alias S``: a container reconnected to a network loses its service name otherwise; ``--ip
A``: the address compose fixed for it, read by ``docker inspect`` before the cut — the router's,
which the clients' hosts file names, :mod:`tlfleet.coordinator.compose`; without it a reconnected
router would get another address.) Every docker command has a timeout (``COMMAND_TIMEOUT``); the
executor ends when ``--parent`` (the script that started it) is gone or after ``--max-wall``
seconds, and on the way out undoes what is still in effect (reconnects what it cut, unpauses
what it paused). Safety (notes §1): it touches only containers and the network of
project P, by id; nothing of the host's network.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tlfleet.coordinator.faults.handoff import (
    EXECUTOR_NAME,
    ack_path,
    read_json,
    request_path,
    write_json_atomically,
)
from tlfleet.coordinator.faults.schedule import FaultError
from tlfleet.coordinator.launch.processes import process_alive

logger = logging.getLogger(__name__)

POLL = 0.01  # [s] wall between looks at the handoff directory
COMMAND_TIMEOUT = 30.0  # [s] wall, one docker command
NETWORK = "fleet"  # the compose file's one network (tlfleet.coordinator.compose)

Run = Callable[[Sequence[str]], str]  # runs an argv, returns its stdout; FaultError on failure


def docker(argv: Sequence[str]) -> str:
    """Run ``docker ARGV`` (bounded); its stdout, or FaultError with its stderr."""
    try:
        done = subprocess.run(["docker", *argv], capture_output=True, text=True,
                              timeout=COMMAND_TIMEOUT)
    except subprocess.TimeoutExpired as exc:
        raise FaultError(f"docker {' '.join(argv)}: no answer within {COMMAND_TIMEOUT:g} s") \
            from exc
    if done.returncode != 0:
        raise FaultError(f"docker {' '.join(argv)}: {done.stderr.strip() or done.returncode}")
    return done.stdout


@dataclass
class Executor:
    """Finds project ``project``'s containers and runs the faults' docker commands (module
    docstring); ``run`` is :func:`docker` or a test double."""

    project: str
    run: Run = docker
    network: str | None = None  # the fleet network's name, found on first use
    containers: dict[str, str] = field(default_factory=dict)  # service -> container id
    cut: set[str] = field(default_factory=set)  # services disconnected now
    paused: set[str] = field(default_factory=set)  # services paused now
    fixed: dict[str, str | None] = field(default_factory=dict)  # a cut service's fixed address

    def fixed_address(self, container: str, net: str) -> str | None:
        """The address compose fixed for ``container`` on ``net`` (``ipv4_address``: the
        router's in a file with faults, which the clients' hosts file names), or None."""
        text = self.run(["inspect", "--format", "{{json .NetworkSettings.Networks}}",
                         container]).strip()
        try:
            ipam = (json.loads(text or "{}").get(net) or {}).get("IPAMConfig") or {}
        except (ValueError, AttributeError) as exc:
            raise FaultError(f"docker inspect {container}: unreadable networks {text[:200]!r}") \
                from exc
        return ipam.get("IPv4Address") or None

    def container(self, service: str) -> str:
        if service not in self.containers:
            found = self.run(["ps", "-aq", "--filter",
                              f"label=com.docker.compose.project={self.project}", "--filter",
                              f"label=com.docker.compose.service={service}"]).split()
            if len(found) != 1:
                raise FaultError(f"project {self.project}: {len(found)} containers of service "
                                 f"{service!r} (expected 1)")
            self.containers[service] = found[0]
        return self.containers[service]

    def fleet_network(self) -> str:
        if self.network is None:
            found = self.run(["network", "ls", "--format", "{{.Name}}", "--filter",
                              f"label=com.docker.compose.project={self.project}", "--filter",
                              f"label=com.docker.compose.network={NETWORK}"]).split()
            if len(found) != 1:
                raise FaultError(f"project {self.project}: {len(found)} networks named "
                                 f"{NETWORK!r} (expected 1)")
            self.network = found[0]
        return self.network

    def commands(self, action: str, kind: str, service: str) -> list[list[str]]:
        """The docker argvs of one request (see the table of the module docstring)."""
        c = self.container(service)
        if kind == "cut":
            net = self.fleet_network()
            if action == "start":
                self.fixed[service] = self.fixed_address(c, net)
                return [["network", "disconnect", net, c]]
            address = self.fixed.get(service)
            return [["network", "connect", "--alias", service,
                     *(["--ip", address] if address else []), net, c]]
        if kind == "freeze":
            return [["pause" if action == "start" else "unpause", c]]
        if action != "start":
            return []
        if kind == "kill":
            return [["kill", c]]
        if kind == "restart":
            return [["kill", c], ["wait", c]]
        raise FaultError(f"{kind!r} is not a fault the executor knows")

    def after_ack(self, action: str, kind: str, service: str) -> list[list[str]]:
        """The docker argvs run once the request is acknowledged (a restart's start)."""
        return [["start", self.container(service)]] if (action, kind) == ("start", "restart") \
            else []

    def then(self, request: dict[str, Any]) -> str | None:
        """Run :meth:`after_ack` of an acknowledged request → what failed, or None."""
        try:
            for argv in self.after_ack(*(str(request[k]) for k in ("action", "kind",
                                                                   "service"))):
                self.run(argv)
        except (FaultError, KeyError) as exc:
            return str(exc)
        return None

    def handle(self, request: dict[str, Any]) -> dict[str, Any]:
        """One request → its ack (never raises: a failure is ``ok: false`` with the reason)."""
        began = time.monotonic()
        how: list[str] = []
        try:
            action, kind, service = (str(request[k]) for k in ("action", "kind", "service"))
            if action not in ("start", "end"):
                raise FaultError(f"action {action!r}: expected start or end")
            for argv in self.commands(action, kind, service):
                how.append("docker " + " ".join(argv))
                self.run(argv)
            book = {"cut": self.cut, "freeze": self.paused}.get(kind)
            if book is not None:
                (book.add if action == "start" else book.discard)(service)
            ok, error = True, None
        except (FaultError, KeyError) as exc:
            ok, error = False, str(exc)
        then = [] if not ok else ["docker " + " ".join(argv) for argv in
                                  self.after_ack(action, kind, service)]
        return {"id": request.get("id"), "ok": ok, "error": error, "how": "; ".join(how),
                "then": "; ".join(then), "wall": time.time(), "took": time.monotonic() - began}

    def undo(self) -> list[str]:
        """Reconnect every service still cut, unpause every one still paused → what failed."""
        failed = []
        for kind, book in (("cut", self.cut), ("freeze", self.paused)):
            for service in sorted(book):
                ack = self.handle({"action": "end", "kind": kind, "service": service})
                if not ack["ok"]:
                    failed.append(ack["error"])
        return failed


def serve(directory: Path, executor: Executor, *, parent: int | None = None,
          max_wall: float = 3600.0, poll: float = POLL,
          stop: Callable[[], bool] = lambda: False) -> int:
    """Announce, then answer requests until ``parent`` is gone, ``max_wall`` [s] passed or
    ``stop()``; undo what is still in effect → number of requests handled."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    write_json_atomically(directory / EXECUTOR_NAME, {
        "pid": os.getpid(), "project": executor.project, "started": time.time()})
    deadline = time.monotonic() + max_wall
    number = 1
    try:
        while time.monotonic() < deadline and not stop() and \
                (parent is None or process_alive(parent)):
            request = read_json(request_path(directory, number))
            if request is None:
                time.sleep(poll)
                continue
            ack = executor.handle(request)
            (logger.info if ack["ok"] else logger.error)("request %d: %s", number,
                                                         ack["how"] or ack["error"])
            write_json_atomically(ack_path(directory, number), ack)
            if ack["ok"] and ack["then"]:
                failed = executor.then(request)
                (logger.error if failed else logger.info)("request %d, after the ack: %s",
                                                          number, failed or ack["then"])
            number += 1
    finally:
        with contextlib.suppress(Exception):
            for error in executor.undo():
                logger.error("undoing a fault on the way out: %s", error)
    return number - 1
