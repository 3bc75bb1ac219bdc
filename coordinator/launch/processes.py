"""Child processes of a run: start each in its own process group, stop them all by group.

architecture.md §1: the coordinator starts the router, the simulator and the agents with
``subprocess`` (fork + exec, so it is safe even after the coordinator's zenoh session is open —
stack-notes.md §1.7 forbids only a bare ``fork``), each with ``start_new_session=True`` so that a
terminal's Ctrl-C reaches the coordinator alone and the coordinator can signal a child together
with anything the child started. Each child's stdout and stderr go to ``<log_dir>/<name>.log``.

Stopping is SIGTERM to every group, then SIGKILL to the groups still present after a grace period;
:meth:`Launcher.stop_all` returns only when no process of any group is left.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.lifeline import child_environment as tie_to_this_process
from tlfleet.bus.transport import child_environment

logger = logging.getLogger(__name__)

# SCHED_FIFO priority of `--sched fifo` (tlfleet.cli.process_flags): the lowest one
FIFO_PRIORITY = 1


def fifo_permitted() -> bool:
    """Whether children started by this user may run under ``SCHED_FIFO`` at
    :data:`FIFO_PRIORITY` as far as the user and limits tell (root, or a soft ``RLIMIT_RTPRIO``
    that allows it). A container without ``CAP_SYS_NICE`` can still refuse: the child then runs
    under ``SCHED_BATCH`` and says so (``tlfleet.cli.process_flags``)."""
    if not hasattr(os, "SCHED_FIFO") or not hasattr(os, "sched_setscheduler"):
        return False
    if os.geteuid() == 0:
        return True
    import resource

    soft, _hard = resource.getrlimit(resource.RLIMIT_RTPRIO)
    return soft == resource.RLIM_INFINITY or soft >= FIFO_PRIORITY


def _threads() -> list[int]:
    """The ids of this process's threads (Linux sets a scheduling policy per thread)."""
    try:
        return [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:
        return [0]


@contextlib.contextmanager
def share_with_children(children_sched: str, above: bool = False) -> Iterator[bool]:
    """While the children run under ``SCHED_FIFO`` (``children_sched == "fifo"``), put every
    thread of this process (zenoh's receivers, the supervision loop, the recorder) under
    ``SCHED_FIFO`` at the children's priority; afterwards, back to the ordinary policy.

    Why: an ordinary task runs only when no real-time task is runnable, and in lockstep the
    fleet's processes hand the CPU to each other without pause, so the coordinator — which
    records every frame and supervises the run — got no CPU until the run ended (the progress
    bar stopped at 6.6 of 90 s; the recorder fell as far behind; bench/recorder_lag_bench.py
    measures it). At equal FIFO priority no one preempts anyone: a woken coordinator queues
    behind the running child for a few hundred microseconds instead of waiting for the end of the
    run. ``above`` (lockstep): one priority above the children, so that a woken coordinator runs at
    once: at equal priority it queued behind the fleet and the record trailed the simulator by up
    to 3.5 s of sim time (bench/recorder_lag_bench.py). Its work is bounded by the messages it
    records, so the fleet loses little (Scenario 1's lockstep wall time within the noise). Threads
    it starts meanwhile inherit the policy (``SCHED_RESET_ON_FORK`` would reset them too), and so
    would a child it starts (a fault's restart), which sets its own ``--sched`` first thing.
    Yields whether the policy was applied (not for other ``children_sched``, nor where the OS
    refuses: then a warning)."""
    if children_sched != "fifo" or not fifo_permitted():
        yield False
        return
    policy = os.SCHED_FIFO
    priority = FIFO_PRIORITY + 1 if above else FIFO_PRIORITY
    raised: list[int] = []
    try:
        for tid in _threads():
            try:
                os.sched_setscheduler(tid, policy, os.sched_param(priority))
                raised.append(tid)
            except ProcessLookupError:
                continue
            except OSError as exc:
                logger.warning("the coordinator stays under the ordinary policy (%s): its "
                               "recording may fall behind a SCHED_FIFO fleet", exc)
                break
        yield bool(raised)
    finally:
        for tid in _threads():  # threads started meanwhile inherited the policy too
            with contextlib.suppress(OSError):
                os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))


