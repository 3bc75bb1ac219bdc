"""Faults in compose without docker: what a compose fleet refuses, the
handoff between the coordinator's actuator and the host's executor through a directory, the
docker commands of each fault, and the compose file that carries the faults."""

from __future__ import annotations

import json
import math
import threading
import time

import pytest
from tlfleet.agent.model.faults import parse_fault
from tlfleet.bus.protocol.codec import decode
from tlfleet.bus.protocol.messages import Control
from tlfleet.coordinator.compose import (
    ComposeConfig,
    ComposeError,
    compose_text,
    hosts_path,
    leased_services,
    write_compose,
    zenoh_path,
)
from tlfleet.coordinator.faults.docker_executor import Executor, serve
from tlfleet.coordinator.faults.handoff import (
    EXECUTOR_NAME,
    ComposeActuator,
    RestartedContainer,
    check_compose_fault,
    service_of,
    wait_for_executor,
)
from tlfleet.coordinator.faults.on_hosts import CUT_GRACE
from tlfleet.coordinator.faults.schedule import FaultError, FaultScheduler
from tlfleet.coordinator.launch.netns_hosts import RECONNECT


class FakeDocker:
    """Answers the executor's look-ups (one container per service, one network) and records
    every argv; ``fail`` makes the commands of that verb fail as docker would."""

    def __init__(self, fail: str | None = None):
        self.calls: list[list[str]] = []
        self.fail = fail

    def __call__(self, argv):
        argv = list(argv)
        self.calls.append(argv)
        if argv[0] == "ps":
            service = argv[-1].rsplit("=", 1)[1]
            return f"id-{service}\n"
        if argv[:2] == ["network", "ls"]:
            return "proj_fleet\n"
        if argv[0] == "inspect":  # compose fixed the router's address only
            fixed = {"IPv4Address": "172.31.247.2"} if argv[-1] == "id-router" else None
            return json.dumps({"proj_fleet": {"IPAMConfig": fixed, "IPAddress": "172.31.247.9"}})
        if argv[0] == self.fail:
            raise FaultError(f"docker {' '.join(argv)}: Error response from daemon: no such")
        return ""

    def actions(self):
        return [c for c in self.calls if c[0] not in ("ps", "inspect")
                and c[:2] != ["network", "ls"]]


class FakeTransport:
    def __init__(self):
        self.sent = []

    def publish(self, key, payload):
        self.sent.append((key, decode(Control, payload)))


class FakeSupervisor:
    fleet = "f"

    def __init__(self):
        self.cut: dict[str, float] = {}
        self.alive: set[str] = set()
        self.children: dict = {}
        self.tokens = {"a/router": "router", "a/sim": "sim", "a/1": "agent-1",
                       "a/3": "agent-3"}
        self.transport = FakeTransport()
        self.killed: list[tuple[str, str]] = []

    def process_killed(self, name: str, how: str) -> None:
        self.killed.append((name, how))


@pytest.fixture
def executor(tmp_path):
    """A real executor thread over ``tmp_path`` with a fake docker; yields (docker, directory)."""
    docker = FakeDocker()
    stop = threading.Event()
    handled = []
    thread = threading.Thread(target=lambda: handled.append(
        serve(tmp_path, Executor("proj", run=docker), max_wall=30, poll=0.002,
              stop=stop.is_set)), daemon=True)
    thread.start()
    wait_for_executor(tmp_path, 5.0)
    yield docker, tmp_path
    stop.set()
    thread.join(10)
    assert not thread.is_alive()


