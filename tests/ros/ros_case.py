"""One ROS test case, run inside an isolated namespace by :func:`ros_harness.run_case`.

``python ros_case.py CASE.json`` starts the case's processes — the fake robots
(:mod:`fake_robots`), and either ``tlfleet run SCENARIO --hardware LAB`` (``"kind": "run"``), a
zenoh router plus ``tlfleet hw`` driven by this script standing in for the coordinator and the
agents (``"kind": "bridge"``), or a bench's probe process on the lab's topics (``"probe"``) —
performs the case's steps and writes ``result.json`` beside the
case file: what this script saw on zenoh (events, frames), when it did what (CLOCK_MONOTONIC),
the bridge's exit code and time, and the commands the fake robots received. Every process is
stopped in ``finally``; every wait is bounded.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from ros_harness import FAKE_ROBOTS, fake_robot_specs, lab_toml, received, wait_file
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import decode, encode
from tlfleet.bus.protocol.messages import Command, Control, Event, MocapFrame
from tlfleet.bus.transport import TransportConfig
from tlfleet.bus.zenoh.transport import open_transport


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def cpu_seconds(procs: dict[str, subprocess.Popen]) -> dict[str, float]:
    """CPU time [s] (user + system) of each live process so far."""
    out = {}
    for name, proc in procs.items():
        try:
            fields = Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
            out[name] = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, IndexError, ValueError):
            continue
    return out


def tlfleet(*args: str) -> list[str]:
    return [sys.executable, "-m", "tlfleet.cli", *args]


class Fleet:
    """This script as coordinator and agents, on zenoh."""

    def __init__(self, fleet: str, endpoint: str):
        self.fleet = fleet
        self.t = open_transport(TransportConfig(mode="client", connect=(endpoint,)))
        self.lock = threading.Lock()
        self.frame: MocapFrame | None = None
        self.frames = 0
        self.events: list[dict] = []
        self.echo: tuple[int, ...] = ()
        self.omni: set[int] = set()  # robots answered at once on every tick frame
        self.echoed: dict[int, float] = {}  # seq -> CLOCK_MONOTONIC when its frame came
        self.handles = [
            self.t.subscribe(keys.mocap(fleet), self._on_frame),
            self.t.subscribe(keys.all_events(fleet), self._on_event),
        ]

    def _on_frame(self, _key: str, payload: bytes) -> None:
        arrival = time.monotonic()
        frame = decode(MocapFrame, payload)
        if self.echo and frame.seq > 0:
            # an agent that answers at once, its angular rate coding the frame's seq (ω is
            # neither rotated into the body frame nor clipped at 0.1 rad/s)
            self.echoed[frame.seq] = arrival
            for robot in self.echo:
                u = (0.0, 0.0, seq_code(frame.seq)) if robot in self.omni else \
                    (0.0, seq_code(frame.seq))
                self.t.publish(keys.cmd(self.fleet, robot),
                               encode(Command(robot, frame.t, frame.seq, u)))
        with self.lock:
            self.frame = frame
            self.frames += 1

    def _on_event(self, _key: str, payload: bytes) -> None:
        event = decode(Event, payload)
        with self.lock:
            self.events.append({"t": event.t, "kind": event.kind, "data": event.data,
                                "wall": time.monotonic()})

    def newest(self) -> MocapFrame | None:
        with self.lock:
            return self.frame

    def control(self, cmd: str) -> None:
        self.t.publish(keys.control(self.fleet), encode(Control(cmd)))

    def command(self, robot: int, u: list[float]) -> None:
        frame = self.newest()
        t, seq = (frame.t, frame.seq) if frame is not None else (0.0, 0)
        self.t.publish(keys.cmd(self.fleet, robot), encode(Command(robot, t, seq, tuple(u))))

    def close(self) -> None:
        for h in self.handles:
            h.close()
        self.t.close()


def seq_code(seq: int) -> float:
    """The angular rate [rad/s] that codes a frame's seq modulo 1000 (:func:`seq_of`)."""
    return (seq % 1000 + 1) * 1e-4


def seq_of(omega: float) -> int:
    return round(omega * 1e4) - 1


