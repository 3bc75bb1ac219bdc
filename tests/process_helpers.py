"""Helpers for tests that start real processes (on loopback only)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess

import psutil
from tlfleet.coordinator.launch.processes import free_port

__all__ = ["free_port", "kill_group", "processes_mentioning"]


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


def processes_mentioning(marker: str) -> list[psutil.Process]:
    """Live (non-zombie) processes whose command line mentions ``marker``, e.g. a scenario path
    unique to one test."""
    found = []
    for proc in psutil.process_iter(["cmdline", "status"]):
        try:
            if proc.info["status"] != psutil.STATUS_ZOMBIE and \
                    any(marker in part for part in proc.info["cmdline"] or ()):
                found.append(proc)
        except psutil.NoSuchProcess:
            continue
    return found