def test_targets_map_to_compose_services_and_what_compose_cannot_do_is_refused():
    assert [service_of(t) for t in ("agent-3", "agent-12", "sim", "router")] == \
        ["robot3", "robot12", "sim", "router"]
    with pytest.raises(FaultError, match="'host-1' is not a process of a compose fleet"):
        service_of("host-1")
    for spec, message in (
            ("partition:robot3,robot4@1+1", "partitions are not supported in compose: every "
                                            "service reaches the others through the one router"),
            ("cut:host1@1+1", "a compose fleet has no namespace hosts"),
            ("restart:sim@1", "a restarted sim would join no run; use kill:sim"),
            ("restart:router@1", "use kill:router")):
        with pytest.raises(FaultError, match=message):
            check_compose_fault(parse_fault(spec))
    for spec in ("cut:robot3@1+1", "cut:router@1+1", "freeze:sim@1+1", "kill:robot2@1",
                 "restart:robot2@1"):
        check_compose_fault(parse_fault(spec))


def test_each_fault_is_the_docker_commands_of_the_table():
    docker = FakeDocker()
    ex = Executor("proj", run=docker)
    assert ex.commands("start", "cut", "robot3") == [
        ["network", "disconnect", "proj_fleet", "id-robot3"]]
    assert ex.commands("end", "cut", "robot3") == [
        ["network", "connect", "--alias", "robot3", "proj_fleet", "id-robot3"]]
    # the router keeps the address the clients' hosts file names; the others get any
    assert ex.commands("start", "cut", "router") == [
        ["network", "disconnect", "proj_fleet", "id-router"]]
    assert ex.commands("end", "cut", "router") == [
        ["network", "connect", "--alias", "router", "--ip", "172.31.247.2", "proj_fleet",
         "id-router"]]
    assert ex.commands("start", "freeze", "sim") == [["pause", "id-sim"]]
    assert ex.commands("end", "freeze", "sim") == [["unpause", "id-sim"]]
    assert ex.commands("start", "kill", "router") == [["kill", "id-router"]]
    assert ex.commands("start", "restart", "robot2") == [["kill", "id-robot2"],
                                                          ["wait", "id-robot2"]]
    assert ex.after_ack("start", "restart", "robot2") == [["start", "id-robot2"]]
    assert ex.after_ack("start", "kill", "robot2") == ex.after_ack("end", "cut", "robot3") == []
    # containers and the network are found by compose's labels, once each
    lookups = [c for c in docker.calls if c[0] == "ps" or c[:2] == ["network", "ls"]]
    assert ["ps", "-aq", "--filter", "label=com.docker.compose.project=proj", "--filter",
            "label=com.docker.compose.service=robot3"] in lookups
    assert ["network", "ls", "--format", "{{.Name}}", "--filter",
            "label=com.docker.compose.project=proj", "--filter",
            "label=com.docker.compose.network=fleet"] in lookups
    assert len(lookups) == 5  # robot3, the network, router, sim, robot2


def test_an_executor_that_finds_no_single_container_says_so():
    ex = Executor("proj", run=lambda argv: "a\nb\n" if argv[0] == "ps" else "")
    ack = ex.handle({"id": 7, "action": "start", "kind": "freeze", "service": "robot3"})
    assert ack["id"] == 7 and ack["ok"] is False
    assert "project proj: 2 containers of service 'robot3' (expected 1)" in ack["error"]


def test_a_cut_goes_through_the_handoff_and_marks_the_link_loss_window(executor):
    docker, directory = executor
    supervisor = FakeSupervisor()
    actuator = ComposeActuator(directory, supervisor, ack_timeout=5.0, poll=0.002)
    fault = parse_fault("cut:robot3@20+3")
    started = actuator.start(fault)
    assert supervisor.cut == {"agent-3": math.inf}
    assert started["how"] == "docker network disconnect proj_fleet id-robot3"
    assert started["docker_s"] >= 0 and started["docker_wall"] <= time.time()
    request = json.loads((directory / "req-0001.json").read_text())
    assert {k: request[k] for k in ("id", "action", "kind", "target", "service", "spec")} == {
        "id": 1, "action": "start", "kind": "cut", "target": "agent-3", "service": "robot3",
        "spec": "cut:robot3@20+3"}
    before = time.monotonic()
    ended = actuator.end(fault)
    assert ended["restore"]["how"] == "docker network connect --alias robot3 proj_fleet id-robot3"
    assert before + CUT_GRACE <= supervisor.cut["agent-3"] <= time.monotonic() + CUT_GRACE
    assert docker.actions() == [["network", "disconnect", "proj_fleet", "id-robot3"],
                                ["network", "connect", "--alias", "robot3", "proj_fleet",
                                 "id-robot3"]]
    assert json.loads((directory / "ack-0002.json").read_text())["ok"] is True
    assert not list(directory.glob(".*.tmp"))  # every file was renamed into place


