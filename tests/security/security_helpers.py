"""Helpers of the security tests: key directories in tmp dirs, secured zenoh client sessions with
explicit loopback endpoints (multicast scouting off), a router process started with --secure."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import zenoh
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.zenoh.security import KeyDir
from tlfleet.coordinator.launch.processes import free_port, wait_for_port
from tlfleet.coordinator.security.authority import write_keys

ROOT = Path(__file__).resolve().parents[2]
SCENARIO1 = ROOT / "scenarios" / "scenario1.toml"
CONNECT_TIMEOUT_MS = 1500


def make_keys(scenario: Path, out: Path) -> KeyDir:
    write_keys(load_scenario(scenario), out)
    return KeyDir(out)


def client_config(endpoint: str, *, ca: Path | None = None, cert: Path | None = None,
                  key: Path | None = None) -> zenoh.Config:
    """A client session config to ``endpoint``; TLS entries only for the files given."""
    c = zenoh.Config()
    c.insert_json5("mode", '"client"')
    c.insert_json5("connect/endpoints", json.dumps([endpoint]))
    c.insert_json5("listen/endpoints", "[]")
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("connect/timeout_ms", str(CONNECT_TIMEOUT_MS))
    c.insert_json5("connect/exit_on_failure", "true")
    if ca is not None:
        c.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(str(ca)))
    if cert is not None and key is not None:
        c.insert_json5("transport/link/tls/enable_mtls", "true")
        c.insert_json5("transport/link/tls/connect_certificate", json.dumps(str(cert)))
        c.insert_json5("transport/link/tls/connect_private_key", json.dumps(str(key)))
    return c


def open_as(endpoint: str, keys: KeyDir, name: str) -> zenoh.Session:
    """A client session holding identity ``name``'s certificate of ``keys``."""
    return zenoh.open(client_config(endpoint, ca=keys.ca, cert=keys.cert(name),
                                    key=keys.key(name)))


class SecuredRouter:
    """``tlfleet router --secure KEYS`` on a free loopback port; its stderr in ``log``."""

    def __init__(self, keys: KeyDir, fleet: str, log: Path):
        self.port = free_port()
        self.endpoint = f"tls/127.0.0.1:{self.port}"
        self.log = log
        self._handle = open(log, "wb")  # noqa: SIM115 (closed in stop())
        self.process = subprocess.Popen(
            [sys.executable, "-m", "tlfleet.cli", "router", "--fleet", fleet, "--listen",
             f"tcp/127.0.0.1:{self.port}", "--secure", str(keys.path)],
            stdout=self._handle, stderr=subprocess.STDOUT, start_new_session=True, cwd=ROOT)
        wait_for_port("127.0.0.1", self.port, 20.0)

    def stop(self) -> int:
        self.process.terminate()
        try:
            code = self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            code = self.process.wait(5)
        self._handle.close()
        return code

    def text(self) -> str:
        return self.log.read_text(errors="replace")


def wait_until(predicate, timeout: float, step: float = 0.02) -> bool:
    """Poll ``predicate`` until true or ``timeout`` [s] (bounded)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(step)
    return bool(predicate())


def robot_path(run_dir: Path, robot: int):
    """(N, 2) positions [m] of ``robot`` from a run's ``trajectory.csv``."""
    import numpy as np

    lines = (run_dir / "trajectory.csv").read_text().splitlines()
    header = lines[0].split(",")
    cols = [header.index(f"x{robot}"), header.index(f"y{robot}")]
    return np.array([[float(row.split(",")[c]) for c in cols] for row in lines[1:]])
