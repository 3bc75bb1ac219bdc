"""``tlfleet.bus.lifeline``: the coordinator's token watch on the fake bus, and the parent tie's
environment handling (the tie itself is exercised by tests/system/test_system_orphans.py)."""

from __future__ import annotations

import os
import threading
import time

import pytest
from tlfleet.bus.fake import FakeNetwork
from tlfleet.bus.lifeline import PARENT_ENV, CoordinatorWatch, child_environment, die_with_parent

KEY = "tlfleet/f/alive/coordinator/0"


def watch(after: float = 0.2):
    net = FakeNetwork()
    stop = threading.Event()
    return net, stop, CoordinatorWatch(net.transport("agent"), KEY, stop, after)


def test_a_coordinator_never_seen_is_not_waited_for():
    _net, stop, w = watch(0.05)
    time.sleep(0.2)
    assert not stop.is_set() and not w.orphaned
    w.close()


def test_a_coordinator_gone_past_the_bound_stops_the_process():
    net, stop, w = watch(0.2)
    coordinator = net.transport("coordinator")
    coordinator.declare_alive(KEY)
    gone = time.monotonic()
    coordinator.kill()
    assert stop.wait(2.0)
    waited = time.monotonic() - gone
    assert 0.2 <= waited < 1.0 and w.orphaned
    w.close()


def test_a_coordinator_back_within_the_bound_is_a_blink():
    net, stop, w = watch(0.3)
    first = net.transport("coordinator")
    first.declare_alive(KEY)
    first.kill()
    time.sleep(0.1)
    net.transport("coordinator again").declare_alive(KEY)
    time.sleep(0.5)
    assert not stop.is_set() and not w.orphaned
    w.close()


def test_a_closed_watch_never_fires():
    net, stop, w = watch(0.1)
    coordinator = net.transport("coordinator")
    coordinator.declare_alive(KEY)
    coordinator.kill()
    w.close()
    time.sleep(0.3)
    assert not stop.is_set()


def test_the_bound_must_be_positive():
    net = FakeNetwork()
    with pytest.raises(ValueError, match="orphan-after"):
        CoordinatorWatch(net.transport(), KEY, threading.Event(), 0.0)


def test_the_tie_is_named_in_the_child_environment_and_removed_from_the_childs():
    env = child_environment({"PATH": "/bin"})
    assert env[PARENT_ENV] == str(os.getpid())
    assert not die_with_parent({})  # started by nobody: no tie
    killed = []
    bad = {PARENT_ENV: "not-a-pid"}
    assert not die_with_parent(bad, kill=lambda *a: killed.append(a))
    assert PARENT_ENV not in bad and not killed  # removed: its own children are not tied
