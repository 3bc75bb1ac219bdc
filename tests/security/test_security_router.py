"""A secured router process (``tlfleet router --secure``) against rogue clients on loopback.

The router enforces mutual TLS and Scenario 1's generated policy; the other processes are client
sessions in this test process, each holding the certificate of the identity it plays (``sim``,
``coordinator``, ``robot4``, ``robot5``) and a rogue holding robot 3's. Every check has its
positive control: what the rogue may do arrives, so what does not arrive was denied.
"""

from __future__ import annotations

import threading
import time

import pytest
import zenoh
from security_helpers import (
    SCENARIO1,
    SecuredRouter,
    client_config,
    make_keys,
    open_as,
    wait_until,
)
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Command, Control

pytestmark = pytest.mark.system
FLEET = "scenario1"


@pytest.fixture(scope="module")
def fleet_keys(tmp_path_factory):
    return make_keys(SCENARIO1, tmp_path_factory.mktemp("keys"))


@pytest.fixture(scope="module")
def other_keys(tmp_path_factory):
    """A complete key directory of another CA (same identities, same names)."""
    return make_keys(SCENARIO1, tmp_path_factory.mktemp("other-ca"))


@pytest.fixture(scope="module")
def router(fleet_keys, tmp_path_factory):
    r = SecuredRouter(fleet_keys, FLEET, tmp_path_factory.mktemp("router") / "router.log")
    yield r
    r.stop()


def test_a_client_with_a_valid_certificate_connects(router, fleet_keys):
    session = open_as(router.endpoint, fleet_keys, "robot3")
    session.close()


@pytest.mark.parametrize("what", ["trusts the CA, no certificate", "no TLS settings",
                                  "plain tcp"])
def test_a_client_without_a_certificate_cannot_connect(router, fleet_keys, what):
    if what == "plain tcp":
        config = client_config(f"tcp/127.0.0.1:{router.port}")
    elif what == "no TLS settings":
        config = client_config(router.endpoint)
    else:
        config = client_config(router.endpoint, ca=fleet_keys.ca)
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        zenoh.open(config)


def test_a_client_with_a_certificate_of_another_ca_cannot_connect(router, fleet_keys,
                                                                   other_keys):
    # it trusts the fleet's CA (so it would accept the router) but presents another CA's robot3
    config = client_config(router.endpoint, ca=fleet_keys.ca, cert=other_keys.cert("robot3"),
                           key=other_keys.key("robot3"))
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        zenoh.open(config)
    # with its own CA as root it does not even accept the router
    config = client_config(router.endpoint, ca=other_keys.ca, cert=other_keys.cert("robot3"),
                           key=other_keys.key("robot3"))
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        zenoh.open(config)
    assert wait_until(lambda: "invalid peer certificate" in router.text(), 15.0), router.text()


class Inbox:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.items: list[tuple[str, bytes]] = []

    def __call__(self, sample) -> None:
        with self.lock:
            self.items.append((str(sample.key_expr), sample.payload.to_bytes()))

    def seen(self) -> set[str]:
        with self.lock:
            return {k for k, _ in self.items}

    def count(self, key: str) -> int:
        with self.lock:
            return sum(1 for k, _ in self.items if k == key)


def replies(session, key: str) -> list[bytes]:
    return sorted(r.ok.payload.to_bytes() for r in session.get(key, timeout=2.0)
                  if r.ok is not None)