def goto_command(kind: str, pose: tuple[float, float, float], goal: list[float],
                 spin: float) -> list[float]:
    """A plain go-to-point law (world-frame for omni robots, spinning at ``spin`` [rad/s] so a
    wrong body-frame rotation sends the robot astray)."""
    x, y, yaw = pose
    dx, dy = goal[0] - x, goal[1] - y
    d = math.hypot(dx, dy)
    if kind == "omni":
        speed = min(0.18, 1.5 * d)
        return [speed * dx / d if d > 1e-9 else 0.0, speed * dy / d if d > 1e-9 else 0.0, spin]
    heading = math.atan2(dy, dx)
    err = math.atan2(math.sin(heading - yaw), math.cos(heading - yaw))
    v = min(0.25, 1.2 * d) * max(0.0, math.cos(err))
    return [v, max(-1.0, min(1.0, 2.5 * err))]


def main(case_path: str) -> int:
    # SIGTERM (a test run ending early) unwinds through the finally below, which stops every
    # process of the case
    signal.signal(signal.SIGTERM, _terminated)
    case_file = Path(case_path)
    case = json.loads(case_file.read_text())
    tmp = case_file.parent
    scenario = load_scenario(case["scenario"])
    domain = int(case["domain_id"])
    overrides = {int(k): v for k, v in case.get("robots", {}).items()}
    lab = tmp / "lab.toml"
    lab.write_text(lab_toml([(r.id, r.kind) for r in scenario.robots],
                            int(case.get("lab_domain", domain)),
                            **case.get("lab", {})))
    log = tmp / "received.jsonl"
    ready = tmp / "robots.ready"
    robots_config = tmp / "robots.json"
    robots_config.write_text(json.dumps({
        "domain_id": domain, "log": str(log), "ready": str(ready),
        "robots": fake_robot_specs(scenario, overrides)}))
    procs: dict[str, subprocess.Popen] = {}
    result: dict = {"marks": {}}
    fleet: Fleet | None = None
    started = time.monotonic()
    try:
        procs["robots"] = subprocess.Popen([sys.executable, str(FAKE_ROBOTS), str(robots_config)])
        if not wait_file(ready, 30.0):
            raise RuntimeError("the fake robots did not come up within 30 s")
        if case["kind"] == "run":
            argv = tlfleet("run", case["scenario"], "--hardware", str(lab), "--out",
                           str(tmp / "run"), "--no-rrd", "--no-figures", "--quiet",
                           *case.get("args", []))
            start = time.monotonic()
            proc = subprocess.run(argv, timeout=float(case.get("timeout", 300)),
                                  capture_output=True, text=True)
            result.update(returncode=proc.returncode, stdout=proc.stdout[-4000:],
                          stderr=proc.stderr[-4000:], wall=time.monotonic() - start,
                          run_dir=str(tmp / "run"))
        elif case["kind"] == "mirror":
            mirror_case(case, tmp, procs, result)
        elif case["kind"] == "probe":
            probe_case(case, lab, procs, result)
        elif case["kind"] == "check":
            proc = subprocess.run(tlfleet("hw", case["scenario"], "--lab", str(lab), "--check",
                                          "--check-wait", "2"),
                                  timeout=60, capture_output=True, text=True)
            result.update(returncode=proc.returncode, stdout=proc.stdout, stderr=proc.stderr)
        else:
            fleet = bridge_case(case, scenario, lab, procs, result, tmp)
    finally:
        result["wall"] = time.monotonic() - started
        result["cpu"] = cpu_seconds(procs)
        for name, proc in reversed(list(procs.items())):
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
            result.setdefault("exit", {})[name] = proc.returncode
        if fleet is not None:
            result["events"] = fleet.events
            result["frames"] = fleet.frames
            fleet.close()
        result["received"] = received(log)
        final = ready.read_text() if ready.exists() else ""
        result["robots_final"] = json.loads(final)["final"] if final.startswith("{") else None
        (tmp / "result.json").write_text(json.dumps(result))
    return 0