def test_a_cut_router_marks_every_process_and_a_freeze_marks_its_target(executor):
    _, directory = executor
    supervisor = FakeSupervisor()
    actuator = ComposeActuator(directory, supervisor, ack_timeout=5.0, poll=0.002)
    actuator.start(parse_fault("cut:router@1+1"))
    assert supervisor.cut == {"sim": math.inf, "agent-1": math.inf, "agent-3": math.inf}
    supervisor.cut.clear()
    actuator.start(parse_fault("freeze:robot1@1+1"))  # its lease expires while it is paused
    assert supervisor.cut == {"agent-1": math.inf}
    actuator.start(parse_fault("kill:robot3@1"))  # a kill is a death: no mark
    assert supervisor.cut == {"agent-1": math.inf}


def test_a_restarted_agent_recovers_and_gets_the_start_again(executor):
    docker, directory = executor
    supervisor = FakeSupervisor()
    actuator = ComposeActuator(directory, supervisor, ack_timeout=5.0, poll=0.002)
    record = actuator.start(parse_fault("restart:robot3@5"))
    assert record["how"] == "docker kill id-robot3; docker wait id-robot3"
    assert record["then"] == "docker start id-robot3"  # after the ack
    # the container killed and waited for: a death the supervisor hears of from the fault
    assert supervisor.killed == [("agent-3", "killed by fault restart:robot3@5")]
    deadline = time.monotonic() + 5.0
    while len(docker.actions()) < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert docker.actions() == [["kill", "id-robot3"], ["wait", "id-robot3"],
                                ["start", "id-robot3"]]
    child = supervisor.children["agent-3"]
    assert isinstance(child, RestartedContainer) and child.returncode is None
    actuator.poll()
    assert supervisor.transport.sent == []  # its token is not back yet
    supervisor.alive.add("agent-3")
    actuator.poll()
    actuator.poll()
    ((key, control),) = supervisor.transport.sent  # once
    assert key.endswith("/control") and control.cmd == "start"
    assert "agent-3" not in supervisor.children  # recovered: nothing to wait for at the end


def test_a_failing_docker_command_is_a_fault_error_and_lifts_the_mark(tmp_path):
    docker = FakeDocker(fail="network")
    stop = threading.Event()
    thread = threading.Thread(target=serve, args=(tmp_path, Executor("proj", run=docker)),
                              kwargs={"max_wall": 30, "poll": 0.002, "stop": stop.is_set},
                              daemon=True)
    thread.start()
    try:
        supervisor = FakeSupervisor()
        actuator = ComposeActuator(tmp_path, supervisor, ack_timeout=5.0, poll=0.002)
        with pytest.raises(FaultError, match="start of cut:robot3@1\\+1 failed on the host: "
                                             "docker network disconnect proj_fleet id-robot3"):
            actuator.start(parse_fault("cut:robot3@1+1"))
        assert supervisor.cut["agent-3"] < time.monotonic()  # a lost token is a death again
    finally:
        stop.set()
        thread.join(10)


