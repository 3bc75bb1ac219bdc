"""What the ROS tests and ``bench/hw_bench.py`` share: an isolated ROS world, lab files and fake
robots for a scenario, and the commands the fake robots received.

**Isolation.** :func:`isolated_argv` wraps a command in a fresh network namespace that has only
``lo`` and a private tmpfs on ``/dev/shm`` (``unshare --net --mount``): Fast DDS keeps its shared
memory there, which a network namespace alone does not isolate, and a killed process's segments
vanish with the mount. Inside, every ROS process runs with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and the test's own ``ROS_DOMAIN_ID``. Needs root.

Each case runs as one process tree inside the namespace: :mod:`ros_case` starts the fake robots,
the bridge or a whole ``tlfleet run --hardware``, and writes its findings as JSON for the test.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterable
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
FAKE_ROBOTS = HERE / "fake_robots.py"
CASE = HERE / "ros_case.py"


def missing_for_ros() -> str | None:
    """Why the ROS tests cannot run here (None: they can)."""
    if importlib.util.find_spec("rclpy") is None:
        return "needs rclpy: the tlfleet[ros2] extra (make .venv/.installed-ros2)"
    if os.geteuid() != 0:
        return "needs root for a network namespace with a private /dev/shm"
    for tool, package in (("unshare", "util-linux"), ("ip", "iproute2")):
        if shutil.which(tool) is None:
            return f"needs `{tool}` (Debian package {package})"
    return None


def need_ros() -> None:
    """Skip without rclpy (the tlfleet[ros2] extra) or without root for the namespace; the
    suite's conftest turns the skip into a failure under TLFLEET_REQUIRE_SYSTEM=1."""
    reason = missing_for_ros()
    if reason is not None:
        pytest.skip(reason)


def isolated_argv(argv: list[str], shm_mb: int = 256) -> list[str]:
    """``argv`` run in a new network namespace (only ``lo``, up) with a private ``/dev/shm``,
    under ``SCHED_FIFO`` priority 1 where ``chrt`` is there (inherited by every process of the
    case): as ``tlfleet run`` schedules a fleet where it may, so that on a loaded machine the
    realtime bridge, the fake robots (on their own computers in a lab) and the case's stand-in
    agents are woken on time, as the realtime tests of the simulator are."""
    script = (f"mount -t tmpfs -o size={shm_mb}m tlfleet-shm /dev/shm && ip link set lo up && "
              'exec "$@"')
    fifo = ["chrt", "-f", "1"] if shutil.which("chrt") else []
    return [*fifo, "unshare", "--net", "--mount", "--propagation", "private", "--", "sh", "-c",
            script, "sh", *argv]


def ros_env(domain: int) -> dict[str, str]:
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               PYTHONUNBUFFERED="1")
    env.pop("ROS_STATIC_PEERS", None)
    return env


_domains = iter(range(20 + (os.getpid() % 50) * 3, 233))


def unique_domain() -> int:
    """A ROS domain id no other test of this session uses (the namespaces isolate them anyway)."""
    return next(_domains)