class LaunchError(TlfleetError, RuntimeError):
    """A child that could not be started or did not come up in time."""


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port on ``host`` that was free a moment ago (bind to port 0, read it, release it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


def wait_for_port(host: str, port: int, timeout: float, child: Child | None = None) -> None:
    """Block until ``host:port`` accepts TCP connections; ``LaunchError`` after ``timeout`` [s]
    or as soon as ``child`` (the process meant to listen there) has exited."""
    deadline = time.monotonic() + timeout
    while True:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
            sock.settimeout(0.2)
            if sock.connect_ex((host, port)) == 0:
                return
        if child is not None and child.returncode is not None:
            raise LaunchError(f"{child.name} exited with code {child.returncode} before listening "
                              f"on {host}:{port}\n{child.log_tail()}")
        if time.monotonic() > deadline:
            who = child.name if child is not None else "nobody"
            tail = f"\n{child.log_tail()}" if child is not None else ""
            raise LaunchError(f"{who} did not listen on {host}:{port} within {timeout:g} s{tail}")
        time.sleep(0.02)


def tlfleet_command(*args: str) -> list[str]:
    """argv running ``tlfleet ARGS`` with this interpreter (independent of PATH). ``-P`` keeps the
    working directory off ``sys.path``, so a user's own ``tlfleet.py`` there cannot shadow the
    package in a child."""
    return [sys.executable, "-P", "-m", "tlfleet.cli", *args]


@dataclass
class Child:
    """One started child: its name (``router``, ``sim``, ``agent-3``…), process and log file."""

    name: str
    argv: list[str]
    process: subprocess.Popen
    log_path: Path
    _log: IO[bytes] | None = field(default=None, repr=False)
    started: float = field(default_factory=time.monotonic)  # [s] monotonic clock

    @property
    def pid(self) -> int:
        return self.process.pid

    @property
    def returncode(self) -> int | None:
        """``None`` while running, else the exit code (negative: killed by that signal)."""
        return self.process.poll()

    def log_tail(self, lines: int = 15) -> str:
        """The last ``lines`` lines of the child's log, indented, for error messages."""
        try:
            text = self.log_path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return f"  (no log at {self.log_path})"
        tail = text.rstrip("\n").splitlines()[-lines:]
        if not tail:
            return f"  ({self.log_path} is empty)"
        return "\n".join(f"  | {line}" for line in [f"last lines of {self.log_path}:", *tail])

    def close_log(self) -> None:
        if self._log is not None:
            self._log.close()
            self._log = None


def process_alive(pid: int) -> bool:
    """True while process ``pid`` exists (one we may not signal counts as alive)."""
    return _signal_reaches(os.kill, pid)


def group_alive(pgid: int) -> bool:
    """True while any process of process group ``pgid`` exists (zombies excluded)."""
    if not _signal_reaches(os.killpg, pgid):
        return False
    # killpg(…, 0) succeeds for zombies too: look for a live member.
    return any(state != "Z" for state in _group_states(pgid))


def _signal_reaches(send, target: int) -> bool:
    """Signal 0 to ``target`` by ``send`` (``os.kill`` or ``os.killpg``): False when nothing is
    there."""
    try:
        send(target, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _group_states(pgid: int) -> list[str]:
    states = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        with contextlib.suppress(OSError, IndexError, ValueError):
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            if int(fields[2]) == pgid:  # fields after "(comm)": state ppid pgrp …
                states.append(fields[0])
    return states


class Launcher:
    """Starts children in their own process groups and stops every one of them.

    Use as a context manager: leaving the block (normally, on error or on Ctrl-C) stops all.
    """

    def __init__(self, log_dir: Path, env: dict[str, str] | None = None):
        self.log_dir = Path(log_dir)
        self.children: list[Child] = []
        self._env = env

    def __enter__(self) -> Launcher:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop_all()

    def start(self, name: str, argv: Sequence[str]) -> Child:
        """Start ``argv`` as child ``name`` in a new session, output to ``logs/<name>.log``."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log_path = self.log_dir / f"{name}.log"
        log = open(log_path, "ab", buffering=0)  # noqa: SIM115 - closed in Child.close_log
        env = child_environment(os.environ if self._env is None else self._env)
        tie_to_this_process(env)  # it dies with us, even when we are SIGKILLed
        env.setdefault("PYTHONUNBUFFERED", "1")
        try:
            process = subprocess.Popen(list(argv), stdin=subprocess.DEVNULL, stdout=log,
                                       stderr=subprocess.STDOUT, start_new_session=True, env=env)
        except OSError as exc:
            log.close()
            raise LaunchError(f"cannot start {name} ({' '.join(argv)}): {exc}") from exc
        child = Child(name, list(argv), process, log_path, log)
        self.children.append(child)
        logger.info("started %s (pid %d): %s", name, process.pid, " ".join(argv))
        return child

    def restart(self, name: str) -> Child:
        """Start child ``name`` again with the same argv (the ``restart:`` fault), once
        its process has exited; the new child takes the old one's place (its log goes on in the
        same file)."""
        old = next((c for c in self.children if c.name == name), None)
        if old is None:
            raise LaunchError(f"no child {name!r} to restart")
        index = self.children.index(old)
        if old.process.poll() is None:
            raise LaunchError(f"{name} (pid {old.pid}) still runs: stop it before restarting")
        old.close_log()
        self.children.pop(index)
        try:
            child = self.start(name, old.argv)
        except BaseException:
            self.children.insert(index, old)
            raise
        self.children.remove(child)
        self.children.insert(index, child)
        return child

    def wait_all(self, timeout: float) -> bool:
        """Wait up to ``timeout`` [s] for every child to exit by itself; True when all did."""
        deadline = time.monotonic() + timeout
        for child in self.children:
            remaining = deadline - time.monotonic()
            try:
                child.process.wait(timeout=max(remaining, 0.0))
            except subprocess.TimeoutExpired:
                return False
        return True

    def stop_all(self, grace: float = 3.0) -> dict[str, int | None]:
        """SIGTERM every child's group (newest first), SIGKILL what is left after ``grace`` [s].

        Returns each child's exit code. Afterwards no process of any child's group is left.
        """
        live = [c for c in reversed(self.children) if _reap_and_check(c)]
        for child in live:
            _signal_group(child, signal.SIGTERM)
        deadline = time.monotonic() + grace
        while time.monotonic() < deadline and any(_reap_and_check(c) for c in live):
            time.sleep(0.02)
        for child in live:
            if _reap_and_check(child):
                logger.warning("%s (pid %d) ignored SIGTERM for %g s: SIGKILL", child.name,
                               child.pid, grace)
                _signal_group(child, signal.SIGKILL)
        for child in live:
            kill_deadline = time.monotonic() + 5.0
            while _reap_and_check(child) and time.monotonic() < kill_deadline:
                time.sleep(0.01)
        for child in self.children:
            child.close_log()
        return {c.name: c.returncode for c in self.children}


def _signal_group(child: Child, sig: signal.Signals) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(child.pid, sig)


def _reap_and_check(child: Child) -> bool:
    """True while the child is not reaped or any process of its group is alive.

    Both are needed: a grandchild may outlive the leader, and a multi-threaded leader shows as a
    zombie while its other threads are still being torn down, before ``waitpid`` can reap it.
    """
    return child.process.poll() is None or group_alive(child.pid)
