"""``tlfleet replay --viewer``: serves on 127.0.0.1, the web viewer page loads, Ctrl-C ends it."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

from tlfleet.coordinator.launch.processes import free_port
from visual_helpers import ROOT, read_rrd


def test_replay_viewer_serves_until_ctrl_c(run_dir: Path) -> None:
    grpc_port, web_port = free_port(), free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "tlfleet.cli", "replay", str(run_dir), "--viewer",
         "--grpc-port", str(grpc_port), "--web-port", str(web_port)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = ""
        deadline = time.monotonic() + 30
        while not url:
            line = proc.stdout.readline()
            assert line and time.monotonic() < deadline, f"no URL: {proc.stderr.read()}"
            if line.startswith("viewer: "):
                url = line.split(" ", 1)[1].strip()
        assert url == (f"http://127.0.0.1:{web_port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A"
                       f"{grpc_port}%2Fproxy")
        with urllib.request.urlopen(url, timeout=10) as page:
            assert page.status == 200
            assert b"<html" in page.read(4096).lower()
        # the file is complete while the viewer still serves
        assert read_rrd(run_dir / "run.rrd")["timed"]["/world/robots"] == 51
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0
    finally:
        proc.kill()
        proc.wait()
