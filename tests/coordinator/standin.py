"""Stand-in router / sim / agent processes for the coordinator tests (a script, not a test module).

``python standin.py ROLE SCENARIO --endpoint EP [--robot ID] [options]`` speaks just enough of the
runtime protocol (architecture.md §2–§3) over a real zenoh session: the router listens; the sim
and agents declare their liveliness tokens; the sim publishes pre-start frames, then after
``Control(start)`` one ``MocapFrame`` per tick (robots moving on circles) until ``--duration``,
publishes ``Event(sim_done)`` and exits at ``Control(stop)``; agents publish a status and wait for
stop. Misbehaviour flags exercise the coordinator: ``--ignore-term`` (needs SIGKILL),
``--grandchild`` (leaves a sleeping grandchild in its process group), ``--die-after S``,
``--no-token``.
"""

from __future__ import annotations

import argparse
import math
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from tlfleet.agent.scenario import load_scenario  # noqa: E402
from tlfleet.bus.protocol import keys  # noqa: E402
from tlfleet.bus.protocol.codec import decode, encode  # noqa: E402
from tlfleet.bus.protocol.messages import Control, Event, LtlStatus, MocapFrame, StlStatus  # noqa: E402
from tlfleet.bus.transport import TransportConfig  # noqa: E402
from tlfleet.bus.zenoh.transport import open_transport  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("role", choices=("router", "sim", "agent"))
    parser.add_argument("scenario")
    parser.add_argument("--endpoint", required=True)
    parser.add_argument("--robot", type=int, default=0)
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument("--rate", type=float, default=100.0)  # [Hz] frames per wall second
    parser.add_argument("--ignore-term", action="store_true")
    parser.add_argument("--grandchild", action="store_true")
    parser.add_argument("--die-after", type=float, default=None)
    parser.add_argument("--no-token", action="store_true")
    args = parser.parse_args()

    stop = threading.Event()
    if args.ignore_term:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    else:
        signal.signal(signal.SIGTERM, lambda *_: stop.set())
    if args.grandchild:
        subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    if args.role == "router":
        transport = open_transport(TransportConfig(mode="router", listen=(args.endpoint,)))
    else:
        transport = open_transport(TransportConfig(mode="client", connect=(args.endpoint,)))
    scenario = load_scenario(args.scenario) if args.role != "router" else None
    fleet = scenario.fleet if scenario is not None else ""
    started = threading.Event()

    def on_control(_key: str, payload: bytes) -> None:
        msg = decode(Control, payload)
        (started if msg.cmd == "start" else stop).set()

    try:
        if args.role == "router":
            while not stop.wait(0.05):
                pass
            return 0
        transport.subscribe(keys.control(fleet), on_control)
        if not args.no_token:
            role, ident = ("sim", 0) if args.role == "sim" else ("agent", args.robot)
            transport.declare_alive(keys.alive(fleet, role, ident))
        born = time.monotonic()
        if args.role == "agent":
            robot = next(r for r in scenario.robots if r.id == args.robot)
            while not stop.wait(0.05):
                if args.die_after is not None and time.monotonic() - born > args.die_after:
                    return 7
                if started.is_set():
                    if robot.is_stl:
                        msg = StlStatus(robot.id, 0.0, 0, 0.1, 0.2, -0.1, 0.05, 1, 0, 1, -1,
                                        (1, 0, 0))
                    else:
                        msg = LtlStatus(robot.id, 0.0, ("start",), (scenario.regions[0].name,),
                                        None, (0,), ((scenario.regions[0].name, 1),), 1, "go")
                    transport.publish(keys.status(fleet, robot.id), encode(msg))
            return 0
        # sim
        ids = sorted(r.id for r in scenario.robots)

        def frame(k: int) -> MocapFrame:
            t = k / 100.0
            return MocapFrame(t, k, tuple((r, math.cos(t + r), math.sin(t + r), 0.0)
                                          for r in ids))

        while not started.wait(0.1):
            transport.publish(keys.mocap(fleet), encode(frame(0)))
            if stop.is_set():
                return 0
        k = 0
        while not stop.is_set() and k / 100.0 < args.duration:
            transport.publish(keys.mocap(fleet), encode(frame(k)))
            k += 1
            time.sleep(1.0 / args.rate)
        transport.publish(keys.mocap(fleet), encode(frame(k)))
        transport.publish(keys.event(fleet, "sim", 0),
                          encode(Event(k / 100.0, "sim", "sim_done", {})))
        transport.publish(keys.event(fleet, "sim", 0), encode(Event(0.5, "sim", "contact",
                                                          {"a": ids[0], "b": "wall"})))
        stop.wait(30.0)
        return 0
    finally:
        transport.close()


if __name__ == "__main__":
    sys.exit(main())
