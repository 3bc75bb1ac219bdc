"""Which faults need namespace hosts, and what a run on them rejects up front."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time

import pytest
from tlfleet.agent.model.faults import parse_fault
from tlfleet.agent.scenario import load_scenario
from tlfleet.coordinator.faults import plan as faults_module
from tlfleet.coordinator.faults.on_hosts import (
    RESTARTED_NAME,
    HostsActuator,
    check_hosts_fault,
    stop_restarted,
)
from tlfleet.coordinator.faults.plan import hosts_for, need_hosts
from tlfleet.coordinator.faults.schedule import FaultError
from tlfleet.coordinator.launch.netns_hosts import (
    PROCESS_PORT0,
    NetnsHosts,
    Placement,
    place,
    place_peers,
)


def test_link_faults_need_root_and_the_tools_and_say_so(monkeypatch):
    assert need_hosts([parse_fault("freeze:robot1@1+1")]) is False
    monkeypatch.setattr(faults_module.os, "geteuid", lambda: 1000)
    with pytest.raises(FaultError, match="fault cut:robot3@20\\+3: dropping a link needs "
                                         "network namespaces, and those need root"):
        need_hosts([parse_fault("cut:robot3@20+3")])
    monkeypatch.setattr(faults_module.os, "geteuid", lambda: 0)
    real = shutil.which
    monkeypatch.setattr(faults_module.shutil, "which",
                        lambda tool: None if tool == "nft" else real(tool) or "/bin/" + tool)
    with pytest.raises(FaultError, match="needs `nft` \\(Debian package nftables\\)"):
        need_hosts([parse_fault("cut:robot3@20+3")])


def test_the_number_of_hosts_a_run_needs(scenarios_dir, monkeypatch):
    monkeypatch.setattr(faults_module, "need_hosts", lambda faults: any(
        f.needs_hosts for f in faults))  # as root with the tools
    s1 = scenarios_dir / "scenario1.toml"
    assert hosts_for(s1, [parse_fault("freeze:robot3@20+3")]) == 0
    assert hosts_for(s1, [parse_fault("cut:robot3@20+3")]) == 1
    assert hosts_for(s1, [parse_fault("cut:robot3@2+3"), parse_fault("cut:host2@5+1")]) == 3
    # a partition: the peer layout, a host per process (coordinator + router, sim, 5 robots)
    assert hosts_for(s1, [parse_fault("partition:robot3,robot4@36+3")]) == 7


def test_namespace_hosts_reject_what_they_cannot_do(scenarios_dir):
    placement = place(load_scenario(scenarios_dir / "scenario1.toml"), 2)
    for spec, message in (("restart:sim@1", "a restarted sim would join no run"),
                          ("partition:robot3,robot4@1+1", "routers route around a dropped "
                                                          "pair"),
                          ("cut:router@1+1", "cut the host \\(host<i>\\) instead"),
                          ("cut:host2@1+1", "there is no host-2 \\(hosts 0 to 1\\)")):
        with pytest.raises(FaultError, match=message):
            check_hosts_fault(parse_fault(spec), placement)
    check_hosts_fault(parse_fault("cut:host1@1+1"), placement)
    net = NetnsHosts(2, prefix="tlft-plan")
    actuator = HostsActuator({"prefix": net.prefix, "count": 2, "subnet": net.subnet,
                              "placement": placement.as_dict(), "pids": {"agent-3": 1}})
    actuator.check(parse_fault("freeze:robot3@1+1"))
    with pytest.raises(FaultError, match="no pid of agent-4 in the fault plan"):
        actuator.check(parse_fault("kill:robot4@1"))
    with pytest.raises(FaultError, match="no command line of agent-3 in the fault plan"):
        actuator.check(parse_fault("restart:robot3@1"))
    assert actuator._cut_names("host-1") == ["agent-2", "agent-4"]


def test_the_peer_layout_gives_every_process_a_host_and_partitions_pairs(scenarios_dir):
    """A partition needs processes that reach each other only over their own direct
    link (peers; a router does not relay between peers), each on a host of its own."""
    placement = place_peers(load_scenario(scenarios_dir / "scenario1.toml"))
    assert placement.layout == "peers" and placement.hosts == 7
    assert placement.host_of == {"coordinator": 0, "sim": 1, "agent-1": 2, "agent-2": 3,
                                 "agent-3": 4, "agent-4": 5, "agent-5": 6}
    assert placement.peers == ["sim", *(f"agent-{i}" for i in range(1, 6))]
    assert placement.link("agent-3") == (0, PROCESS_PORT0 + 4)  # its port on router 0
    assert Placement.from_dict(placement.as_dict()) == placement
    check_hosts_fault(parse_fault("partition:robot3,robot4@36+3"), placement)
    check_hosts_fault(parse_fault("partition:sim,robot2@1+1"), placement)
    net = NetnsHosts(7, prefix="tlft-peers")
    actuator = HostsActuator({"prefix": net.prefix, "count": 7, "subnet": net.subnet,
                              "placement": placement.as_dict(), "pids": {}})
    done = []
    actuator.net.partition = lambda a, b: done.append(("partition", a, b))
    actuator.net.heal = lambda a, b: done.append(("heal", a, b))
    actuator.net.cut_host = lambda h: done.append(("cut", h))
    actuator.net.restore_host = lambda h: done.append(("restore", h))
    for spec in ("partition:robot3,robot4@36+3", "cut:robot2@1+1"):
        fault = parse_fault(spec)
        actuator.check(fault)
        actuator.start(fault)
        actuator.end(fault)
    # in the peer layout a cut is the carrier loss of the process's own host (all its links)
    assert done == [("partition", 4, 5), ("heal", 4, 5), ("cut", 3), ("restore", 3)]
    with pytest.raises(Exception, match="a partition needs two hosts"):
        NetnsHosts._pair_table(2, 2)


def test_a_restart_on_hosts_starts_the_plans_command_again_and_the_launcher_stops_it(
        scenarios_dir, tmp_path):
    """``restart:`` on namespace hosts: the actuator (in ``tlfleet supervise``)
    kills the group, starts the plan's argv again, records the new pid for the launcher; no
    namespace is needed to check that much."""
    placement = place(load_scenario(scenarios_dir / "scenario1.toml"), 1)
    argv = [sys.executable, "-c", "import time; print('up', flush=True); time.sleep(60)"]
    old = subprocess.Popen(argv, start_new_session=True)
    try:
        actuator = HostsActuator({"prefix": "tlft-rs", "count": 1, "subnet": 1,
                                  "placement": placement.as_dict(), "pids": {"agent-3": old.pid},
                                  "argv": {"agent-3": argv}, "log_dir": str(tmp_path)})
        fault = parse_fault("restart:robot3@1")
        actuator.check(fault)
        done = actuator.start(fault)
        assert old.wait(5.0) == -9 and done["pid"] == old.pid
        new = done["new_pid"]
        assert new != old.pid and actuator.pids["agent-3"] == new
        assert json.loads((tmp_path / RESTARTED_NAME).read_text()) == {"agent-3": new}
        assert actuator.start_again.awaiting == {"agent-3"}
        log = tmp_path / "agent-3.log"
        for _ in range(200):  # ≤ 10 s: the new process is up and writes to the log
            if "up" in log.read_text():
                break
            time.sleep(0.05)
        assert "up" in log.read_text()
        assert stop_restarted(tmp_path, 2.0) == {"agent-3": new}
        actuator._launcher.children[0].process.wait(5.0)
        assert stop_restarted(tmp_path, 2.0) == {}  # nothing left to stop
    finally:
        if old.poll() is None:
            old.kill()
            old.wait(5.0)
