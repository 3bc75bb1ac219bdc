"""docker compose fleets (§4d): ``tlfleet compose``, the committed compose file, and
``make compose-run``'s script giving Scenario 1's lockstep ``trajectory.csv`` byte for byte.

The docker tests need root, docker.io, docker-compose and mmdebstrap (installed by .ci/run); they
skip with the reason elsewhere and fail under TLFLEET_REQUIRE_SYSTEM=1. The base image and the
wheelhouse are cached in ``$TLFLEET_DOCKER_WORK`` (default /tmp/tlfleet-docker) and docker/wheels
for the rest of the run; the image is rebuilt only when the project's sources change.
"""

from __future__ import annotations

import os
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


@pytest.mark.needs_system
def test_the_compose_file_is_valid_for_docker_compose():
    need_docker()
    compose = ["docker", "compose"] if subprocess.run(
        ["docker", "compose", "version"], capture_output=True).returncode == 0 \
        else ["docker-compose"]
    done = subprocess.run([*compose, "-f", str(COMMITTED), "config", "-q"], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr


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
    assert daemon_answers() == had_daemon  # a dockerd the script started is gone again
    if had_daemon:  # nothing of the project left in the daemon that was already there
        project = "tlfleet-scenario1-"
        for what in (["ps", "-a", "--format", "{{.Names}}"],
                     ["network", "ls", "--format", "{{.Name}}"]):
            listed = subprocess.run(["docker", *what], capture_output=True, text=True).stdout
            assert project not in listed, listed
