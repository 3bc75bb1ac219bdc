"""docker compose fleets (§4d): ``tlfleet compose``, the committed compose file, and
``make compose-run``'s script giving Scenario 1's lockstep ``trajectory.csv`` byte for byte.

The docker tests need root, docker.io, docker-compose and mmdebstrap (installed by .ci/run); they
skip with the reason elsewhere and fail under TLFLEET_REQUIRE_SYSTEM=1. The base image and the
wheelhouse are cached in ``$TLFLEET_DOCKER_WORK`` (default /tmp/tlfleet-docker) and docker/wheels
for the rest of the run; the image is rebuilt only when the project's sources change.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import pytest
from needs import need_docker
from system_helpers import ROOT, SCENARIOS
from tlfleet.coordinator.compose import ComposeConfig, compose_text

COMMITTED = ROOT / "docker" / "compose.scenario1.yaml"


def tlfleet(*args: str, cwd=ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tlfleet.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=60)


def test_the_committed_compose_file_is_current(monkeypatch):
    monkeypatch.chdir(ROOT)
    expected = compose_text(ComposeConfig(SCENARIOS.relative_to(ROOT) / "scenario1.toml",
                                          COMMITTED.relative_to(ROOT)))
    assert COMMITTED.read_text() == expected, \
        "regenerate: tlfleet compose scenarios/scenario1.toml --out docker/compose.scenario1.yaml"


def test_compose_writes_one_service_per_process(tmp_path):
    done = tlfleet("compose", str(SCENARIOS / "scenario1.toml"), "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr
    text = (tmp_path / "compose.yaml").read_text()
    services = [line.strip()[:-1] for line in text.splitlines()
                if line.startswith("  ") and not line.startswith("   ") and line.endswith(":")]
    assert services == ["router", "sim", *(f"robot{i}" for i in range(1, 6)), "coordinator",
                        "fleet"]  # "fleet": the one network
    assert text.count("condition: service_healthy") == 7  # every client waits for the router
    # secured by default: tls, --secure, the key directory mounted read-only
    assert '["agent", "/fleet/scenario.toml", "--robot", "3", "--connect", "tls/router:7447", ' \
        '"--secure", "/fleet/keys"]' in text
    assert '"--listen", "tls/0.0.0.0:7447", "--secure", "/fleet/keys"]' in text
    assert text.count('"${TLFLEET_KEYS:-./keys}:/fleet/keys:ro"') == 8  # every service
    assert '"supervise", "/fleet/scenario.toml", "--lockstep"' in text
    assert os.path.relpath(SCENARIOS / "scenario1.toml", tmp_path) in text
    done = tlfleet("compose", str(SCENARIOS / "scenario1.toml"), "--out",
                   str(tmp_path / "plain.yaml"), "--insecure")
    assert done.returncode == 0, done.stderr
    plain = (tmp_path / "plain.yaml").read_text()
    assert '["agent", "/fleet/scenario.toml", "--robot", "3", "--connect", "tcp/router:7447"]' \
        in plain
    assert "/fleet/keys" not in plain and "--secure" not in plain


def test_compose_on_an_invalid_scenario_fails_before_writing_anything(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nduration = 10\n[[robots]]\nid = 1\nkind = "tank"\n')
    done = tlfleet("compose", str(bad), "--out", str(tmp_path / "out"))
    assert done.returncode == 1
    assert f"tlfleet compose: {bad}: robots[id=1].kind" in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()


def compose_implementations() -> list[list[str]]:
    """Every docker compose on this machine: v2 (the docker plugin) and v1 (docker-compose)."""
    found = []
    if subprocess.run(["docker", "compose", "version"], capture_output=True).returncode == 0:
        found.append(["docker", "compose"])
    if shutil.which("docker-compose"):
        found.append(["docker-compose"])
    return found


@pytest.mark.needs_system
def test_the_compose_file_is_valid_for_docker_compose():
    """Each compose implementation present (v2 and v1 where both are; Debian bookworm ships v1)
    reads the file, with the keys this project relies on: init, a non-root user, the router's
    health check that does not connect, the coordinator's own image."""
    need_docker()
    implementations = compose_implementations()
    assert implementations, "no docker compose (make system-deps)"
    for compose in implementations:
        done = subprocess.run([*compose, "-f", str(COMMITTED), "config"], capture_output=True,
                              text=True, timeout=60, env=dict(os.environ, TLFLEET_UID="4321",
                                                              TLFLEET_GID="4322"))
        assert done.returncode == 0, (compose, done.stderr)
        config = done.stdout
        # every service: the router, the sim, 5 robots and the coordinator
        assert config.count("init: true") == 8, compose
        assert "4321:4322" in config and "create_connection" not in config
        assert "tlfleet-coordinator:local" in config


def daemon_answers() -> bool:
    return subprocess.run(["docker", "version"], capture_output=True).returncode == 0


@pytest.mark.slow
@pytest.mark.system
@pytest.mark.needs_system
def test_scenario1_as_a_compose_fleet_is_byte_identical_to_tlfleet_run(tmp_path, scenario1_run):
    need_docker()
    had_daemon = daemon_answers()
    out = tmp_path / "run"
    env = dict(os.environ, PYTHON=sys.executable)
    done = subprocess.run(["bash", str(ROOT / "docker" / "compose-run.sh"), str(COMMITTED),
                           str(out)], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=1200)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    for name in ("scenario.toml", "trajectory.csv", "status.csv", "events.jsonl", "run.json",
                 "summary.txt", "report.md", "report.json", "run.rrd", "logs/sim.log",
                 "logs/router.log", "logs/agent-1.log", "logs/coordinator.log"):
        assert (out / name).is_file(), name
    assert "report scenario1: t_end 90.00 s, 9001 frames, lockstep" in done.stdout
    assert (out / "trajectory.csv").read_bytes() == \
        (scenario1_run.run_dir / "trajectory.csv").read_bytes()
    # the router's health check reads the socket table: no TLS handshake cut short in its log
    router_log = (out / "logs" / "router.log").read_text()
    assert "handshake" not in router_log.lower(), router_log[-2000:]
    # the run directory is the invoking user's
    assert {p.stat().st_uid for p in out.rglob("*")} == {os.getuid()}
    assert "make clean` removes them" in done.stderr
    # the slim runtime image of the router, sim and agents (the coordinator's has rerun too)
    kept = re.search(r"tlfleet:local \(([\d.]+)([MG]B)\)", done.stderr)
    assert kept is not None, done.stderr[-2000:]
    size_mb = float(kept.group(1)) * (1000 if kept.group(2) == "GB" else 1)
    assert size_mb <= 400, f"runtime image {size_mb} MB"
    assert daemon_answers() == had_daemon  # a dockerd the script started is gone again
    if had_daemon:  # nothing of the project left in the daemon that was already there
        project = "tlfleet-scenario1-"
        for what in (["ps", "-a", "--format", "{{.Names}}"],
                     ["network", "ls", "--format", "{{.Name}}"]):
            listed = subprocess.run(["docker", *what], capture_output=True, text=True).stdout
            assert project not in listed, listed
