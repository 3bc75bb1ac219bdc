"""``tlfleet supervise`` (§4b): a fleet whose processes were started by hand.

The processes are started with the command lines a user types (``by_hand.start_by_hand``), on
loopback; ``tlfleet supervise`` joins them, records the run like ``tlfleet run`` and must give a
byte-identical Scenario 1 lockstep ``trajectory.csv``.
"""

from __future__ import annotations

import json
import time

import pytest
from by_hand import start_by_hand, supervise
from process_helpers import free_port
from system_helpers import HERE, SCENARIOS
from tlfleet.agent.scenario import load_scenario
from tlfleet.coordinator.launch.processes import Launcher, tlfleet_command
from tlfleet.coordinator.supervise import SuperviseConfig, SuperviseError, supervise_fleet

pytestmark = pytest.mark.system
TWO = HERE / "two_robots.toml"
RUN_FILES = ("scenario.toml", "trajectory.csv", "status.csv", "events.jsonl", "run.json",
             "summary.txt", "report.md", "report.json")


def test_supervise_with_no_router_fails_within_5_s_naming_the_endpoint(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    # the wait itself, in this process (interpreter start-up is not supervise's doing)
    started = time.monotonic()
    with pytest.raises(SuperviseError, match=f"no zenoh router answers at {endpoint}"):
        supervise_fleet(SuperviseConfig(TWO, connect=(endpoint,), out=tmp_path / "run"))
    assert time.monotonic() - started <= 5.0
    assert not (tmp_path / "run").exists()  # nothing written
    done = supervise(TWO, endpoint, tmp_path / "run", timeout=60)  # the command: exit 1, named
    assert done.returncode == 1, done.stderr
    assert f"tlfleet supervise: no zenoh router answers at {endpoint}" in done.stderr
    assert not (tmp_path / "run").exists()


def test_supervise_names_the_processes_it_still_waits_for(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Launcher(tmp_path / "logs") as launcher:
        launcher.start("router", tlfleet_command("router", "--fleet", "two_robots",
                                                 "--listen", endpoint))
        launcher.start("agent-2", tlfleet_command("agent", str(TWO), "--robot", "2",
                                                  "--connect", endpoint))
        time.sleep(1.0)
        done = supervise(TWO, endpoint, tmp_path / "run", "--wait", "3", timeout=60)
    assert done.returncode == 1
    waiting = [line for line in done.stderr.splitlines() if "waiting for" in line]
    assert len(waiting) >= 2, done.stderr  # at once, then every second
    assert "sim" in waiting[-1] and "agent-1" in waiting[-1] and "agent-2" not in waiting[-1]
    assert "not up after 3 s (no liveliness token): sim, agent-1" in done.stderr


def test_every_process_started_by_hand_says_what_it_waits_for(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Launcher(tmp_path / "logs") as launcher:
        start_by_hand(launcher, TWO, endpoint)
        deadline = time.monotonic() + 20
        logs = {}
        while time.monotonic() < deadline:
            logs = {c.name: c.log_path.read_text() for c in launcher.children}
            if all("waiting for" in text for text in logs.values()):
                break
            time.sleep(0.1)
    assert ("sim: waiting for start from a coordinator on tlfleet/two_robots/control"
            in logs["sim"])
    for robot in (1, 2):
        assert (f"agent {robot}: waiting for start from a coordinator on "
                "tlfleet/two_robots/control") in logs[f"agent-{robot}"]
    assert "router: listening on " + endpoint in logs["router"]


def test_a_secured_fleet_by_hand_is_supervised_with_its_keys(tmp_path):
    from tlfleet.coordinator.security.authority import write_keys

    keydir = tmp_path / "keys"
    write_keys(load_scenario(TWO), keydir)
    endpoint = f"tls/127.0.0.1:{free_port()}"
    common = ("--secure", str(keydir))
    with Launcher(tmp_path / "logs") as launcher:
        start_by_hand(launcher, TWO, endpoint, sim_args=("--duration", "3"), common=common)
        plain = supervise(TWO, endpoint.replace("tls/", "tcp/"), tmp_path / "refused",
                          "--duration", "3", "--wait", "3", "--connect-timeout", "2", timeout=60)
        done = supervise(TWO, endpoint, tmp_path / "run", "--duration", "3", "--no-rrd",
                         "--no-figures", *common, timeout=120)
    assert plain.returncode == 1, plain.stderr  # a plain-TCP coordinator cannot join
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    info = json.loads((tmp_path / "run" / "run.json").read_text())
    assert info["secure"] is True and info["coordinator"] == "supervise"
    assert set(info["fingerprints"]) >= {"ca", "router", "coordinator", "robot1", "robot2"}
    assert info["outcome"]["label"] == "clean", info["outcome"]


def test_each_process_of_a_secured_fleet_needs_only_the_ca_and_its_own_pair(tmp_path):
    """Least privilege: every process, the coordinator included, gets a directory with
    ``ca.pem`` and its own certificate and private key (the router also ``acl.json``) — no other
    process's private key anywhere — and the secured fleet runs clean."""
    import shutil

    from tlfleet.coordinator.security.authority import write_keys

    keydir = tmp_path / "keys"
    write_keys(load_scenario(TWO), keydir)

    def own(identity: str, *extra: str):
        path = tmp_path / f"keys-{identity}"
        path.mkdir()
        for name in ("ca.pem", f"{identity}.pem", f"{identity}.key", *extra):
            shutil.copy2(keydir / name, path / name)
        return path

    dirs = {"router": own("router", "acl.json"), "sim": own("sim"), "agent-1": own("robot1"),
            "agent-2": own("robot2"), "coordinator": own("coordinator")}
    endpoint = f"tls/127.0.0.1:{free_port()}"
    with Launcher(tmp_path / "logs") as launcher:
        start_by_hand(launcher, TWO, endpoint, sim_args=("--duration", "3"),
                      common=lambda name: ("--secure", str(dirs[name])))
        done = supervise(TWO, endpoint, tmp_path / "run", "--duration", "3", "--no-rrd",
                         "--no-figures", "--secure", str(dirs["coordinator"]), timeout=120)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    info = json.loads((tmp_path / "run" / "run.json").read_text())
    assert info["outcome"]["label"] == "clean", info["outcome"]
    assert set(info["fingerprints"]) == {"ca", "coordinator"}  # the certificates it holds
    keys_held = sorted(p.name for p in dirs["coordinator"].iterdir() if p.suffix == ".key")
    assert keys_held == ["coordinator.key"]


@pytest.mark.slow
def test_scenario1_by_hand_plus_supervise_is_byte_identical_to_tlfleet_run(tmp_path,
                                                                          scenario1_run):
    scenario = SCENARIOS / "scenario1.toml"
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Launcher(tmp_path / "logs") as launcher:
        start_by_hand(launcher, scenario, endpoint)
        done = supervise(scenario, endpoint, tmp_path / "run", "--no-rrd")
        exits = {c.name: c.process.wait(10) for c in launcher.children if c.name != "router"}
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    assert exits == {"sim": 0, **{f"agent-{r}": 0 for r in range(1, 6)}}
    run_dir = tmp_path / "run"
    for name in RUN_FILES:
        assert (run_dir / name).is_file(), name
    info = json.loads((run_dir / "run.json").read_text())
    assert info["clean"] and info["coordinator"] == "supervise"
    assert all(info["left_after_stop"].values())
    reference = (scenario1_run.run_dir / "trajectory.csv").read_bytes()
    assert len(reference.splitlines()) == 1 + 9001
    assert (run_dir / "trajectory.csv").read_bytes() == reference
    assert f"run directory: {run_dir}" in done.stdout