def test_without_an_executor_the_coordinator_says_how_to_start_one(tmp_path):
    began = time.monotonic()
    with pytest.raises(FaultError, match=r"none announced itself in .* within 0\.2 s: run the "
                                         r"fleet with docker/compose-run\.sh"):
        wait_for_executor(tmp_path, 0.2)
    actuator = ComposeActuator(tmp_path, FakeSupervisor(), ack_timeout=0.2, poll=0.01)
    with pytest.raises(FaultError, match=r"did not answer request 1 \(start freeze:robot1@1\+1"
                                         r"\) within 0\.2 s"):
        actuator.start(parse_fault("freeze:robot1@1+1"))
    assert time.monotonic() - began < 3.0


def test_the_scheduler_records_what_the_host_did(executor):
    _, directory = executor
    recorded = []
    scheduler = FaultScheduler([parse_fault("freeze:robot1@2+0.05")],
                               ComposeActuator(directory, FakeSupervisor(), poll=0.002),
                               recorded.append, report=lambda text: None)
    scheduler.poll(2.0)
    deadline = time.monotonic() + 5.0
    while scheduler.active and time.monotonic() < deadline:
        scheduler.poll(2.1)
        time.sleep(0.01)
    start, end = recorded
    assert (start.kind, end.kind) == ("fault_start", "fault_end")
    assert start.data["how"] == "docker pause id-robot1"
    assert end.data["restore"]["how"] == "docker unpause id-robot1"


def test_the_executor_undoes_what_is_still_in_effect_when_it_ends(tmp_path):
    docker = FakeDocker()
    stop = threading.Event()
    thread = threading.Thread(target=serve, args=(tmp_path, Executor("proj", run=docker)),
                              kwargs={"max_wall": 30, "poll": 0.002, "stop": stop.is_set},
                              daemon=True)
    thread.start()
    actuator = ComposeActuator(tmp_path, None, ack_timeout=5.0, poll=0.002)
    actuator.start(parse_fault("cut:robot3@1+1"))
    actuator.start(parse_fault("freeze:robot1@1+1"))
    stop.set()
    thread.join(10)
    assert docker.actions()[2:] == [
        ["network", "connect", "--alias", "robot3", "proj_fleet", "id-robot3"],
        ["unpause", "id-robot1"]]
    info = json.loads((tmp_path / EXECUTOR_NAME).read_text())
    assert info["project"] == "proj" and info["pid"] > 0


def test_an_executor_ends_when_its_parent_is_gone(tmp_path):
    import subprocess
    import sys

    parent = subprocess.Popen([sys.executable, "-c", "pass"])
    parent.wait()
    began = time.monotonic()
    assert serve(tmp_path, Executor("proj", run=FakeDocker()), parent=parent.pid,
                 max_wall=30) == 0
    assert time.monotonic() - began < 5.0


