"""Helpers for tests that start real processes (on loopback only)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess

from coordinator.launcher import free_port

__all__ = ["free_port", "kill_group"]


def kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL the process group of ``proc`` (started with ``start_new_session=True``) if it is
    still running, reap it and close its pipes."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(5)
    for stream in (proc.stdout, proc.stderr):
        if stream:
            stream.close()
