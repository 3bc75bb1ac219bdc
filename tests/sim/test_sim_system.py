"""``tlfleet sim`` as a real process on loopback zenoh: liveliness, frames, Control(stop), exit 0.

The sim runs as a peer listening on a free 127.0.0.1 port; the test connects a peer to it.
Every wait is on a condition with a timeout, and the process group is killed in ``finally``.
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from process_helpers import free_port, kill_group
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import Control, Event, MocapFrame
from tlfleet.bus.transport import TransportConfig
from tlfleet.bus.zenoh.transport import ZenohTransport

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "scenario1.toml"



def start_sim(endpoint: str, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "tlfleet.cli", "sim", str(SCENARIO), "--mode", "peer",
         "--listen", endpoint, *extra],
        cwd=ROOT, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)



def open_peer(endpoint: str) -> ZenohTransport:
    # The sim may still be starting: a peer retries its connect endpoint in the background.
    return ZenohTransport.open(TransportConfig(mode="peer", connect=(endpoint,)))


@pytest.mark.system
@pytest.mark.parametrize("how", ["control", "sigterm", "duration"])
def test_sim_process_publishes_frames_and_stops_cleanly(how):
    fleet = load_scenario(SCENARIO).fleet
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    proc = start_sim(endpoint, "--lockstep", "--duration", "0.2")
    transport = None
    try:
        transport = open_peer(endpoint)
        alive, framed = threading.Event(), threading.Event()
        frames: list[MocapFrame] = []

        def on_alive(key: str, up: bool) -> None:
            if up and key == keys.alive(fleet, "sim", 0):
                alive.set()

        def on_frame(_key: str, payload: bytes) -> None:
            frames.append(decode(MocapFrame, payload))
            framed.set()

        transport.watch_alive(keys.all_alive(fleet), on_alive)
        transport.subscribe(keys.mocap(fleet), on_frame)
        assert alive.wait(15), "no liveliness token alive/sim/0"
        assert framed.wait(10), "no mocap frame"
        frame = frames[0]
        assert (frame.t, frame.seq, frame.due) == (0.0, 0, ())
        assert [row[0] for row in frame.poses] == [1, 2, 3, 4, 5]
        assert frame.pose(3) == pytest.approx((-0.5, -1.0, 0.0))

        if how == "control":
            deadline = time.monotonic() + 10
            while proc.poll() is None and time.monotonic() < deadline:
                transport.publish(keys.control(fleet), encode(Control("stop")))
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(0.2)
        elif how == "sigterm":
            proc.send_signal(signal.SIGTERM)
        else:  # start the mission: no agent is alive, so no tick waits; it ends at 0.2 s
            events: list[Event] = []
            done = threading.Event()

            def on_event(_key: str, payload: bytes) -> None:
                events.append(decode(Event, payload))
                if events[-1].kind == "sim_done":
                    done.set()

            transport.subscribe(keys.all_events(fleet), on_event)
            deadline = time.monotonic() + 10
            while not done.is_set() and time.monotonic() < deadline:
                transport.publish(keys.control(fleet), encode(Control("start")))
                done.wait(0.2)
            assert [e.kind for e in events] == ["sim_stats", "sim_done"]
            while frames[-1].seq < 20 and time.monotonic() < deadline:  # other subscriber thread
                time.sleep(0.01)
            assert frames[-1].seq == 20 and frames[-1].t == pytest.approx(0.2)
        assert proc.wait(10) == 0
    finally:
        if transport is not None:
            transport.close()
        kill_group(proc)
        if proc.stderr:
            proc.stderr.close()
        if proc.stdout:
            proc.stdout.close()
