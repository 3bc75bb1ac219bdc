"""``tlfleet echo`` and ``tlfleet topics`` against a real fleet (router, sim, agents on loopback):
the frames echo prints are the frames the coordinator recorded (trajectory.csv, compared row by
row), and topics lists the keys the key layout says, with their publishers and the processes."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from system_helpers import HERE, load_trajectory, run

pytestmark = pytest.mark.system
TLFLEET = [sys.executable, "-m", "tlfleet.cli"]


def test_echo_and_topics_on_a_running_fleet(tmp_path: Path) -> None:
    out = tmp_path / "run"
    result: dict = {}
    # paced at wall-clock speed so that the run lasts while echo and topics listen
    runner = threading.Thread(target=lambda: result.update(r=run(
        HERE / "two_robots.toml", out, duration=8.0, sim_args=("--max-speed", "1"),
        report=False, rrd=False)), daemon=True)
    runner.start()
    try:
        deadline = time.monotonic() + 60
        while not (out / "run.json").is_file() or not (out / "trajectory.csv").is_file():
            assert time.monotonic() < deadline and runner.is_alive(), "the run did not start"
            time.sleep(0.1)
        echo = subprocess.run([*TLFLEET, "echo", "mocap", "--run", str(out), "--count", "30",
                               "--duration", "20"], capture_output=True, text=True, timeout=60)
        topics = subprocess.run([*TLFLEET, "topics", "--run", str(out), "--json",
                                 "--listen-for", "1.5"], capture_output=True, text=True,
                                timeout=60)
    finally:
        runner.join(timeout=120)
    assert not runner.is_alive()
    assert result["r"].verdict.label == "clean"
    assert echo.returncode == 0, echo.stderr
    lines = [json.loads(line) for line in echo.stdout.splitlines()]
    assert len(lines) == 30
    t, states = load_trajectory(out)
    row_of = {round(float(v), 6): k for k, v in enumerate(t)}
    for line in lines:
        assert line["kind"] == "MocapFrame" and line["from"] == "sim"
        msg = line["msg"]
        k = row_of[round(msg["t"], 6)]  # every echoed frame was recorded
        for robot, x, y, theta in msg["poses"]:
            assert states[robot][k] == pytest.approx([x, y, theta], abs=1e-6)
    assert [line["msg"]["seq"] for line in lines] == sorted(line["msg"]["seq"] for line in lines)

    assert topics.returncode == 0, topics.stderr
    listed = json.loads(topics.stdout)
    fleet = "two_robots"
    expect = {f"tlfleet/{fleet}/mocap": ("MocapFrame", "sim"),
              f"tlfleet/{fleet}/clock": ("Clock", "sim"),
              f"tlfleet/{fleet}/robot/1/cmd": ("Command", "robot1"),
              f"tlfleet/{fleet}/robot/2/cmd": ("Command", "robot2")}
    for key, (kind, who) in expect.items():
        assert (listed["keys"][key]["kind"], listed["keys"][key]["from"]) == (kind, who), key
    assert 60 < listed["keys"][f"tlfleet/{fleet}/mocap"]["hz"] < 140  # 100 Hz, paced
    assert {"sim 0", "agent 1", "agent 2", "router 0", "coordinator 0"} <= \
        set(listed["processes"])