def test_the_compose_file_carries_the_faults_to_the_coordinator(tmp_path, scenarios_dir):
    s1 = scenarios_dir / "scenario1.toml"
    out = tmp_path / "compose.yaml"
    plain = compose_text(ComposeConfig(s1, out))
    text = compose_text(ComposeConfig(s1, out, mode="realtime", lease_ms=500,
                                      faults=(parse_fault("cut:robot3@20+3"),
                                              parse_fault("freeze:robot1@35+3"))))
    assert "--fault-handoff" not in plain and "dns_opt" not in plain and "zenoh" not in plain
    coordinator = next(line for line in text.splitlines() if '"supervise"' in line)
    assert coordinator.endswith('"--fault-handoff", "/out/logs/faults", "--fault", '
                                '"cut:robot3@20+3", "--fault", "freeze:robot1@35+3"]')
    def command(service):
        return text.split(f"  {service}:\n", 1)[1].split("networks:", 1)[0]

    for service in ("robot1", "robot3"):  # the targets of the cut and the freeze
        assert '"--lease-ms", "500", "--zenoh-config", "/fleet/zenoh.json5"' in command(service)
    for service in ("sim", "robot2", "robot4", "robot5"):  # zenoh's lease: no false losses
        assert '"--secure", "/fleet/keys", "--zenoh-config", "/fleet/zenoh.json5"]' in \
            command(service), service
    assert leased_services((parse_fault("restart:robot2@5"),)) == frozenset({"router"})
    assert leased_services((parse_fault("cut:router@5+1"),)) is None  # everyone notices it
    assert leased_services(()) is None
    every = compose_text(ComposeConfig(s1, out, lease_ms=700))  # no faults: every service
    assert every.count('"--lease-ms", "700"') == 7
    assert '"--secure", "/fleet/keys", "--zenoh-config", "/fleet/zenoh.json5", "--out"' in \
        coordinator  # zenoh's lease: a stalled coordinator must not lose every token
    assert text.count('"./compose.zenoh.json5:/fleet/zenoh.json5:ro"') == 7
    assert text.count('dns_opt: ["timeout:1", "attempts:1"]') == 7
    # the router at a fixed address of the network's subnet, named in every client's own hosts
    # file (docker's /etc/hosts loses extra_hosts on a network disconnect)
    assert text.count('"./compose.hosts:/etc/hosts:ro"') == 7
    assert "ipv4_address: 172.31.247.2" in text.split("  sim:\n")[0]
    assert text.endswith("        - subnet: 172.31.247.0/24\n")
    assert "ipam" not in plain and "/etc/hosts" not in plain
    router = text.split("  router:\n", 1)[1].split("  sim:\n", 1)[0]
    assert '"--lease-ms", "500"]' in router and "zenoh.json5" not in router
    assert "--fault cut:robot3@20+3 --fault freeze:robot1@35+3" in text.splitlines()[0]
    path = write_compose(ComposeConfig(s1, out, faults=(parse_fault("kill:robot2@5"),)))
    assert RECONNECT in zenoh_path(path).read_text()
    assert "172.31.247.2\trouter\n" in hosts_path(path).read_text()
    plain_path = write_compose(ComposeConfig(s1, tmp_path / "plain.yaml"))
    assert not zenoh_path(plain_path).exists() and not hosts_path(plain_path).exists()
    other = write_compose(ComposeConfig(s1, tmp_path / "other.yaml", fault_subnet="10.9.8.0/24",
                                        faults=(parse_fault("kill:robot2@5"),)))
    assert "10.9.8.2\trouter\n" in hosts_path(other).read_text()
    assert "ipv4_address: 10.9.8.2" in other.read_text()
    assert "--fault-subnet 10.9.8.0/24" in other.read_text().splitlines()[0]
    for bad, why in (("10.9.8.1/24", "host bits set"), ("fe80::/64", "expected an IPv4"),
                     ("10.9.8.0/29", "5 address\\(es\\) for 8 containers")):
        with pytest.raises(ComposeError, match=why):
            write_compose(ComposeConfig(s1, tmp_path / "bad" / "c.yaml", fault_subnet=bad,
                                        faults=(parse_fault("kill:robot2@5"),)))
    assert not (tmp_path / "bad").exists()


def test_a_scenarios_own_faults_get_the_handoff_and_partitions_write_nothing(tmp_path,
                                                                             scenarios_dir):
    scenario = tmp_path / "s.toml"
    scenario.write_text((scenarios_dir / "scenario1.toml").read_text()
                        + '\n[[faults]]\nspec = "freeze:robot1@5+1"\n')
    text = compose_text(ComposeConfig(scenario, tmp_path / "compose.yaml"))
    coordinator = next(line for line in text.splitlines() if '"supervise"' in line)
    assert coordinator.endswith('"--fault-handoff", "/out/logs/faults"]')  # it reads the file
    bad = ComposeConfig(scenarios_dir / "scenario1.toml", tmp_path / "out" / "compose.yaml",
                        faults=(parse_fault("partition:robot3,robot4@5+1"),))
    with pytest.raises(FaultError, match="partitions are not supported in compose"):
        write_compose(bad)
    assert not (tmp_path / "out").exists()
