"""The access policy on a direct peer link: two zenoh peers on loopback, the simulator's
listening with its own certificate and the fleet's policy (``secure_transport`` in peer mode),
robot 2's peer linked straight to it — no router in between to enforce anything. What robot 2
may write (its own command key) arrives; what it may not (robot 1's command key) never does."""

from __future__ import annotations

import threading
import time

from security_helpers import SCENARIO1, wait_until
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.protocol import keys
from tlfleet.bus.transport import TransportConfig
from tlfleet.bus.zenoh.security import KeyDir, secure_transport
from tlfleet.bus.zenoh.transport import ZenohTransport
from tlfleet.coordinator.launch.processes import free_port
from tlfleet.coordinator.security.authority import write_keys

PUTS = 20  # per key


def test_a_robot_on_a_direct_peer_link_writes_only_its_own_keys(tmp_path):
    scenario = load_scenario(SCENARIO1)
    fleet = scenario.fleet
    # the simulator's certificate names the address robot 2 connects to, as in the peer layout
    write_keys(scenario, tmp_path / "keys", addresses={"sim": ["127.0.0.1"]})
    keydir = KeyDir(tmp_path / "keys")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    sim = ZenohTransport.open(secure_transport(
        TransportConfig(mode="peer", listen=(endpoint,)), keydir.path, "sim"))
    robot = None
    try:
        assert "access_control" in secure_transport(
            TransportConfig(mode="peer", listen=(endpoint,)), keydir.path, "sim").extra
        got: dict[str, int] = {keys.cmd(fleet, 1): 0, keys.cmd(fleet, 2): 0}
        lock = threading.Lock()

        def count(key: str, _payload: bytes) -> None:
            with lock:
                if key in got:
                    got[key] += 1

        subs = [sim.subscribe(key, count) for key in got]
        robot = ZenohTransport.open(secure_transport(
            TransportConfig(mode="peer", connect=(endpoint,)), keydir.path, "robot2"))
        # the link is up once robot 2's own command arrives (bounded: 10 s)
        deadline = time.monotonic() + 10.0
        while got[keys.cmd(fleet, 2)] == 0 and time.monotonic() < deadline:
            robot.publish(keys.cmd(fleet, 2), b"probe")
            time.sleep(0.1)
        with lock:
            got[keys.cmd(fleet, 2)] = 0
        for _ in range(PUTS):
            robot.publish(keys.cmd(fleet, 1), b"forged")
            robot.publish(keys.cmd(fleet, 2), b"own")
            time.sleep(0.01)
        assert wait_until(lambda: got[keys.cmd(fleet, 2)] >= PUTS, 10.0), got
        time.sleep(0.3)  # anything forged in flight would have arrived by now
        assert got[keys.cmd(fleet, 1)] == 0, got
        for sub in subs:
            sub.close()
    finally:
        if robot is not None:
            robot.close()
        sim.close()
