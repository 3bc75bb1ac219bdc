"""Launcher: children in their own process groups, all of them (grandchildren too) stopped."""

from __future__ import annotations

import os
import signal
import sys
import time

import psutil
import pytest
from tlfleet.coordinator.launch.processes import (
    Launcher,
    LaunchError,
    free_port,
    group_alive,
    wait_for_port,
)

SLEEPER = "import time; print('ready', flush=True); time.sleep(600)"
WITH_GRANDCHILD = (
    "import subprocess, sys, time; "
    "subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(600)']); "
    "print('ready', flush=True); time.sleep(600)")
IGNORES_TERM = (
    "import signal, subprocess, sys, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
    "subprocess.Popen([sys.executable, '-c', 'import signal, time; "
    "signal.signal(signal.SIGTERM, signal.SIG_IGN); time.sleep(600)']); "
    "print('ready', flush=True); time.sleep(600)")


def wait_for_log(child, text: str, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while text not in child.log_path.read_text():
        assert time.monotonic() < deadline, f"{child.name} never printed {text!r}"
        time.sleep(0.01)


def processes_in_groups(pgids: set[int]) -> list[psutil.Process]:
    found = []
    for proc in psutil.process_iter(["pid", "status"]):
        try:
            if os.getpgid(proc.pid) in pgids and proc.info["status"] != psutil.STATUS_ZOMBIE:
                found.append(proc)
        except (ProcessLookupError, psutil.NoSuchProcess):
            continue
    return found


def test_stop_all_leaves_no_process_of_any_group(tmp_path):
    launcher = Launcher(tmp_path / "logs")
    try:
        children = [launcher.start("plain", [sys.executable, "-c", SLEEPER]),
                    launcher.start("parent", [sys.executable, "-c", WITH_GRANDCHILD]),
                    launcher.start("stubborn", [sys.executable, "-c", IGNORES_TERM])]
        for child in children:
            wait_for_log(child, "ready")
        pgids = {c.pid for c in children}
        assert all(os.getpgid(c.pid) == c.pid != os.getpgid(0) for c in children)
        assert len(processes_in_groups(pgids)) == 5  # 3 children + 2 grandchildren
        started = time.monotonic()
        codes = launcher.stop_all(grace=0.5)
        assert time.monotonic() - started < 5.0
        assert codes == {"plain": -signal.SIGTERM, "parent": -signal.SIGTERM,
                         "stubborn": -signal.SIGKILL}
        assert processes_in_groups(pgids) == []
        assert not any(group_alive(p) for p in pgids)
    finally:
        launcher.stop_all(grace=0.1)


def test_leaving_the_block_on_an_error_stops_everything(tmp_path):
    pgids = set()
    with pytest.raises(RuntimeError, match="boom"), Launcher(tmp_path / "logs") as launcher:
        child = launcher.start("parent", [sys.executable, "-c", WITH_GRANDCHILD])
        wait_for_log(child, "ready")
        pgids.add(child.pid)
        raise RuntimeError("boom")
    assert processes_in_groups(pgids) == []


def test_log_tail_and_exit_code(tmp_path):
    with Launcher(tmp_path / "logs") as launcher:
        child = launcher.start("noisy", [sys.executable, "-c",
                                         "import sys; [print(i) for i in range(40)]; "
                                         "print('bad news', file=sys.stderr); sys.exit(4)"])
        assert launcher.wait_all(10.0)
        assert child.returncode == 4
        tail = child.log_tail(3)
        assert "bad news" in tail and "39" in tail and "\n  | 37" not in tail
        assert (tmp_path / "logs" / "noisy.log").exists()


def test_wait_for_port_names_the_child_that_exited(tmp_path):
    with Launcher(tmp_path / "logs") as launcher:
        child = launcher.start("router", [sys.executable, "-c",
                                          "import sys; print('cannot bind'); sys.exit(2)"])
        with pytest.raises(LaunchError, match=r"router exited with code 2[\s\S]*cannot bind"):
            wait_for_port("127.0.0.1", free_port(), 10.0, child)