def test_robot3s_certificate_cannot_command_robot4_send_control_or_serve_robot4(
        fleet_keys, tmp_path):
    router = SecuredRouter(fleet_keys, FLEET, tmp_path / "router.log")
    sim = open_as(router.endpoint, fleet_keys, "sim")
    coordinator = open_as(router.endpoint, fleet_keys, "coordinator")
    robot4 = open_as(router.endpoint, fleet_keys, "robot4")
    robot5 = open_as(router.endpoint, fleet_keys, "robot5")
    rogue = open_as(router.endpoint, fleet_keys, "robot3")
    sessions = [rogue, robot5, robot4, coordinator, sim]
    try:
        cmds, controls, alive = Inbox(), Inbox(), Inbox()
        sim.declare_subscriber(keys.all_cmds(FLEET), cmds)
        sim.declare_subscriber(keys.control(FLEET), controls)
        coordinator.liveliness().declare_subscriber(keys.all_alive(FLEET), alive, history=True)
        # settled before any token exists: a token declared while the subscriber's history
        # interest is still on its way was missed about 1 run in 10 (a zenoh race, not the ACL)
        assert wait_until(lambda: keys.alive(FLEET, "router", 0) in alive.seen(), 15.0)
        time.sleep(0.2)
        collab4 = keys.collab_all(FLEET, 4)  # robot 4's queryable: every sender's key
        real4 = robot4.declare_queryable(collab4, lambda q: q.reply(q.key_expr, b"robot4"))
        rogue.declare_queryable(collab4, lambda q: q.reply(q.key_expr, b"rogue"))
        rogue.liveliness().declare_token(keys.alive(FLEET, "agent", 4))
        rogue.liveliness().declare_token(keys.alive(FLEET, "agent", 3))
        time.sleep(0.5)  # declarations reach the router

        own, other, ctl = (rogue.declare_publisher(k) for k in
                           (keys.cmd(FLEET, 3), keys.cmd(FLEET, 4), keys.control(FLEET)))
        for seq in range(20):
            own.put(encode(Command(3, 0.01 * seq, seq, (0.1, 0.0, 0.0))))
            other.put(encode(Command(4, 0.01 * seq, seq, (1.0, 1.0, 0.0))))
            ctl.put(encode(Control("stop")))
            rogue.put(keys.cmd(FLEET, 4), encode(Command(4, 0.0, seq, (1.0, 0.0, 0.0))))
            time.sleep(0.005)
        coordinator.put(keys.control(FLEET), encode(Control("start")))
        assert wait_until(lambda: cmds.count(keys.cmd(FLEET, 3)) == 20
                          and controls.count(keys.control(FLEET)) == 1, 15.0)
        time.sleep(0.3)  # anything denied would have arrived by now
        assert cmds.seen() == {keys.cmd(FLEET, 3)}  # robot/4/cmd never reached the sim
        assert controls.count(keys.control(FLEET)) == 1  # the coordinator's, not the rogue's
        assert wait_until(lambda: keys.alive(FLEET, "agent", 3) in alive.seen(), 15.0)
        assert keys.alive(FLEET, "agent", 4) not in alive.seen()

        # robot 5 (coupled with 4) reaches robot 4's queryable on its own key, never the
        # rogue's; on robot 3's key it reaches nothing (it may query only its own)
        from5 = keys.collab_from(FLEET, 4, 5)
        assert replies(robot5, from5) == [b"robot4"]
        assert replies(robot5, keys.collab_from(FLEET, 4, 3)) == []
        real4.undeclare()
        time.sleep(0.3)
        assert replies(robot5, from5) == []
    finally:
        for session in sessions:
            session.close()
        router.stop()
    log = router.text()
    prefix = "ACL denied: robot3 "
    for denial in (f"Put (ingress) on {keys.cmd(FLEET, 4)}",
                   f"Put (ingress) on {keys.control(FLEET)}",
                   f"Declare Queryable (ingress) on {collab4}",
                   f"Liveliness Token (ingress) on {keys.alive(FLEET, 'agent', 4)}"):
        assert prefix + denial in log, log
    # what robot 3 may do is not reported as a denial (the permission-cache lines are dropped)
    for allowed in (f"Put (ingress) on {keys.cmd(FLEET, 3)}",
                    f"Liveliness Token (ingress) on {keys.alive(FLEET, 'agent', 3)}"):
        assert prefix + allowed not in log, log
