"""Nothing of a run outlives it: a fleet process ends when its coordinator is gone.

Two mechanisms, for the two ways a process is started:

* **A child of the coordinator** (``tlfleet run`` starts every process itself): the launcher puts
  its own pid in the child's environment (:data:`PARENT_ENV`) and the child, first thing, asks
  Linux to kill it when that parent dies (:func:`die_with_parent`: ``prctl(PR_SET_PDEATHSIG,
  SIGKILL)``). SIGKILL rather than SIGTERM because a child may be stopped (a ``freeze:`` fault
  sends SIGSTOP), and a stopped process never handles a SIGTERM. It also works when the
  coordinator itself is killed with SIGKILL, where no clean-up of the coordinator runs.
* **A process started by someone else** (by hand, on namespace hosts, as a compose service):
  :class:`CoordinatorWatch` watches the coordinator's liveliness token ``alive/coordinator/0``;
  once the token has been seen, its absence for longer than a bound (``--orphan-after``, default
  :data:`ORPHAN_AFTER`) ends the process as a stop would. The bound is longer than anything a
  fault run makes the token blink for (a restarted router: under 1 s; a cut of a few seconds).
"""

from __future__ import annotations

import ctypes
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable, MutableMapping

from tlfleet.bus.transport import Closeable, Transport

logger = logging.getLogger(__name__)

#: environment variable holding the pid of the coordinator that started this process
PARENT_ENV = "TLFLEET_PARENT_PID"
#: [s] wall: how long a process waits for a lost coordinator's token to come back
ORPHAN_AFTER = 10.0
_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def child_environment(env: MutableMapping[str, str]) -> MutableMapping[str, str]:
    """``env`` for a child this process starts and must not outlive it."""
    env[PARENT_ENV] = str(os.getpid())
    return env


def die_with_parent(env: MutableMapping[str, str] | None = None,
                    kill: Callable[[int, int], None] = os.kill) -> bool:
    """If a coordinator started this process (:data:`PARENT_ENV`), have Linux SIGKILL it when
    that coordinator dies; if it is already gone (re-parented before the request took effect),
    kill it now. The variable is removed, so this process's own children are not affected.
    Returns whether the request is in force (False elsewhere than Linux, or without the
    variable)."""
    env = os.environ if env is None else env
    parent = env.pop(PARENT_ENV, None)
    if parent is None or not sys.platform.startswith("linux"):
        return False
    try:
        expected = int(parent)
    except ValueError:
        logger.warning("%s=%r is not a pid: not tied to a parent", PARENT_ENV, parent)
        return False
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
        logger.warning("prctl(PR_SET_PDEATHSIG) failed: errno %d", ctypes.get_errno())
        return False
    if os.getppid() != expected:  # the parent died before the request: nobody will signal us
        logger.error("the coordinator (pid %d) that started this process is gone: exiting",
                     expected)
        kill(os.getpid(), signal.SIGKILL)
    return True


class CoordinatorWatch:
    """Sets ``stop`` when the coordinator's token (``key``: ``alive/coordinator/0`` of the fleet),
    once seen, stays away ``after`` [s] wall.

    The timer runs on a thread of its own (started when the token goes, cancelled when it comes
    back); ``orphaned`` tells afterwards why the process stopped."""

    def __init__(self, transport: Transport, key: str, stop: threading.Event,
                 after: float = ORPHAN_AFTER, source: str = "process"):
        if not after > 0.0:
            raise ValueError(f"--orphan-after must be positive, got {after}")
        self.stop = stop
        self.after = after
        self.source = source
        self.seen = False
        self.orphaned = False
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None
        self._handle: Closeable = transport.watch_alive(key, self._on_token)

    def _on_token(self, _key: str, alive: bool) -> None:
        with self._lock:
            if alive:
                self.seen = True
                if self._timer is not None:
                    self._timer.cancel()
                    self._timer = None
            elif self.seen and self._timer is None:
                self._timer = threading.Timer(self.after, self._expire)
                self._timer.daemon = True
                self._timer.start()

    def _expire(self) -> None:
        with self._lock:
            if self._timer is None:  # came back meanwhile
                return
            self._timer = None
            self.orphaned = True
        logger.error("%s: the coordinator's liveliness token has been gone for %g s: the run "
                     "is over without it, exiting (--orphan-after)", self.source, self.after)
        self.stop.set()

    def close(self) -> None:
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
        self._handle.close()
