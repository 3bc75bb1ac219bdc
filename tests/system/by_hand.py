"""Helpers of the by-hand fleet tests: the processes a user starts in their own terminals.

:func:`start_by_hand` starts ``tlfleet router``, ``tlfleet sim`` and one ``tlfleet agent`` per
robot with the command lines of the README ("Processes can also be started by hand"), each in its
own process group (:class:`tlfleet.coordinator.launch.processes.Launcher`: stopping it leaves
nothing behind);
``prefix`` puts each one inside something else (``ip netns exec NS``).
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from tlfleet.agent.scenario import load_scenario
from tlfleet.coordinator.launch.processes import Launcher, tlfleet_command, wait_for_port

Prefix = Callable[[str], Sequence[str]]  # process name -> argv prefix


def start_by_hand(launcher: Launcher, scenario: Path, listen: str, connect: str | None = None,
                  *, prefix: Prefix = lambda name: (), sim_args: Sequence[str] = (),
                  agent_args: Sequence[str] = (), wait_host: str | None = "127.0.0.1",
                  common: Sequence[str] | Callable[[str], Sequence[str]] = ()) -> None:
    """Router listening on ``listen``; sim and agents connecting to ``connect`` (default the
    same endpoint); ``common``: flags every process gets (``--secure DIR``), or a function of
    the process's name giving its own."""
    fleet = load_scenario(scenario).fleet
    flags = common if callable(common) else (lambda _name, given=tuple(common): given)
    connect = connect or listen
    router = launcher.start("router", [*prefix("router"), *tlfleet_command(
        "router", "--fleet", fleet, "--listen", listen, *flags("router"))])
    if wait_host is not None:
        wait_for_port(wait_host, int(listen.rsplit(":", 1)[1]), 15.0, router)
    launcher.start("sim", [*prefix("sim"), *tlfleet_command(
        "sim", str(scenario), "--connect", connect, *sim_args, *flags("sim"))])
    for robot in sorted(load_scenario(scenario).robot_ids):
        name = f"agent-{robot}"
        launcher.start(name, [*prefix(name), *tlfleet_command(
            "agent", str(scenario), "--robot", str(robot), "--connect", connect, *agent_args,
            *flags(name))])


def supervise(scenario: Path, connect: str, out: Path, *args: str, prefix: Sequence[str] = (),
              timeout: float = 400.0) -> subprocess.CompletedProcess:
    """``tlfleet supervise`` as a user runs it (a process of its own), output captured."""
    return subprocess.run([*prefix, sys.executable, "-m", "tlfleet.cli", "supervise", str(scenario),
                           "--connect", connect, "--out", str(out), *args],
                          capture_output=True, text=True, timeout=timeout)


def wait_until(predicate: Callable[[], bool], timeout: float, period: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period)
    return predicate()
