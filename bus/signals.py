"""Signal handling of every tlfleet process: SIGINT and SIGTERM set a stop event.

``install_signal_handlers`` is for the long-running processes (router, simulator, agents): the
process's loop sees the event, ends and closes its session in ``finally`` (style.md §6).
``stop_on_signals`` is for the coordinator's commands: ``tlfleet run`` passes the event to the
runner (Ctrl-C ends the mission, and the processes are still stopped and the files written);
``tlfleet run --viewer`` and ``tlfleet replay --viewer`` wait on it while the viewer serves. The
previous handlers are restored on exit, so a second Ctrl-C after the block behaves as Python's
default again.
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

logger = logging.getLogger(__name__)


def install_signal_handlers(stop: threading.Event) -> None:
    """SIGINT and SIGTERM set ``stop``; the process's loop then ends and closes its session."""

    def handler(signum: int, _frame: Any) -> None:
        logger.info("signal %s: stopping", signal.Signals(signum).name)
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


@contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """An event set by SIGINT or SIGTERM inside the ``with`` block (main thread only)."""
    stop = threading.Event()
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    for sig in previous:
        signal.signal(sig, lambda *_: stop.set())
    try:
        yield stop
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def wait_for_signal(stop: threading.Event, poll: float = 0.5) -> None:
    """Block until ``stop`` is set, waking every ``poll`` [s] so signals are handled promptly."""
    while not stop.wait(poll):
        pass