def probe_case(case: dict, lab: Path, procs: dict, result: dict) -> None:
    """``case["argv"] + [LAB]`` beside the fake robots (a bench's bare node on the lab's
    topics): its CPU time over ``window`` [s] wall after ``warmup`` [s]."""
    procs["probe"] = subprocess.Popen([*case["argv"], str(lab)])
    time.sleep(float(case.get("warmup", 2.0)))
    t0, cpu0 = time.monotonic(), cpu_seconds(procs).get("probe")
    time.sleep(float(case["window"]))
    t1, cpu1 = time.monotonic(), cpu_seconds(procs).get("probe")
    if cpu0 is None or cpu1 is None or procs["probe"].poll() is not None:
        raise RuntimeError(f"the probe exited early ({procs['probe'].poll()})")
    result.update(probe_cpu_share=(cpu1 - cpu0) / (t1 - t0), window_s=t1 - t0)


def mirror_case(case: dict, tmp: Path, procs: dict, result: dict) -> None:
    """A simulated realtime run, ``tlfleet ros-mirror`` joined to it, and an rclpy node here
    recording what the mirror publishes."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseArray, PoseStamped
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
    from visualization_msgs.msg import MarkerArray

    run_dir = tmp / "run"
    procs["run"] = subprocess.Popen(tlfleet(
        "run", case["scenario"], "--realtime", "--duration", str(case["duration"]), "--out",
        str(run_dir), "--no-report", "--no-figures", "--no-rrd", "--quiet"),
        stdout=subprocess.DEVNULL, stderr=open(tmp / "run.log", "w"))  # noqa: SIM115
    deadline = time.monotonic() + 30
    endpoint = None
    while endpoint is None and time.monotonic() < deadline:
        try:
            endpoint = json.loads((run_dir / "run.json").read_text())["endpoint"]
        except (OSError, ValueError, KeyError):
            time.sleep(0.1)
    if endpoint is None:
        raise RuntimeError("the run wrote no endpoint within 30 s")
    mirror_log = open(tmp / "mirror.log", "w")  # noqa: SIM115
    procs["mirror"] = subprocess.Popen(tlfleet(
        "ros-mirror", case["scenario"], "--connect", endpoint, "--domain-id",
        str(case["domain_id"]), "--rate", "50"), stdout=mirror_log, stderr=subprocess.STDOUT)
    rclpy.init(domain_id=int(case["domain_id"]))
    node = rclpy.create_node("mirror_probe")
    got: dict[str, list] = {}

    def keep(topic, convert):
        return lambda msg: got.setdefault(topic, []).append(convert(msg))

    def stamp(h):
        return h.stamp.sec + 1e-9 * h.stamp.nanosec

    def q_yaw(q):
        return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))

    node.create_subscription(PoseStamped, "/tlfleet/robot1/pose", keep("pose1", lambda m: [
        stamp(m.header), m.pose.position.x, m.pose.position.y, q_yaw(m.pose.orientation),
        m.header.frame_id]), qos_profile_sensor_data)
    node.create_subscription(Odometry, "/tlfleet/robot2/odom", keep("odom2", lambda m: [
        stamp(m.header), m.pose.pose.position.x, m.twist.twist.linear.x,
        m.twist.twist.linear.y, m.child_frame_id]), qos_profile_sensor_data)
    node.create_subscription(PoseArray, "/tlfleet/poses", keep("array", lambda m: [
        stamp(m.header), [[p.position.x, p.position.y] for p in m.poses]]),
        qos_profile_sensor_data)
    node.create_subscription(MarkerArray, "/tlfleet/scene", keep("scene", lambda m: [
        [mk.ns, mk.text, mk.pose.position.x] for mk in m.markers]),
        QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
    node.create_subscription(DiagnosticArray, "/diagnostics", keep("diag", lambda m: [
        [s.name, s.message, s.level[0] if isinstance(s.level, bytes) else s.level,
         {kv.key: kv.value for kv in s.values}] for s in m.status]), 10)
    end = time.monotonic() + float(case["duration"]) + 60
    while time.monotonic() < end and procs["mirror"].poll() is None:
        rclpy.spin_once(node, timeout_sec=0.05)
    for _ in range(20):
        rclpy.spin_once(node, timeout_sec=0.05)
    with contextlib.suppress(subprocess.TimeoutExpired):
        procs["run"].wait(timeout=30)
    result.update(mirror_rc=procs["mirror"].poll(), run_rc=procs["run"].poll(),
                  got=got, run_dir=str(run_dir))
    mirror_log.close()
    result["mirror_log"] = (tmp / "mirror.log").read_text(errors="replace")[-3000:]
    node.destroy_node()
    rclpy.shutdown()


def bridge_case(case: dict, scenario, lab: Path, procs: dict, result: dict,
                tmp: Path) -> Fleet:
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    procs["router"] = subprocess.Popen(tlfleet("router", "--fleet", scenario.fleet, "--listen",
                                               endpoint))
    deadline = time.monotonic() + 20
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            break
        except OSError:
            if time.monotonic() > deadline:
                raise RuntimeError("the router did not listen within 20 s") from None
            time.sleep(0.1)
    hw_log = open(tmp / "hw.log", "w")  # noqa: SIM115 (the child writes it; closed at exit)
    procs["bridge"] = subprocess.Popen(
        tlfleet("-v", "hw", case["scenario"], "--lab", str(lab), "--connect", endpoint,
                "--wait-mocap", str(case.get("wait_mocap", 10)), *case.get("args", [])),
        stdout=hw_log, stderr=subprocess.STDOUT)
    fleet = Fleet(scenario.fleet, endpoint)
    kinds = {r.id: r.kind for r in scenario.robots}
    marks = result["marks"]
    deadline = time.monotonic() + 30
    while fleet.newest() is None and procs["bridge"].poll() is None:
        if time.monotonic() > deadline:
            raise RuntimeError("no frame from the bridge within 30 s")
        time.sleep(0.05)
    for step in case["steps"]:
        do = step["do"]
        marks.setdefault(do, []).append(time.monotonic())
        result.setdefault("cpu_at", []).append([do, time.monotonic(), cpu_seconds(procs)])
        if procs["bridge"].poll() is not None and do not in ("wait_exit",):
            break
        if do == "start":
            fleet.control("start")
        elif do == "stop":
            fleet.control("stop")
        elif do == "sleep":
            time.sleep(float(step["s"]))
        elif do == "stream":
            # commands at each robot's rate (Hz) for `s` seconds; `u` per robot (or goto goals)
            end = time.monotonic() + float(step["s"])
            rates = {int(r): float(hz) for r, hz in step["rates"].items()}
            due = dict.fromkeys(rates, time.monotonic())
            goals = {int(r): g for r, g in step.get("goals", {}).items()}
            while time.monotonic() < end:
                now = time.monotonic()
                frame = fleet.newest()
                for robot, hz in rates.items():
                    if now < due[robot]:
                        continue
                    due[robot] = now + 1.0 / hz
                    if robot in goals and frame is not None:
                        u = goto_command(kinds[robot], frame.pose(robot), goals[robot],
                                         float(step.get("spin", 0.0)))
                    else:
                        u = step["u"][str(robot)]
                    fleet.command(robot, u)
                time.sleep(0.002)
            frame = fleet.newest()
            if frame is not None:
                result.setdefault("poses", []).append(
                    {str(r): list(frame.pose(r)) for r in kinds})
        elif do == "echo":
            fleet.omni = {r for r, k in kinds.items() if k == "omni"}
            fleet.echo = tuple(sorted(kinds))
            time.sleep(float(step["s"]))
            fleet.echo = ()
            result["echoed"] = dict(fleet.echoed)
        elif do == "sigterm":
            result["cpu_before_sigterm"] = cpu_seconds(procs)
            procs["bridge"].send_signal(signal.SIGTERM)
        elif do == "wait_exit":
            with contextlib.suppress(subprocess.TimeoutExpired):
                procs["bridge"].wait(timeout=float(step.get("s", 15)))
            marks["bridge_exit"] = [time.monotonic()]
        else:
            raise ValueError(f"unknown step {do!r}")
    bridge = procs["bridge"]
    if bridge.poll() is None:
        with contextlib.suppress(subprocess.TimeoutExpired):
            bridge.wait(timeout=float(case.get("end_wait", 0.1)))
    result["bridge_rc"] = bridge.poll()
    hw_log.close()
    result["hw_log"] = (tmp / "hw.log").read_text(errors="replace")[-6000:]
    return fleet


def _terminated(_signum: int, _frame: object) -> None:
    raise SystemExit(f"{Path(__file__).name}: terminated")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
