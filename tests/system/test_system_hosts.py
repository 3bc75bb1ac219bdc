"""Fleets across namespace hosts (§4c): ``tlfleet run --hosts N``.

Root only (``ip netns``); elsewhere these skip with the reason, and fail under
TLFLEET_REQUIRE_SYSTEM=1. Every namespace is created and deleted by the test (nothing attached
to the root namespace).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from by_hand import start_by_hand, supervise
from needs import need_root_netns
from system_helpers import HERE, ROOT, SCENARIOS, run
from tlfleet.agent.scenario import load_scenario
from tlfleet.coordinator.launch.netns_hosts import NetnsHosts, place, wait_listening
from tlfleet.coordinator.launch.processes import Launcher
from tlfleet.coordinator.run_hosts import run_on_hosts

pytestmark = [pytest.mark.system, pytest.mark.needs_system]


def netns_list() -> str:
    return subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout


def connects(hosts: NetnsHosts, src: int, dst: int, port: int) -> bool:
    """A TCP connect from host ``src`` to a listener on host ``dst`` within 1 s."""
    code = ("import socket, sys\n"
            "try:\n"
            f"    socket.create_connection(('{hosts.address(dst)}', {port}), 1.0).close()\n"
            "except OSError:\n"
            "    sys.exit(1)\n")
    return subprocess.run([*hosts.exec_prefix(src), sys.executable, "-c", code]).returncode == 0


def test_hosts_come_up_joined_a_link_is_cut_and_restored_and_they_go(tmp_path):
    need_root_netns()
    hosts = NetnsHosts(2, prefix="tlft-cut")
    with hosts:
        assert all(hosts.name(h) in netns_list() for h in (0, 1))
        server = subprocess.Popen([*hosts.exec_prefix(1), sys.executable, "-c",
                                   "import socket, time\n"
                                   "s = socket.socket(); s.setsockopt(socket.SOL_SOCKET, "
                                   "socket.SO_REUSEADDR, 1)\n"
                                   f"s.bind(('{hosts.address(1)}', 7501)); s.listen(16)\n"
                                   "while True:\n    c, _ = s.accept(); c.close()\n"])
        try:
            assert any(connects(hosts, 0, 1, 7501) for _ in range(50))  # the server is up
            hosts.cut_port(1, 7501)  # one process's link: its port on its host
            assert not connects(hosts, 0, 1, 7501)
            hosts.restore_port(1, 7501)
            assert connects(hosts, 0, 1, 7501)
            hosts.cut_host(1)  # the whole host
            assert not connects(hosts, 0, 1, 7501)
            hosts.restore_host(1)
            assert connects(hosts, 0, 1, 7501)
        finally:
            server.kill()
            server.wait()
    assert "tlft-cut" not in netns_list()


def test_placement_spreads_the_robots_and_gives_every_process_its_own_port():
    placement = place(load_scenario(SCENARIOS / "scenario1.toml"), 3)
    assert placement.host_of == {"coordinator": 0, "sim": 0, "agent-1": 0, "agent-2": 1,
                                 "agent-3": 2, "agent-4": 0, "agent-5": 1}
    links = [placement.link(p) for p in placement.host_of]
    assert len(set(links)) == len(links)  # one (host, port) per process: cut one, cut only it


def test_the_two_machine_recipe_in_two_namespaces(tmp_path):
    """README "Two machines": router, sim and robot 1 on A; robot 2 on B; supervise on B."""
    need_root_netns()
    two = HERE / "two_robots.toml"
    hosts = NetnsHosts(2, prefix="tlft-two")
    with hosts, Launcher(tmp_path / "logs") as launcher:
        endpoint = f"tcp/{hosts.address(0)}:7447"  # A's address: B reaches it over the bridge
        on = {"router": 0, "sim": 0, "agent-1": 0, "agent-2": 1}

        def prefix(name: str) -> list[str]:
            if name == "sim":  # the router must listen before the clients start
                wait_listening(hosts, 0, 7447, 15.0)
            return hosts.exec_prefix(on[name])

        start_by_hand(launcher, two, endpoint, prefix=prefix,
                      sim_args=("--duration", "8", "--seed", "11"), wait_host=None)
        done = supervise(two, endpoint, tmp_path / "run", "--duration", "8", "--seed", "11",
                         "--no-rrd", "--no-figures", prefix=hosts.exec_prefix(1), timeout=120)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    assert "tlft-two" not in netns_list()
    local = run(two, tmp_path / "local", duration=8.0, seed=11, report=False, rrd=False)
    assert local.clean
    assert (tmp_path / "run" / "trajectory.csv").read_bytes() == \
        (tmp_path / "local" / "trajectory.csv").read_bytes()


def test_hosts_insecure_keeps_plain_tcp_and_gives_the_same_trajectory(tmp_path):
    need_root_netns()
    two = HERE / "two_robots.toml"
    runs = {}
    for name, insecure in (("plain", True), ("secured", False)):
        result = run_on_hosts(two, 2, out=tmp_path / name, insecure=insecure, capture=True,
                              supervise_args=["--duration", "4", "--no-rrd", "--no-report",
                                              "--quiet"],
                              sim_args=["--duration", "4"], prefix=f"tlft-{name[:3]}")
        assert result.returncode == 0, result.stderr[-3000:]
        runs[name] = json.loads((tmp_path / name / "run.json").read_text())
        scheme = "tcp" if insecure else "tls"
        assert f"router: listening on {scheme}/" in \
            (tmp_path / name / "logs" / "router-0.log").read_text()
    assert runs["plain"]["secure"] is False and "fingerprints" not in runs["plain"]
    assert runs["secured"]["secure"] is True
    assert (tmp_path / "plain" / "trajectory.csv").read_bytes() == \
        (tmp_path / "secured" / "trajectory.csv").read_bytes()


@pytest.mark.slow
def test_scenario1_across_three_hosts_is_byte_identical_to_tlfleet_run(tmp_path, scenario1_run):
    need_root_netns()
    result = run_on_hosts(SCENARIOS / "scenario1.toml", 3, out=tmp_path / "run",
                          supervise_args=["--no-rrd", "--quiet"], capture=True,
                          prefix="tlft-s1")
    assert result.returncode == 0, result.stderr[-3000:]
    assert "tlft-s1" not in netns_list()
    info = json.loads((tmp_path / "run" / "run.json").read_text())
    assert info["clean"] and info["hosts"]["hosts"] == 3
    # secured by default: mutual TLS, the mesh policy, keys made for the run and gone
    assert info["secure"] is True
    assert set(info["fingerprints"]) == {"ca", "router", "sim", "coordinator",
                                         *(f"robot{i}" for i in range(1, 6))}
    assert "deleted" in info["keys"]
    assert result.keys is not None and not result.keys.exists()
    logs = tmp_path / "run" / "logs"
    addresses = list(info["addresses"].values())
    assert len(set(addresses)) == 3
    for host, address in enumerate(addresses):  # one router per host, on its own address
        text = (logs / f"router-{host}.log").read_text()
        assert f"router: listening on tls/{address}:7447" in text
    for process, host in info["hosts"]["host_of"].items():  # each process on its host's router
        if process.startswith("agent-"):
            port = info["hosts"]["port_of"][process]
            assert f"tls/{addresses[host]}:{port}" in (logs / f"{process}.log").read_text() or \
                f"tls/{addresses[host]}:{port}" in (logs / f"router-{host}.log").read_text()
    assert {c for n, c in result.exit_codes.items() if not n.startswith("router")} == {0}
    assert (tmp_path / "run" / "trajectory.csv").read_bytes() == \
        (scenario1_run.run_dir / "trajectory.csv").read_bytes()


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_an_interrupted_hosts_run_ends_interrupted_and_leaves_nothing(tmp_path, signum):
    """``kill`` or Ctrl-C of ``tlfleet run --hosts N`` (a run with link faults takes this path
    too): supervise ends the run as *interrupted* and writes the run directory, every process
    it started is gone, every namespace deleted and the run's private key directory removed.
    (Before, SIGTERM killed ``tlfleet run`` at once and left its routers, namespaces and keys.)"""
    need_root_netns()
    run_dir = tmp_path / "run"
    process = subprocess.Popen(
        [sys.executable, "-m", "tlfleet.cli", "run", str(HERE / "two_robots.toml"), "--realtime",
         "--hosts", "2", "--duration", "120", "--out", str(run_dir), "--quiet", "--no-rrd",
         "--no-figures"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)  # the signal reaches tlfleet run alone, as `kill PID` does
    prefix = f"tlf{process.pid % 100000}-"
    try:
        trajectory = run_dir / "trajectory.csv"
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline and process.poll() is None:
            if trajectory.is_file() and trajectory.read_text().count("\n") > 200:
                break  # two seconds of the mission recorded
            time.sleep(0.2)
        assert process.poll() is None, process.communicate()[1][-3000:]
        namespaces = [ns.split()[0] for ns in netns_list().splitlines()
                      if ns.startswith(prefix)]
        pids = [int(pid) for ns in namespaces for pid in subprocess.run(
            ["ip", "netns", "pids", ns], capture_output=True, text=True).stdout.split()]
        assert len(pids) >= 4  # routers, sim, agents, supervise
        argv = Path(f"/proc/{pids[0]}/cmdline").read_bytes().split(b"\0")
        keys = Path(argv[argv.index(b"--secure") + 1].decode())  # the run's own key directory
        assert keys.is_dir()
        process.send_signal(signum)
        _out, err = process.communicate(timeout=90.0)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 130, err[-3000:]
    info = json.loads((run_dir / "run.json").read_text())
    assert info["outcome"]["label"] == "interrupted" and 2.0 <= info["t_end"] < 120.0
    assert prefix not in netns_list()
    left = [pid for pid in pids if os.path.exists(f"/proc/{pid}")]
    assert left == [], f"processes of the run still running: {left}"
    assert not keys.exists()
