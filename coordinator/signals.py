"""Ctrl-C handling of the coordinator's commands: SIGINT and SIGTERM set an event for a while.

``tlfleet run`` passes the event to the runner (Ctrl-C ends the mission, and the processes are
still stopped and the files written); ``tlfleet run --viewer`` and ``tlfleet replay --viewer`` wait
on it while the viewer serves. The previous handlers are restored on exit, so a second Ctrl-C after
the block behaves as Python's default again.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager


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
