"""zenoh's receive runtime in tlfleet processes (tlfleet.bus.transport.RX_WORKERS): enough
workers that links held in close(2) by a partition (zenoh's 10 s SO_LINGER) leave the others
received. Checked on the threads zenoh really starts, in a fresh process (zenoh reads
``ZENOH_RUNTIME`` once per process)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from process_helpers import free_port
from tlfleet.bus.transport import DEFAULT_RUNTIME, RX_WORKERS, TransportConfig

PROBE = """
import json, os, sys, time
sys.path.insert(0, {root!r})
from tlfleet.bus.transport import TransportConfig
from tlfleet.bus.zenoh.transport import open_transport
listen = open_transport(TransportConfig(mode="peer", listen=("tcp/127.0.0.1:{port}",)))
dial = open_transport(TransportConfig(mode="peer", connect=("tcp/127.0.0.1:{port}",)))
got = []
listen.subscribe("probe/x", lambda k, p: got.append(p))
deadline = time.monotonic() + 10.0
while not got and time.monotonic() < deadline:  # a link is up and data went over it
    dial.publish("probe/x", b"1")
    time.sleep(0.05)
names = [open(f"/proc/self/task/{{t}}/comm").read().strip() for t in os.listdir("/proc/self/task")]
print(json.dumps({{"received": bool(got), "rx": sum(n.startswith("rx-") for n in names),
                   "env": os.environ.get("ZENOH_RUNTIME")}}))
os._exit(0)
"""


def probe(env_runtime: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "ZENOH_RUNTIME"}
    if env_runtime is not None:
        env["ZENOH_RUNTIME"] = env_runtime
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = subprocess.run([sys.executable, "-c", PROBE.format(root=root, port=free_port())],
                         env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_default_runtime_gives_rx_its_workers():
    assert TransportConfig().runtime == DEFAULT_RUNTIME
    assert f"worker_threads: {RX_WORKERS}" in DEFAULT_RUNTIME and RX_WORKERS > 2


@pytest.mark.system
def test_a_tlfleet_session_runs_rx_workers_and_the_environment_still_wins():
    default = probe(None)
    assert default["received"] and default["env"] == DEFAULT_RUNTIME
    assert default["rx"] >= RX_WORKERS  # zenoh's own default starts 2
    mine = probe("(rx: (worker_threads: 3))")  # a user's ZENOH_RUNTIME is kept
    assert mine["received"] and mine["env"] == "(rx: (worker_threads: 3))"
    assert mine["rx"] < RX_WORKERS


def test_children_do_not_inherit_the_runtime_a_process_set_for_itself(monkeypatch, tmp_path):
    """zenoh reads ZENOH_RUNTIME once per process and an environment value wins: the runtime a
    coordinator set for its own session must not decide its children's (each picks its own
    from its flags, e.g. the lockstep peers' --zenoh-runtime minimal); a user's value stays."""
    from tlfleet.bus import transport
    from tlfleet.coordinator.launch.processes import Launcher

    monkeypatch.setattr(transport, "_runtime_set_here", None)
    assert transport.child_environment({"ZENOH_RUNTIME": "(mine)", "A": "1"}) == \
        {"ZENOH_RUNTIME": "(mine)", "A": "1"}  # the user's: passed on
    transport.note_runtime_set_here(DEFAULT_RUNTIME)
    assert transport.child_environment({"ZENOH_RUNTIME": DEFAULT_RUNTIME, "A": "1"}) == {"A": "1"}
    assert transport.child_environment({"ZENOH_RUNTIME": "(mine)"}) == {"ZENOH_RUNTIME": "(mine)"}
    monkeypatch.setenv("ZENOH_RUNTIME", DEFAULT_RUNTIME)
    launcher = Launcher(tmp_path)
    child = launcher.start("env", [sys.executable, "-c",
                                   "import os; print(os.environ.get('ZENOH_RUNTIME'))"])
    child.process.wait(30)
    launcher.stop_all(1.0)
    assert (tmp_path / "env.log").read_text().strip() == "None"
