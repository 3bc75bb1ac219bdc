"""Exception-safe, time-bounded clean-up of a run.

``tlfleet run`` must end whatever the fleet did: every clean-up step (drain and close the recorder
tap, close the supervisor and the zenoh session, stop every child's process group, close the
files, rewrite ``run.json``) runs in its own guard, so one failing step never skips the next —
on main a decode error inside the tap's final drain skipped closing the session and stopping the
children, and ``tlfleet run`` hung. A step that may block (closing a zenoh session whose router
is gone) runs in a daemon thread and is abandoned after its time bound; errors and timeouts are
logged and kept in :attr:`Cleanup.errors` for ``run.json``.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

logger = logging.getLogger(__name__)


class Cleanup:
    """Runs clean-up steps, each guarded (see the module docstring)."""

    def __init__(self) -> None:
        self.errors: list[str] = []

    def step(self, name: str, fn: Callable[[], Any], *, timeout: float | None = None) -> Any:
        """Run ``fn``; on an exception (or after ``timeout`` [s] wall, in a thread) log it,
        remember it and return None."""
        if timeout is None:
            try:
                return fn()
            except BaseException as exc:  # KeyboardInterrupt included: the next step still runs
                self._failed(name, f"{type(exc).__name__}: {exc}")
                return None
        result: list[Any] = []
        failure: list[BaseException] = []

        def target() -> None:
            try:
                result.append(fn())
            except BaseException as exc:
                failure.append(exc)

        thread = threading.Thread(target=target, name=f"cleanup-{name}", daemon=True)
        thread.start()
        thread.join(timeout)
        if thread.is_alive():
            self._failed(name, f"still running after {timeout:g} s: abandoned")
            return None
        if failure:
            self._failed(name, f"{type(failure[0]).__name__}: {failure[0]}")
            return None
        return result[0] if result else None

    def _failed(self, name: str, what: str) -> None:
        logger.error("clean-up step %r failed: %s", name, what)
        self.errors.append(f"{name}: {what}"[:300])