class CaseRun:
    """One :mod:`ros_case` case running isolated in the background (:func:`start_case`)."""

    def __init__(self, case: dict, tmp: Path, timeout: float):
        tmp.mkdir(parents=True, exist_ok=True)
        self.tmp = tmp
        spec = tmp / "case.json"
        spec.write_text(json.dumps(case))
        self.log = tmp / "case.log"
        self.deadline = time.monotonic() + timeout
        self.timeout = timeout
        with open(self.log, "w", encoding="utf-8") as out:
            self.proc = subprocess.Popen(isolated_argv([sys.executable, str(CASE), str(spec)]),
                                         stdout=out, stderr=subprocess.STDOUT,
                                         env=ros_env(int(case["domain_id"])), cwd=str(ROOT))

    def result(self) -> dict:
        """Wait for the case (until its timeout); its JSON result (``AssertionError`` with its
        log when it failed or timed out)."""
        try:
            self.proc.wait(timeout=max(0.0, self.deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            self.stop()
            raise AssertionError(f"case timed out after {self.timeout} s:\n"
                                 f"{_tail(self.log)}") from None
        result_path = self.tmp / "result.json"
        if self.proc.returncode != 0 or not result_path.exists():
            raise AssertionError(f"case exited {self.proc.returncode}:\n{_tail(self.log)}")
        return json.loads(result_path.read_text())

    def stop(self) -> None:
        """End the case early: SIGTERM (ros_case stops its processes), then SIGKILL."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def start_case(case: dict, tmp: Path, timeout: float) -> CaseRun:
    """Start one :mod:`ros_case` case isolated, in the background."""
    return CaseRun(case, tmp, timeout)


def run_case(case: dict, tmp: Path, timeout: float) -> dict:
    """Run one :mod:`ros_case` case isolated; its JSON result (``AssertionError`` with its log
    when it failed)."""
    return start_case(case, tmp, timeout).result()


def _tail(path: Path, lines: int = 80) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return "(no log)"


# --------------------------------------------------------------------------- labs and robots


def robot_name(robot_id: int) -> str:
    return f"r{robot_id}"


def lab_toml(robots: Iterable[tuple[int, str]], domain: int, *, stamp: str = "now",
             lost_after: float = 0.5, repeat_hz: float = 20.0, margin: float = 0.3,
             cmd_types: dict[str, str] | None = None, robot_timeout: float = 0.3) -> str:
    """A lab file for fake robots ``(id, kind)``: vrpn-style pose topics, TwistStamped (or
    ``cmd_types[id]``) commands on ``/<name>/cmd_vel``."""
    lines = ["[ros]", f"domain_id = {domain}", 'discovery_range = "LOCALHOST"',
             f'cmd_stamp = "{stamp}"', "", "[mocap]", f"lost_after = {lost_after}", "",
             "[safety]", f"geofence_margin = {margin}", ""]
    for robot_id, _kind in robots:
        name = robot_name(robot_id)
        cmd_type = (cmd_types or {}).get(str(robot_id), "geometry_msgs/msg/TwistStamped")
        lines += ["[[robots]]", f"id = {robot_id}",
                  f'mocap = {{ topic = "/vrpn_mocap/{name}/pose", '
                  f'type = "geometry_msgs/msg/PoseStamped" }}',
                  f'cmd = {{ topic = "/{name}/cmd_vel", type = "{cmd_type}", '
                  f'repeat_hz = {repeat_hz} }}',
                  f"robot_timeout = {robot_timeout}", ""]
    return "\n".join(lines)


def fake_robot_specs(scenario, overrides: dict[int, dict] | None = None) -> list[dict]:
    """One fake robot per scenario robot at its start pose: a unicycle for a unicycle, a mecanum
    car for an omni robot, with the scenario's acceleration limits; ``overrides``: per-robot
    dicts by id (noise, latency, dropout, lose_after, mocap_reliable, cmd_type…)."""
    specs = []
    for robot in scenario.robots:
        if robot.kind == "omni":
            acc = {"acc_lin": robot.omni.acc_lin, "acc_ang": robot.omni.acc_ang}
        else:
            acc = {"acc_lin": robot.unicycle.acc_v, "acc_ang": robot.unicycle.acc_omega}
        name = robot_name(robot.id)
        spec = {"name": name, "kind": "mecanum" if robot.kind == "omni" else "unicycle",
                "pose": list(robot.pose), "cmd_topic": f"/{name}/cmd_vel",
                "cmd_timeout": 0.3, **acc, "seed": robot.id}
        spec.update((overrides or {}).get(robot.id, {}))
        specs.append(spec)
    return specs


def received(log: Path) -> list[dict]:
    """The commands the fake robots logged (JSON lines)."""
    if not log.exists():
        return []
    return [json.loads(line) for line in log.read_text().splitlines() if line.strip()]


def wait_file(path: Path, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and path.stat().st_size > 0:
            return True
        time.sleep(0.05)
    return False
