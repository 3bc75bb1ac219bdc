"""``tlfleet router`` + ``tlfleet agent`` as real processes on loopback zenoh (one smoke test).

Router on a free 127.0.0.1 port, an agent of Scenario 1 as a client (robot 3: STL, robot 1: LTL);
the test is a client too: it waits for ``alive/agent/<id>``, sends Control(start) and a due frame,
receives the Command, then stops the agent (SIGTERM or SIGINT) and the router (SIGTERM) and checks
that they exit cleanly. Every wait is on a condition
with a timeout; process groups are killed in ``finally``.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from process_helpers import free_port, kill_group
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import Command, Control, MocapFrame
from tlfleet.bus.transport import TransportConfig
from tlfleet.bus.zenoh.transport import ZenohTransport

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "scenario1.toml"



def tlfleet(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tlfleet.cli", *args], cwd=ROOT,
                            start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)



def open_client(endpoint: str, timeout: float = 15.0) -> ZenohTransport:
    """A client fails at once while the router is not listening yet: retry until it is."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return ZenohTransport.open(TransportConfig(mode="client", connect=(endpoint,)))
        except Exception:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


@pytest.mark.system
@pytest.mark.parametrize("robot, size, stop_signal", [(3, 3, signal.SIGTERM),
                                                      (1, 2, signal.SIGINT)])
def test_router_and_agent_processes_answer_a_frame_and_stop_on_a_signal(robot, size,
                                                                        stop_signal):
    """Robot 3 is an STL agent (u = (vx, vy, ω)), robot 1 an LTL agent (u = (v, ω))."""
    scenario = load_scenario(SCENARIO)
    fleet = scenario.fleet
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = tlfleet("router", "--listen", endpoint, "--fleet", fleet)
    agent = None
    transport = None
    try:
        transport = open_client(endpoint)
        agent = tlfleet("agent", str(SCENARIO), "--robot", str(robot), "--connect", endpoint)
        alive = {"router": threading.Event(), "agent": threading.Event()}
        commands: list[Command] = []
        answered = threading.Event()

        def on_alive(key: str, up: bool) -> None:
            if up and key == keys.alive(fleet, "agent", robot):
                alive["agent"].set()
            if up and key == keys.alive(fleet, "router", 0):
                alive["router"].set()

        def on_cmd(_key: str, payload: bytes) -> None:
            commands.append(decode(Command, payload))
            answered.set()

        transport.watch_alive(keys.all_alive(fleet), on_alive)
        transport.subscribe(keys.cmd(fleet, robot), on_cmd)
        assert alive["router"].wait(15), "no liveliness token alive/router/0"
        assert alive["agent"].wait(30), f"no liveliness token alive/agent/{robot}"

        transport.publish(keys.control(fleet), encode(Control("start")))
        poses = tuple((r.id, *r.pose) for r in sorted(scenario.robots, key=lambda r: r.id))
        frame = MocapFrame(0.0, 0, poses, due=(robot,))
        # the keys the simulator publishes frame 0 on (robot 1, an LTL agent at 5 Hz, reads only
        # mocap_every/20/0)
        frame_keys = keys.frame_keys(fleet, 0, keys.frame_schedules(
            (scenario.control_divider(r.id), scenario.control_phase(r.id))
            for r in scenario.robots))
        deadline = time.monotonic() + 10
        while not answered.is_set() and time.monotonic() < deadline:
            for key in frame_keys:  # duplicates are ignored
                transport.publish(key, encode(frame))
            answered.wait(0.2)
        assert answered.is_set(), "no command for the due frame"
        command = commands[0]
        assert (command.robot, command.seq, command.t, len(command.u)) == (robot, 0, 0.0, size)

        agent.send_signal(stop_signal)
        assert agent.wait(10) == 0
        assert {c.seq for c in commands} == {0}  # one frame (then maybe a stale zero command)
        router.send_signal(signal.SIGTERM)
        assert router.wait(10) == 0
    finally:
        if transport is not None:
            transport.close()
        if agent is not None:
            kill_group(agent)
        kill_group(router)
